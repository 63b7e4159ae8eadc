"""Sampling one beacon's posterior: from the EM solution to a :class:`PosteriorResult`."""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from ..._rng import RNGLike, as_generator
from ...exceptions import UnusableStartError
from ...io.survey import BeaconData
from ...mcmc import ess_and_rhat, hdi, thin_index, to_datatree
from ...mixture.densities import CLASSES
from ..em.em_mixture import fit_mixture_em
from ..em.em_result import EMResult, check_fit_data, options_as_input_errors
from .beacon_chains import beacon_chains, sampled
from .posterior import BeaconPosterior, check_sample_options


@dataclass(frozen=True)
class PosteriorResult:
    """Posterior of one beacon.

    Attributes
    ----------
    beacon : str
    priors : {"learned", "equal"}
    path : str
    idata : xarray.DataTree
        ArviZ data: ``posterior`` (chain = walker, its ensemble the coordinate
        ``ensemble``), ``sample_stats`` (``lp``),
        ``observed_data`` (``z`` over ``range``: the input row, with the ping ``time``
        as a coordinate; units as attributes); ``log_likelihood`` and
        ``posterior_predictive`` when asked for.
    summary : dict
        Per parameter (``d0``, ``sigma_mp``, ``sigma_dp``, ``weights``):
        ``mean``, ``sd``, ``interval`` (highest-density, probability ``ci``).
    tau : dict
        ``steps x walkers / ESS`` per sampled parameter: the autocorrelation time (steps).
    ess, ess_bulk : dict
        ArviZ's bulk ESS of the draws in :attr:`idata` (the same dict under both names).
    rhat : dict
        ArviZ's rank-normalised R-hat: over the walkers (each its own chain under the
        independence move; a heuristic for one ensemble of differential evolution),
        or across independent ensembles.
    class_probs, class_probs_sd : numpy.ndarray
        ``(n, 3)`` posterior mean and standard deviation of each range's class
        probabilities (dp, mp, ol), over the kept draws.
    rows : numpy.ndarray
        Positions of the ranges in the input table.
    em : EMResult
        The EM fit the walkers started from.
    diagnostics : dict
        ``sampler`` (``"independence"`` or ``"ensemble"``), ``moves``, ``fallback``
        (why the independence move was not kept, or None), ``n_walkers`` (per
        ensemble), ``n_chains`` (walkers in all), ``n_steps``, ``burn``, ``thin``,
        ``n_draws``, ``n_ensembles``, ``converged`` (the stopping rule met),
        ``acceptance``, ``seconds``, ``min_ess``, ``precision`` (of the kernel), and
        ``proposal_df`` and ``pilot`` when they apply.
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
        """Whether the stopping rule was met before ``max_steps``."""
        return bool(self.diagnostics.get("converged", True))

    @property
    def class_fractions(self) -> dict:
        """Fraction of ranges whose most probable class is dp, mp and ol."""
        lab = np.argmax(self.class_probs, axis=1)
        return {c: float(np.mean(lab == j)) if self.n else float("nan")
                for j, c in enumerate(CLASSES)}

    def to_dict(self) -> dict:
        """JSON-ready summary."""
        return {**self.summary, "ess": dict(self.ess), "tau": dict(self.tau),
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
    min_ess: float = 1000.0,
    max_steps: int = 20000,
    n_ensembles: int | None = None,
    n_draws: int = 2000,
    ci: float = 0.95,
    log_likelihood: bool = False,
    predictive: bool = False,
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
        The move (``docs/bayes.md``, Which move).
    n_walkers : int, optional
        Walkers (default 16 for the independence move, ``max(24, 4 ndim)`` per ensemble).
    min_ess : float, default 1000
        Stop when the smallest bulk ESS reaches this and R-hat < 1.01.
    max_steps : int, default 20000
        Step cap (``SamplingWarning`` when reached).
    n_ensembles : int, optional
        Independent ensembles of differential evolution (default 2; more than one implies it).
    n_draws : int, default 2000
        Draws kept at least (a longer chain is thinned evenly to at most ``2 n_draws``).
    ci : float, default 0.95
        Probability of the highest-density intervals.
    log_likelihood : bool, default False
        Keep the per-range log-likelihood of every draw (``log_likelihood`` group, for
        PSIS-LOO).
    predictive : bool, default False
        Draw a range per ping at every draw (``posterior_predictive`` group).
    rng : None, int or numpy.random.Generator
        The only source of randomness: same seed, same chain.
    progress : bool or "auto"
        Progress bar or lines (:mod:`bayes_mpem.mcmc.progress`).
    allow_flagged_start : bool, default False
        Sample even when the EM start carries fit-quality flags
        (:func:`~bayes_mpem.lbl.em.em_result.quality_flags`).
    precision : {"auto", "float32", "float64"}
        Of the likelihood kernel while sampling
        (:class:`~bayes_mpem.lbl.model.loglik_kernel.LoglikKernel`).

    Returns
    -------
    PosteriorResult

    Raises
    ------
    UnusableStartError
        When the EM solution lies outside the prior support or is flagged.
    InputError
        ``data`` not a BeaconData (a Survey: ``survey.for_beacon(id)``) or with fewer than 3
        ranges, or an invalid option (an ``InputError`` is a ``ValueError``).

    Warns
    -----
    SamplingWarning
        When the sampler reaches ``max_steps`` first.
    """
    data = check_fit_data(data)
    with options_as_input_errors():
        check_sample_options(priors=priors, ci=ci, n_ensembles=n_ensembles, sampler=sampler,
                             concentration=concentration, sigma_dp=sigma_dp, path=path,
                             min_ess=min_ess, max_steps=max_steps, n_draws=n_draws,
                             n_walkers=n_walkers)
    gen = as_generator(rng)
    post = BeaconPosterior(data, priors=priors, sigma_dp=sigma_dp, path=path,
                           concentration=concentration, precision=precision)
    post.em = init or fit_mixture_em(data, path=path, sigma_dp=sigma_dp,
                                     weights="learned" if priors == "learned" else "equal",
                                     rng=gen)
    _check_start(post, allow_flagged_start)
    t0 = time.perf_counter()
    chains = beacon_chains(post, gen, sampler=sampler, n_walkers=n_walkers, min_ess=min_ess,
                           max_steps=max_steps, n_ensembles=n_ensembles, n_draws=n_draws,
                           progress=progress, stacklevel=3)
    seconds = time.perf_counter() - t0
    run = chains.run
    idx, thin = thin_index(chains.chain.shape[0], chains.chain.shape[1], n_draws)
    theta = np.swapaxes(chains.chain[idx], 0, 1)  # walkers become ArviZ chains
    lp = chains.log_prob[idx].T
    flat = theta.reshape(-1, post.ndim)
    nat = {k: v[:, 0].reshape(theta.shape[:2]) for k, v in post.unpack(flat).items()}
    ll, probs, probs_sd = post.pointwise_moments(flat)
    extra = {}
    if log_likelihood:
        extra["log_likelihood"] = {"z": ll.reshape(*theta.shape[:2], -1)}
    if predictive:
        extra["posterior_predictive"] = {"z": _predict(post, nat, gen)}
    idata = _datatree(post, data, nat, lp, chains.sampler, extra, run.n_ensembles)
    names = sampled(post)
    if thin == 1 and idx.size == chains.chain.shape[0]:  # the draws written are those checked
        ess_, rhat_ = dict(run.ess_by), dict(run.rhat_by)
    else:
        ess_, rhat_ = ess_and_rhat({k: idata.posterior[k].values for k in names},
                                   run.n_ensembles)
    tau = {k: float(idx.size * thin * theta.shape[0] / ess_[k]) for k in names}
    diagnostics = {"sampler": chains.sampler, "moves": chains.info["moves"],
                   "fallback": chains.info["fallback"], "n_walkers": run.n_walkers,
                   "n_chains": int(theta.shape[0]), "n_steps": run.n_steps, "burn": run.burn,
                   "thin": int(thin), "n_draws": int(flat.shape[0]),
                   "n_ensembles": run.n_ensembles, "converged": run.converged,
                   "acceptance": run.acceptance, "seconds": float(seconds),
                   "min_ess": float(min_ess), "precision": post.kernel.dtype.name,
                   **{k: chains.info[k] for k in ("proposal_df", "pilot") if k in chains.info}}
    return PosteriorResult(
        beacon=data.beacon, priors=priors, path=path, idata=idata,
        summary=_summary(nat, ci), tau=tau, ess=ess_, ess_bulk=ess_, rhat=rhat_,
        class_probs=probs, class_probs_sd=probs_sd, rows=np.asarray(data.rows), em=post.em,
        ci=float(ci), diagnostics=diagnostics)


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


