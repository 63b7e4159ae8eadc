"""ESS per second on one beacon of 5,000 ranges: bayes_mpem against three NUTS samplers.

Run from the repository root (the NUTS peers need ``pip install -e ".[bench]"``)::

    python benchmarks/bench_bayes.py                # writes its section of docs/benchmarks.md
    python benchmarks/bench_bayes.py --quick        # bayes_mpem only, once, prints only

One run, interleaved: every measurement is a fresh Python process (start-up and
imports included in its wall time), the methods in a rotating order within each
round. Round 0 is *cold* (empty compile caches: PyTensor's C code, numba's and
JAX's caches in fresh folders); the later rounds are *warm* (the same folders,
as on a second run on a machine). All methods sample the same model (d0 and
log-scales uniform, Dirichlet(1, 1, 1) weights, the mixture likelihood of
:mod:`bayes_mpem.lbl.model.likelihood`) on the same data; the NUTS samplers start from
the EM solution, run 2 chains x 1,000 draws after 1,000 tuning steps, and report
ArviZ's bulk ESS; bayes_mpem runs ``sample_beacon`` with its defaults (EM start,
sampling to min bulk ESS 1,000 with the shipped sampler, post-processing:
pointwise log-likelihood, class probabilities, ArviZ data). When bayes_mpem's
draws are not thinned (every kept draw in its ArviZ data), the driver recomputes
their bulk ESS with ``arviz_stats`` and stops if it differs from the reported one.

Columns: *wall* is the whole process; *CPU* its processor time (user and
system, threads and child processes included: the NUTS samplers run their two
chains on both cores), a measure that a loaded machine inflates less;
*sampling* is the sampler alone (for bayes_mpem the sampler's own clock: the
Laplace proposal and the chains, or the emcee run; for nutpie
``nutpie.sample`` after compilation, for PyMC its reported ``sampling_time``,
for NumPyro a second ``mcmc.run`` in the same process, compiled). ESS/s is min
bulk ESS over wall or over sampling. The
posterior means and sds of every parameter are compared with bayes_mpem's.
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

T_START = time.perf_counter()  # a worker's clock starts at its first line

import numpy as np  # noqa: E402

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
NAMES = ("d0", "sigma_mp", "sigma_dp", "w_dp", "w_mp", "w_ol")
METHODS = ("bayes_mpem", "nutpie", "numpyro", "pymc")


# ------------------------------------------------------------------ the data


def make_data(n=5000, seed=0):
    """Beacon 4 of abe58 (50 % direct path, 35 % multipath, 15 % outliers), n replies."""
    import bayes_mpem as bm
    from bayes_mpem.lbl.simulation.presets import ABE58

    sim = bm.simulate_survey(
        "abe58", rng=seed, n_cycles=n, p_no_reply=0.0,
        beacons={"4": ABE58["beacons"]["4"]}, weights={"4": ABE58["weights"]["4"]},
        sigma_mp={"4": ABE58["sigma_mp"]["4"]})
    return sim.survey.for_beacon("4")


def write_data(path):
    """The beacon's arrays, prior bounds and EM start, for workers that do not import us."""
    import bayes_mpem as bm
    from bayes_mpem.lbl.bayes.posterior import BeaconPosterior

    data = make_data()
    post = BeaconPosterior(data)
    em = bm.fit_mixture_em(data, rng=0)
    g = post.geom
    np.savez(path, range=data.range, x=data.x, y=data.y, depth=data.depth,
             position=np.asarray(data.position, float), z=g.z, h=g.h, dz=g.dz, direct=g.direct,
             log_ol=g.log_ol_density, d0_bounds=post.d0_bounds,
             log_sigma_bounds=post.log_sigma_bounds,
             em=[em.d0, np.log(em.sigma_mp), np.log(em.sigma_dp), em.weights["dp"],
                 em.weights["mp"], em.weights["ol"]])
    return data.n


