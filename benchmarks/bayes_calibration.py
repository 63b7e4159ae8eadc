"""Calibration of the posterior intervals, and what LOO says about the priors.

Run from the repository root::

    python benchmarks/bayes_calibration.py                    # both generators, docs page
    python benchmarks/bayes_calibration.py --quick            # 6 surveys each, prints only
    python benchmarks/bayes_calibration.py --generator independent --surveys 250 --no-loo
    python benchmarks/bayes_calibration.py --from-raw NEW.csv.gz ... --against OLD.csv.gz ...

1. Coverage: over many seeded surveys, every beacon of each, how often the 95 %
   highest-density interval (and the equal-tailed one) contains the true d0,
   sigma_MP, sigma_DP and each weight (learned priors, the path chosen by
   ``path="auto"``). Two generators: the project's ``random`` preset (700 ping
   cycles) and ``tests/independent_generator.py`` (written without the package:
   its own tracks, per-beacon noise, double-bounce multipath, ~1,250 replies per
   beacon). Each beacon's rows (truth, interval ends, posterior mean and sd) go to
   ``--raw`` (CSV) so the numbers can be studied without sampling again.
2. Equal against learned priors: the ELPD difference (learned - equal), its SE,
   and the verdict on surveys whose weights are far from equal and on surveys
   simulated with equal weights.
3. With ``--against`` (raw files of the same surveys sampled another way, e.g. by
   ``sampler="ensemble"``): beacon by beacon, the difference of the posterior means
   in posterior sds and the ratio of the sds, and the coverage of each.
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
import pandas as pd
from scipy import stats

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT / "benchmarks"))

import independent_generator as indep  # noqa: E402
from _report import machine, write_section  # noqa: E402

import bayes_mpem as bm  # noqa: E402
from bayes_mpem.io.survey import load_survey  # noqa: E402
from bayes_mpem.lbl.bayes.beacon_sampling import sample_beacon  # noqa: E402
from bayes_mpem.lbl.bayes.loo import compare_beacon  # noqa: E402
from bayes_mpem.lbl.em.path_choice import choose_path  # noqa: E402
from bayes_mpem.mcmc import equal_tailed  # noqa: E402

KEYS = ("d0", "sigma_mp", "sigma_dp", "w_dp", "w_mp", "w_ol")
SEED0 = {"random": 2000, "independent": 30_000}


def survey(generator, i):
    """Survey ``i`` of a generator: ``(Survey, {beacon: truth})`` with the six true values."""
    if generator == "random":
        sim = bm.simulate_survey("random", rng=SEED0["random"] + i, n_cycles=700)
        truth = {b: {"d0": t["d0"], "sigma_mp": t["sigma_mp"], "sigma_dp": t["sigma_dp"],
                     **{f"w_{c}": t["weights"][c] for c in ("dp", "mp", "ol")}}
                 for b, t in sim.truth.items()}
        return sim.survey, truth
    g = indep.generate(seed=SEED0["independent"] + i)
    t = g["truth"]
    truth = {b: {"d0": t["d0"][b], "sigma_mp": t["sigma_mp"][b], "sigma_dp": t["sigma_dp"][b],
                 **{f"w_{c}": t["weights"][b][c] for c in ("dp", "mp", "ol")}}
             for b in t["d0"]}
    return load_survey(g["pings"], g["beacons"]), truth


def one_survey(i, generator, n_draws=4000, ci=0.95):
    """Sample every beacon of survey ``i``; one row per beacon and parameter."""
    sv, truth = survey(generator, i)
    rows = []
    for b in sorted(truth):
        data = sv.for_beacon(b)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            choice = choose_path(data, "auto", rng=i)
            t0 = time.perf_counter()
            r = sample_beacon(data, rng=1000 + i, ci=ci, path=choice.path, init=choice.fit,
                              progress=False, n_draws=n_draws, allow_flagged_start=True)
        post = r.idata.posterior.dataset
        for k in KEYS:
            x = np.ravel(post[k].values)
            sub = np.ravel(post[k].values[:, ::4])  # a quarter of the draws
            lo, hi = bm.mcmc.hdi(x, ci)
            slo, shi = bm.mcmc.hdi(sub, ci)
            elo, ehi = equal_tailed(x, ci)
            tv = truth[b][k]
            rows.append({"generator": generator, "survey": i, "beacon": b, "param": k,
                         "truth": tv, "mean": float(x.mean()), "sd": float(x.std(ddof=1)),
                         "hdi_lo": lo, "hdi_hi": hi, "et_lo": elo, "et_hi": ehi,
                         "hdi_sub_lo": slo, "hdi_sub_hi": shi, "n_draws": x.size,
                         "rank": float(np.mean(x < tv)), "n": data.n, "path": choice.path,
                         "ess": r.ess.get(k, np.nan), "flags": "; ".join(r.em.flags),
                         "sampler": r.diagnostics["sampler"],
                         "seconds": time.perf_counter() - t0})
    return rows


def coverage_table(df):
    """Per parameter: coverage of the HDI, its SE and p-value, equal-tailed, sd of z."""
    out = []
    for k in KEYS:
        s = df[df.param == k]
        n = len(s)
        hit = ((s.hdi_lo <= s.truth) & (s.truth <= s.hdi_hi)).to_numpy()
        sub = ((s.hdi_sub_lo <= s.truth) & (s.truth <= s.hdi_sub_hi)).to_numpy()
        et = ((s.et_lo <= s.truth) & (s.truth <= s.et_hi)).to_numpy()
        z = ((s["mean"] - s.truth) / s.sd).to_numpy()
        p = hit.mean()
        pval = stats.binomtest(int(hit.sum()), n, 0.95).pvalue
        out.append({"param": k, "n": n, "hdi": p, "se": np.sqrt(p * (1 - p) / n),
                    "p_value": pval, "hdi_quarter": sub.mean(), "et": et.mean(),
                    "sd_z": float(np.std(z, ddof=1)), "mean_z": float(np.mean(z))})
    return pd.DataFrame(out)


def loo_cases(n):
    """ELPD differences on far-from-equal and on equal-weight surveys (beacon 2 of abe58)."""
    rows = []
    kw = {"progress": False, "n_draws": 1000}
    for label, w in (("far from equal (0.75, 0.15, 0.10)", (0.75, 0.15, 0.10)),
                     ("abe58 beacon 2 (0.60, 0.25, 0.15)", (0.60, 0.25, 0.15)),
                     ("equal (1/3 each)", (1 / 3, 1 / 3, 1 / 3))):
        for seed in range(n):
            sim = bm.simulate_survey("abe58", rng=seed, n_cycles=700,
                                     weights={b: w for b in "1234"})
            c = compare_beacon(sim.survey.for_beacon("2"), rng=seed, **kw)
            rows.append((label, seed, c.elpd_diff, c.elpd_diff_se, c.verdict,
                         c.pareto_k["equal"]["n_bad"] + c.pareto_k["learned"]["n_bad"],
                         len(c.changed)))
    return rows


def coverage_lines(gen, tab, df, seconds):
    """The Markdown section of one generator."""
    what = ("the project's `random` preset (3-5 beacons, weights, sigma_MP 3-20 m, sigma_DP "
            "1-6 m drawn per survey; 700 ping cycles, ~600-700 replies per beacon)"
            if gen == "random" else
            "`tests/independent_generator.py` (4 beacons, sigma_DP 1-5 m and sigma_MP 3-15 m "
            "per beacon, double-bounce multipath, ~1,100-1,250 replies per beacon)")
    n_s = df.survey.nunique()
    chosen = ", ".join(f"{k} {v // len(KEYS)}" for k, v in df.path.value_counts().items())
    lines = [f"### {gen}: {n_s} surveys, {len(df) // len(KEYS)} beacons", "",
             f"Surveys from {what}; every beacon, learned priors, `path=\"auto\"` "
             f"(chosen: {chosen}); "
             f"{int(df.n_draws.iloc[0])} draws per beacon; sampling took {seconds:.0f} s in all.",
             "",
             "| parameter | HDI coverage | SE | p (binomial, 95 %) | HDI from 1/4 of the draws "
             "| equal-tailed | mean z | sd z |", "|---|---:|---:|---:|---:|---:|---:|---:|"]
    for r in tab.itertuples():
        lines.append(f"| {r.param} | {100 * r.hdi:.1f} % | {100 * r.se:.1f} | {r.p_value:.2f} | "
                     f"{100 * r.hdi_quarter:.1f} % | {100 * r.et:.1f} % | {r.mean_z:+.2f} | "
                     f"{r.sd_z:.2f} |")
    return lines + [""]


def agreement_lines(new, old):
    """Markdown: the two raw tables' posteriors compared beacon by beacon."""
    m = new.merge(old, on=["generator", "survey", "beacon", "param"], suffixes=("", "_old"))
    used = ", ".join(f"{k} {v // len(KEYS)}" for k, v in new.sampler.value_counts().items()) \
        if "sampler" in new else "n/a"
    lines = ["## The default sampler against the ensemble, beacon by beacon", "",
             f"The surveys of the coverage tables above, sampled twice: as shipped (sampler "
             f"used: {used}) and, in the earlier run kept in `benchmarks/results/` "
             f"(`*_ensemble.csv.gz`), with emcee's ensemble (differential evolution). "
             f"{len(m) // len(KEYS)} beacons matched. Per parameter: the difference of the "
             "posterior means in the ensemble's posterior sd (its mean and spread over the "
             "beacons; the Monte-Carlo error of two runs of ESS ~1,000-4,000 alone gives a "
             "spread of ~0.03), the ratio of the posterior sds (median and 5-95 %), and the "
             "coverage of the 95 % HDI by each, with the number of beacons where they "
             "disagree (the truth near an interval end, where the Monte-Carlo error of the "
             "ends decides).", "",
             "| generator | parameter | mean diff / sd: mean | spread | sd ratio: median | 5-95 % "
             "| coverage, default | coverage, ensemble | beacons disagreeing |",
             "|---|---|---:|---:|---:|---:|---:|---:|---:|"]
    for (gen, k), d in m.groupby(["generator", "param"], sort=False):
        dz = (d["mean"] - d.mean_old) / d.sd_old
        ratio = d.sd / d.sd_old
        hit = (d.hdi_lo <= d.truth) & (d.truth <= d.hdi_hi)
        hit_old = (d.hdi_lo_old <= d.truth_old) & (d.truth_old <= d.hdi_hi_old)
        lines.append(f"| {gen} | {k} | {dz.mean():+.3f} | {dz.std():.3f} | {ratio.median():.3f} "
                     f"| {ratio.quantile(0.05):.3f}-{ratio.quantile(0.95):.3f} | "
                     f"{100 * hit.mean():.1f} % | {100 * hit_old.mean():.1f} % | "
                     f"{int((hit != hit_old).sum())} |")
    return lines + [""]


