"""No confident wrong answer: what ``fit`` and ``sample`` say on surveys with a hidden effect.

Run from the repository root::

    python benchmarks/model_checks.py                 # writes docs/model-checks.md
    python benchmarks/model_checks.py --quick         # 1 seed per cell, prints only
    python benchmarks/model_checks.py --seeds 5 --clean 40 --workers 2

Every effect of ``bayes_mpem.lbl.simulation.effects`` is hidden in surveys of three generators
(the project's ``abe58`` and ``random`` presets at 700 ping cycles, and
``tests/independent_generator.py``), both signs for the signed ones, at a magnitude drawn
from a realistic range; then ``fit`` (mixture EM, ``path="auto"``) and ``sample``
(learned priors) run on the survey as a user would run them. For every beacon:

* the plane's interval: ``d0 +- 1.96 d0_se`` for the EM, the 95 % highest-density
  interval for the posterior, against the true plane (the sea surface; for a drifting
  plane, the plane at the mean time of that beacon's replies, what a static plane
  estimates);
* whether the result carries a flag: a model check (:mod:`bayes_mpem.lbl.survey.model_checks`),
  a quality flag of the fit, or (``sample``) a beacon left unsampled because its start
  was not credible.

A beacon is *confidently wrong* when its interval misses the true plane and nothing is
flagged. The acceptance: none, and no plane more than 10 m off without a flag. Clean
surveys measure the false-alarm rate: the share of beacons (and of surveys) with a flag.
"""

from __future__ import annotations

import argparse
import datetime as dt
import sys
import time
import warnings
from functools import partial
from multiprocessing import Pool
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT / "benchmarks"))

import independent_generator as indep  # noqa: E402
from _report import machine, write_section  # noqa: E402

import bayes_mpem as bm  # noqa: E402
from bayes_mpem.io.survey import load_survey  # noqa: E402
from bayes_mpem.lbl.simulation.effects import EFFECTS, PER_BEACON  # noqa: E402

#: Realistic magnitudes for the project simulator (|value|); the independent
#: generator uses its own (``indep.MAGNITUDE_RANGES``).
RANGES = {"range_bias": (1.0, 15.0), "sound_speed": (0.002, 0.02), "plane_drift": (3.0, 12.0),
          "second_reflector": None, "early_outliers": (0.05, 0.2), "nav_drift": (10.0, 60.0),
          "beacon_bias": (2.0, 15.0), "beacon_position": (10.0, 60.0)}
SIGNED = {"range_bias", "sound_speed", "plane_drift", "beacon_bias"}
GENERATORS = ("abe58", "random", "independent")
LIMIT = 10.0  # m: a plane this far off must be flagged


def _sim(gen_name, effect, sign, seed):
    """A project-simulator survey: (survey, true plane depth per beacon, magnitude, beacon)."""
    gen = np.random.default_rng(50_000 + seed)
    eff, target = {}, None
    if effect == "second_reflector":
        probe = bm.simulate_survey(gen_name, rng=seed, n_cycles=20)
        top = float(np.nanmin(probe.survey.depth))
        eff[effect] = float(gen.uniform(150.0, max(0.6 * top, 200.0)))
    elif effect is not None:
        lo, hi = RANGES[effect]
        eff[effect] = sign * float(gen.uniform(lo, hi))
    if effect == "nav_drift":
        eff["nav_drift_direction"] = float(gen.uniform(0.0, 360.0))
    if effect in PER_BEACON:
        probe = bm.simulate_survey(gen_name, rng=seed, n_cycles=20)
        target = str(gen.choice(sorted(probe.truth)))
        eff.update(beacon=target, beacon_position_direction=float(gen.uniform(0.0, 360.0)))
    sim = bm.simulate_survey(gen_name, rng=seed, n_cycles=700, effects=eff)
    t = sim.survey.time
    t0, t1 = float(np.min(t)), float(np.max(t))
    planes = {}
    for b, v in sim.truth.items():
        drift = eff.get("plane_drift", 0.0)
        mean_tau = (float(np.mean(sim.survey.for_beacon(b).time)) - t0) / (t1 - t0)
        planes[b] = v["plane_depth"] + drift * mean_tau
    return sim.survey, planes, eff.get(effect), target


