"""Run the catalogue of malformed inputs and options over every command.

Every case (``tests/catalogue.py``) breaks one thing of a small valid input and is run
in-process through ``bayes_mpem.cli.main`` with a time limit; the answer is judged
independently: ``ok`` (exit 0, rows out = rows in, finite outputs, a complete marked
folder; for ``stream`` every data line answered once and in order, and every answer
after a refused line the very answer of the clean dive; for ``batch`` every manifest row
with its status and a folder that matches it; for GARPOS and GNATSS every data line in
``classified.csv``), ``refused`` (exit 2 naming the file, line, column or option; the
output folder as before), or a failure (traceback, hang, another exit status, lost rows or
lines, non-finite output, a poisoned stream, a changed folder on a refusal). Prints the
counts by command and verdict and every failure; exits 1 if there is any.

``--part lbl`` runs the first catalogue (fit, sample, diagnose, locate, plot), ``--part
surfaces`` the newer surfaces (navigate, stream lines, replay, options and state, batch,
GARPOS, GNATSS; issue 27), ``all`` (default) both.

    nice -n 10 .venv/bin/python benchmarks/malformed_catalogue.py [--part surfaces]
        [--no-sample] [--keep DIR] [--only TEXT]
"""

from __future__ import annotations

import argparse
import collections
import sys
import tempfile
import time
import warnings
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
import catalogue  # noqa: E402


def _cases(args, work):
    cases = []
    if args.part in ("all", "lbl"):
        base = catalogue.make_base(work / "base", with_sample=not args.no_sample)
        cases += catalogue.cases(base, work / "cases", sample=not args.no_sample)
    cluster = None
    if args.part in ("all", "surfaces"):
        from distributed import LocalCluster

        cluster = LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                               dashboard_address=None, silence_logs=40)
        s = catalogue.make_surfaces(work / "surfaces")
        cases += catalogue.surface_cases(s, work / "surface_cases",
                                         scheduler=cluster.scheduler_address)
    return cases, cluster


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--part", choices=("all", "lbl", "surfaces"), default="all")
    ap.add_argument("--no-sample", action="store_true", help="skip the sample command's cases")
    ap.add_argument("--keep", default=None, help="work in this folder and keep it")
    ap.add_argument("--only", default=None, help="run only cases whose name contains this")
    args = ap.parse_args()
    warnings.simplefilter("ignore")
    work = Path(args.keep or tempfile.mkdtemp(prefix="bayes_mpem_catalogue_"))
    t0 = time.perf_counter()
    cases, cluster = _cases(args, work)
    if args.only:
        cases = [c for c in cases if args.only in c.name]
    counts = collections.Counter()
    failures = []
    try:
        for i, case in enumerate(cases, 1):
            o = catalogue.run_case(case, limit=120)
            group = case.kind or case.command
            counts[(group, o.verdict)] += 1
            if o.verdict not in ("ok", "refused"):
                failures.append(o)
            print(f"[{i}/{len(cases)}] {case.name}: {o.verdict} ({o.seconds:.1f} s)"
                  + (f"  {o.problems}" if o.problems else ""), flush=True)
    finally:
        if cluster is not None:
            cluster.close()
    print(f"\n{len(cases)} cases in {time.perf_counter() - t0:.0f} s (work folder {work})")
    commands = sorted({c for c, _ in counts})
    verdicts = sorted({v for _, v in counts})
    print(f"{'command':<10}" + "".join(f"{v:>10}" for v in verdicts) + f"{'total':>8}")
    for c in commands:
        print(f"{c:<10}" + "".join(f"{counts[(c, v)]:>10}" for v in verdicts)
              + f"{sum(counts[(c, v)] for v in verdicts):>8}")
    print(f"{'total':<10}" + "".join(f"{sum(counts[(c, v)] for c in commands):>10}"
                                     for v in verdicts) + f"{len(cases):>8}")
    for o in failures:
        print(f"FAILED {o.case.name}: {o.verdict}: {o.problems}")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