def moments(draws: dict) -> dict:
    """Mean and sd of each parameter's draws."""
    return {k: [float(np.mean(v)), float(np.std(v, ddof=1))] for k, v in draws.items()}


def bulk_ess_min(draws: dict) -> float:
    """Smallest ArviZ bulk ESS of ``{name: (chain, draw)}`` arrays."""
    import arviz_stats as azs

    return float(min(azs.ess(np.asarray(v), method="bulk", chain_axis=0, draw_axis=1)
                     for v in draws.values()))


# ------------------------------------------------------------------ the workers


def worker_ours(d, seed):
    from bayes_mpem.io.survey import BeaconData
    from bayes_mpem.lbl.bayes.beacon_sampling import sample_beacon

    data = BeaconData.from_arrays(d["range"], d["x"], d["y"], d["depth"], d["position"],
                                  beacon="4")
    t0 = time.perf_counter()
    r = sample_beacon(data, rng=seed, progress=False)
    call = time.perf_counter() - t0
    post = r.idata.posterior
    draws = {k: post[k].values for k in NAMES}
    out = {"call": call, "sampling": r.diagnostics["seconds"],
           "ess": min(r.ess_bulk.values()), "own_ess": r.min_ess,
           "steps": r.diagnostics["n_steps"], "chains": r.diagnostics["n_chains"],
           "sampler": r.diagnostics["sampler"], "moments": moments(draws)}
    if r.diagnostics["thin"] == 1:  # every kept draw is in idata: the driver checks the ESS
        out["draws"] = {k: v.tolist() for k, v in draws.items()}
    return out


def _pymc_model(d):
    import pymc as pm
    import pytensor.tensor as pt

    em = d["em"]
    with pm.Model() as model:
        d0 = pm.Uniform("d0", *d["d0_bounds"], initval=em[0])
        lsm = pm.Uniform("log_sigma_mp", *d["log_sigma_bounds"], initval=em[1])
        lsd = pm.Uniform("log_sigma_dp", *d["log_sigma_bounds"], initval=em[2])
        w = pm.Dirichlet("w", a=np.ones(3), initval=em[3:])
        mp = 0.5 * (d["direct"] + pt.sqrt(d["h"] ** 2 + (2 * d0 - d["dz"]) ** 2))
        comp = pt.stack([
            pt.log(w[0]) + pm.logp(pm.Normal.dist(d["direct"], pt.exp(lsd)), d["z"]),
            pt.log(w[1]) + pm.logp(pm.Normal.dist(mp, pt.exp(lsm)), d["z"]),
            pt.log(w[2]) + float(d["log_ol"]) + 0 * d["z"]])
        pm.Potential("likelihood", pm.math.logsumexp(comp, axis=0).sum())
    return model


def _pymc_draws(idata):
    p = idata.posterior
    return {"d0": p["d0"].values, "sigma_mp": np.exp(p["log_sigma_mp"].values),
            "sigma_dp": np.exp(p["log_sigma_dp"].values), "w_dp": p["w"].values[..., 0],
            "w_mp": p["w"].values[..., 1], "w_ol": p["w"].values[..., 2]}


def worker_pymc(d, seed):
    import pymc as pm

    t0 = time.perf_counter()
    with _pymc_model(d):
        idata = pm.sample(draws=1000, tune=1000, chains=2, cores=2, random_seed=seed,
                          progressbar=False, compute_convergence_checks=False)
    draws = _pymc_draws(idata)
    return {"call": time.perf_counter() - t0,
            "sampling": float(idata.sample_stats.attrs.get("sampling_time", np.nan)),
            "ess": bulk_ess_min(draws), "moments": moments(draws), "version": pm.__version__}


def worker_nutpie(d, seed):
    import nutpie

    t0 = time.perf_counter()
    compiled = nutpie.compile_pymc_model(_pymc_model(d))
    t1 = time.perf_counter()
    idata = nutpie.sample(compiled, draws=1000, tune=1000, chains=2, cores=2, seed=seed,
                          progress_bar=False)
    t2 = time.perf_counter()
    draws = _pymc_draws(idata)
    return {"call": t2 - t0, "compile": t1 - t0, "sampling": t2 - t1,
            "ess": bulk_ess_min(draws), "moments": moments(draws),
            "version": nutpie.__version__}


