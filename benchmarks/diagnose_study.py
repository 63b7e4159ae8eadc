"""How often ``diagnose`` names the hidden effect, and how well it sizes it.

Run from the repository root::

    python benchmarks/diagnose_study.py --seeds 4 --workers 2  # its section of the study page
    python benchmarks/diagnose_study.py --quick    # 2 seeds per cell, prints only

Three generators: the project simulator's ``abe58`` and ``random`` presets, and
``tests/independent_generator.py`` (written from the issue text alone: other
tracks, per-beacon noise, double-bounce multipath, irregular pings). For each
effect (and for clean data) and each seed a magnitude is drawn from a
realistic range, the survey is diagnosed, and the result counts as *right*
when exactly the hidden effects are named with every magnitude within 30 %.
Then pairs of effects, and the detection limit of ``plane_drift`` against its
size.
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import sys
import time
import warnings
from multiprocessing import Pool
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT / "benchmarks"))

import independent_generator as indep  # noqa: E402
from _report import machine, write_section  # noqa: E402

from bayes_mpem.lbl.diagnosis.driver import diagnose  # noqa: E402
from bayes_mpem.lbl.simulation.effects import EFFECTS  # noqa: E402
from bayes_mpem.lbl.simulation.simulate import simulate_survey  # noqa: E402

RANGES = {"range_bias": (1.0, 15.0), "sound_speed": (0.002, 0.02), "plane_drift": (3.0, 12.0),
          "second_reflector": None, "early_outliers": (0.05, 0.2), "nav_drift": (10.0, 60.0),
          "beacon_bias": (2.0, 15.0), "beacon_position": (10.0, 60.0)}
SIGNED = {"range_bias", "sound_speed", "plane_drift", "beacon_bias"}
PER_BEACON = ("beacon_bias", "beacon_position")
PAIRS = [("range_bias", "nav_drift"), ("sound_speed", "plane_drift"),
         ("second_reflector", "early_outliers"), ("range_bias", "sound_speed"),
         ("plane_drift", "nav_drift")]


def _sim_case(preset, names, seed, fixed=None):
    gen = np.random.default_rng(10_000 + seed)
    probe = simulate_survey(preset, rng=seed, n_cycles=20)
    top = float(np.nanmin(probe.survey.depth))
    eff = {}
    for n in names:
        if fixed is not None:
            eff[n] = fixed
        elif n == "second_reflector":
            eff[n] = float(gen.uniform(150.0, max(0.6 * top, 200.0)))
        else:
            lo, hi = RANGES[n]
            m = float(gen.uniform(lo, hi))
            eff[n] = -m if n in SIGNED and gen.random() < 0.5 else m
    if "nav_drift" in eff:
        eff["nav_drift_direction"] = float(gen.uniform(0.0, 360.0))
    target = None
    if set(PER_BEACON) & set(eff):
        target = str(gen.choice(sorted(probe.truth)))
        eff.update(beacon=target, beacon_position_direction=float(gen.uniform(0.0, 360.0)))
    sim = simulate_survey(preset, rng=seed, effects=eff)
    return (sim.survey, None, sim.truth[next(iter(sim.truth))]["effects"],
            {k: v["d0"] for k, v in sim.truth.items()}, target)


def _indep_case(names, seed, fixed=None):
    kw = {}
    if names:
        kw["effect"] = names[0]
        if fixed is not None:
            kw["magnitude"] = fixed
    if len(names) > 1:
        kw["second_effect"] = names[1]
    g = indep.generate(seed=seed, **kw)
    t = g["truth"]
    return g["pings"], g["beacons"], dict(t["effects"]), t["d0"], t["effect_beacon"]


def case(gen_name, names, seed, fixed=None):
    """Generate one survey; return (pings, beacons, true effects, true d0, effect's beacon)."""
    if gen_name == "independent":
        return _indep_case(names, seed, fixed)
    return _sim_case(gen_name, names, seed, fixed)


def run(gen_name, names, seed, fixed=None):
    """Diagnose one survey; return a dict of outcomes."""
    pings, beacons, truth, d0, target = case(gen_name, names, seed, fixed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        t = time.perf_counter()
        res = diagnose(pings, beacons, rng=seed, progress=False)
        wall = time.perf_counter() - t
    found = {e.name: e.magnitude for e in res.effects}
    where = {e.name: e.beacons for e in res.effects if e.name in PER_BEACON}
    named = set(found) == set(truth)
    right_beacon = all(v == [target] for v in where.values())
    sized = (named and right_beacon
             and all(abs(found[k] - v) <= 0.3 * abs(v) for k, v in truth.items()))
    final = res.final.beacons(res.data)
    d0err = max(abs(final[b]["d0"] - d0[b]) for b in final)
    relerr = [abs(found[k] / v - 1) for k, v in truth.items() if k in found]
    return {"named": named, "right": sized, "right_beacon": named and right_beacon,
            "found": sorted(f"{e.name}:{e.beacons[0]}" if e.name in PER_BEACON else e.name
                            for e in res.effects), "target": target, "d0err": d0err,
            "relerr": max(relerr) if relerr else 0.0, "wall": wall, "n": res.data.n,
            "unexplained": len(res.unexplained)}


def _cached(path):
    """Finished surveys of an earlier run (``--cache``), by task key."""
    out = {}
    if path and Path(path).exists():
        for line in Path(path).read_text().splitlines():
            rec = json.loads(line)
            out[rec["key"]] = rec["out"]
    return out


def _run_task(task):
    gen_name, names, seed, fixed = task
    return run(gen_name, names, seed, fixed)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--beacon-seeds", type=int, default=10,
                    help="seeds per generator for each per-beacon effect")
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--drift-seeds", type=int, default=None,
                    help="seeds per size of the plane-drift limit (default --seeds; 0 skips)")
    ap.add_argument("--cache", default=None,
                    help="JSON-lines file of finished surveys, to resume an interrupted run")
    args = ap.parse_args(argv)
    n_seeds = 2 if args.quick else args.seeds
    n_beacon = 2 if args.quick else args.beacon_seeds
    n_drift = n_seeds if args.drift_seeds is None else args.drift_seeds
    gens = ["abe58", "random", "independent"]
    n_pair = max(2, n_seeds // 2)
    sizes = [2.0, 3.0, 4.0, 6.0]
    tasks = {}
    for g in gens:
        for eff in (None, *EFFECTS):
            for seed in range(n_seeds):
                tasks[("one", g, eff, seed)] = (g, [] if eff is None else [eff], seed, None)
        for pair in PAIRS:
            for s in range(n_pair):
                tasks[("pair", g, pair, s)] = (g, list(pair), 100 + s, None)
        for size in sizes:
            for s in range(n_drift):
                tasks[("drift", g, size, s)] = (g, ["plane_drift"], 200 + s, size)
        for eff in PER_BEACON:
            for s in range(n_beacon):
                tasks[("beacon", g, eff, s)] = (g, [eff], 300 + s, None)
    t0 = time.perf_counter()
    outs = _cached(args.cache)
    todo = [k for k in tasks if repr(k) not in outs]
    with Pool(args.workers) as pool:
        for key, o in zip(todo, pool.imap(_run_task, [tasks[k] for k in todo]), strict=True):
            outs[repr(key)] = o
            if args.cache:  # one line per survey: an interrupted study resumes
                with open(args.cache, "a") as fh:
                    fh.write(json.dumps({"key": repr(key), "out": o}) + "\n")
    outs = {k: outs[repr(k)] for k in tasks}
    took = time.perf_counter() - t0
    lines = []

    def log(msg):
        print(msg, flush=True)

    for key, o in outs.items():
        if not o["right"]:
            log(f"  miss: {key}: found {o['found']} (beacon {o['target']}), "
                f"rel. error {o['relerr']:.2f}, d0 error {o['d0err']:.2f} m")

    # ---- one effect (or none) at a time
    rows = {(g, eff): [outs[("one", g, eff, s)] for s in range(n_seeds)]
            for g in gens for eff in (None, *EFFECTS)}
    lines += ["## One effect at a time", "",
              f"{n_seeds} seeds per cell; magnitudes drawn uniformly from the realistic ranges "
              "below (random sign for the biases, sound speed and plane drift). *Right* = "
              "exactly the hidden effect named (none for clean data) with its magnitude within "
              "30 % and, for a per-beacon effect, on the right beacon alone. "
              "*Worst d0 error*: largest plane-height error of the final model over the "
              "surveys of the cell (m); the clean-data recovery limit is 3 m.", "",
              "| effect | range | " + " | ".join(f"{g}: right" for g in gens)
              + " | " + " | ".join(f"{g}: worst d0 error" for g in gens) + " |",
              "|---|---|" + "---|" * (2 * len(gens))]
    indep_ranges = indep.MAGNITUDE_RANGES
    for eff in (None, *EFFECTS):
        if eff is None:
            rng_txt = "-"
        elif eff == "second_reflector":
            rng_txt = ("sim: 150 m to 0.6 x shallowest vehicle depth; indep: "
                       f"{indep_ranges[eff][0]:g}-{indep_ranges[eff][1]:g} m")
        else:
            rng_txt = (f"sim: {RANGES[eff][0]:g}-{RANGES[eff][1]:g}; indep: "
                       f"{indep_ranges[eff][0]:g}-{indep_ranges[eff][1]:g}")
        cells = [f"{sum(o['right'] for o in rows[(g, eff)])}/{len(rows[(g, eff)])}"
                 for g in gens]
        d0s = [f"{max(o['d0err'] for o in rows[(g, eff)]):.2f}" for g in gens]
        lines.append(f"| {eff or 'clean'} | {rng_txt} | " + " | ".join(cells) + " | "
                     + " | ".join(d0s) + " |")
    total = sum(o["right"] for v in rows.values() for o in v)
    count = sum(len(v) for v in rows.values())
    fp = sum(len(o["found"]) > 0 for g in gens for o in rows[(g, None)])
    lines += ["", f"Overall {total}/{count} right; {fp} of {n_seeds * len(gens)} clean surveys "
              "had an effect claimed.", ""]

    # ---- pairs
    lines += ["## Two effects at once", "",
              f"{n_pair} seeds per pair and generator.", "",
              "| pair | " + " | ".join(gens) + " |", "|---|" + "---|" * len(gens)]
    n_right = 0
    for pair in PAIRS:
        cells = []
        for g in gens:
            po = [outs[("pair", g, pair, s)] for s in range(n_pair)]
            n_right += sum(o["right"] for o in po)
            cells.append(f"{sum(o['right'] for o in po)}/{len(po)}")
        lines.append(f"| {' + '.join(pair)} | " + " | ".join(cells) + " |")
    lines += ["", f"Pairs right: {n_right} of {len(PAIRS) * len(gens) * n_pair}.", ""]

    # ---- per-beacon effects: the right beacon
    lines += ["## Per-beacon effects: found on the right beacon", "",
              f"{n_beacon} seeds per effect and generator (seeds 300 on), the beacon drawn at "
              "random; *right beacon* = exactly that effect named, on that beacon alone; "
              "*right* = also sized within 30 %.", "",
              "| effect | " + " | ".join(f"{g}: right beacon" for g in gens) + " | "
              + " | ".join(f"{g}: right" for g in gens) + " |",
              "|---|" + "---|" * (2 * len(gens))]
    rb = nb = 0
    for eff in PER_BEACON:
        po = {g: [outs[("beacon", g, eff, s)] for s in range(n_beacon)] for g in gens}
        rb += sum(o["right_beacon"] for g in gens for o in po[g])
        nb += sum(len(po[g]) for g in gens)
        lines.append(f"| {eff} | "
                     + " | ".join(f"{sum(o['right_beacon'] for o in po[g])}/{n_beacon}"
                                  for g in gens) + " | "
                     + " | ".join(f"{sum(o['right'] for o in po[g])}/{n_beacon}"
                                  for g in gens) + " |")
    lines += ["", f"Right beacon in {rb} of {nb} ({100 * rb / max(nb, 1):.0f} %).", ""]

    # ---- plane drift detection limit
    if n_drift:
        lines += ["## Detection limit of plane_drift", "",
                  "Fraction of surveys where plane_drift is named with its size within 30 % "
                  f"({n_drift} seeds per size, positive drift).", "",
                  "| drift (m) | " + " | ".join(gens) + " |", "|---|" + "---|" * len(gens)]
        for size in sizes:
            cells = [f"{sum(outs[('drift', g, size, s)]['right'] for s in range(n_drift))}/"
                     f"{n_drift}" for g in gens]
            lines.append(f"| {size:g} | " + " | ".join(cells) + " |")
    w = np.array([o["wall"] for o in outs.values()])
    n = [o["n"] for o in outs.values()]
    lines += ["", f"Wall time per diagnosis ({len(w)} surveys of {min(n)}-{max(n)} replies, "
              f"{args.workers} worker(s), {took:.0f} s in all): median {np.median(w):.1f} s, "
              f"max {w.max():.1f} s.", ""]
    text = "\n".join(lines)
    print(text)
    if not args.quick:
        cmd = "python benchmarks/diagnose_study.py " + " ".join(
            argv if argv is not None else sys.argv[1:])
        head = (f"Written by `{cmd.strip()}` on {dt.date.today()} ({machine()}); rerun it to "
                "refresh.\n\n")
        write_section(ROOT / "docs" / "diagnose-study.md", "diagnose-study", head + text)


if __name__ == "__main__":
    main()
