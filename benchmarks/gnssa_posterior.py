"""Do the array posterior's intervals cover the truth? Simulated GNSS-A campaigns, emcee.

Each campaign (:func:`bayes_mpem.survey_in.gnssa_simulate.simulate_gnssa`, seeds 0 to
N-1): 4 transponders at about 1,500 m, ``HOURS`` of shots every ``SHOT_INTERVAL`` s along
transits across the array, the simulator's defaults otherwise (a profile scaled in time by
0.5 m/s, 50 us timing noise, GNSS noise, 5 % spurious, 2 % missing, attitude). Each is
located by the EM with the defaults (the survey's profile, the smooth sound speed) and its
posterior sampled by :func:`~bayes_mpem.survey_in.array_sampling.sample_array` (seed = the
campaign's).

Reported: how often the 95 % equal-tailed posterior intervals of the array centre and of
each coordinate contain the truth, the same for the EM's Wald intervals (cluster-robust,
averaged over smoothing weights: what ``locate`` reports) and for the EM's model-based ones,
the ratio of the posterior sds to the EM's, the sampler used, ESS, acceptance and seconds.

``--long``: the acceptance campaigns of issue 26 instead (6 h, ``star+circle``, the
sound-speed field with gradients, ``locate``'s defaults: gradients fitted, a speed knot every
5 min, about 90 parameters), section ``gnssa-posterior-long``. ``--deep``: the same with
three transponders at 5,000 m and no gradients in the water (``auto`` still fits them),
section ``gnssa-posterior-deep``.

Writes the section ``gnssa-posterior`` of ``docs/gnssa.md`` and prints it::

    python benchmarks/gnssa_posterior.py [N_CAMPAIGNS] [--long | --deep]
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one thread: the machine is shared

import numpy as np  # noqa: E402
from scipy.stats import norm  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import commit, machine, write_section  # noqa: E402

from bayes_mpem.survey_in.array_sampling import sample_array  # noqa: E402
from bayes_mpem.survey_in.array_survey import array_shots, locate_array_survey  # noqa: E402
from bayes_mpem.survey_in.gnssa_simulate import simulate_gnssa  # noqa: E402

CI = 0.95
HOURS, SHOT_INTERVAL, TRACK = 2.0, 30.0, "star"
#: ``--long``: the acceptance campaigns of issue 26
LONG = {"hours": 6.0, "shot_interval": 30.0, "track": "star+circle", "speed_model": "field",
        "gradients": True}
#: ``--deep``: three transponders at 5,000 m, no gradients simulated
DEEP = {**LONG, "gradients": False, "n_transponders": 3, "depth": 5000.0}
AXES = ("east", "north", "up")
#: a bound on a campaign whose proposal fits poorly (differential evolution then)
MAX_STEPS = 3000


def one_campaign(seed, config):
    """Locate and sample one campaign; the standardised errors and intervals' verdicts."""
    sim = simulate_gnssa(rng=seed, **config)
    raw = sim.raw()
    t0 = time.perf_counter()
    fit = locate_array_survey(raw).fits["array"]  # the defaults: correlation "auto"
    t_em = time.perf_counter() - t0
    t0 = time.perf_counter()
    post = sample_array(array_shots(raw), fit, rng=seed, progress=False, max_steps=MAX_STEPS)
    t_post = time.perf_counter() - t0
    truth = sim.truth["transponders"].loc[list(fit.ids), list(AXES)].to_numpy()
    K = len(fit.ids)
    pos = post.draws["position"].reshape(-1, K, 3)
    cen = post.draws["centre"].reshape(-1, 3)
    lo, hi = (1 - CI) / 2, (1 + CI) / 2

    def covered(draws, true):
        q = np.quantile(draws, [lo, hi], axis=0)
        return (q[0] <= true) & (true <= q[1])

    q = norm.ppf(hi)
    m, C = fit.centre()
    G = np.kron(np.ones(K) / K, np.eye(3))
    Cm = G @ fit.cov_model[:3 * K, :3 * K] @ G.T
    em_sd = fit.sd
    em_model_sd = np.sqrt(np.diag(fit.cov_model)[:3 * K]).reshape(K, 3)
    return {
        "pos_cov": covered(pos, truth), "centre_cov": covered(cen, truth.mean(axis=0)),
        "em_pos_cov": np.abs(fit.enu - truth) < q * em_sd,
        "em_centre_cov": np.abs(m - truth.mean(axis=0)) < q * np.sqrt(np.diag(C)),
        "model_pos_cov": np.abs(fit.enu - truth) < q * em_model_sd,
        "model_centre_cov": np.abs(m - truth.mean(axis=0)) < q * np.sqrt(np.diag(Cm)),
        "z": (pos.mean(axis=0) - truth) / pos.std(axis=0, ddof=1),
        "sd_ratio": pos.std(axis=0, ddof=1) / em_sd,
        "sd_ratio_model": pos.std(axis=0, ddof=1) / em_model_sd,
        "centre_sd_ratio": cen.std(axis=0, ddof=1) / np.sqrt(np.diag(C)),
        "centre_err_mm": 1e3 * (cen.mean(axis=0) - truth.mean(axis=0)),
        "centre_sd_mm": 1e3 * cen.std(axis=0, ddof=1),
        "moves": post.diagnostics["moves"].split(" (")[0],
        "ess": min(post.ess.values()), "acceptance": post.diagnostics["acceptance"],
        "ndim": post.diagnostics["ndim"], "converged": post.converged,
        "t_em": t_em, "t_post": t_post, "n_shots": int(len(fit.rows))}


