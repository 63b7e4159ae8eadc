"""The shipped emcee moves: exact, and their ESS per second on the LBL posterior.

Two parts, both written to ``docs/benchmarks.md`` (section ``bench_moves``):

1. Exactness: 5-D and 16-D standard normals, 32 walkers, 6,000 steps, 3 seeds each; the sd
   of every coordinate against 1 (pooled z-score of ``sd - 1`` over its Monte-Carlo error),
   for the independence ``MHMove`` (a t proposal, offset and too wide), differential
   evolution, and emcee 3.1.6's released snooker in a DE mix (which the check catches).
2. Speed: ``sample_beacon`` on beacon 4 of ``abe58`` with ``sampler="independence"`` and
   ``"ensemble"``, interleaved over seeds, wall time and the smallest bulk ESS; the
   posterior sd of d0 and sigma_MP shows the width each gives.

    python benchmarks/bench_moves.py [--seeds 3]
"""

from __future__ import annotations

import argparse
import sys
import time
from datetime import date
from pathlib import Path

import emcee
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import machine, write_section  # noqa: E402
from released_snooker import ReleasedSnooker  # noqa: E402
from test_mcmc import _sd_z  # noqa: E402

from bayes_mpem import mcmc  # noqa: E402
from bayes_mpem.lbl.bayes.beacon_sampling import sample_beacon  # noqa: E402
from bayes_mpem.lbl.simulation.simulate import simulate_survey  # noqa: E402


def _independence(ndim):
    prop = mcmc.TProposal(centre=np.full(ndim, 0.3), chol=1.3 * np.eye(ndim), df=10.0)
    return mcmc.independence_move(prop)


MIXES = {
    "independence MHMove (t proposal, offset 0.3, scale 1.3)": _independence,
    "DE only": lambda ndim: mcmc.default_moves(),
    "DE 0.8 + emcee 3.1.6 snooker 0.2":
        lambda ndim: [(emcee.moves.DEMove(), 0.8), (ReleasedSnooker(), 0.2)],
}
SAMPLERS = ("independence", "ensemble")


def exactness(seeds):
    rows = []
    for ndim in (5, 16):
        for name, mv in MIXES.items():
            res = [_sd_z(mv(ndim), ndim, seed=100 + s) for s in range(seeds)]
            sds = [float(sd.mean()) for _, sd in res]
            zs = [z for z, _ in res]
            rows.append(f"| {ndim} | {name} | {np.mean(sds):.3f} ({min(sds):.3f}-{max(sds):.3f}) "
                        f"| {min(zs):+.1f} to {max(zs):+.1f} |")
    return rows


def speed(seeds):
    data = simulate_survey("abe58", rng=0).survey.for_beacon("4")
    out = {name: [] for name in SAMPLERS}
    for seed in range(seeds):
        for name in SAMPLERS:  # interleaved: the machine's load hits every sampler alike
            t0 = time.perf_counter()
            r = sample_beacon(data, rng=seed, sampler=name, progress=False)
            wall = time.perf_counter() - t0
            post = r.idata["posterior"]
            out[name].append((wall, r.min_ess, float(post["d0"].std()),
                              float(post["sigma_mp"].std())))
    rows = []
    for name, v in out.items():
        a = np.array(v)
        rows.append(f"| {name} | {np.median(a[:, 0]):.2f} | {np.median(a[:, 1]):.0f} | "
                    f"{np.median(a[:, 1] / a[:, 0]):.0f} | {np.mean(a[:, 2]):.3f} | "
                    f"{np.mean(a[:, 3]):.3f} |")
    return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=3)
    args = ap.parse_args()
    ex = exactness(args.seeds)
    sp = speed(args.seeds)
    text = "\n".join([
        "## Sampler moves: exact, and ESS per second", "",
        f"Produced by `python benchmarks/bench_moves.py --seeds {args.seeds}` on "
        f"{date.today().isoformat()}; machine: {machine()}, emcee {emcee.__version__}.", "",
        "Exactness on standard normals (32 walkers, 6,000 steps, 1,200 discarded; sd averaged "
        "over coordinates and seeds; z = (sd - 1) / Monte-Carlo error, pooled over coordinates; "
        "`tests/test_mcmc.py` asserts |z| < 8 for DE and z < -8 for the released snooker):",
        "",
        "| dim | moves | sd (range over seeds) | pooled z (range) |",
        "|---|---|---:|---:|", *ex, "",
        f"Speed on beacon 4 of abe58 (learned priors; `sample_beacon` to min bulk ESS "
        f"1,000 and R-hat < 1.01, medians over {args.seeds} seeds, interleaved):", "",
        "| sampler | wall (s) | min ESS (bulk) | ESS/s | posterior sd d0 (m) | sd sigma_MP (m) |",
        "|---|---:|---:|---:|---:|---:|", *sp, "",
    ])
    write_section(ROOT / "docs" / "benchmarks.md", "bench_moves", text)
    print(text)


if __name__ == "__main__":
    main()
