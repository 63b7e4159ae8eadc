"""Where to fit the horizontal gradients: a track's spread against the intervals' honesty.

``locate --gradients auto`` fits GARPOS's gradient terms when the track spreads over at least
:data:`bayes_mpem.survey_in.array_survey.MIN_SPREAD` of the depth
(``array_survey.gradient_gate``). This study shows what the threshold decides. Each campaign
(:func:`bayes_mpem.survey_in.gnssa_simulate.simulate_gnssa`, seeds 0 to N-1): four transponders
at about 1 500 m, 6 hours (``--hours``) of shots every 20 s on the ``star+circle`` track of
radius ``R`` depths (the spread is about 0.5 R), the sound-speed field, and the water's horizontal
gradients ``none``, ``weak`` (0.1 and 0.02 (m/s)/km at the surface and through the column)
or ``strong`` (the simulator's 0.5 and 0.1). Each is located with the defaults but
``gradients="off"`` and ``gradients="on"``.

Reported per radius and water: the spread, the centre's median horizontal error and sd, and
how often the 95 % intervals of the centre's east and north cover the truth.

Writes the section ``gnssa-gate`` of ``docs/gnssa.md`` (``gnssa-gate-HOURSh`` for other hours,
``...-R0.2-0.3`` for other radii) and prints it::

    python benchmarks/gnssa_gate.py [N_SEEDS] [--radii "0.1 0.15 ..."] [--hours H] [--jobs J]
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
    MIN_SPREAD,
    array_shots,
    gradient_gate,
    locate_array_survey,
    track_geometry,
)
from bayes_mpem.survey_in.gnssa_simulate import simulate_gnssa  # noqa: E402

DEPTH = 1500.0
#: the water's gradients: (shallow, deep) in (m/s)/km, None for none
WATERS = {"none": None, "weak": (0.1, 0.02), "strong": (0.5, 0.1)}
Z95 = float(norm.ppf(0.975))


def one(radius, water, seed, hours=6.0):
    """Return ``(spread, auto, {"off": (err, sd), "on": (err, sd)})`` of one campaign.

    ``auto``: whether ``gradients="auto"`` fits them there (``gradient_gate``).
    """
    g = WATERS[water]
    sim = simulate_gnssa(hours=hours, rng=seed, depth=DEPTH, speed_model="field",
                         track="star+circle", track_radius=radius * DEPTH,
                         gradients=g is not None,
                         **({} if g is None else {"shallow_gradient": g[0],
                                                  "deep_gradient": g[1]}))
    raw = sim.raw()
    tp = sim.truth["transponders"][["east", "north", "up"]]
    truth = tp.to_numpy().mean(axis=0)
    shots = array_shots(raw)
    geo = track_geometry(shots, {t: r.to_numpy(float) for t, r in tp.iterrows()})
    auto = gradient_gate(shots, sim.header["transponders"])[0]
    out = {}
    for fit in ("off", "on"):
        m, C = locate_array_survey(raw, gradients=fit).fits["array"].centre()
        out[fit] = (m - truth, np.sqrt(np.diag(C)))
    return geo["spread_over_depth"], auto, out


def report(rows, n_seeds, radii, seconds, jobs, hours=6.0):
    """Return the Markdown section."""
    radii = " ".join(map(str, radii))
    lines = [
        f"Written by `python benchmarks/gnssa_gate.py {n_seeds} --radii \"{radii}\" "
        + ("" if hours == 6.0 else f"--hours {hours:g} ")
        + f"--jobs {jobs}` ({machine()}; {seconds:.0f} s; git {commit()}).",
        "",
        f"{n_seeds} campaigns per row (seeds 0-{n_seeds - 1}; {hours:g} h, `star+circle` of "
        "radius R depths, the sound-speed field, the water's gradients as named), each located "
        "with `gradients=\"off\"` and `\"on\"`; `auto` fits them from a spread of "
        f"{MIN_SPREAD:g} (the spread column is the median, from the true positions; `auto` "
        "uses the header's priors). Horizontal error and sd of the "
        "centre (cm, median; the sd is the rms of east's and north's); the 95 % "
        "intervals of its east and north covering the truth (% of "
        f"{2 * n_seeds}).",
        "",
        f"| R | spread | water | `auto` fits (of {n_seeds}) | off: error / sd | off: covered "
        "| on: error / sd | on: covered |",
        "|---|---|---|---|---|---|---|---|"]
    for (radius, water), recs in rows.items():
        spread = float(np.median([s for s, _, _ in recs]))
        cells = []
        for fit in ("off", "on"):
            err = np.array([o[fit][0] for _, _, o in recs])
            sd = np.array([o[fit][1] for _, _, o in recs])
            cover = np.abs(err[:, :2] / sd[:, :2]) < Z95
            cells += [f"{100 * np.median(np.hypot(err[:, 0], err[:, 1])):.1f} / "
                      f"{100 * np.median(np.hypot(sd[:, 0], sd[:, 1]) / np.sqrt(2)):.1f}",
                      f"{100 * cover.mean():.0f}"]
        lines.append(f"| {radius:g} | {spread:.2f} | {water} | "
                     f"{sum(a for _, a, _ in recs)} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main(argv=None):
    """Run the study and write its section."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("seeds", nargs="?", type=int, default=8)
    p.add_argument("--radii", default="0.1 0.15 0.2 0.3 0.4",
                   help="track radii in depths (default %(default)s)")
    p.add_argument("--hours", type=float, default=6.0, help="campaign length (default 6)")
    p.add_argument("--jobs", type=int, default=1)
    args = p.parse_args(argv)
    radii = [float(v) for v in args.radii.split()]
    keys = [(r, w) for r in radii for w in WATERS]
    t0 = time.perf_counter()
    tasks = [(r, w, s) for r, w in keys for s in range(args.seeds)]
    with ProcessPoolExecutor(args.jobs) as pool:
        done = list(pool.map(one, *zip(*tasks, strict=True), [args.hours] * len(tasks)))
    rows = {k: done[i * args.seeds:(i + 1) * args.seeds] for i, k in enumerate(keys)}
    text = report(rows, args.seeds, radii, time.perf_counter() - t0, args.jobs, args.hours)
    print(text)
    name = "gnssa-gate" + ("" if args.hours == 6.0 else f"-{args.hours:g}h")
    if radii != [float(v) for v in p.get_default("radii").split()]:
        name += "-R" + "-".join(f"{r:g}" for r in radii)
    write_section(ROOT / "docs" / "gnssa.md", name, text)


if __name__ == "__main__":
    main()
