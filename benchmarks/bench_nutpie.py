"""ESS per wall second of the whole public ``sample_beacon`` against nutpie, call to call.

Needs the ``bench`` extra (PyMC and nutpie)::

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_nutpie.py --pairs 5

On the two beacons of ``bench_bayes.py`` (abe58's beacon 4, 1,241 ranges, and a
4,764-range beacon), in one process: the same mixture likelihood and priors written in
PyMC (``d0`` uniform on the sampler's bounds, ``log sigma_MP`` and ``log sigma_DP``
uniform on ``[log 0.05, log 500]``, the weights ``Dirichlet(1, 1, 1)``: docs/bayes.md),
compiled once by ``nutpie.compile_pymc_model`` (its time reported apart), then after one
warm-up call of each, ``--pairs`` pairs interleaved (order alternating):
``sample_beacon(data, rng=i, progress=False)`` with its defaults (EM start, sampling,
per-range pass, ArviZ data; the likelihood kernel in its float32 default, one thread) and
``nutpie.sample(compiled, draws, tune, chains, cores)``. ESS is the smallest ArviZ bulk ESS
(arviz-stats) of the six natural parameters of each call's draws; the medians of ESS per
wall second of the call are compared. The end-to-end process figure (imports, EM start,
compilation and one call, each side in a fresh process) is printed with ``--process``.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
NAMES = ("d0", "sigma_mp", "sigma_dp", "w_dp", "w_mp", "w_ol")


def pymc_model(post, em):
    """The beacon posterior of ``post`` (learned priors, triangle path) in PyMC."""
    import pymc as pm
    import pytensor.tensor as pt

    g = post.geom
    with pm.Model() as model:
        d0 = pm.Uniform("d0", *post.d0_bounds, initval=em.d0)
        lsm = pm.Uniform("log_sigma_mp", *post.log_sigma_bounds, initval=np.log(em.sigma_mp))
        lsd = pm.Uniform("log_sigma_dp", *post.log_sigma_bounds, initval=np.log(em.sigma_dp))
        w = pm.Dirichlet("w", a=np.ones(3),
                         initval=np.array([em.weights[c] for c in ("dp", "mp", "ol")]))
        mp = 0.5 * (g.direct + pt.sqrt(g.h ** 2 + (2 * d0 - g.dz) ** 2))
        comp = pt.stack([
            pt.log(w[0]) + pm.logp(pm.Normal.dist(g.direct, pt.exp(lsd)), g.z),
            pt.log(w[1]) + pm.logp(pm.Normal.dist(mp, pt.exp(lsm)), g.z),
            pt.log(w[2]) + float(g.log_ol_density) + 0 * g.z])
        pm.Potential("likelihood", pm.math.logsumexp(comp, axis=0).sum())
    return model


def nutpie_draws(idata) -> dict:
    """``{name: (chain, draw)}`` of the natural parameters of a nutpie result."""
    p = idata.posterior
    w = p["w"].values
    return {"d0": p["d0"].values, "sigma_mp": np.exp(p["log_sigma_mp"].values),
            "sigma_dp": np.exp(p["log_sigma_dp"].values), "w_dp": w[..., 0],
            "w_mp": w[..., 1], "w_ol": w[..., 2]}


def min_ess(draws: dict) -> float:
    """Smallest ArviZ bulk ESS of ``{name: (chain, draw)}`` arrays."""
    from arviz_stats.base import array_stats

    return float(min(array_stats.ess(np.asarray(v, float), method="bulk")
                     for v in draws.values()))


def ours(sample_beacon, data, seed):
    """One call of ``sample_beacon``: ``(ESS, wall s, draws)``."""
    t0 = time.perf_counter()
    r = sample_beacon(data, rng=seed, progress=False)
    wall = time.perf_counter() - t0
    draws = {k: r.idata.posterior[k].values for k in NAMES}
    return min_ess(draws), wall, draws


def theirs(nutpie, compiled, args, seed):
    """One call of ``nutpie.sample``: ``(ESS, wall s, draws)``."""
    t0 = time.perf_counter()
    idata = nutpie.sample(compiled, draws=args.draws, tune=args.tune, chains=args.chains,
                          cores=args.cores, seed=seed, progress_bar=False)
    wall = time.perf_counter() - t0
    draws = nutpie_draws(idata)
    return min_ess(draws), wall, draws


def agreement(a: dict, b: dict) -> str:
    """Largest difference of the means in pooled sds, and the range of the sd ratios."""
    diff, ratio = [], []
    for k in NAMES:
        sa, sb = np.std(a[k]), np.std(b[k])
        diff.append(abs(np.mean(a[k]) - np.mean(b[k])) / np.sqrt(0.5 * (sa ** 2 + sb ** 2)))
        ratio.append(sa / sb)
    return (f"largest mean difference {max(diff):.3f} pooled sds, sd ratio (ours / nutpie) "
            f"{min(ratio):.3f} to {max(ratio):.3f}")


PROCESS_OURS = """
import sys; sys.path.insert(0, {bench!r})
from bench_bayes import beacons
import bayes_mpem
data = beacons(bayes_mpem)[{name!r}]
from bayes_mpem.lbl.bayes.beacon_sampling import sample_beacon
r = sample_beacon(data, rng=0, progress=False)
from bench_nutpie import min_ess, NAMES
print(min_ess({{k: r.idata.posterior[k].values for k in NAMES}}))
"""

PROCESS_THEIRS = """
import sys; sys.path.insert(0, {bench!r})
from bench_bayes import beacons
import bayes_mpem
from bayes_mpem.lbl.bayes.posterior import BeaconPosterior
from bayes_mpem.lbl.em.em_mixture import fit_mixture_em
data = beacons(bayes_mpem)[{name!r}]
post = BeaconPosterior(data); em = fit_mixture_em(data, rng=0)
import nutpie
from bench_nutpie import pymc_model, nutpie_draws, min_ess
compiled = nutpie.compile_pymc_model(pymc_model(post, em))
idata = nutpie.sample(compiled, draws={draws}, tune={tune}, chains={chains}, cores={cores},
                      seed=0, progress_bar=False)