def _indep(effect, sign, seed):
    """An independent-generator survey, same return as :func:`_sim`."""
    kw = {}
    if effect is not None:
        lo, hi = indep.MAGNITUDE_RANGES[effect]
        m = float(np.random.default_rng(60_000 + seed).uniform(lo, hi))
        kw = {"effect": effect, "magnitude": sign * m if effect in SIGNED else m}
    g = indep.generate(seed=seed, **kw)
    t = g["truth"]
    survey = load_survey(g["pings"], g["beacons"])
    frac = (g["pings"]["time"] - g["pings"]["time"].min()) / np.ptp(g["pings"]["time"])
    planes = {}
    for b in t["d0"]:
        sel = (g["pings"]["beacon"] == b).to_numpy()
        planes[b] = t["plane_depth_first"] + (t["plane_depth_last"] - t["plane_depth_first"]) \
            * float(np.mean(frac[sel]))
    return survey, planes, t["magnitude"], t["effect_beacon"]


def _indep40(seed):
    """A positive range bias in an independent survey with 40 % outliers (the issue's case)."""
    from diagnose_bias_replant import survey

    bias, g = survey(seed, outliers=0.4)
    survey_ = load_survey(g["pings"], g["beacons"])
    return survey_, {b: 0.0 for b in g["truth"]["d0"]}, bias, None


def case(gen_name, effect, sign, seed):
    """One survey of a generator."""
    if gen_name == "independent":
        return _indep(effect, sign, seed)
    if gen_name == "independent-40%-outliers":
        return _indep40(seed)
    return _sim(gen_name, effect, sign, seed)


def one(args, sample=True):
    """Fit and sample one survey; one row per beacon and method."""
    gen_name, effect, sign, seed = args
    survey, planes, magnitude, target = case(gen_name, effect, sign, seed)
    rows = []
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fit = bm.fit(survey, rng=seed)
        post = bm.sample(survey, rng=seed, progress=False) if sample else None
    seconds = time.perf_counter() - t0
    depth = survey.beacons["depth"]
    for b, r in fit.results.items():
        lo = r.d0 - 1.96 * (r.d0_se or np.inf)
        hi = r.d0 + 1.96 * (r.d0_se or np.inf)
        checks = fit.checks.get(b, [])
        flags = [c["name"] for c in checks if c["flagged"]] + (["quality"] if r.flags else [])
        rows.append(_row("fit", b, float(depth[b]) - r.d0, (float(depth[b]) - hi,
                                                               float(depth[b]) - lo),
                         planes[b], flags))
    if post is not None:
        for b in fit.results:
            if b not in post.results:
                rows.append(_row("sample", b, np.nan, (np.nan, np.nan), planes[b],
                                 ["unsampled"]))
                continue
            r = post.results[b]
            d_lo, d_hi = r.summary["d0"]["interval"]
            checks = post.checks.get(b, [])
            flags = ([c["name"] for c in checks if c["flagged"]]
                     + (["quality"] if r.em.flags else []))
            rows.append(_row("sample", b, float(depth[b]) - r.summary["d0"]["mean"],
                             (float(depth[b]) - d_hi, float(depth[b]) - d_lo), planes[b],
                             flags))
    for row in rows:
        row.update(generator=gen_name, effect=effect or "clean", sign=sign, seed=seed,
                   magnitude=magnitude, target=target, seconds=seconds)
    return rows


def _row(method, beacon, plane, interval, truth, flags):
    err = plane - truth
    covered = bool(interval[0] <= truth <= interval[1])
    return {"method": method, "beacon": beacon, "plane": plane, "truth": truth,
            "error": err, "covered": covered, "flags": flags, "flagged": bool(flags),
            "wrong": not covered and not flags,
            "far_unflagged": bool(abs(err) > LIMIT and not flags) if np.isfinite(err) else False}


def cells(n_seeds):
    """The (generator, effect, sign, seed) cases of the effect study."""
    out = []
    for g in GENERATORS:
        for e in EFFECTS:
            for sign in ((1, -1) if e in SIGNED else (1,)):
                out += [(g, e, sign, s) for s in range(n_seeds)]
    # the case: a positive bias with 40 % outliers (independent generator)
    out += [("independent-40%-outliers", "range_bias", 1, s) for s in range(2 * n_seeds)]
    return out


