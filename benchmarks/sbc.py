"""Simulation-based calibration (Talts et al. 2018) of the beacon posterior and its sampler.

Run from the repository root::

    python benchmarks/sbc.py --arms shipped --section sbc_samplers   # docs page + figure
    python benchmarks/sbc.py --quick         # 40 per arm, prints only

For one design (beacon 4 of the ``abe58`` preset, 330 ping cycles; pings with a
direct path under 200 m left out, ~300 replies), each simulation draws the
parameters from the calibration's proper prior (``bayes_mpem.lbl.bayes.sbc``: plane
within 30 m of the sea surface, sigma_DP and sigma_MP log-uniform on 1-20 m,
weights Dirichlet(1, 1, 1), outliers uniform over a fixed window), simulates the
ranges from the model, samples their posterior exactly as ``bayes-mpem sample``
does (EM start, the shipped stopping rule: bulk ESS 1,000 and R-hat < 1.01), and
ranks each true value among 99 draws thinned from the kept chain.

Three arms (``--arms``): the shipped sampler (``sampler="auto"``: emcee with the
independence ``MHMove``, differential evolution where a pilot finds the proposal fits
poorly; 500 simulations), and 250 each of the independence move alone and
differential evolution alone. Per parameter:
the chi-square test of 10 equal rank bins and the binomial test of the share of
ranks in the outer 10 % (a too-narrow posterior puts the truth there too often).
A parameter passes at the 1 % level when both p-values are above 0.01.
"""

from __future__ import annotations

import argparse
import datetime as dt
import sys
import time
from functools import partial
from multiprocessing import Pool
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT / "benchmarks"))

from _report import machine, write_section  # noqa: E402

import bayes_mpem as bm  # noqa: E402
from bayes_mpem.lbl.bayes.sbc import SBCResult, run_sbc, sbc_design  # noqa: E402
from bayes_mpem.mcmc.sbc import rank_dispersion  # noqa: E402
from bayes_mpem.plots.bayes import plot_sbc_ranks  # noqa: E402

#: arm: (label, the options of run_sbc, made in the worker)
ARMS = {
    "shipped": ("shipped (auto)", lambda: {"sampler": "auto"}),
    "independence": ("independence MHMove alone", lambda: {"sampler": "independence"}),
    "ensemble": ("differential evolution alone", lambda: {"sampler": "ensemble"}),
}
SAMPLER = {"min_ess": 1000.0}  # the shipped stopping rule (and R-hat < 1.01)


def design():
    """Beacon 4 of abe58, 330 ping cycles, pings with a direct path of 200 m or more."""
    sim = bm.simulate_survey("abe58", rng=0, n_cycles=330)
    return sbc_design(sim.survey.for_beacon("4"))


def chunk(args, arm):
    """Run one seeded block of simulations of the arm ``arm``."""
    seed, n = args
    return run_sbc(design(), n, rng=seed, **ARMS[arm][1](), **SAMPLER)


def merged(parts):
    """One SBCResult of several blocks."""
    first = parts[0]
    return SBCResult(names=first.names, ranks=np.concatenate([p.ranks for p in parts]),
                     truths=np.concatenate([p.truths for p in parts]), n_draws=first.n_draws,
                     settings={**first.settings, "n_sims": sum(len(p.ranks) for p in parts)},
                     diagnostics={k: sum((p.diagnostics[k] for p in parts), [])
                                  for k in first.diagnostics})


def table(label, res, seconds):
    """Markdown rows of one move set."""
    lines = []
    for i, (k, t) in enumerate(res.tests().items()):
        disp = rank_dispersion(res.ranks[:, i], res.n_draws)
        ok = t["p_value"] > 0.01 and t["tails_p_value"] > 0.01
        lines.append(f"| {label} | {k} | {t['chi2']:.1f} | {t['p_value']:.3f} | "
                     f"{100 * t['tails']:.1f} % | {t['tails_p_value']:.2g} | "
                     f"{disp['ratio']:.3f} ({disp['z']:+.1f}) | "
                     f"{'pass' if ok else '**fail**'} |")
    d = res.diagnostics
    pooled = rank_dispersion(res.ranks, res.n_draws)
    used = ", ".join(f"{k} {v}" for k, v in
                     zip(*np.unique(d["sampler"], return_counts=True), strict=True))
    note = (f"{label}: {len(res.ranks)} simulations in {seconds:.0f} s; sampler used: {used}; "
            f"steps (or draws per chain) median {np.median(d['n_steps']):.0f}, max "
            f"{max(d['n_steps'])}; stopping rule met in {sum(d['converged'])} of "
            f"{len(d['converged'])}; dispersion of all parameters together "
            f"{pooled['ratio']:.3f} (z {pooled['z']:+.1f}, p {pooled['p_value']:.2g})")
    return lines, note


