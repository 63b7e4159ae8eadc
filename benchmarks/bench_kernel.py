"""The sampler's likelihood kernel: the options measured side by side, per call.

Run from the repository root::

    python benchmarks/bench_kernel.py          # writes its section of docs/benchmarks.md

One beacon of 5,000 ranges (beacon 4 of abe58), batches of 12 walkers drawn
from its posterior (what emcee's differential-evolution move evaluates: half of
24 walkers), 300 batches per timing, the options interleaved and each timed
five times (best kept). Columns: milliseconds per call; the largest error
against the log-space form (``loglik_per_range`` summed, float64); one-off costs
(import, compilation). The options: the previous NumPy kernel (float64, a
screen of ranges per call), :class:`~bayes_mpem.lbl.model.loglik_kernel.LoglikKernel` in
float64 and float32, and, where installed, numexpr, numba and JAX (the ``bench``
extra brings numba and JAX) on the same fused expression.
"""

from __future__ import annotations

import argparse
import datetime as dt
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from _report import machine, write_section  # noqa: E402
from bench_bayes import make_data  # noqa: E402

from bayes_mpem.lbl.bayes.beacon_sampling import sample_beacon  # noqa: E402
from bayes_mpem.lbl.model import geometry  # noqa: E402
from bayes_mpem.lbl.model.beacon_geometry import BeaconGeometry  # noqa: E402
from bayes_mpem.lbl.model.likelihood import loglik_per_range  # noqa: E402
from bayes_mpem.lbl.model.loglik_kernel import LoglikKernel  # noqa: E402
from bayes_mpem.mixture.densities import LOG_SQRT_2PI  # noqa: E402

ROOT = HERE.parent


def previous_kernel(geom, d0, sigma_dp, sigma_mp, w_dp, w_mp, w_ol):
    """The kernel before issue 17 (``total_loglik`` of commit f31dfee), for comparison."""
    d0, sigma_dp, sigma_mp, w_dp, w_mp, w_ol = (np.asarray(v)[:, None] for v in
                                                (d0, sigma_dp, sigma_mp, w_dp, w_mp, w_ol))
    r_dp = geom.z - geom.direct
    near_dp = np.abs(r_dp) < 40.0 * float(sigma_dp.max())
    d_ref = float(np.median(d0))
    reach = float(np.max(np.abs(d0 - d_ref)))
    near_mp = np.abs(geom.z - geom.multipath(d_ref)) - reach < 40.0 * float(sigma_mp.max())
    only_dp = np.flatnonzero(near_dp & ~near_mp)
    both = np.flatnonzero(near_dp & near_mp)
    only_mp = np.flatnonzero(~near_dp & near_mp)
    cols = np.concatenate([only_dp, both, only_mp])
    n_dp = only_dp.size + both.size
    ol = w_ol * np.exp(geom.log_ol_density + LOG_SQRT_2PI)
    dens = np.repeat(np.reshape(ol, (-1, 1)), cols.size, axis=1)
    rd = r_dp[cols[:n_dp]]
    dens[:, :n_dp] += (w_dp / sigma_dp) * np.exp(-0.5 * (rd * rd) / (sigma_dp * sigma_dp))
    m = cols[only_dp.size:]
    pred = geometry.multipath_range(geom.h[m], geom.dz[m], d0, direct=geom.direct[m])
    rm = geom.z[m] - pred
    dens[:, only_dp.size:] += (w_mp / sigma_mp) * np.exp(-0.5 * (rm * rm) / (sigma_mp**2))
    out = np.log(dens).sum(axis=-1) + (geom.n - cols.size) * np.log(ol).ravel()
    return out - geom.n * LOG_SQRT_2PI


def numexpr_kernel(geom):
    import numexpr as ne

    const = {"rdp2": ((geom.z - geom.direct) ** 2)[None, :], "h2": (geom.h**2)[None, :],
             "dz": geom.dz[None, :], "zc": (geom.z - 0.5 * geom.direct)[None, :]}
    c_ol = np.exp(geom.log_ol_density + LOG_SQRT_2PI)

    def call(d0, sd, sm, wd, wm, wo):
        names = {"d0": d0, "sd": sd, "sm": sm, "wd": wd, "wm": wm, "ol": wo * c_ol}
        return ne.evaluate(
            "sum(log(ol + wd / sd * exp(-0.5 * rdp2 / (sd * sd)) + wm / sm * "
            "exp(-0.5 * (zc - 0.5 * sqrt(h2 + (2 * d0 - dz) ** 2)) ** 2 / (sm * sm))), axis=1)",
            local_dict={**const, **{k: v[:, None] for k, v in names.items()}}
        ) - geom.n * LOG_SQRT_2PI
    return call


def numba_kernel(geom):
    import numba

    rdp2 = (geom.z - geom.direct) ** 2
    h2, dz, zc = geom.h**2, geom.dz, geom.z - 0.5 * geom.direct
    c_ol = float(np.exp(geom.log_ol_density + LOG_SQRT_2PI))

    @numba.njit(fastmath=True, cache=False)
    def kern(d0, sd, sm, wd, wm, wo):
        out = np.empty(d0.size)
        for i in range(d0.size):
            ad, bd = wd[i] / sd[i], -0.5 / (sd[i] * sd[i])
            am, bm = wm[i] / sm[i], -0.5 / (sm[i] * sm[i])
            ol, acc = wo[i] * c_ol, 0.0
            for k in range(rdp2.size):
                u = 2.0 * d0[i] - dz[k]
                r = zc[k] - 0.5 * np.sqrt(h2[k] + u * u)
                acc += np.log(ol + ad * np.exp(bd * rdp2[k]) + am * np.exp(bm * r * r))
            out[i] = acc - rdp2.size * LOG_SQRT_2PI
        return out
    return kern