def main(argv=None):
    """Command-line entry point."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true")
    p.add_argument("--surveys", type=int, default=100, help="surveys per generator")
    p.add_argument("--generator", choices=("random", "independent", "both"), default="both")
    p.add_argument("--workers", type=int, default=1)
    p.add_argument("--no-loo", action="store_true", help="skip the equal/learned section")
    p.add_argument("--raw", default=None, help="CSV of every beacon's rows (default: none)")
    p.add_argument("--from-raw", default=None, nargs="+", metavar="CSV",
                   help="build the coverage section from earlier --raw files, no sampling")
    p.add_argument("--against", default=None, nargs="+", metavar="CSV",
                   help="with --from-raw: compare with these raw files of the same surveys")
    p.add_argument("--out", default=str(ROOT / "docs" / "bayes-calibration.md"))
    args = p.parse_args(argv)
    n_cov = 6 if args.quick else args.surveys
    gens = ("random", "independent") if args.generator == "both" else (args.generator,)
    cmd = "python benchmarks/bayes_calibration.py " + " ".join(argv or sys.argv[1:])
    lines = ["## Coverage of the 95 % intervals", "",
             f"Produced by `{cmd.strip()}` on {dt.date.today().isoformat()} ({machine()}).",
             "", "Standard error of a coverage: sqrt(p (1 - p) / n). The p-value is the "
             "two-sided binomial test of the hits against 95 %. z = (posterior mean - truth) / "
             "posterior sd: mean 0 and sd 1 for calibrated, near-Gaussian posteriors.", ""]
    frames = []
    if args.from_raw:
        old = pd.concat([pd.read_csv(f, dtype={"beacon": str}) for f in args.from_raw])
        gens = tuple(g for g in ("random", "independent") if g in set(old.generator))
    for gen in gens:
        if args.from_raw:
            df = old[old.generator == gen]
        else:
            rows = []
            with Pool(args.workers) as pool:
                for i, rs in enumerate(pool.imap(partial(one_survey, generator=gen),
                                                 range(n_cov))):
                    rows += rs
                    if args.raw and (i + 1) % 10 == 0:  # progress, and a partial file
                        pd.concat(frames + [pd.DataFrame(rows)]).to_csv(args.raw, index=False)
                        print(f"{gen}: {i + 1} surveys", file=sys.stderr, flush=True)
            df = pd.DataFrame(rows)
        frames.append(df)
        if args.raw:
            pd.concat(frames).to_csv(args.raw, index=False)
        tab = coverage_table(df)
        seconds = df.drop_duplicates(["survey", "beacon"]).seconds.sum()
        lines += coverage_lines(gen, tab, df, seconds)
        print("\n".join(lines[-len(KEYS) - 6:]), flush=True)
    sections = {"calibration-coverage": "\n".join(lines)}
    if args.against:
        if not args.from_raw:
            p.error("--against needs --from-raw")
        ref = pd.concat([pd.read_csv(f, dtype={"beacon": str}) for f in args.against])
        sections["calibration-agreement"] = "\n".join(
            [*agreement_lines(old, ref)[:2],
             f"Produced by `{cmd.strip()}` on {dt.date.today().isoformat()}.", "",
             *agreement_lines(old, ref)[2:]])
    if not args.no_loo:
        rows = loo_cases(2 if args.quick else 6)
        loo = ["## Equal against learned priors (PSIS-LOO)", "",
               f"Produced by `{cmd.strip()}` on {dt.date.today().isoformat()}.", "",
               "Beacon 2 of `abe58` with the weights given, 700 ping cycles. A difference is "
               "claimed when |ELPD learned - equal| exceeds both 2 SE and 4 nats.", "",
               "| simulated weights | seed | ELPD diff | SE | diff / SE | verdict "
               "| Pareto k above threshold | ranges changing class |",
               "|---|---:|---:|---:|---:|---|---:|---:|"]
        for label, seed, d, se, v, bad, ch in rows:
            loo.append(f"| {label} | {seed} | {d:.1f} | {se:.1f} | {d / se:.1f} | {v} | "
                       f"{bad} | {ch} |")
        sections["calibration-loo"] = "\n".join(loo)
    for text in sections.values():
        print(text)
    if not args.quick:
        for name, text in sections.items():
            write_section(args.out, name, text)
        print(f"wrote {args.out}", file=sys.stderr)


if __name__ == "__main__":
    main()
