"""Sampling one beacon's posterior: from the EM solution to a :class:`PosteriorResult`.

:func:`sample_beacon` samples :class:`~bayes_mpem.lbl.bayes.posterior.BeaconPosterior`
(the parameters and their priors are listed there):

1. the mixture EM (:func:`~bayes_mpem.lbl.em.em_mixture.fit_mixture_em`) gives the
   start; a start outside the prior support, or one the EM flagged (no multipath,
   a plane above the sea surface, ...), raises :class:`UnusableStartError`;
2. :func:`~bayes_mpem.lbl.bayes.beacon_chains.beacon_chains` samples: by default four
   independence Metropolis-Hastings chains from a Student-t at the posterior mode
   until the smallest bulk ESS reaches ``min_ess``, or, when that proposal fits
   poorly (or ``sampler="ensemble"``), emcee ensembles from a small ball around the
   EM solution, run in blocks until the post-burn-in chain is longer than
   ``tau_factor`` (default 50) integrated autocorrelation times and its smallest
   ESS reaches ``min_ess`` (by emcee's and by the bulk estimate), discarding
   ``2 max(tau)`` steps of burn-in;
3. about ``n_draws`` evenly thinned draws give the ArviZ data (chains or walkers as
   ArviZ chains, the log-likelihood of every range for PSIS-LOO in
   :mod:`bayes_mpem.lbl.bayes.loo`), the highest-density intervals and the posterior
   mean and sd of each range's class probabilities; the autocorrelation times
   and ESS use the whole kept chain, R-hat compares the independence chains
   (or independent ensembles).

See ``docs/bayes.md``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from ..._rng import RNGLike, as_generator
from ...exceptions import UnusableStartError
from ...io.survey import BeaconData
from ...mcmc import (
    autocorr_ess,
    bulk_ess,
    hdi,
    rhat_across_ensembles,
    thin_index,
    to_datatree,
)
from ...mcmc.convergence import ess_mean, rhat_rank
from ...mixture.densities import CLASSES
from ..em.em_mixture import fit_mixture_em
from ..em.em_result import EMResult
from .beacon_chains import BeaconChains, beacon_chains
from .posterior import PARAMS, BeaconPosterior, check_sample_options


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
        Integrated autocorrelation time (steps) and ``ESS = steps x chains / tau``
        per sampled parameter: emcee's estimate for an ensemble (walkers as
        chains), the split-chain ESS of the mean for independence chains.
    ess_bulk : dict
        Rank-normalised bulk ESS (ArviZ's estimator) of every kept (unthinned)
        draw, walkers or chains as chains: a second estimate, comparable with
        other samplers.
    rhat : dict or None
        Rank-normalised split R-hat across the independence chains, or across
        independent ensembles (None for a single ensemble).
    class_probs, class_probs_sd : numpy.ndarray
        ``(n, 3)`` posterior mean and standard deviation of each range's class
        probabilities (dp, mp, ol), over the kept draws.
    rows : numpy.ndarray
        Positions of the ranges in the input table.
    em : EMResult
        The EM fit the walkers started from.
    diagnostics : dict
        ``sampler`` (``"independence"`` or ``"ensemble"``), ``fallback`` (why the
        independence chains were not kept, or None), ``n_chains`` (chains, or
        walkers per ensemble), ``n_steps``, ``burn``, ``thin``, ``n_draws``,
        ``n_ensembles``, ``converged`` (the stopping rule met), ``acceptance``,
        ``seconds``, ``precision`` (of the kernel); for an ensemble also
        ``n_walkers`` and ``moves``, for independence chains ``proposal_df``.
    ci : float

    Notes
    -----
    ``d0``, ``sigma_mp``, ``sigma_dp``, ``weights``, ``n``, ``converged``,
    ``class_fractions`` and ``labels`` answer as the same names of
    :class:`~bayes_mpem.lbl.em.em_result.EMResult` do (here from the posterior means), so a
    fit's and a sample's per-beacon results read alike; ``summary`` has the intervals.
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

    # the names an EMResult answers to, as posterior means: fit and sample results read alike

    @property
    def d0(self) -> float:
        """Posterior mean height of the reflecting plane above the beacon (m)."""
        return float(self.summary["d0"]["mean"])

    @property
    def sigma_mp(self) -> float:
        """Posterior mean multipath scatter (m)."""
        return float(self.summary["sigma_mp"]["mean"])

    @property
    def sigma_dp(self) -> float:
        """Posterior mean direct-path scatter (m; the fixed value when it was fixed)."""
        return float(self.summary["sigma_dp"]["mean"])

    @property
    def weights(self) -> dict:
        """Posterior mean mixing weights ``{"dp", "mp", "ol"}``."""
        return {k: float(v["mean"]) for k, v in self.summary["weights"].items()}

    @property
    def n(self) -> int:
        """Number of ranges."""
        return int(self.class_probs.shape[0])

    @property
    def converged(self) -> bool:
        """Whether every ensemble met its stopping rule before ``max_steps``."""
        return bool(self.diagnostics.get("converged", True))

    @property
    def class_fractions(self) -> dict:
        """Fraction of ranges whose most probable class is dp, mp and ol."""
        lab = np.argmax(self.class_probs, axis=1)
        return {c: float(np.mean(lab == j)) if self.n else float("nan")
                for j, c in enumerate(CLASSES)}

    def to_dict(self) -> dict:
        """JSON-ready summary."""
        return {**self.summary, "ess": dict(self.ess), "ess_bulk": dict(self.ess_bulk),
                "tau": dict(self.tau),
                "rhat": None if self.rhat is None else dict(self.rhat), "priors": self.priors,
                "path": self.path, "ci": self.ci, "diagnostics": dict(self.diagnostics),
                "em": {"d0": self.em.d0, "sigma_mp": self.em.sigma_mp,
                       "sigma_dp": self.em.sigma_dp, "weights": dict(self.em.weights)}}



def sample_beacon(
    data: BeaconData,
    *,
    priors: str = "learned",
    sigma_dp: float | None = None,
    path: str = "triangle",
    concentration: float = 1.0,
    init: EMResult | None = None,
    sampler: str = "auto",
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
    precision: str = "auto",
) -> PosteriorResult:
    """Sample the posterior of one beacon, started from the EM solution.

    Parameters
    ----------
    data : BeaconData
        The ranges of one beacon.
    priors : {"learned", "equal"}
        Learned weights with a Dirichlet prior, or the paper's equal weights.
    sigma_dp : float, optional
        Fix sigma_DP (m) instead of sampling it.
    path : {"triangle", "double"}
        The multipath geometry.
    concentration : float, default 1
        Dirichlet concentration (learned priors).
    init : EMResult, optional
        EM fit to start from (default: :func:`~bayes_mpem.lbl.em.em_mixture.fit_mixture_em`
        with the matching weights option).
    sampler : {"auto", "independence", "ensemble"}
        Independence chains from a Laplace proposal, emcee's ensemble, or the
        first unless its proposal fits poorly (``"auto"``); see
        :mod:`bayes_mpem.lbl.bayes.beacon_chains`. ``n_walkers``, ``moves`` or
        ``n_ensembles > 1`` imply the ensemble.
    n_walkers : int, optional
        Walkers per ensemble (default ``max(24, 4 ndim)``).
    moves : list, optional
        emcee moves; default :func:`~bayes_mpem.mcmc.default_moves`
        (differential evolution alone).
    tau_factor : float, default 50
        Ensemble: stop when the kept chain is this many autocorrelation times long ...
    min_ess : float, default 1000
        ... and its smallest ESS reaches this, by emcee's estimate and by the bulk
        ESS (per ensemble; 0 to rely on ``tau_factor`` alone). Independence
        chains: stop when the smallest bulk ESS reaches this and R-hat < 1.01.
    max_steps : int, default 20000
        Step cap per ensemble, or draws per independence chain
        (``SamplingWarning`` when reached).
    n_ensembles : int, default 1
        Independent ensembles (different seeds; more than one implies the
        ensemble); R-hat is reported when > 1. (Independence chains: always
        four, and R-hat.)
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
        (:func:`~bayes_mpem.lbl.em.em_result.quality_flags`: no multipath found, a
        plane above the sea surface, ...); by default that raises, as such a
        posterior describes no reflector and mixes slowly.
    precision : {"auto", "float32", "float64"}
        Of the likelihood kernel while sampling
        (:class:`~bayes_mpem.lbl.model.loglik_kernel.LoglikKernel`; ``"auto"``: float32
        where its rounding error is known to be harmless; ``"float64"``: the same
        chain as the log-space likelihood, seed for seed). The per-range
        log-likelihood and class probabilities are float64 either way.

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
        When an ensemble or the independence chains reach ``max_steps`` first.
    """
    check_sample_options(priors=priors, ci=ci, n_ensembles=n_ensembles, sampler=sampler,
                         concentration=concentration, sigma_dp=sigma_dp, path=path,
                         tau_factor=tau_factor, min_ess=min_ess, max_steps=max_steps,
                         n_draws=n_draws)
    gen = as_generator(rng)
    post = BeaconPosterior(data, priors=priors, sigma_dp=sigma_dp, path=path,
                           concentration=concentration, precision=precision)
    post.em = init or fit_mixture_em(data, path=path, sigma_dp=sigma_dp,
                                     weights="learned" if priors == "learned" else "equal",
                                     rng=gen)
    _check_start(post, allow_flagged_start)
    t0 = time.perf_counter()
    chains = beacon_chains(post, gen, sampler=sampler, n_walkers=n_walkers, moves=moves,
                           tau_factor=tau_factor, min_ess=min_ess, max_steps=max_steps,
                           n_ensembles=n_ensembles, n_draws=n_draws, progress=progress,
                           where=f"beacon {data.beacon}", stacklevel=3)
    seconds = time.perf_counter() - t0
    groups = chains.groups
    kept = min(c.shape[0] for c in groups)
    idx, thin = thin_index(kept, sum(c.shape[1] for c in groups), n_draws)
    # chains (walkers) become ArviZ chains: (chain, draw, ndim) and (chain, draw)
    theta = np.swapaxes(np.concatenate([c[idx] for c in groups], axis=1), 0, 1)
    lp = np.concatenate([lp_[idx] for lp_ in chains.log_prob], axis=1).T
    flat = theta.reshape(-1, post.ndim)
    nat = {k: v[:, 0].reshape(theta.shape[:2]) for k, v in post.unpack(flat).items()}
    ll, probs, probs_sd = post.pointwise_moments(flat)
    idata = _datatree(post, nat, ll.reshape(*theta.shape[:2], -1), lp, chains.sampler)
    tau, ess, ess_bulk = _chain_diagnostics(post, chains, kept)
    if chains.sampler == "independence":  # the four chains, every kept draw
        rhat = {k: rhat_rank(_natural(post, groups[0], k).T) for k in _sampled(post)}
    else:
        rhat = (rhat_across_ensembles(idata.posterior.dataset, len(groups)) if len(groups) > 1
                else None)
    info = chains.info
    diagnostics = {"sampler": chains.sampler, "fallback": info["fallback"],
                   "n_chains": info["n_chains"], "n_steps": info["n_steps"],
                   "burn": info["burn"], "thin": int(thin), "n_draws": int(flat.shape[0]),
                   "n_ensembles": len(groups), "converged": info["converged"],
                   "acceptance": float(info["acceptance"]), "seconds": float(seconds),
                   "tau_factor": float(tau_factor), "min_ess": float(min_ess),
                   "precision": post.kernel.dtype.name}
    if chains.sampler == "ensemble":
        from ...mcmc import DEFAULT_MOVES_LABEL

        diagnostics.update(n_walkers=info["n_chains"],
                           moves=DEFAULT_MOVES_LABEL if moves is None else repr(moves))
    else:
        diagnostics.update(proposal_df=info["proposal_df"])
    return PosteriorResult(
        beacon=data.beacon, priors=priors, path=path, idata=idata,
        summary=_summary(nat, ci), tau=tau, ess=ess,
        ess_bulk=ess_bulk, rhat=rhat, class_probs=probs, class_probs_sd=probs_sd,
        rows=np.asarray(data.rows), em=post.em, ci=float(ci), diagnostics=diagnostics)


def _check_start(post: BeaconPosterior, allow_flagged: bool) -> None:
    """Raise :class:`UnusableStartError` for an EM start outside the prior or flagged."""
    em = post.em
    bad = post.outside_prior(em.to_dict())
    if bad or (em.flags and not allow_flagged):
        where = (f"lies outside the prior support ({'; '.join(bad)})" if bad
                 else "is not a credible reflector")
        raise UnusableStartError(
            f"beacon {post.beacon}: the EM solution to start from {where}"
            + (f"; the EM fit was flagged: {'; '.join(em.flags)}" if em.flags else "")
            + ". Check this beacon's position and ranges with 'bayes-mpem fit' first.")


def _sampled(post: BeaconPosterior) -> list:
    """List the natural parameters that vary over the draws, in :data:`PARAMS` order."""
    return [k for k in PARAMS if k == "d0" or k == "sigma_mp"
            or (k == "sigma_dp" and post.sigma_dp is None)
            or (k.startswith("w_") and post.priors == "learned")]


def _datatree(post: BeaconPosterior, nat: dict, ll, lp, sampler: str):
    """ArviZ data of the thinned draws, chains (walkers) as chains."""
    idata = to_datatree(
        {"posterior": {k: nat[k] for k in _sampled(post)},
         "log_likelihood": {"z": ll},
         "sample_stats": {"lp": lp},
         "observed_data": {"z": post.geom.z}},
        dims={"z": ["range"]}, coords={"range": np.arange(post.geom.n)})
    if sampler == "ensemble":
        import emcee

        label = f"emcee {emcee.__version__}"
    else:
        from ... import __version__

        label = f"bayes_mpem {__version__} independence Metropolis-Hastings"
    idata.attrs.update({"beacon": post.beacon, "priors": post.priors, "path": post.path,
                        "sampler": label})
    return idata


def _summary(nat: dict, ci) -> dict:
    """Mean, sd and highest-density interval of every natural parameter."""
    summary = {k: _describe(nat[k], ci) for k in ("d0", "sigma_mp", "sigma_dp")}
    summary["weights"] = {c: _describe(nat["w_" + c], ci) for c in CLASSES}
    return summary


def _natural(post: BeaconPosterior, chain, k) -> np.ndarray:
    """Natural parameter ``k`` of a ``(steps, chains, ndim)`` chain, ``(steps, chains)``."""
    return post.unpack(chain.reshape(-1, post.ndim))[k][:, 0].reshape(chain.shape[:2])


def _chain_diagnostics(post: BeaconPosterior, chains: BeaconChains, kept):
    """Autocorrelation time and ESS, and the bulk ESS, of every sampled natural parameter.

    An ensemble: emcee's estimates on the whole kept chain of each (ESS summed
    over ensembles), the bulk ESS on the last ``kept`` steps of each, walkers of
    all ensembles as chains. Independence chains: the split-chain ESS of the
    mean and the bulk ESS, chains as chains; ``tau = steps x chains / ESS``.
    """
    tau, ess, full = {}, {}, {}
    for k in _sampled(post):
        if chains.sampler == "independence":
            x = _natural(post, chains.groups[0], k).T  # (chain, draw)
            ess[k] = ess_mean(x)
            tau[k] = float(x.size / ess[k])
            full[k] = x
            continue
        tk, ek = [], 0.0
        for c in chains.groups:
            t, e = autocorr_ess(_natural(post, c, k))
            tk.append(t)
            ek += e
        tau[k], ess[k] = float(np.max(tk)), float(ek)
        full[k] = np.concatenate([_natural(post, c[-kept:], k).T for c in chains.groups],
                                 axis=0)  # (walker, step) per ensemble, common length
    return tau, ess, bulk_ess(full)


def _describe(x, ci):
    lo, hi = hdi(x, ci)  # highest-density interval
    return {"mean": float(np.mean(x)), "sd": float(np.std(x, ddof=1)) if x.size > 1 else 0.0,
            "interval": [lo, hi]}