def jax_kernel(geom, dtype):
    import jax

    jax.config.update("jax_enable_x64", True)
    import jax.numpy as jnp

    rdp2, h2, dz, zc = (jnp.asarray(a, dtype) for a in (
        (geom.z - geom.direct) ** 2, geom.h**2, geom.dz, geom.z - 0.5 * geom.direct))
    c_ol = float(np.exp(geom.log_ol_density + LOG_SQRT_2PI))

    @jax.jit
    def kern(d0, sd, sm, wd, wm, wo):
        d0, sd, sm, wd, wm, wo = (v[:, None] for v in (d0, sd, sm, wd, wm, wo))
        u = 2 * d0 - dz
        r = zc - 0.5 * jnp.sqrt(h2 + u * u)
        dens = wo * c_ol + wd / sd * jnp.exp(-0.5 * rdp2 / (sd * sd)) \
            + wm / sm * jnp.exp(-0.5 * r * r / (sm * sm))
        return jnp.sum(jnp.log(dens), axis=1, dtype=jnp.float64) - geom.n * LOG_SQRT_2PI

    def call(*cols):
        return np.asarray(kern(*(jnp.asarray(c, dtype) for c in cols)))
    return call


def options(geom, first):
    """Name -> (callable, one-off seconds: import, compilation, first call on ``first``)."""
    out = {"previous NumPy kernel (float64)": (lambda *c: previous_kernel(geom, *c), 0.0),
           "LoglikKernel float64": (LoglikKernel(geom, precision="float64"), 0.0),
           "LoglikKernel float32 (shipped for <= 20,971 ranges)":
               (LoglikKernel(geom, precision="float32"), 0.0)}
    for name, make in (("numexpr 2 threads, float64", lambda: numexpr_kernel(geom)),
                       ("numba njit fastmath, float64", lambda: numba_kernel(geom)),
                       ("JAX jit, float64", lambda: jax_kernel(geom, "float64")),
                       ("JAX jit, float32", lambda: jax_kernel(geom, "float32"))):
        t0 = time.perf_counter()
        try:
            fn = make()
        except ImportError:
            print(f"{name}: not installed")
            continue
        fn(*first)
        out[name] = (fn, time.perf_counter() - t0)
    return out


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--batches", type=int, default=300)
    p.add_argument("--out", default=str(ROOT / "docs" / "benchmarks.md"))
    args = p.parse_args(argv)
    data = make_data()
    post = sample_beacon(data, rng=0, progress=False).idata.posterior
    draws = np.column_stack([post[k].values.ravel() for k in
                             ("d0", "sigma_dp", "sigma_mp", "w_dp", "w_mp", "w_ol")])
    rng = np.random.default_rng(0)
    batches = [tuple(draws[rng.choice(len(draws), 12)].T.copy()) for _ in range(args.batches)]
    geom = BeaconGeometry.from_data(data)
    ref = [loglik_per_range(geom, *(c[:, None] for c in b[:3]), [c[:, None] for c in b[3:]])
           .sum(axis=1) for b in batches]
    opts = options(geom, batches[0])
    err, best = {}, {}
    for name, (fn, _) in opts.items():
        err[name] = max(float(np.max(np.abs(fn(*b) - r))) for b, r in zip(batches, ref,
                                                                          strict=True))
    for _ in range(5):
        for name, (fn, _) in opts.items():
            t0 = time.perf_counter()
            for b in batches:
                fn(*b)
            best[name] = min(best.get(name, np.inf), (time.perf_counter() - t0) / len(batches))
    import os

    load = " / ".join(f"{v:.2f}" for v in os.getloadavg())
    base = best["previous NumPy kernel (float64)"]
    lines = ["## The likelihood kernel: options per call", "",
             f"Produced by `python benchmarks/bench_kernel.py` on {dt.date.today().isoformat()}; "
             f"machine: {machine()}; load average {load} at the end. One beacon of "
             f"{data.n:,d} ranges, {args.batches} batches of 12 walkers from its posterior, "
             "best of 5 interleaved timings. Error: the largest |difference| from the "
             "log-space form (float64), in nats. One-off: import, compilation and the first "
             "call of the options that compile.", "",
             "| kernel | ms per call | speed-up | max error (nats) | one-off (s) |",
             "|---|---:|---:|---:|---:|"]
    for name in opts:
        lines.append(f"| {name} | {1e3 * best[name]:.3f} | {base / best[name]:.2f}x "
                     f"| {err[name]:.1e} | {opts[name][1]:.2f} |")
    # walkers per call: a fixed cost per call against a cost per walker
    kern = opts["LoglikKernel float32 (shipped for <= 20,971 ranges)"][0]
    lines += ["", "Walkers per call (float32 kernel, best of 5): the cost is mostly per walker, "
              "so evaluating more walkers per call would save little, and the stopping rule "
              "(50 autocorrelation times of kept chain) makes the evaluations needed grow "
              "with the walkers: 24 walkers already end with an ESS above 1,000.", "",
              "| walkers per call | ms per call | us per walker |", "|---:|---:|---:|"]
    for w in (6, 12, 24, 48):
        bw = [tuple(draws[rng.choice(len(draws), w)].T.copy()) for _ in range(100)]
        t = np.inf
        for _ in range(5):
            t0 = time.perf_counter()
            for b in bw:
                kern(*b)
            t = min(t, (time.perf_counter() - t0) / len(bw))
        lines.append(f"| {w} | {1e3 * t:.3f} | {1e6 * t / w:.1f} |")
    text = "\n".join(lines + [""])
    print(text)
    write_section(args.out, "bench_kernel", text)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