def summarise(rows):
    """Markdown tables of the effect study and the clean surveys."""
    import pandas as pd

    df = pd.DataFrame(rows)
    eff = df[df.effect != "clean"]
    lines = ["| effect | sign | method | beacons | covered | flagged | covered or flagged | "
             "confidently wrong | worst error unflagged (m) | planes > 10 m off unflagged |",
             "|---|---|---|---:|---:|---:|---:|---:|---:|---:|"]
    eff = eff.assign(effect=np.where(eff.generator == "independent-40%-outliers",
                                     "range_bias, 40 % outliers (indep.)", eff.effect))
    for (e, sign, m), s in eff.groupby(["effect", "sign", "method"], sort=False):
        unfl = s[~s.flagged]
        worst = f"{np.nanmax(np.abs(unfl.error)):.2f}" if len(unfl) else "-"  # all flagged
        lines.append(f"| {e} | {'+' if sign > 0 else '-'} | {m} | {len(s)} | "
                     f"{int(s.covered.sum())} | {int(s.flagged.sum())} | "
                     f"{int((s.covered | s.flagged).sum())} | {int(s.wrong.sum())} | "
                     f"{worst} | {int(s.far_unflagged.sum())} |")
    clean = df[df.effect == "clean"]
    fa = ["| generator | method | surveys | beacons | beacons flagged | surveys with a flag "
          "| interval coverage |", "|---|---|---:|---:|---:|---:|---:|"]
    for (g, m), s in clean.groupby(["generator", "method"], sort=False):
        per_survey = s.groupby("seed").flagged.any()
        fa.append(f"| {g} | {m} | {per_survey.size} | {len(s)} | {int(s.flagged.sum())} "
                  f"({100 * s.flagged.mean():.1f} %) | {int(per_survey.sum())} | "
                  f"{100 * s.covered.mean():.1f} % |")
    which = clean[clean.flagged]
    fa_detail = sorted({f for fl in which["flags"] for f in fl})
    return lines, fa, df, fa_detail


def main(argv=None):
    """Command-line entry point."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="1 seed per cell, 3 clean, print")
    ap.add_argument("--seeds", type=int, default=3, help="seeds per effect, sign, generator")
    ap.add_argument("--clean", type=int, default=30, help="clean surveys per generator")
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--no-sample", action="store_true", help="fit only (fast)")
    args = ap.parse_args(argv)
    n_seeds, n_clean = (1, 3) if args.quick else (args.seeds, args.clean)
    todo = cells(n_seeds) + [(g, None, 1, 100 + s) for g in GENERATORS for s in range(n_clean)]
    t0 = time.perf_counter()
    with Pool(args.workers) as pool:
        rows = [r for rs in pool.imap(partial(one, sample=not args.no_sample), todo)
                for r in rs]
    took = time.perf_counter() - t0
    lines, fa, df, fa_detail = summarise(rows)
    eff = df[df.effect != "clean"]
    cmd = "python benchmarks/model_checks.py " + " ".join(argv if argv is not None
                                                         else sys.argv[1:])
    text = "\n".join([
        f"Produced by `{cmd.strip()}` on {dt.date.today().isoformat()} ({machine()}; "
        f"{took:.0f} s).", "",
        "### Surveys with a hidden effect", "",
        f"{n_seeds} seeds per effect, sign and generator ({', '.join(GENERATORS)}); one row "
        "per effect, sign and method, over all beacons of those surveys. *Covered*: the "
        "plane's interval holds the true plane; *flagged*: a model check or a quality flag "
        "(or, for `sample`, the beacon left unsampled); *confidently wrong*: neither.", "",
        *lines, "",
        f"In all: {int(eff.wrong.sum())} of {len(eff)} beacon results confidently wrong; "
        f"{int(eff.far_unflagged.sum())} planes more than {LIMIT:g} m off without a flag.", "",
        "### Clean surveys: false alarms", "",
        f"{n_clean} surveys per generator, no effect.", "", *fa, "",
        "Checks that raised the false alarms: " + (", ".join(fa_detail) or "none") + ".", ""])
    print(text)
    if not args.quick:
        write_section(ROOT / "docs" / "model-checks.md", "model-checks-study", text)


if __name__ == "__main__":
    main()