print(min_ess(nutpie_draws(idata)))
"""


def process_rows(name, args):
    """Each side once in a fresh process: imports, (EM start,) compilation and one call."""
    bench = str(Path(__file__).resolve().parent)
    out = {}
    for who, code in (("ours", PROCESS_OURS), ("nutpie", PROCESS_THEIRS)):
        src = code.format(bench=bench, name=name, draws=args.draws, tune=args.tune,
                          chains=args.chains, cores=args.cores)
        t0 = time.perf_counter()
        res = subprocess.run([sys.executable, "-c", src], capture_output=True, text=True,
                             check=True, env=dict(os.environ))
        wall = time.perf_counter() - t0
        ess = float(res.stdout.split()[-1])
        out[who] = (ess, wall)
        print(f"  process, {who}: ESS {ess:,.0f} in {wall:.2f} s of the whole process "
              f"(python start, imports, compilation, one call): {ess / wall:,.0f} ESS/s")
    print(f"  process ratio ours / nutpie, ESS per second: "
          f"{(out['ours'][0] / out['ours'][1]) / (out['nutpie'][0] / out['nutpie'][1]):.1f}")


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--pairs", type=int, default=5)
    p.add_argument("--draws", type=int, default=1000, help="nutpie draws per chain")
    p.add_argument("--tune", type=int, default=1000, help="nutpie tuning steps per chain")
    p.add_argument("--chains", type=int, default=2, help="nutpie chains")
    p.add_argument("--cores", type=int, default=2, help="nutpie threads")
    p.add_argument("--process", action="store_true", help="also the fresh-process figure")
    p.add_argument("--only", default=None, help="one beacon of bench_bayes.beacons")
    args = p.parse_args(argv)

    import nutpie
    from bench_bayes import beacons

    import bayes_mpem
    from bayes_mpem.lbl.bayes.beacon_sampling import sample_beacon
    from bayes_mpem.lbl.bayes.posterior import BeaconPosterior
    from bayes_mpem.lbl.em.em_mixture import fit_mixture_em

    print(f"nutpie {nutpie.__version__}, bayes_mpem {bayes_mpem.__version__}; "
          f"OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS', 'unset')}; "
          f"nutpie: {args.chains} chains x ({args.tune} tune + {args.draws} draws), "
          f"cores={args.cores}; load average {os.getloadavg()[0]:.1f}")
    for name, data in beacons(bayes_mpem).items():
        if args.only and name != args.only:
            continue
        post = BeaconPosterior(data)
        em = fit_mixture_em(data, rng=0)
        t0 = time.perf_counter()
        compiled = nutpie.compile_pymc_model(pymc_model(post, em))
        compile_s = time.perf_counter() - t0
        ours(sample_beacon, data, 100)  # warm-up
        theirs(nutpie, compiled, args, 100)
        rows = {"ours": [], "nutpie": []}
        for i in range(args.pairs):
            order = ("ours", "nutpie") if i % 2 == 0 else ("nutpie", "ours")
            for who in order:
                rows[who].append(ours(sample_beacon, data, i) if who == "ours"
                                 else theirs(nutpie, compiled, args, i))
        print(f"\n{name}: {post.geom.n:,} ranges, kernel {post.kernel.dtype.name}; nutpie "
              f"compiled once in {compile_s:.1f} s; {args.pairs} interleaved warm pairs, "
              f"medians")
        rate = {}
        for who, rs in rows.items():
            ess = np.median([r[0] for r in rs])
            wall = np.median([r[1] for r in rs])
            rate[who] = np.median([r[0] / r[1] for r in rs])
            print(f"  {who:<7} ESS {ess:6,.0f} (range {min(r[0] for r in rs):,.0f}-"
                  f"{max(r[0] for r in rs):,.0f}), call {wall:.3f} s, "
                  f"{rate[who]:8,.0f} ESS per wall second")
        print(f"  ours / nutpie, ESS per wall second of the call: "
              f"{rate['ours'] / rate['nutpie']:.1f}")
        print("  posterior agreement: " + agreement(
            {k: np.concatenate([r[2][k].ravel() for r in rows["ours"]]) for k in NAMES},
            {k: np.concatenate([r[2][k].ravel() for r in rows["nutpie"]]) for k in NAMES}))
        if args.process:
            process_rows(name, args)


if __name__ == "__main__":
    main()