def worker_numpyro(d, seed, cache):
    import jax

    jax.config.update("jax_enable_x64", True)
    jax.config.update("jax_compilation_cache_dir", cache)
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
    import jax.numpy as jnp
    import numpyro
    import numpyro.distributions as dist
    from numpyro.infer import MCMC, NUTS, init_to_value

    numpyro.set_host_device_count(2)
    z, h, dz, direct = (jnp.asarray(d[k]) for k in ("z", "h", "dz", "direct"))
    lo, hi = d["d0_bounds"]
    slo, shi = d["log_sigma_bounds"]
    log_ol = float(d["log_ol"])

    def model():
        d0 = numpyro.sample("d0", dist.Uniform(lo, hi))
        lsm = numpyro.sample("log_sigma_mp", dist.Uniform(slo, shi))
        lsd = numpyro.sample("log_sigma_dp", dist.Uniform(slo, shi))
        w = numpyro.sample("w", dist.Dirichlet(jnp.ones(3)))
        mp = 0.5 * (direct + jnp.sqrt(h**2 + (2 * d0 - dz) ** 2))
        comp = jnp.stack([jnp.log(w[0]) + dist.Normal(direct, jnp.exp(lsd)).log_prob(z),
                          jnp.log(w[1]) + dist.Normal(mp, jnp.exp(lsm)).log_prob(z),
                          jnp.log(w[2]) + log_ol + 0 * z])
        numpyro.factor("likelihood", jax.scipy.special.logsumexp(comp, axis=0).sum())

    em = d["em"]
    init = init_to_value(values={"d0": em[0], "log_sigma_mp": em[1], "log_sigma_dp": em[2],
                                 "w": jnp.asarray(em[3:])})
    t0 = time.perf_counter()
    mcmc = MCMC(NUTS(model, init_strategy=init), num_warmup=1000, num_samples=1000,
                num_chains=2, chain_method="parallel", progress_bar=False)
    mcmc.run(jax.random.PRNGKey(seed))
    t1 = time.perf_counter()
    mcmc.run(jax.random.PRNGKey(seed + 1000))  # compiled: the sampling phase alone
    t2 = time.perf_counter()
    s = mcmc.get_samples(group_by_chain=True)
    draws = {"d0": np.asarray(s["d0"]), "sigma_mp": np.exp(np.asarray(s["log_sigma_mp"])),
             "sigma_dp": np.exp(np.asarray(s["log_sigma_dp"])),
             "w_dp": np.asarray(s["w"][..., 0]), "w_mp": np.asarray(s["w"][..., 1]),
             "w_ol": np.asarray(s["w"][..., 2])}
    return {"call": t1 - t0, "sampling": t2 - t1, "ess": bulk_ess_min(draws),
            "moments": moments(draws), "version": numpyro.__version__}


def worker(method, data_file, seed, cache):
    d = dict(np.load(data_file))
    if method == "bayes_mpem":
        out = worker_ours(d, seed)
    elif method == "pymc":
        out = worker_pymc(d, seed)
    elif method == "nutpie":
        out = worker_nutpie(d, seed)
    else:
        out = worker_numpyro(d, seed, cache)
    out["in_process"] = time.perf_counter() - T_START
    print("RESULT " + json.dumps(out))


# ------------------------------------------------------------------ the driver


def available(method):
    """Whether a peer is installed (without importing it here)."""
    import importlib.util

    name = {"bayes_mpem": "bayes_mpem", "nutpie": "nutpie", "numpyro": "numpyro",
            "pymc": "pymc"}[method]
    return importlib.util.find_spec(name) is not None


