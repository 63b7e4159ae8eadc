"""ESS per second of the emcee driver against the independence chains it replaced, in one process.

The old code is bayes_mpem at commit 6f13177 (its own independence Metropolis-Hastings
runner); it is imported under the name ``bayes_mpem_old`` from a copy of its ``src``::

    git worktree add /work/wt/bayes-old 6f13177
    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_bayes.py --old /work/wt/bayes-old/src

On each beacon (abe58's beacon 4, and a 4,764-range beacon), after one warm-up call of
each, ``--pairs`` pairs are timed interleaved (the order alternating), the public
``sample_beacon`` with its defaults (EM start, sampling to bulk ESS 1,000, per-range
pass, ArviZ data). ESS is the smallest ArviZ bulk ESS (arviz-stats) of the draws in each
result's ArviZ data; *sampler* is each result's own ``diagnostics["seconds"]`` (Laplace
proposal, pilot and chains), *call* the whole call. Medians are printed, and the ratio
new / old of the ESS per second.
"""

from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

NAMES = ("d0", "sigma_mp", "sigma_dp", "w_dp", "w_mp", "w_ol")


def load_old(src: str):
    """Import the old package under the name ``bayes_mpem_old`` (a copy; relative imports)."""
    tmp = Path(tempfile.mkdtemp())
    shutil.copytree(Path(src) / "bayes_mpem", tmp / "bayes_mpem_old")
    sys.path.insert(0, str(tmp))
    import bayes_mpem_old

    return bayes_mpem_old


def beacons(pkg):
    """The two benchmark beacons, simulated by ``pkg`` (old and new give the same ranges)."""
    from importlib import import_module

    presets = (import_module(f"{pkg.__name__}.lbl.simulation.presets")
               if pkg.__name__ == "bayes_mpem" else import_module(f"{pkg.__name__}.lbl.presets"))
    abe = presets.ABE58
    big = pkg.simulate_survey("abe58", rng=0, n_cycles=5000, p_no_reply=0.0,
                              beacons={"4": abe["beacons"]["4"]},
                              weights={"4": abe["weights"]["4"]},
                              sigma_mp={"4": abe["sigma_mp"]["4"]})
    return {"abe58 beacon 4": pkg.simulate_survey("abe58", rng=0).survey.for_beacon("4"),
            "4,764-range beacon": big.survey.for_beacon("4")}


def min_ess(idata) -> float:
    """Smallest ArviZ bulk ESS of the sampled parameters in ``idata``'s posterior."""
    from arviz_stats.base import array_stats

    post = idata.posterior
    return float(min(array_stats.ess(post[k].values, method="bulk") for k in NAMES
                     if k in post.data_vars and np.ptp(post[k].values) > 0))


def one(sample, data, seed):
    """Time one call: ``(ESS, sampler s, call s, sampler label)``."""
    t0 = time.perf_counter()
    r = sample(data, rng=seed, progress=False)
    call = time.perf_counter() - t0
    return min_ess(r.idata), float(r.diagnostics["seconds"]), call, r.diagnostics["sampler"]


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--old", required=True, help="src folder of bayes_mpem at 6f13177")
    p.add_argument("--pairs", type=int, default=5)
    args = p.parse_args(argv)

    import bayes_mpem
    from bayes_mpem.lbl.bayes.beacon_sampling import sample_beacon as new_sample

    old = load_old(args.old)
    from bayes_mpem_old.lbl.beacon_sampling import sample_beacon as old_sample

    new_data, old_data = beacons(bayes_mpem), beacons(old)
    for name, data in new_data.items():
        assert np.array_equal(data.range, old_data[name].range), name
        one(new_sample, data, 100)  # warm-up: imports, caches
        one(old_sample, old_data[name], 100)
        rows = {"new": [], "old": []}
        for i in range(args.pairs):
            order = ("new", "old") if i % 2 == 0 else ("old", "new")
            for who in order:
                fn, d = (new_sample, data) if who == "new" else (old_sample, old_data[name])
                rows[who].append(one(fn, d, i))
        print(f"\n{name}: {data.n:,} ranges, {args.pairs} interleaved warm pairs, medians")
        med = {}
        for who, rs in rows.items():
            ess, samp, call = (np.median([r[j] for r in rs]) for j in range(3))
            es = np.median([r[0] / r[1] for r in rs])
            ec = np.median([r[0] / r[2] for r in rs])
            med[who] = (es, ec)
            print(f"  {who}: {rs[0][3]:<12} ESS {ess:6,.0f} (range {min(r[0] for r in rs):,.0f}-"
                  f"{max(r[0] for r in rs):,.0f}), sampler {samp:.3f} s, call {call:.3f} s, "
                  f"{es:7,.0f} ESS/s sampler, {ec:7,.0f} ESS/s call")
        print(f"  new / old ESS per second: sampler {med['new'][0] / med['old'][0]:.2f}, "
              f"call {med['new'][1] / med['old'][1]:.2f}")


if __name__ == "__main__":
    main()
