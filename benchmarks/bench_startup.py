"""Start-up time of ``bayes-mpem --help`` and ``import bayes_mpem`` (goal: --help < 0.5 s).

Each command runs in a fresh Python process, ``--repeats`` times, interleaved; the median
wall time is reported, with the interpreter's own start (``python -c pass``) for reference
and the full scientific stack (``from bayes_mpem import fit``) for contrast. The console
script ``bayes-mpem`` does exactly what the ``--help`` line runs. Written to
``docs/benchmarks.md`` (section ``bench_startup``).

    python benchmarks/bench_startup.py [--repeats 15] [--before REV] [--no-write]

``--before REV`` also times ``bayes-mpem --help`` with the package source of git revision
``REV`` (checked out into a temporary folder and put first on ``PYTHONPATH``), e.g. the
commit before the lazy imports, ``c1ad3c0^``.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from datetime import date
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import machine, write_section  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
GOAL_S = 0.5
CASES = {
    "python -c pass (interpreter alone)": "pass",
    "import bayes_mpem": "import bayes_mpem",
    "bayes-mpem --help": ("import sys, contextlib, io\n"
                          "from bayes_mpem.cli import main\n"
                          "sys.argv[0] = 'bayes-mpem'\n"
                          "with contextlib.redirect_stdout(io.StringIO()):\n"
                          "    try:\n        main(['--help'])\n"
                          "    except SystemExit as e:\n        assert e.code == 0\n"),
    "bayes-mpem fit --help": ("import sys, contextlib, io\n"
                              "from bayes_mpem.cli import main\n"
                              "with contextlib.redirect_stdout(io.StringIO()):\n"
                              "    try:\n        main(['fit', '--help'])\n"
                              "    except SystemExit as e:\n        assert e.code == 0\n"),
    "from bayes_mpem import fit (numpy, pandas, SciPy, emcee, ArviZ)":
        "from bayes_mpem import fit",
}


def time_once(code: str, src: str | None = None) -> float:
    """Wall seconds of one fresh process running ``code`` (package from ``src`` if given)."""
    env = dict(os.environ, PYTHONPATH=src) if src else None
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-c", code], check=True, stdout=subprocess.DEVNULL, env=env)
    return time.perf_counter() - t0


def checkout(rev: str, tmp: str) -> str:
    """The ``src`` folder of git revision ``rev``, extracted under ``tmp``."""
    archive = subprocess.run(["git", "-C", str(ROOT), "archive", rev, "src"], check=True,
                             capture_output=True).stdout
    subprocess.run(["tar", "-x", "-C", tmp], input=archive, check=True)
    return str(Path(tmp) / "src")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=15)
    ap.add_argument("--before", default=None, metavar="REV")
    ap.add_argument("--no-write", action="store_true")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        cases = {name: (code, None) for name, code in CASES.items()}
        if args.before:
            cases[f"bayes-mpem --help, source of {args.before}"] = (
                CASES["bayes-mpem --help"], checkout(args.before, tmp))
        for code, src in cases.values():  # warm the file cache and the bytecode
            time_once(code, src)
        runs: dict[str, list[float]] = {name: [] for name in cases}
        for _ in range(args.repeats):
            for name, (code, src) in cases.items():
                runs[name].append(time_once(code, src))
    load = os.getloadavg()
    rows = [f"| {name} | {statistics.median(t):.3f} | {min(t):.3f} | {max(t):.3f} |"
            for name, t in runs.items()]
    help_s = statistics.median(runs["bayes-mpem --help"])
    text = "\n".join([
        "## Start-up: `bayes-mpem --help` and `import bayes_mpem`",
        "",
        f"Produced by `python benchmarks/bench_startup.py` on {date.today()}; machine: "
        f"{machine()}; load average {load[0]:.2f}, {load[1]:.2f}, {load[2]:.2f} (1, 5, 15 min) "
        "at the end of the run.",
        "",
        f"Wall seconds of a fresh Python process, {args.repeats} runs of each, interleaved "
        "(after one warm-up run). The public names of `bayes_mpem` and the sub-commands of the "
        "command line are imported on first use (PEP 562 `__getattr__`; "
        "`bayes_mpem.cli.parser.COMMANDS`), so `--help` loads no numpy; "
        "`tests/test_layout.py::test_import_and_help_load_no_heavy_library` keeps it so.",
        "",
        "| command | median (s) | min (s) | max (s) |",
        "|---|---:|---:|---:|",
        *rows,
        "",
        f"Goal: `bayes-mpem --help` under {GOAL_S} s: "
        f"{'met' if help_s < GOAL_S else 'NOT met'} ({help_s:.3f} s).",
    ])
    print(text)
    if not args.no_write:
        write_section(ROOT / "docs" / "benchmarks.md", "bench_startup", text)


if __name__ == "__main__":
    main()