def spawn(method, data_file, seed, caches):
    """Run one measurement in a fresh process; its wall time includes start-up."""
    env = dict(os.environ, PYTENSOR_FLAGS=f"base_compiledir={caches['pytensor']}",
               NUMBA_CACHE_DIR=caches["numba"], PYTHONWARNINGS="ignore")
    cmd = [sys.executable, str(Path(__file__).resolve()), "--worker", method, "--data",
           str(data_file), "--seed", str(seed), "--cache", caches["jax"]]
    import resource

    cpu0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True, env=env, cwd=ROOT)
    wall = time.perf_counter() - t0
    cpu1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (cpu1.ru_utime - cpu0.ru_utime) + (cpu1.ru_stime - cpu0.ru_stime)
    line = [ln for ln in proc.stdout.splitlines() if ln.startswith("RESULT ")]
    if proc.returncode or not line:
        print(f"{method} failed:\n{proc.stderr[-3000:]}", file=sys.stderr)
        return None
    res = json.loads(line[-1][len("RESULT "):]) | {"wall": wall, "cpu": cpu,
                                                    "method": method, "seed": seed}
    draws = res.pop("draws", None)
    if draws is not None:  # bayes_mpem's own bulk ESS, recomputed here by ArviZ
        res["ess_arviz"] = bulk_ess_min({k: np.asarray(v) for k, v in draws.items()})
        if not np.isclose(res["ess_arviz"], res["ess"], rtol=1e-8):
            raise SystemExit(f"bayes_mpem's bulk ESS {res['ess']} differs from ArviZ's "
                             f"{res['ess_arviz']} on the same draws")
    return res


def loadavg():
    try:
        return " / ".join(f"{v:.2f}" for v in os.getloadavg())
    except OSError:  # pragma: no cover
        return "n/a"


def run_rounds(methods, data_file, rounds, tmp):
    caches = {k: tempfile.mkdtemp(prefix=k, dir=tmp) for k in ("pytensor", "numba", "jax")}
    results = []
    for r in range(rounds):
        order = methods[r % len(methods):] + methods[:r % len(methods)]
        for m in order:
            res = spawn(m, data_file, r, caches)
            if res is None:
                continue
            res["round"] = "cold" if r == 0 else "warm"
            results.append(res)
            print(f"round {r} ({res['round']}) {m}: wall {res['wall']:.1f} s, sampling "
                  f"{res['sampling']:.2f} s, min bulk ESS {res['ess']:.0f}, load {loadavg()}",
                  flush=True)
    return results


def median(rows, key):
    return float(np.median([r[key] for r in rows])) if rows else float("nan")


def agreement(results):
    """Per peer, the largest |mean difference| with bayes_mpem in pooled sds, and sd ratio."""
    ours = [r["moments"] for r in results if r["method"] == "bayes_mpem"]
    out = {}
    for m in METHODS[1:]:
        theirs = [r["moments"] for r in results if r["method"] == m]
        if not theirs or not ours:
            continue
        z, ratio = 0.0, []
        for k in NAMES:
            mo = np.mean([o[k][0] for o in ours])
            mt = np.mean([t[k][0] for t in theirs])
            so = np.mean([o[k][1] for o in ours])
            st = np.mean([t[k][1] for t in theirs])
            z = max(z, abs(mo - mt) / (0.5 * (so + st)))
            ratio.append(so / st)
        out[m] = (z, min(ratio), max(ratio))
    return out