def main(argv=None):
    """Command-line entry point."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="40 simulations per arm, print")
    ap.add_argument("--sims", type=int, default=500, help="simulations, shipped sampler")
    ap.add_argument("--sims-other", type=int, default=250,
                    help="simulations for each of the other arms")
    ap.add_argument("--arms", default=",".join(ARMS),
                    help=f"comma-separated arms (default all: {','.join(ARMS)})")
    ap.add_argument("--section", default="sbc",
                    help="section of docs/bayes-calibration.md to write (default sbc)")
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--block", type=int, default=20, help="simulations per seeded block")
    args = ap.parse_args(argv)
    rows, notes, results = [], [], {}
    arms = [a.strip() for a in args.arms.split(",")]
    bad = [a for a in arms if a not in ARMS]
    if bad:
        ap.error(f"--arms: unknown {bad}; expected some of {list(ARMS)}")
    for arm in arms:
        label = ARMS[arm][0]
        n = 40 if args.quick else (args.sims if arm == "shipped" else args.sims_other)
        blocks = [(7_000 + b, min(args.block, n - b * args.block))
                  for b in range(int(np.ceil(n / args.block)))]
        t0 = time.perf_counter()
        with Pool(args.workers) as pool:
            parts = pool.map(partial(chunk, arm=arm), blocks, chunksize=1)
        res = merged(parts)
        results[label] = res
        lines, note = table(label, res, time.perf_counter() - t0)
        rows += lines
        notes.append(note)
        print("\n".join(lines), "\n" + note, flush=True)
    s = next(iter(results.values())).settings
    figure = "sbc_ranks.png" if args.section == "sbc" else f"{args.section}_ranks.png"
    cmd = "python benchmarks/sbc.py " + " ".join(argv if argv is not None else sys.argv[1:])
    title = ("## Simulation-based calibration of the ensemble's moves (issue 14)"
             if args.section == "sbc"
             else "## Simulation-based calibration of the samplers (the default since issue 17)")
    text = "\n".join([
        title, "",
        f"Produced by `{cmd.strip()}` on {dt.date.today().isoformat()} ({machine()}).", "",
        f"Design: beacon 4 of `abe58`, {s['n_ranges']} pings (direct path >= 200 m). Prior "
        f"(`bayes_mpem.lbl.bayes.sbc`): d0 uniform on [{s['d0_bounds'][0]:.0f}, "
        f"{s['d0_bounds'][1]:.0f}] m (the plane within 30 m of the sea surface), sigma_DP "
        f"and sigma_MP log-uniform on {s['sigma_bounds'][0]:g}-{s['sigma_bounds'][1]:g} m, "
        f"weights Dirichlet(1, 1, 1), outliers uniform on [{s['window'][0]:.0f}, "
        f"{s['window'][1]:.0f}] m. Each simulation: prior draw, ranges from the model, EM "
        "start, the arm's sampler to the shipped stopping rule (bulk ESS 1,000, R-hat < "
        "1.01), rank of the truth "
        f"among {next(iter(results.values())).n_draws} draws thinned from the kept chain.", "",
        "A parameter passes at the 1 % level when the chi-square test of 10 equal rank bins "
        "and the binomial test of the share of ranks in the outer 10 % (expected 10 %) both "
        "give p > 0.01.", "",
        "*Dispersion*: the mean squared normal score of the ranks over its value for uniform "
        "ranks (`bayes_mpem.mcmc.sbc.rank_dispersion`; about 1 / s^2 for draws s times too "
        "narrow) and its z; given for reading, not part of the pass rule.", "",
        "| sampler | parameter | chi2 (9 dof) | p | ranks in outer 10 % | p | dispersion (z) "
        "| 1 % level |",
        "|---|---|---:|---:|---:|---:|---:|---|", *rows, "", *[f"- {x}." for x in notes], "",
        f"![SBC rank histograms](figures/{figure})", ""])
    print(text)
    if not args.quick:
        fig = plot_sbc_ranks(results)
        fig.savefig(ROOT / "docs" / "figures" / figure, dpi=80)
        write_section(ROOT / "docs" / "bayes-calibration.md", args.section, text)


if __name__ == "__main__":
    main()
