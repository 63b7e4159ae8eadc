"""ESS per second of the sampler on one beacon of 5,000 ranges, against baselines.

Run from the repository root on a quiet machine::

    python benchmarks/bench_bayes.py              # writes its section of docs/benchmarks.md
    python benchmarks/bench_bayes.py --quick      # one repeat, no baselines, prints only

Goal (issue 3): the minimum ESS over d0, sigma_MP, sigma_DP and the weights
reaches 1,000 within 10 s of wall time. Baselines on the same data in the same
run: a plain emcee run (stretch move, one walker at a time, scipy.stats
log-densities with ``logsumexp``) and, if PyMC is installed (``pip install
.[bench]``), NUTS on the same model, started from the same EM solution.

ESS is reported two ways: ArviZ's rank-normalised bulk ESS on every kept
draw (the same estimator for bayes_mpem and PyMC; for emcee, walkers are the
chains), and for emcee also emcee's ``steps x walkers / tau``.
"""

from __future__ import annotations

import argparse
import datetime as dt
import sys
import time
import warnings
from pathlib import Path

import emcee
import numpy as np
from scipy import special, stats

import bayes_mpem as bm
from bayes_mpem.lbl.beacon_sampling import sample_beacon
from bayes_mpem.lbl.posterior import BeaconPosterior
from bayes_mpem.lbl.presets import ABE58

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import machine, write_section  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
NAMES = ("d0", "sigma_mp", "sigma_dp", "w_dp", "w_mp", "w_ol")


def make_data(n=5000, seed=0):
    """Beacon 4 of abe58 (50 % direct path, 35 % multipath, 15 % outliers), n replies."""
    sim = bm.simulate_survey(
        "abe58", rng=seed, n_cycles=n, p_no_reply=0.0,
        beacons={"4": ABE58["beacons"]["4"]}, weights={"4": ABE58["weights"]["4"]},
        sigma_mp={"4": ABE58["sigma_mp"]["4"]})
    return sim.survey.for_beacon("4")


def bulk_ess(draws: dict) -> dict:
    """ArviZ bulk ESS of ``{name: (chain, draw)}`` arrays."""
    import arviz_base as azb
    import arviz_stats as azs

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        tree = azb.from_dict({"posterior": draws})
        ess = azs.ess(tree, method="bulk")
    return {k: float(ess[k]) for k in draws}


def run_ours(data, seed):
    """bayes_mpem.sample_beacon with its defaults (learned priors), timed end to end."""
    t0 = time.perf_counter()
    r = sample_beacon(data, rng=seed, progress=False)
    wall = time.perf_counter() - t0
    return {"wall": wall, "sampling": r.diagnostics["seconds"], "emcee_ess": r.min_ess,
            "bulk_ess": min(r.ess_bulk.values()), "steps": r.diagnostics["n_steps"],
            "walkers": r.diagnostics["n_walkers"], "tau": max(r.tau.values())}