def _pct(x):
    return f"{100 * np.mean(x):.0f}"


def main(n=20, design=""):
    config = {"--long": LONG, "--deep": DEEP}.get(
        design, {"hours": HOURS, "shot_interval": SHOT_INTERVAL, "track": TRACK})
    rows, t0 = [], time.perf_counter()
    for seed in range(n):
        rows.append(one_campaign(seed, config))
        print(f"campaign {seed} done ({time.perf_counter() - t0:.0f} s)", file=sys.stderr)
    load = os.getloadavg()
    stack = {k: np.array([r[k] for r in rows]) for k in rows[0]}
    lines = ["| intervals | array centre covered (%), east / north / up | all 3 centre coords (%) "
             "| transponder coordinates covered (%), east / north / up | all coordinates (%) |",
             "|---|---|---:|---|---:|"]
    for label, pre in (("posterior (emcee), equal-tailed", ""),
                       ("EM, Wald, cluster-robust (what `locate` reports)", "em_"),
                       ("EM, Wald, model-based", "model_")):
        c, p = stack[pre + "centre_cov"], stack[pre + "pos_cov"]
        lines.append(f"| {label} | " + " / ".join(_pct(c[:, a]) for a in range(3))
                     + f" | {_pct(c)} | "
                     + " / ".join(_pct(p[:, :, a]) for a in range(3)) + f" | {_pct(p)} |")
    r, rm, rc = stack["sd_ratio"], stack["sd_ratio_model"], stack["centre_sd_ratio"]
    z = stack["z"]
    err, sd = stack["centre_err_mm"], stack["centre_sd_mm"]
    moves = {m: int(np.sum(stack["moves"] == m)) for m in np.unique(stack["moves"])}
    field = {"--long": ", the sound-speed field with horizontal gradients",
             "--deep": ", the sound-speed field without horizontal gradients (fitted by "
                       "`auto`)"}.get(design, "")
    where = (f"{config.get('n_transponders', 4)} transponders at about "
             f"{config.get('depth', 1500.0):,.0f} m")
    text = (
        f"Written by `python benchmarks/gnssa_posterior.py {n}{' ' * bool(design)}{design}` "
        f"({machine()}; "
        f"{time.perf_counter() - t0:.0f} s, load average {load[0]:.1f} / {load[1]:.1f} / "
        f"{load[2]:.1f}; git {commit()}).\n\n"
        f"{n} campaigns (seeds 0-{n - 1}) of {config['hours']:g} h, a shot every "
        f"{config['shot_interval']:g} s, track \"{config['track']}\"{field}, "
        f"{where} ({int(np.median(stack['n_shots']))} replies in the median), the "
        f"simulator's defaults otherwise; EM with `locate`'s defaults, then `sample_array` "
        f"({100 * CI:g} % intervals).\n\n" + "\n".join(lines) + "\n\n"
        "| | east | north | up |\n|---|---:|---:|---:|\n"
        "| posterior sd / EM sd (cluster-robust, reported), median over transponders | "
        + " | ".join(f"{np.median(r[:, :, a]):.2f}" for a in range(3)) + " |\n"
        "| posterior sd / EM model-based sd, median | "
        + " | ".join(f"{np.median(rm[:, :, a]):.2f}" for a in range(3)) + " |\n"
        "| centre: posterior sd / EM sd, median | "
        + " | ".join(f"{np.median(rc[:, a]):.2f}" for a in range(3)) + " |\n"
        "| sd of the standardised errors (posterior) | "
        + " | ".join(f"{z[:, :, a].std():.2f}" for a in range(3)) + " |\n"
        "| centre error, rms (mm) | "
        + " | ".join(f"{np.sqrt(np.mean(err[:, a] ** 2)):.1f}" for a in range(3)) + " |\n"
        "| centre posterior sd, median (mm) | "
        + " | ".join(f"{np.median(sd[:, a]):.1f}" for a in range(3)) + " |\n\n"
        f"Sampler: {', '.join(f'{k} {v}' for k, v in moves.items())} of {n}; "
        f"{int(stack['converged'].sum())} converged; {int(np.median(stack['ndim']))} "
        f"parameters (median); smallest bulk ESS {stack['ess'].min():,.0f} (median "
        f"{np.median(stack['ess']):,.0f}); acceptance {np.median(stack['acceptance']):.2f} "
        f"(median); EM {np.median(stack['t_em']):.2f} s, sampling "
        f"{np.median(stack['t_post']):.1f} s per campaign (median).\n")
    write_section(ROOT / "docs" / "gnssa.md", "gnssa-posterior" + design[1:], text)
    print(text)


if __name__ == "__main__":
    flags = [a for a in sys.argv[1:] if a.startswith("--")]
    if any(f not in ("--long", "--deep") for f in flags) or len(flags) > 1:
        sys.exit(f"usage: gnssa_posterior.py [N_CAMPAIGNS] [--long | --deep]; got {flags}")
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    main(int(args[0]) if args else 20, design=flags[0] if flags else "")
