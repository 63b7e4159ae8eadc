"""Circles about the array: which gradient terms a track that never passes over it determines.

On a track that never comes within ``CENTRAL_RADIUS`` (0.3) depths of the array's centre
(a circle about it), GARPOS's deep gradient term (the transponder's offset across the array)
trades with the centre's horizontal position. ``locate --gradients auto`` therefore fits
the shallow term only there (``array_survey.deep_gradient_gate``). This study shows why.
Each campaign (:func:`bayes_mpem.survey_in.gnssa_simulate.simulate_gnssa`, seeds 0 to
N-1): four transponders at about 1 500 m, ``--hours`` of shots every 20 s on the ``circle``
track (radius 0.9 depths), the sound-speed field, and the water's horizontal gradients
``none``, ``strong`` (the simulator's 0.5 (m/s)/km at the surface and 0.1 through the
column) or ``deep`` (0.1 through the column only). Each is located with the defaults but
``gradients="off"``, ``"on"`` (both terms) and ``"shallow"``.

Reported per length and water: the centre's median horizontal error and sd, how often the
95 % intervals of the centre's east and north cover the truth, and what ``auto`` chose.

With ``--shift`` the array is located as a rigid body (``shift=True``, GARPOS's
fixed-geometry solution) from priors that are the true geometry moved by (1, -2, 0.5) m, in
the simulator's gradients only: there the deep term cannot trade with the transponders one
by one, and ``auto`` keeps it.

Writes the section ``gnssa-circles`` (``gnssa-circles-shift``) of ``docs/gnssa.md`` and prints
it::

    python benchmarks/gnssa_circles.py [N_SEEDS] [--hours "6 2 1"] [--shift] [--jobs J]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one thread: the machine is shared

import numpy as np  # noqa: E402
from scipy.stats import norm  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import commit, machine, write_section  # noqa: E402

from bayes_mpem.survey_in.array_survey import (  # noqa: E402
    array_shots,
    deep_gradient_gate,
    gradient_gate,
    locate_array_survey,
)
from bayes_mpem.survey_in.gnssa_simulate import simulate_gnssa  # noqa: E402

#: the water's gradients: (shallow, deep) in (m/s)/km, None for none
WATERS = {"none": None, "strong": (0.5, 0.1), "deep": (0.0, 0.1)}
FITS = ("off", "on", "shallow")
Z95 = float(norm.ppf(0.975))


#: ``--shift``: the priors are the true geometry moved by this (east, north, up; m)
SHIFT = (1.0, -2.0, 0.5)


def one(hours, water, seed, shift=False):
    """Return ``(auto, {fit: (err, sd)})`` of one campaign; ``auto`` is what auto fits."""
    g = WATERS[water]
    sim = simulate_gnssa(hours=hours, rng=seed, speed_model="field", track="circle",
                         gradients=g is not None,
                         **({} if g is None else {"shallow_gradient": g[0],
                                                  "deep_gradient": g[1]}))
    raw = sim.raw()
    true = sim.truth["transponders"][["east", "north", "up"]].to_numpy()
    if shift:
        raw.header["transponders"].loc[:, ["east", "north", "up"]] = true + np.array(SHIFT)
    truth = true.mean(axis=0)
    shots, priors = array_shots(raw), raw.header["transponders"]
    auto = ("off" if not gradient_gate(shots, priors)[0]
            else "on" if deep_gradient_gate(shots, priors, shift)[0] else "shallow")
    out = {}
    for fit in FITS:
        res = locate_array_survey(raw, gradients=fit, shift=True if shift else None)
        m, C = res.fits["array"].centre()
        out[fit] = (m - truth, np.sqrt(np.diag(C)))
    return auto, out


def report(rows, n_seeds, hours_list, seconds, jobs, shift=False):
    """Return the Markdown section."""
    lines = [
        f"Written by `python benchmarks/gnssa_circles.py {n_seeds} --hours "
        f"\"{' '.join(f'{h:g}' for h in hours_list)}\"{' --shift' if shift else ''} --jobs "
        f"{jobs}` ({machine()}; {seconds:.0f} s; git {commit()}).",
        "",
        f"{n_seeds} campaigns per row (seeds 0-{n_seeds - 1}; a circle of radius 0.9 depths "
        "about the array, shots every 20 s, the sound-speed field, the water's gradients as "
        "named"
        + (f"; located as a rigid body, `shift=True`, from the true geometry moved by "
           f"{SHIFT} m" if shift else "")
        + "), each located with `gradients=\"off\"`, `\"on\"` (both terms) and "
        "`\"shallow\"`. Horizontal error and sd of the centre (cm, median; the sd is the rms of "
        "east's and north's); the 95 % intervals of its east and north covering the truth "
        f"(% of {2 * n_seeds}).",
        "",
        "| hours | water | `auto` fits | off: error / sd | off: covered | on: error / sd "
        "| on: covered | shallow: error / sd | shallow: covered |",
        "|---|---|---|---|---|---|---|---|---|"]
    for (hours, water), recs in rows.items():
        autos = sorted({a for a, _ in recs})
        cells = []
        for fit in FITS:
            err = np.array([o[fit][0] for _, o in recs])
            sd = np.array([o[fit][1] for _, o in recs])
            cover = np.abs(err[:, :2] / sd[:, :2]) < Z95
            cells += [f"{100 * np.median(np.hypot(err[:, 0], err[:, 1])):.1f} / "
                      f"{100 * np.median(np.hypot(sd[:, 0], sd[:, 1]) / np.sqrt(2)):.1f}",
                      f"{100 * cover.mean():.0f}"]
        lines.append(f"| {hours:g} | {water} | {', '.join(autos)} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main(argv=None):
    """Run the study and write its section."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("seeds", nargs="?", type=int, default=20)
    p.add_argument("--hours", default="6 2 1", help="campaign lengths (default %(default)s)")
    p.add_argument("--shift", action="store_true",
                   help="a rigid shift from the true geometry moved (the simulator's gradients)")
    p.add_argument("--jobs", type=int, default=1)
    args = p.parse_args(argv)
    hours_list = [float(v) for v in args.hours.split()]
    waters = ["strong"] if args.shift else list(WATERS)
    keys = [(h, w) for h in hours_list for w in waters]
    t0 = time.perf_counter()
    tasks = [(h, w, s, args.shift) for h, w in keys for s in range(args.seeds)]
    with ProcessPoolExecutor(args.jobs) as pool:
        done = list(pool.map(one, *zip(*tasks, strict=True)))
    rows = {k: done[i * args.seeds:(i + 1) * args.seeds] for i, k in enumerate(keys)}
    text = report(rows, args.seeds, hours_list, time.perf_counter() - t0, args.jobs,
                  args.shift)
    print(text)
    write_section(ROOT / "docs" / "gnssa.md",
                  "gnssa-circles" + ("-shift" if args.shift else ""), text)


if __name__ == "__main__":
    main()
