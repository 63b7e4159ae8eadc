"""Bayesian variant: emcee over the mixture likelihood of one beacon.

The posterior samples the same density as the mixture EM
(:mod:`bayes_mpem.mixture`). Parameters, in the sampler's coordinates:

==================  =====================================================
``d0``              plane height above the beacon (m); prior uniform on
                    ``[max(0, max dz), hi + max(0, max dz) + 1]``, the EM's bounds
``log_sigma_mp``    prior uniform on ``[log 0.05, log 500]``, i.e.
                    ``p(sigma) ~ 1 / sigma`` (scale-invariant) on 0.05-500 m
``log_sigma_dp``    the same prior; absent when ``sigma_dp`` is fixed
``w_dp, w_mp``      learned priors only: ``w_ol = 1 - w_dp - w_mp``, prior
                    ``Dirichlet(c, c, c)`` (``c = concentration``, default 1:
                    uniform on the simplex); equal priors fix all at 1/3
==================  =====================================================

The ensemble (emcee) starts in a small ball around the EM solution, runs in
blocks until the post-burn-in chain is longer than ``tau_factor`` (default 50)
integrated autocorrelation times, and discards ``2 * max(tau)`` steps of
burn-in. See ``docs/bayes.md``.
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass, field

import emcee
import numpy as np

from .._rng import RNGLike, as_generator
from ..exceptions import SamplingWarning, UnusableStartError
from ..io.survey import BeaconData
from ..mcmc import run_ensemble
from ..mixture.densities import CLASSES
from .em_mixture import fit_mixture_em
from .em_result import EMResult
from .likelihood import weighted_densities
from .posterior import PARAMS, BeaconPosterior, check_sample_options, start_ball


@dataclass(frozen=True)
class PosteriorResult:
    """Posterior of one beacon.

    Attributes
    ----------
    beacon : str
    priors : {"learned", "equal"}
    path : str
    idata : xarray.DataTree
        ArviZ data: ``posterior`` (chain = walker), ``log_likelihood`` (``z``
        per range), ``sample_stats`` (``lp``), ``observed_data``.
    summary : dict
        Per parameter (``d0``, ``sigma_mp``, ``sigma_dp``, ``weights``):
        ``mean``, ``sd``, ``interval`` (highest-density, probability ``ci``).
    tau, ess : dict
        emcee's integrated autocorrelation time (steps) and
        ``ESS = steps x walkers / tau`` per sampled parameter.
    ess_bulk : dict
        ArviZ's rank-normalised bulk ESS of every kept (unthinned) draw, walkers
        as chains: a second, independent estimate, comparable with other samplers.
    rhat : dict or None
        Rank-normalised split R-hat across independent ensembles (if several ran).
    class_probs, class_probs_sd : numpy.ndarray
        ``(n, 3)`` posterior mean and standard deviation of each range's class
        probabilities (dp, mp, ol), over the kept draws.
    rows : numpy.ndarray
        Positions of the ranges in the input table.
    em : EMResult
        The EM fit the walkers started from.
    diagnostics : dict
        ``n_walkers``, ``n_steps``, ``burn``, ``thin``, ``n_draws``,
        ``n_ensembles``, ``converged`` (chain longer than ``tau_factor`` tau),
        ``acceptance``, ``seconds``, ``moves``.
    ci : float
    """

    beacon: str
    priors: str
    path: str
    idata: object = field(repr=False)
    summary: dict
    tau: dict
    ess: dict
    ess_bulk: dict
    rhat: dict | None
    class_probs: np.ndarray = field(repr=False)
    class_probs_sd: np.ndarray = field(repr=False)
    rows: np.ndarray = field(repr=False)
    em: EMResult = field(repr=False)
    diagnostics: dict = field(default_factory=dict)
    ci: float = 0.95

    @property
    def labels(self) -> np.ndarray:
        """Most probable class of each range under the posterior mean probabilities."""
        return np.asarray(CLASSES)[np.argmax(self.class_probs, axis=1)]

    @property
    def min_ess(self) -> float:
        """Smallest ESS over the sampled parameters."""
        return float(min(self.ess.values()))

    def to_dict(self) -> dict:
        """JSON-ready summary."""
        return {**self.summary, "ess": dict(self.ess), "ess_bulk": dict(self.ess_bulk),
                "tau": dict(self.tau),
                "rhat": None if self.rhat is None else dict(self.rhat), "priors": self.priors,
                "path": self.path, "ci": self.ci, "diagnostics": dict(self.diagnostics),
                "em": {"d0": self.em.d0, "sigma_mp": self.em.sigma_mp,
                       "sigma_dp": self.em.sigma_dp, "weights": dict(self.em.weights)}}


def _pointwise(post, draws, chunk=64):
    """Per-range log-likelihood of every draw, and the mean and sd over draws of each
    range's class probabilities, in one pass over chunks of draws (never a
    draws x ranges x 3 array). Linear-space densities: exact, as ``w_ol > 0``
    in the posterior's support."""
    ll = np.empty((draws.shape[0], post.geom.n))
    s1 = np.zeros((post.geom.n, 3))
    s2 = np.zeros((post.geom.n, 3))
    for i in range(0, draws.shape[0], chunk):
        p = post.unpack(draws[i:i + chunk])
        terms = weighted_densities(post.geom, p["d0"], p["sigma_dp"], p["sigma_mp"],
                                   [p["w_dp"], p["w_mp"], p["w_ol"]], post.path)
        total = terms[0] + terms[1] + terms[2]
        ll[i:i + chunk] = np.log(total)
        for j in range(3):
            r = terms[j] / total
            s1[:, j] += r.sum(axis=0)
            s2[:, j] += (r * r).sum(axis=0)
    m = s1 / draws.shape[0]
    return ll, m, np.sqrt(np.maximum(s2 / draws.shape[0] - m * m, 0.0))