#: units of the variables written (``units`` attributes)
UNITS = {"d0": "m", "sigma_mp": "m", "sigma_dp": "m", "w_dp": "1", "w_mp": "1", "w_ol": "1",
         "z": "m", "time": "s"}


def _predict(post: BeaconPosterior, nat: dict, gen) -> np.ndarray:
    """One range per ping at every draw, from the mixture: ``(chain, draw, range)`` float32."""
    g = post.geom
    shape = nat["d0"].shape + (g.n,)
    u = gen.random(shape)
    cls = (u > nat["w_dp"][..., None]).astype(int) + (u > (nat["w_dp"] + nat["w_mp"])[..., None])
    dp = g.direct + nat["sigma_dp"][..., None] * gen.standard_normal(shape)
    mp = (g.multipath(nat["d0"][..., None], post.path)
          + nat["sigma_mp"][..., None] * gen.standard_normal(shape))
    ol = gen.uniform(g.lo, g.hi, shape)
    return np.choose(cls, [dp, mp, ol]).astype(np.float32)


def _datatree(post: BeaconPosterior, data: BeaconData, nat: dict, lp, sampler: str,
              extra: dict, n_ensembles: int):
    """ArviZ data of the kept draws, walkers as chains; units, ping times and ensembles attached."""
    import emcee
    import xarray as xr

    idata = to_datatree(
        {"posterior": {k: nat[k] for k in sampled(post)}, "sample_stats": {"lp": lp},
         "observed_data": {"z": post.geom.z}, **extra},
        dims={"z": ["range"]}, coords={"range": np.asarray(data.rows)},
        attrs={"beacon": post.beacon, "priors": post.priors, "path": post.path,
               "sampler": f"emcee {emcee.__version__} ({sampler})"},
        n_ensembles=n_ensembles)
    for name in idata.children:
        ds = idata[name].to_dataset()
        if "range" in ds.dims:
            ds = ds.assign_coords(time=("range", np.asarray(data.time, float)))
            ds["range"].attrs.update(long_name="input row")
        for var in list(ds.data_vars) + list(ds.coords):
            if var in UNITS and not (name == "log_likelihood" and var == "z"):
                ds[var].attrs["units"] = UNITS[var]
        idata[name] = xr.DataTree(ds)
    return idata


def _summary(nat: dict, ci) -> dict:
    """Mean, sd and highest-density interval of every natural parameter."""
    summary = {k: _describe(nat[k], ci) for k in ("d0", "sigma_mp", "sigma_dp")}
    summary["weights"] = {c: _describe(nat["w_" + c], ci) for c in CLASSES}
    return summary


def _describe(x, ci):
    x = np.asarray(x, float)
    if np.ptp(x) == 0:  # a fixed parameter
        v = float(x.flat[0])
        return {"mean": v, "sd": 0.0, "interval": [v, v]}
    return {"mean": float(np.mean(x)), "sd": float(np.std(x, ddof=1)),
            "interval": hdi(x, ci)}