def run_plain_emcee(data, seed, target=1000, cap=180.0):
    """A straightforward emcee run: stretch move, per-walker scipy log-density."""
    post = BeaconPosterior(data)
    g = post.geom
    em = bm.fit_mixture_em(data, rng=seed)

    def log_prob(theta):
        d0, lsm, lsd, wd, wm = theta
        wo = 1 - wd - wm
        if not (post.d0_bounds[0] <= d0 <= post.d0_bounds[1] and wd > 0 and wm > 0 and wo > 0
                and np.log(0.05) <= lsm <= np.log(500) and np.log(0.05) <= lsd <= np.log(500)):
            return -np.inf
        mp = 0.5 * (g.direct + np.sqrt(g.h**2 + (2 * d0 - g.dz) ** 2))
        comp = np.stack([np.log(wd) + stats.norm.logpdf(g.z, g.direct, np.exp(lsd)),
                         np.log(wm) + stats.norm.logpdf(g.z, mp, np.exp(lsm)),
                         np.full(g.n, np.log(wo) + g.log_ol_density)])
        return float(special.logsumexp(comp, axis=0).sum())

    nw = 32
    rs = np.random.default_rng(seed)
    centre = post.theta_from(em.to_dict())
    p0 = centre + 1e-3 * np.abs(centre) * rs.standard_normal((nw, 5)) * [1e-3, 1, 1, 0.1, 0.1]
    sampler = emcee.EnsembleSampler(nw, 5, log_prob)
    sampler.random_state = np.random.RandomState(seed).get_state()
    t0 = time.perf_counter()
    state, ess = p0, 0.0
    while time.perf_counter() - t0 < cap:
        state = sampler.run_mcmc(state, 200, progress=False)
        tau = sampler.get_autocorr_time(tol=0, quiet=True)
        burn = int(2 * tau.max())
        kept = sampler.iteration - burn
        ess = kept * nw / tau.max() if kept > 0 else 0.0
        if ess >= target:
            break
    return {"wall": time.perf_counter() - t0, "emcee_ess": float(ess),
            "steps": sampler.iteration, "capped": ess < target}


def run_pymc(data, seed):
    """NUTS (PyMC) on the same model and priors, from the same EM start."""
    import pymc as pm
    import pytensor.tensor as pt

    post = BeaconPosterior(data)
    g = post.geom
    em = bm.fit_mixture_em(data, rng=seed)
    t0 = time.perf_counter()
    with pm.Model():
        d0 = pm.Uniform("d0", *post.d0_bounds)
        lsm = pm.Uniform("log_sigma_mp", *post.log_sigma_bounds)
        lsd = pm.Uniform("log_sigma_dp", *post.log_sigma_bounds)
        w = pm.Dirichlet("w", a=np.ones(3))
        mp = 0.5 * (g.direct + pt.sqrt(g.h**2 + (2 * d0 - g.dz) ** 2))
        comp = pt.stack([
            pt.log(w[0]) + pm.logp(pm.Normal.dist(g.direct, pt.exp(lsd)), g.z),
            pt.log(w[1]) + pm.logp(pm.Normal.dist(mp, pt.exp(lsm)), g.z),
            pt.log(w[2]) + g.log_ol_density + 0 * g.z])
        pm.Potential("likelihood", pm.math.logsumexp(comp, axis=0).sum())
        init = {"d0": em.d0, "log_sigma_mp": np.log(em.sigma_mp),
                "log_sigma_dp": np.log(em.sigma_dp),
                "w": np.array([em.weights[c] for c in ("dp", "mp", "ol")])}
        idata = pm.sample(draws=1000, tune=1000, chains=2, cores=2, random_seed=seed,
                          initvals=init, progressbar=False, compute_convergence_checks=False)
    wall = time.perf_counter() - t0
    p = idata.posterior
    draws = {"d0": p["d0"].values, "sigma_mp": np.exp(p["log_sigma_mp"].values),
             "sigma_dp": np.exp(p["log_sigma_dp"].values),
             "w_dp": p["w"].values[..., 0], "w_mp": p["w"].values[..., 1],
             "w_ol": p["w"].values[..., 2]}
    sampling = float(idata.sample_stats.attrs.get("sampling_time", np.nan))
    return {"wall": wall, "sampling": sampling, "bulk_ess": min(bulk_ess(draws).values()),
            "version": pm.__version__}