def sample_beacon(
    data: BeaconData,
    *,
    priors: str = "learned",
    sigma_dp: float | None = None,
    path: str = "triangle",
    concentration: float = 1.0,
    init: EMResult | None = None,
    n_walkers: int | None = None,
    moves=None,
    tau_factor: float = 50.0,
    min_ess: float = 1000.0,
    max_steps: int = 20000,
    n_ensembles: int = 1,
    n_draws: int = 2000,
    ci: float = 0.95,
    rng: RNGLike = None,
    progress="auto",
    allow_flagged_start: bool = False,
) -> PosteriorResult:
    """Sample the posterior of one beacon with emcee, started from the EM solution.

    Parameters
    ----------
    data : BeaconData
    priors : {"learned", "equal"}
        Learned weights with a Dirichlet prior, or the paper's equal weights.
    sigma_dp : float, optional
        Fix sigma_DP (m) instead of sampling it.
    path : {"triangle", "double"}
    concentration : float, default 1
        Dirichlet concentration (learned priors).
    init : EMResult, optional
        EM fit to start from (default: :func:`~bayes_mpem.em.fit_mixture_em` with
        the matching weights option).
    n_walkers : int, optional
        Walkers per ensemble (default ``max(24, 4 ndim)``).
    moves : list, optional
        emcee moves; default 80 % ``DEMove`` + 20 % ``DESnookerMove``.
    tau_factor : float, default 50
        Stop when the kept chain is this many autocorrelation times long ...
    min_ess : float, default 1000
        ... and its smallest ESS reaches this, by emcee's estimate and by ArviZ's
        bulk ESS (per ensemble; 0 to rely on ``tau_factor`` alone).
    max_steps : int, default 20000
        Step cap per ensemble (``SamplingWarning`` when reached).
    n_ensembles : int, default 1
        Independent ensembles (different seeds); R-hat is reported when > 1.
    n_draws : int, default 2000
        Draws kept (thinned evenly) for the ArviZ data, LOO and class probabilities.
    ci : float, default 0.95
        Probability of the highest-density intervals.
    rng : None, int or numpy.random.Generator
        The only source of randomness: same seed, same chain.
    progress : bool or "auto"
        Progress bar (``"auto"``: when standard error is a terminal).
    allow_flagged_start : bool, default False
        Sample even when the EM start carries fit-quality flags
        (:func:`~bayes_mpem.em.quality_flags`: no multipath found, a plane above
        the sea surface, ...); by default that raises, as such a posterior
        describes no reflector and mixes slowly.

    Returns
    -------
    PosteriorResult

    Raises
    ------
    UnusableStartError
        When the EM solution lies outside the prior support or is flagged (a
        sign of a wrong beacon position or of a beacon without multipath).
    ValueError
        For invalid options.

    Warns
    -----
    SamplingWarning
        When an ensemble reaches ``max_steps`` first.
    """
    import arviz_base as azb
    import arviz_stats as azs

    check_sample_options(priors=priors, ci=ci, n_ensembles=n_ensembles,
                         concentration=concentration, sigma_dp=sigma_dp, path=path,
                         tau_factor=tau_factor, min_ess=min_ess, max_steps=max_steps,
                         n_draws=n_draws)
    gen = as_generator(rng)
    post = BeaconPosterior(data, priors=priors, sigma_dp=sigma_dp, path=path,
                           concentration=concentration)
    em = init or fit_mixture_em(data, path=path, sigma_dp=sigma_dp,
                                weights="learned" if priors == "learned" else "equal", rng=gen)
    bad = post.outside_prior(em.to_dict())
    if bad or (em.flags and not allow_flagged_start):
        where = (f"lies outside the prior support ({'; '.join(bad)})" if bad
                 else "is not a credible reflector")
        raise UnusableStartError(
            f"beacon {data.beacon}: the EM solution to start from {where}"
            + (f"; the EM fit was flagged: {'; '.join(em.flags)}" if em.flags else "")
            + ". Check this beacon's position and ranges with 'bayes-mpem fit' first.")
    n_walkers = int(n_walkers or max(24, 4 * post.ndim))
    t0 = time.perf_counter()
    chains, lps, taus, burns, accs, steps, conv, status = [], [], [], [], [], [], [], []
    for _ in range(int(n_ensembles)):
        start = start_ball(post, em, n_walkers, gen)
        sampler, burn, tau, ok, st = run_ensemble(
            post, start, seed=int(gen.integers(2**63)), moves=moves, tau_factor=tau_factor,
            min_ess=min_ess, max_steps=max_steps, progress=progress)
        chains.append(sampler.get_chain(discard=burn))
        lps.append(sampler.get_log_prob(discard=burn))
        taus.append(tau)
        burns.append(burn)
        accs.append(float(np.mean(sampler.acceptance_fraction)))
        steps.append(sampler.iteration)
        conv.append(ok)
        status.append(st)
    seconds = time.perf_counter() - t0
    if not all(conv):
        warnings.warn(f"beacon {data.beacon}: the chain reached max_steps={max_steps} before "
                      "meeting its stopping rule: "
                      + "; ".join(s for s, c in zip(status, conv, strict=True) if not c)
                      + "; estimates may be unreliable",
                      SamplingWarning, stacklevel=2)

    # thin evenly to about n_draws draws in all; walkers become ArviZ chains
    n_chains = n_walkers * len(chains)
    kept = min(c.shape[0] for c in chains)
    per_chain = max(1, min(kept, int(np.ceil(n_draws / n_chains))))
    thin = max(1, kept // per_chain)
    idx = np.arange(kept - (per_chain - 1) * thin - 1, kept, thin)[-per_chain:]
    theta = np.concatenate([c[idx] for c in chains], axis=1)  # (draw, chain, ndim)
    lp = np.concatenate([lp_[idx] for lp_ in lps], axis=1)
    theta = np.swapaxes(theta, 0, 1)  # (chain, draw, ndim)
    flat = theta.reshape(-1, post.ndim)
    nat = {k: v[:, 0].reshape(theta.shape[:2]) for k, v in post.unpack(flat).items()}
    sampled = [k for k in PARAMS if k == "d0" or k == "sigma_mp"
               or (k == "sigma_dp" and sigma_dp is None) or (k.startswith("w_") and
                                                             priors == "learned")]
    ll, probs, probs_sd = _pointwise(post, flat)
    ll = ll.reshape(*theta.shape[:2], -1)
    with warnings.catch_warnings():
        # walkers are ArviZ chains by design (emcee convention); with many walkers and
        # few kept draws each, ArviZ's dimension-name heuristic would misfire
        warnings.filterwarnings("ignore", message="Found chain dimension to be longer")
        idata = azb.from_dict(
            {"posterior": {k: nat[k] for k in sampled},
             "log_likelihood": {"z": ll},
             "sample_stats": {"lp": lp.T},
             "observed_data": {"z": post.geom.z}},
            dims={"z": ["range"]}, coords={"range": np.arange(post.geom.n)})
    idata.attrs.update({"beacon": data.beacon, "priors": priors, "path": path,
                        "sampler": f"emcee {emcee.__version__}"})

    summary = {}
    for k in ("d0", "sigma_mp", "sigma_dp"):
        summary[k] = _describe(nat[k], ci)
    summary["weights"] = {c: _describe(nat["w_" + c], ci) for c in CLASSES}

    # emcee's tau (steps) on the kept chain, per natural parameter; ESS = steps x walkers / tau
    tau_d, ess_d = {}, {}
    for k in sampled:
        tk, ek = [], 0.0
        for c in chains:
            series = post.unpack(c.reshape(-1, post.ndim))[k][:, 0].reshape(c.shape[:2])
            t = float(emcee.autocorr.integrated_time(series[:, :, None], tol=0, quiet=True)[0])
            tk.append(t)
            ek += c.shape[0] * c.shape[1] / t
        tau_d[k], ess_d[k] = float(np.max(tk)), float(ek)
    full = {}
    for k in sampled:
        series = [post.unpack(c[-kept:].reshape(-1, post.ndim))[k][:, 0].reshape(kept, -1).T
                  for c in chains]  # (walker, step) per ensemble, common length
        full[k] = np.concatenate(series, axis=0)
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="Found chain dimension to be longer")
        bulk = azs.ess(azb.from_dict({"posterior": full}), method="bulk")
    ess_bulk = {k: float(bulk[k]) for k in sampled}
    rhat = None
    if len(chains) > 1:
        rh = azs.rhat(_ensembles_as_chains(idata.posterior.dataset, len(chains)))
        rhat = {k: float(rh[k]) for k in sampled}
    return PosteriorResult(
        beacon=data.beacon, priors=priors, path=path, idata=idata, summary=summary,
        tau=tau_d, ess=ess_d, ess_bulk=ess_bulk, rhat=rhat, class_probs=probs,
        class_probs_sd=probs_sd,
        rows=np.asarray(data.rows), em=em, ci=float(ci),
        diagnostics={"n_walkers": n_walkers, "n_steps": int(max(steps)),
                     "burn": int(max(burns)), "thin": int(thin), "n_draws": int(flat.shape[0]),
                     "n_ensembles": len(chains), "converged": bool(all(conv)),
                     "acceptance": float(np.mean(accs)), "seconds": float(seconds),
                     "tau_factor": float(tau_factor), "min_ess": float(min_ess),
                     "moves": "default (DEMove 0.8, DESnookerMove 0.2)" if moves is None
                     else repr(moves)})


def _describe(x, ci):
    import arviz_stats as azs

    lo, hi = (float(v) for v in azs.hdi(np.ravel(x), prob=ci))  # highest-density interval
    return {"mean": float(np.mean(x)), "sd": float(np.std(x, ddof=1)) if x.size > 1 else 0.0,
            "interval": [lo, hi]}


def _ensembles_as_chains(ds, n_ens):
    """Regroup walker-chains into one chain per ensemble (draws = walkers x kept draws)."""
    import xarray as xr

    out = {}
    for k, v in ds.data_vars.items():
        a = v.values  # (chain, draw)
        a = a.reshape(n_ens, -1, a.shape[1])  # (ensemble, walker, draw)
        out[k] = xr.DataArray(a.transpose(0, 2, 1).reshape(n_ens, -1), dims=("chain", "draw"))
    return xr.Dataset(out)
