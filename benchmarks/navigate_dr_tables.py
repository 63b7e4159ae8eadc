"""A dead-reckoning table coarser than the vehicle's turns: navigate's ellipses against truth.

Run from the repository root::

    nice python benchmarks/navigate_dr_tables.py   # seeds 1-40, writes docs/navigate.md
    python benchmarks/navigate_dr_tables.py --seeds 2 --quick   # prints only

Dives: ``simulate_dive("abe58", rng=seed, n_cycles=200)`` (four beacons, all
interrogated every 12 s, the vehicle at 8.7 m/s on lines joined by U-turns),
navigated with its own dead reckoning given as a separate table of positions
(``dead_reckoning=``) at every row, or every 2nd, 3rd, 5th or 10th row (and the
last): rows 12, 24, 36, 60 or 120 s apart, so that the turns fall between rows
and a straight line between them cuts the corner by up to 215 m (60 s).
"""

from __future__ import annotations

import argparse
import datetime as dt
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import pandas as pd

from bayes_mpem.lbl.navigate import navigate, simulate_dive

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import commit, machine, write_section  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
CHI2_95 = 5.991
EVERY = (1, 2, 3, 5, 10)


def one(seed: int, every: int) -> dict:
    """Navigate one dive with its dead reckoning every ``every`` rows; the errors."""
    sim = simulate_dive("abe58", rng=seed, n_cycles=200)
    tt = sim.true_track
    keep = sorted(set(range(0, len(tt), every)) | {len(tt) - 1})
    table = pd.DataFrame({"time": tt["time"], "x": tt["dr_x"], "y": tt["dr_y"]}).iloc[keep]
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        nav = navigate(sim.survey.table.drop(columns="true_class"),
                       sim.survey.beacons.reset_index(), dead_reckoning=table, rng=0)
    seconds = time.perf_counter() - t0
    err = nav.track - tt[["x", "y"]].to_numpy()
    m2 = np.einsum("ki,kij,kj->k", err, np.linalg.inv(nav.cov), err)
    flagged = nav.uncorrected
    dist = np.hypot(*err.T)
    return {"covered": float(np.mean(m2 < CHI2_95)), "max_err": float(dist.max()),
            "max_err_unflagged": float(dist[~flagged].max()),
            "max_z_unflagged": float(np.sqrt(m2[~flagged].max())),
            "flagged": float(flagged.mean()),
            "turns": sum(f["kind"] == "dead_reckoning_turn" for f in nav.flags),
            "seconds": seconds}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="print only")
    ap.add_argument("--seeds", type=int, default=40, help="seeds 1..N")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    seeds = range(1, args.seeds + 1)
    rows = []
    for every in EVERY:
        runs = [one(seed, every) for seed in seeds]
        z = np.array([r["max_z_unflagged"] for r in runs])
        rows.append(
            f"| {12 * every} | {100 * np.mean([r['covered'] for r in runs]):.1f} | "
            f"{np.median([r['max_err'] for r in runs]):.1f} "
            f"({max(r['max_err'] for r in runs):.1f}) | "
            f"{np.median([r['max_err_unflagged'] for r in runs]):.1f} | "
            f"{np.median(z):.1f} ({z.max():.1f}); {int(np.sum(z < 4))} of {z.size} | "
            f"{100 * np.mean([r['flagged'] for r in runs]):.1f} | "
            f"{np.median([r['turns'] for r in runs]):.0f} | "
            f"{np.median([r['seconds'] for r in runs]):.1f} |")
        print(rows[-1], flush=True)
    setup = __doc__.split("Dives: ", 1)[1].strip()
    text = [f"Written by `python benchmarks/navigate_dr_tables.py --seeds {args.seeds}` "
            f"({machine()}; {time.perf_counter() - t0:.0f} s; {dt.date.today()}; git "
            f"{commit()}). Dives (seeds 1-{args.seeds}): {setup}", "",
            "| rows every (s) | 95 % ellipses covering (% of epochs) | largest error, "
            "median (largest) (m) | largest error of an unflagged epoch, median (m) | "
            "largest standardised error of an unflagged epoch, median (largest); dives "
            "below 4 | epochs flagged not corrected (%) | turns flagged per dive | seconds "
            "per dive |", "|---|---|---|---|---|---|---|---|", *rows]
    print("\n".join(text))
    if not args.quick:
        write_section(ROOT / "docs" / "navigate.md", "navigate_dr_tables", "\n".join(text))


if __name__ == "__main__":
    main()
