"""Time ``bayes-mpem diagnose`` on a 5,000-range, 4-beacon survey (goal: under a minute).

Run from the repository root on a quiet machine::

    python benchmarks/bench_diagnose.py            # writes its section of docs/benchmarks.md
    python benchmarks/bench_diagnose.py --quick    # one repeat, prints only

The survey is the ``abe58`` preset (4 beacons, about 5,000 replies), clean and
with each effect hidden. Timed: the library call ``diagnose`` on a validated
survey (best and worst of ``--repeat`` runs), and the whole command line
(reading the CSVs, diagnosing, writing diagnosis.json and the four figures)
once per survey.
"""

from __future__ import annotations

import argparse
import datetime as dt
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

from bayes_mpem.lbl.diagnosis.driver import diagnose
from bayes_mpem.lbl.simulation.simulate import simulate_survey

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import machine, write_section  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
CASES = {"clean": {}, "range_bias": {"range_bias": 6.0}, "sound_speed": {"sound_speed": -0.008},
         "plane_drift": {"plane_drift": 6.0}, "second_reflector": {"second_reflector": 700.0},
         "early_outliers": {"early_outliers": 0.12}, "nav_drift": {"nav_drift": 35.0},
         "range_bias + nav_drift": {"range_bias": -4.0, "nav_drift": 25.0}}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args(argv)
    repeat = 1 if args.quick else args.repeat
    exe = Path(sys.executable).with_name("bayes-mpem")
    lines = ["## diagnose", "",
             f"`python benchmarks/bench_diagnose.py` on {dt.date.today()} ({machine()}). "
             "Survey: the `abe58` preset, seed 1. Library: wall seconds of `diagnose(survey)` "
             f"over {repeat} runs (best / worst). Command: `bayes-mpem diagnose` from CSV to "
             "diagnosis.json and the four figures, once. Goal: under 60 s.", "",
             "| hidden | replies | library best (s) | library worst (s) | command (s) | found |",
             "|---|---|---|---|---|---|"]
    worst = 0.0
    for label, eff in CASES.items():
        sim = simulate_survey("abe58", rng=1, effects=eff)
        times = []
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            for _ in range(repeat):
                t0 = time.perf_counter()
                res = diagnose(sim.survey, rng=0, progress=False)
                times.append(time.perf_counter() - t0)
        with tempfile.TemporaryDirectory() as tmp:
            paths = sim.write(tmp)
            t0 = time.perf_counter()
            subprocess.run([str(exe), "diagnose", str(paths["pings"]), "--beacons",
                            str(paths["beacons"]), "--out", str(Path(tmp) / "dx"),
                            "--no-progress"], check=True, capture_output=True)
            cli = time.perf_counter() - t0
        worst = max(worst, max(times), cli)
        found = ", ".join(f"{e.name} {e.magnitude:+.4g}" for e in res.effects) or "none"
        row = (f"| {label} | {res.data.n} | {min(times):.1f} | {max(times):.1f} | {cli:.1f} | "
               f"{found} |")
        print(row, flush=True)
        lines.append(row)
    lines += ["", f"Slowest: {worst:.1f} s (goal 60 s)."]
    text = "\n".join(lines)
    print(text)
    if not args.quick:
        write_section(ROOT / "docs" / "benchmarks.md", "bench_diagnose", text)
    return 0 if worst < 60 else 1


if __name__ == "__main__":
    sys.exit(main())