def report(results, n, rounds, load_before, load_after):
    import emcee

    sys.path.insert(0, str(HERE))
    from _report import machine

    lines = ["## Bayesian sampler: ESS per second against NUTS", "",
             f"Produced by `python benchmarks/bench_bayes.py --rounds {rounds}` on "
             f"{dt.date.today().isoformat()}; machine: {machine()}, emcee {emcee.__version__}; "
             f"load average (1/5/15 min) {load_before} before, {load_after} after. Data: one "
             f"beacon, {n:,d} ranges (beacon 4 of `abe58`), learned priors (5 free "
             "parameters). Every row is a fresh process, the methods interleaved; round 0 is "
             "cold (empty compile caches), the others warm.", "",
             "| method | round | wall (s) | CPU (s) | sampling (s) | min bulk ESS "
             "| ESS/s (wall) | ESS/s (sampling) | ESS per CPU s |",
             "|---|---|---:|---:|---:|---:|---:|---:|---:|"]
    for r in results:
        lines.append(f"| {r['method']} | {r['round']} | {r['wall']:.2f} | {r['cpu']:.1f} "
                     f"| {r['sampling']:.2f} | {r['ess']:.0f} | {r['ess'] / r['wall']:.0f} "
                     f"| {r['ess'] / r['sampling']:.0f} | {r['ess'] / r['cpu']:.0f} |")
    rate = {}
    for m in METHODS:
        for rnd in ("cold", "warm"):
            rows = [r for r in results if r["method"] == m and r["round"] == rnd]
            if rows:
                rate[m, rnd] = (float(np.median([r["ess"] / r["wall"] for r in rows])),
                                float(np.median([r["ess"] / r["sampling"] for r in rows])))
    ours = [r for r in results if r["method"] == "bayes_mpem"]
    lines += ["", "Medians (ESS per second of wall time / of the sampling phase):", ""]
    for (m, rnd), (w, s) in rate.items():
        lines.append(f"* {m}, {rnd}: {w:.0f} / {s:.0f}")
    lines.append("")
    lines.append(f"bayes_mpem: `sample_beacon` took {median(ours, 'call'):.2f} s (median; "
                 f"the whole process {median(ours, 'wall'):.2f} s), min bulk ESS "
                 f"{min(r['ess'] for r in ours):.0f} to {max(r['ess'] for r in ours):.0f}.")
    ow = np.median([r["ess"] / r["wall"] for r in ours])
    os_ = np.median([r["ess"] / r["sampling"] for r in ours])
    if ("nutpie", "warm") in rate:
        nw, ns = rate["nutpie", "warm"]
        lines.append(f"Against nutpie (warm): {ow / nw:.1f}x its ESS per second end to end "
                     f"(target >= 5x: {'met' if ow / nw >= 5 else 'NOT met'}); sampling "
                     f"phase {os_ / ns:.2f}x (target >= 1: "
                     f"{'met' if os_ >= ns else 'NOT met'}).")
    for m, (z, lo, hi) in agreement(results).items():
        lines.append(f"Posterior agreement with {m}: largest mean difference {z:.2f} pooled "
                     f"sds, sd ratio (ours / theirs) {lo:.3f} to {hi:.3f}.")
    return "\n".join(lines + [""])


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="bayes_mpem only, one round")
    p.add_argument("--rounds", type=int, default=3, help="round 0 cold, the rest warm")
    p.add_argument("--methods", default=",".join(METHODS))
    p.add_argument("--out", default=str(ROOT / "docs" / "benchmarks.md"))
    p.add_argument("--worker", default=None, help=argparse.SUPPRESS)
    p.add_argument("--data", default=None, help=argparse.SUPPRESS)
    p.add_argument("--seed", type=int, default=0, help=argparse.SUPPRESS)
    p.add_argument("--cache", default=None, help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.worker:
        return worker(args.worker, args.data, args.seed, args.cache)
    methods = ["bayes_mpem"] if args.quick else [
        m for m in args.methods.split(",") if available(m) or print(f"{m} not installed")]
    with tempfile.TemporaryDirectory() as tmp:
        data_file = Path(tmp) / "beacon.npz"
        n = write_data(data_file)
        load_before = loadavg()
        results = run_rounds(methods, data_file, 1 if args.quick else args.rounds, tmp)
        load_after = loadavg()
    text = report(results, n, 1 if args.quick else args.rounds, load_before, load_after)
    print(text)
    if not args.quick:
        sys.path.insert(0, str(HERE))
        from _report import write_section

        write_section(args.out, "bench_bayes", text)
        print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