def main(argv=None):
    """Command-line entry point."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true")
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--out", default=str(ROOT / "docs" / "benchmarks.md"))
    args = p.parse_args(argv)
    if not args.quick:  # a fresh PyTensor compile directory, so the first NUTS run is cold
        import os
        import tempfile

        os.environ["PYTENSOR_FLAGS"] = f"base_compiledir={tempfile.mkdtemp(prefix='pytensor')}"
    data = make_data()
    reps = 1 if args.quick else args.repeat
    ours = [run_ours(data, seed) for seed in range(reps)]
    for o in ours:
        print(f"bayes_mpem: {o['wall']:.2f} s wall ({o['sampling']:.2f} s sampling), min ESS "
              f"{o['emcee_ess']:.0f} (emcee) / {o['bulk_ess']:.0f} (ArviZ bulk), "
              f"{o['steps']} steps x {o['walkers']} walkers", flush=True)
    if args.quick:
        return
    plain = run_plain_emcee(data, 0)
    print(f"plain emcee: {plain['wall']:.1f} s for min ESS {plain['emcee_ess']:.0f}"
          + (" (capped)" if plain["capped"] else ""), flush=True)
    nuts = []
    try:
        for label in ("cold compile cache", "warm compile cache"):
            nuts.append(run_pymc(data, 0) | {"label": label})
            print(f"PyMC NUTS ({label}): {nuts[-1]['wall']:.1f} s wall, "
                  f"min bulk ESS {nuts[-1]['bulk_ess']:.0f}", flush=True)
    except ImportError:
        print("PyMC not installed (pip install .[bench]); NUTS baseline skipped")

    med = {k: float(np.median([o[k] for o in ours])) for k in ("wall", "emcee_ess", "bulk_ess")}
    rate = med["bulk_ess"] / med["wall"]
    lines = [
        "## Bayesian sampler: ESS per second",
        "",
        f"Produced by `python benchmarks/bench_bayes.py` on {dt.date.today().isoformat()}; "
        f"machine: {machine()}, emcee {emcee.__version__}. Data: one beacon, "
        f"{data.n:,d} ranges (beacon 4 of `abe58`), learned priors (d0, sigma_MP, sigma_DP "
        "and three weights: 5 free parameters). Wall time includes the EM start, sampling, "
        "and the post-processing (pointwise log-likelihood, class probabilities, ArviZ data).",
        "",
        "| method | wall (s) | min ESS, ArviZ bulk (all kept draws) | min ESS, emcee tau "
        "| ESS/s (bulk) |",
        "|---|---:|---:|---:|---:|",
    ]
    for i, o in enumerate(ours):
        lines.append(f"| bayes_mpem, seed {i} | {o['wall']:.2f} | {o['bulk_ess']:.0f} "
                     f"| {o['emcee_ess']:.0f} | {o['bulk_ess'] / o['wall']:.0f} |")
    lines.append(f"| plain emcee (stretch, per-walker scipy) | {plain['wall']:.1f} | - "
                 f"| {plain['emcee_ess']:.0f}{' (capped)' if plain['capped'] else ''} "
                 f"| {plain['emcee_ess'] / plain['wall']:.0f} (emcee tau) |")
    for n in nuts:
        lines.append(f"| PyMC {n['version']} NUTS, 2 chains x 1000 (+1000 tune), "
                     f"incl. compilation, {n['label']} | {n['wall']:.1f} | {n['bulk_ess']:.0f} "
                     f"| - | {n['bulk_ess'] / n['wall']:.0f} |")
    lines += ["", f"Goal: min ESS >= 1,000 within 10 s. Median over {reps} seeds: "
              f"{med['wall']:.2f} s for a min ESS of {med['bulk_ess']:.0f} (ArviZ bulk) / "
              f"{med['emcee_ess']:.0f} (emcee): "
              + ("met." if med["wall"] <= 10 and min(med["bulk_ess"], med["emcee_ess"]) >= 1000
                 else "NOT met.")]
    for n in nuts:
        lines.append(f"Against PyMC NUTS ({n['label']}): "
                     f"{rate / (n['bulk_ess'] / n['wall']):.1f}x its ESS per second "
                     "(target: at least 5x).")
    if nuts:
        lines.append("The cold run compiles PyTensor's C code into a fresh directory (a first "
                     "run on a machine); the warm one reuses it (a repeat run).")
    lines.append("")
    write_section(args.out, "bench_bayes", "\n".join(lines))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
