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

With ``--along`` the study asks where a short circle's error goes: in water with only a shallow
gradient (``shallowonly``: 0.5 (m/s)/km at the surface), only a deep one (``deep``) or both
(``strong``), each campaign located with ``gradients="off"`` and ``"shallow"`` (independent
replies), the centre's horizontal error is split along and across the direction of the
water's gradient (its mean over the campaign; the deep one where there is one).

Writes the section ``gnssa-circles`` (``gnssa-circles-shift``, ``gnssa-circles-along``) of
``docs/gnssa.md`` and prints it::

    python benchmarks/gnssa_circles.py [N_SEEDS] [--hours "6 2 1"] [--shift | --along] [--jobs J]
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
    auto_gradients,
    deep_gradient_gate,
    gradient_gate,
    locate_array_survey,
)
from bayes_mpem.survey_in.gnssa_simulate import simulate_gnssa  # noqa: E402

#: the water's gradients: (shallow, deep) in (m/s)/km, None for none
WATERS = {"none": None, "strong": (0.5, 0.1), "deep": (0.0, 0.1), "shallowonly": (0.5, 0.0)}
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
    auto = {True: "on", "shallow": "shallow", False: "off"}[auto_gradients(
        gradient_gate(shots, priors), deep_gradient_gate(shots, priors, shift), shots)[0]]
    out = {}
    for fit in FITS:
        res = locate_array_survey(raw, gradients=fit, shift=True if shift else None)
        m, C = res.fits["array"].centre()
        out[fit] = (m - truth, np.sqrt(np.diag(C)))
    return auto, out


def along(hours, water, seed):
    """Return ``{fit: (along, across, sd)}``: the centre's horizontal error (m) split along and
    across the water's gradient (the deep one where there is one), and its sd (m)."""
    g = WATERS[water]
    sim = simulate_gnssa(hours=hours, rng=seed, speed_model="field", track="circle",
                         gradients=True, shallow_gradient=g[0], deep_gradient=g[1])
    raw = sim.raw()
    truth = sim.truth["transponders"][["east", "north", "up"]].to_numpy().mean(axis=0)
    t = raw.pings["time"].to_numpy(float)
    shallow, deep = sim.truth["field"].gradients(np.linspace(t.min(), t.max(), 200))
    u = (deep if g[1] > 0 else shallow).mean(axis=0)
    u /= np.linalg.norm(u)
    out = {}
    for fit in ("off", "shallow"):
        m, C = locate_array_survey(raw, gradients=fit, correlation="off").fits["array"].centre()
        e = (m - truth)[:2]
        out[fit] = (float(e @ u), float(e @ np.array([-u[1], u[0]])),
                    float(np.sqrt(np.diag(C))[:2].mean()))
    return out


def report_along(rows, n_seeds, hours, seconds, jobs):
    """Return the Markdown section of ``--along``."""
    lines = [
        f"Written by `python benchmarks/gnssa_circles.py {n_seeds} --hours \"{hours:g}\" --along "
        f"--jobs {jobs}` ({machine()}; {seconds:.0f} s; git {commit()}).",
        "",
        f"{n_seeds} campaigns per row (seeds 0-{n_seeds - 1}; {hours:g} h on a circle of radius "
        "0.9 depths, shots every 20 s, the sound-speed field; the water's gradients: "
        "`shallowonly` 0.5 (m/s)/km at the surface, `deep` 0.1 (m/s)/km through the column, "
        "`strong` both), each located with `gradients=\"off\"` and `\"shallow\"` "
        "(`correlation=\"off\"`). The centre's horizontal error split along and across the "
        "direction of the water's gradient (the deep one where there is one; its mean over the "
        "campaign): the mean (cm) with its standard error, and the rms of each over the "
        "centre's sd.",
        "",
        "| water | fit | along: mean (se) | across: mean (se) | rms along / sd | rms across / sd |",
        "|---|---|---|---|---|---|"]
    for water, recs in rows.items():
        for fit in ("off", "shallow"):
            a = np.array([r[fit][0] for r in recs])
            c = np.array([r[fit][1] for r in recs])
            sd = np.array([r[fit][2] for r in recs])
            se = np.sqrt(len(recs))
            lines.append(f"| {water} | {fit} | {100 * a.mean():+.2f} ({100 * a.std() / se:.2f}) "
                         f"| {100 * c.mean():+.2f} ({100 * c.std() / se:.2f}) "
                         f"| {np.sqrt(np.mean((a / sd) ** 2)):.2f} "
                         f"| {np.sqrt(np.mean((c / sd) ** 2)):.2f} |")
    return "\n".join(lines)


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
    p.add_argument("--along", action="store_true",
                   help="split a short circle's error along the water's gradient")
    p.add_argument("--jobs", type=int, default=1)
    args = p.parse_args(argv)
    hours_list = [float(v) for v in args.hours.split()]
    if args.along:
        t0 = time.perf_counter()
        waters = ["shallowonly", "deep", "strong"]
        tasks = [(hours_list[0], w, s) for w in waters for s in range(args.seeds)]
        with ProcessPoolExecutor(args.jobs) as pool:
            done = list(pool.map(along, *zip(*tasks, strict=True)))
        rows = {w: done[i * args.seeds:(i + 1) * args.seeds] for i, w in enumerate(waters)}
        text = report_along(rows, args.seeds, hours_list[0], time.perf_counter() - t0,
                            args.jobs)
        print(text)
        write_section(ROOT / "docs" / "gnssa.md", "gnssa-circles-along", text)
        return
    waters = ["strong"] if args.shift else ["none", "strong", "deep"]
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
