"""How short a campaign the array's intervals hold on: coverage against campaign length.

Each campaign (:func:`bayes_mpem.survey_in.gnssa_simulate.simulate_gnssa`, seeds 100 to
100 + N - 1): four transponders at about 1 500 m, ``hours`` of shots every 20 s on a
``circle``, a ``star`` or holding ``station``, the simulator's defaults otherwise (the profile
scaled in time, 50 us timing noise, 2 cm GNSS noise, 5 % spurious replies, no gradients). Each
is located by ``locate_array_survey`` with its defaults. A circle of 0.9 depths takes the
ship about 57 min, so half an hour covers half of it; a star's eight transits take about 2.5 h.

Reported per length and track: how often the 95 % intervals of the array centre's east,
north and up, and of every transponder coordinate, cover the truth; the rms of the centre's
standardised errors; its median sd; and the seconds per fit (median).

Writes the section ``gnssa-short`` of ``docs/gnssa.md`` and prints it::

    python benchmarks/gnssa_short.py [N_SEEDS] [--hours "0.5 1 2"]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
import warnings
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one thread: the machine is shared

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import commit, machine, write_section  # noqa: E402

from bayes_mpem.exceptions import LocateWarning  # noqa: E402
from bayes_mpem.survey_in.array_survey import locate_array_survey  # noqa: E402
from bayes_mpem.survey_in.gnssa_simulate import simulate_gnssa  # noqa: E402

TRACKS = ("circle", "star", "station")
AXES = ("east", "north", "up")
Z95 = 1.959964


def one(hours, track, seed):
    """Return the centre's z (3,), its sd (3,), the transponders' z (K, 3) and the seconds."""
    sim = simulate_gnssa(n_transponders=4, hours=hours, track=track, rng=seed)
    rec = sim.truth_record()
    truth = np.array([[rec["transponders"][k][a] for a in AXES]
                      for k in sorted(rec["transponders"])])
    centre = np.array([rec["array_centre"][a] for a in AXES])
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LocateWarning)
        fit = locate_array_survey(sim.raw()).fits["array"]
    seconds = time.perf_counter() - t0
    m, C = fit.centre()
    sd = np.sqrt(np.diag(C))
    return ((m - centre) / sd, sd, (fit.enu - truth) / fit.sd.reshape(fit.enu.shape), seconds)


def main(argv=None):
    """Run the study, write the docs section and print it."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("n_seeds", nargs="?", type=int, default=30)
    ap.add_argument("--hours", default="0.5 1 2")
    args = ap.parse_args(argv)
    hours = [float(h) for h in args.hours.split()]
    t_start = time.perf_counter()
    rows = []
    for h in hours:
        for track in TRACKS:
            out = [one(h, track, 100 + s) for s in range(args.n_seeds)]
            zc = np.array([o[0] for o in out])
            sd = np.array([o[1] for o in out])
            zt = np.array([o[2] for o in out])
            cover = 100 * np.mean(np.abs(zc) < Z95, axis=0)
            rows.append(
                f"| {h:g} h | {track} | "
                + " / ".join(f"{c:.0f}" for c in cover)
                + f" | {100 * np.mean(np.abs(zt) < Z95):.0f} | "
                + " / ".join(f"{v:.2f}" for v in np.sqrt(np.mean(zc**2, axis=0)))
                + " | " + " / ".join(f"{100 * v:.1f}" for v in np.median(sd, axis=0))
                + f" | {np.median([o[3] for o in out]):.2f} |")
            print(rows[-1], flush=True)
    seconds = time.perf_counter() - t_start
    hours_arg = "" if args.hours == "0.5 1 2" else f' --hours "{args.hours}"'
    text = "\n".join([
        f"Written by `python benchmarks/gnssa_short.py {args.n_seeds}{hours_arg}` "
        f"({machine()}; {seconds:.0f} s; git {commit()}).",
        "",
        f"{args.n_seeds} campaigns per row (seeds 100-{99 + args.n_seeds}), four transponders "
        "at 1,500 m, `locate_array_survey` with its defaults; 95 % intervals.",
        "",
        "| length | track | centre covered (%; east / north / up) | transponder coordinates "
        "covered (%) | rms standardised error of the centre, east / north / up | centre sd, "
        "median east / north / up (cm) | seconds per fit |",
        "|---|---|---|---|---|---|---|",
        *rows,
    ])
    write_section(ROOT / "docs" / "gnssa.md", "gnssa-short", text)
    print(text)


if __name__ == "__main__":
    main()
