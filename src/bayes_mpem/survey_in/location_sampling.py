"""Posterior of a transponder location jointly with the class of every ping (emcee)."""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from .._rng import RNGLike, as_generator
from ..mcmc import (
    bulk_ess,
    draw_moments,
    draw_summary,
    equal_tailed,
    rhat,
    run_ensembles,
    thin_index,
)
from .classes import true_probability
from .drift import drift_from_draws
from .location import LocateResult
from .posterior import (
    PARAMS,
    SIGMA_BOUNDS,
    TAT_BOUNDS,
    LocationLogPosterior,
    check_location_options,
    posterior_tree,
)

#: independent ensembles of differential evolution: the stopping rule's R-hat compares them
N_ENSEMBLES = 2
#: units of the variables written (``units`` attributes)
UNITS = {"east": "m", "north": "m", "depth": "m", "sound_speed": "m/s", "tat": "s",
         "sigma": "s", "weight": "1", "twtt": "s", "time": "s", "p_true": "1",
         "p_true_sd": "1", "lp": "1"}


@dataclass(frozen=True)
class LocationPosterior:
    """Posterior of one transponder's location and of the class of each of its pings.

    Attributes
    ----------
    transponder : str
    names : tuple of str
        The sampler's coordinates.
    draws : dict
        Thinned draws of each reported parameter (``east``, ``north``, ``depth``,
        ``sound_speed`` m/s, ``sigma`` s, ``weight``, ``tat`` when fitted), shape
        ``(walker, draw)``, ``lp`` (their log density, the same shape) and ``theta``:
        ``(walker, draw, ndim)`` in the sampler's coordinates; the walkers of both
        ensembles, one after the other.
    p_true, p_true_sd : numpy.ndarray
        Per ping (table order of ``rows``): posterior mean and standard deviation
        over the draws of the probability of being a true arrival.
    rows : numpy.ndarray
        Positions of the pings in the input table.
    shots : pandas.DataFrame
        ``line``, ``time`` (s), ``transponder``, ``twtt`` (s) of those pings (the
        file's ``observed_data``; as :class:`~.array_sampling.ArrayPosterior`'s).
    tau, ess, ess_bulk : dict
        Per reported parameter: ``steps x walkers / ESS`` (steps), and ArviZ's bulk ESS
        of :attr:`draws` (walkers as chains; the same dict under both names).
    rhat : dict
        ArviZ's R-hat of :attr:`draws` across the two ensembles (each ensemble's walkers,
        which are not independent chains, pooled into one chain).
    em : LocateResult
        The EM fit the walkers started from.
    diagnostics : dict
        ``n_walkers`` (per ensemble), ``n_ensembles``, ``n_steps``, ``burn``, ``thin``,
        ``n_draws``, ``converged``,
        ``acceptance``, ``seconds``, ``min_ess``, ``travel_times``.
    ci : float
    """

    transponder: str
    names: tuple
    draws: dict = field(repr=False)
    p_true: np.ndarray = field(repr=False)
    p_true_sd: np.ndarray = field(repr=False)
    rows: np.ndarray = field(repr=False)
    shots: pd.DataFrame = field(default=None, repr=False)
    tau: dict = field(default_factory=dict)
    ess: dict = field(default_factory=dict)
    ess_bulk: dict = field(default_factory=dict)
    rhat: dict = field(default_factory=dict)
    em: LocateResult = field(default=None, repr=False)
    diagnostics: dict = field(default_factory=dict)
    ci: float = 0.95

    @property
    def params(self) -> tuple:
        """The reported parameters present (``tat`` only when fitted)."""
        return tuple(k for k in PARAMS if k in self.draws)

    @property
    def n_spurious(self) -> int:
        """Pings whose posterior mean probability of being true is below 1/2."""
        return int(np.sum(self.p_true < 0.5))

    @property
    def converged(self) -> bool:
        """Whether the chain met its stopping rule before ``max_steps``."""
        return bool(self.diagnostics.get("converged", False))

    @property
    def min_ess(self) -> float:
        """Smallest bulk ESS over the reported parameters."""
        return float(min(self.ess.values()))

    def mean(self, name: str) -> float:
        """Posterior mean of a reported parameter.

        Parameters
        ----------
        name : str
            A reported parameter (``east``, ``north``, ``depth``, ``sound_speed``, ...).

        Returns
        -------
        float
        """
        return float(np.mean(self.draws[name]))

    def sd(self, name: str) -> float:
        """Posterior standard deviation of a reported parameter.

        Parameters
        ----------
        name : str
            A reported parameter (``east``, ``north``, ``depth``, ``sound_speed``, ...).

        Returns
        -------
        float
        """
        return float(np.std(self.draws[name], ddof=1))

    def interval(self, name: str, ci: float | None = None) -> list:
        """Equal-tailed posterior interval of a reported parameter with probability ``ci``.

        Parameters
        ----------
        name : str
            A reported parameter (``east``, ``north``, ``depth``, ``sound_speed``, ...).
        ci : float, optional
            Default: the probability the posterior was summarised with.

        Returns
        -------
        list of float
        """
        return equal_tailed(self.draws[name], self.ci if ci is None else float(ci))

    def describe(self, name: str, ci: float | None = None) -> dict:
        """``mean``, ``sd`` and ``interval`` of a reported parameter.

        Parameters
        ----------
        name : str
            A reported parameter (``east``, ``north``, ``depth``, ``sound_speed``, ...).
        ci : float, optional

        Returns
        -------
        dict
        """
        return draw_summary(self.draws[name], self.ci if ci is None else float(ci))

    def to_dict(self, ci: float | None = None) -> dict:
        """JSON-ready summary (equal-tailed intervals with probability ``ci``).

        Parameters
        ----------
        ci : float, optional
            Default: the probability the posterior was summarised with.

        Returns
        -------
        dict
        """
        ci = self.ci if ci is None else float(ci)
        out = {k: self.describe(k, ci) for k in ("east", "north", "depth", "sound_speed")}
        if "tat" in self.draws:
            out["tat"] = {**self.describe("tat", ci), "fitted": True}
        else:
            out["tat"] = {"mean": self.em.tat, "sd": 0.0, "fitted": False}
        s = self.describe("sigma", ci)
        out["sigma_ms"] = {"mean": 1e3 * s["mean"], "sd": 1e3 * s["sd"],
                           "interval": [1e3 * v for v in s["interval"]]}
        out["weight_true"] = self.describe("weight", ci)
        out.update(n_spurious=self.n_spurious, n=int(self.p_true.size), ci=ci,
                   interval_method="posterior", ess=dict(self.ess), rhat=dict(self.rhat),
                   tau=dict(self.tau),
                   diagnostics=dict(self.diagnostics))
        return out

    def to_inference_data(self):
        """ArviZ data of the kept draws, walkers as chains; units and ping times attached.

        The layout of the array's (:meth:`.array_sampling.ArrayPosterior.to_inference_data`,
        :func:`~.posterior.posterior_tree`).

        Returns
        -------
        xarray.DataTree
            ``posterior`` (the reported parameters; each walker's ensemble the chain
            coordinate ``ensemble``), ``sample_stats`` (``lp``), ``observed_data``
            (``twtt`` over ``shot``: the input row, with the ping's ``time``,
            ``shot_transponder`` and file ``line``) and ``class_probabilities``
            (``p_true``, ``p_true_sd`` per ping, averaged over the draws).

        Raises
        ------
        ValueError
            For a posterior built without its pings (``shots``) or log densities (``lp``).
        """
        import emcee

        if self.shots is None or "lp" not in self.draws:
            raise ValueError(f"transponder {self.transponder}: a posterior without its pings "
                             "(shots) or log densities (draws['lp']) cannot be written")
        return posterior_tree(
            {k: self.draws[k] for k in self.params}, self.draws["lp"], self.shots, self.p_true,
            self.p_true_sd, self.rows, units=UNITS,
            n_ensembles=int(self.diagnostics.get("n_ensembles", N_ENSEMBLES)),
            attrs={"kind": "one transponder", "transponder": self.transponder,
                   "sampler": f"emcee {emcee.__version__} ({self.diagnostics.get('moves')})",
                   "frame": "local east, north (m) of the survey, depth (m) down",
                   "travel_times": self.diagnostics.get("travel_times", ""), "ci": self.ci})


def _true_probability(post: LocationLogPosterior, theta):
    """Each ping's probability of being a true arrival, ``(W, n)``, for :func:`draw_moments`."""
    ld, lu = post.class_log_densities(theta)
    return None, [true_probability(ld, lu)]


def _location_posterior(pings, fit, *, n_walkers, bending):
    """Build the log-posterior of ``fit``'s transponder; check it and the number of walkers."""
    if not isinstance(fit, LocateResult):
        raise TypeError(f"fit: expected a LocateResult, got {type(fit).__name__}")
    if fit.model.get("fit_lag") or fit.model.get("lag", 0.0):
        raise ValueError(f"transponder {fit.transponder}: the posterior of a fit with a position "
                         "lag (fit_lag=True) is not implemented; sample the fit without it")
    post = LocationLogPosterior(pings, fit, bending=bending)
    if not np.isfinite(post.log_prior(post.theta_em()[None]))[0]:
        raise ValueError(f"transponder {fit.transponder}: the EM solution lies outside the "
                         f"prior (sigma {fit.sigma:.3g} s in {SIGMA_BOUNDS}, weight "
                         f"{fit.weight:.3g} in (0, 1), tat {fit.tat:.3g} s in {TAT_BOUNDS})")
    least = 2 * post.ndim + 2  # each half's proposals span the other half's differences
    n_walkers = int(max(32, least) if n_walkers is None else n_walkers)
    if n_walkers < least:
        raise ValueError(f"n_walkers: expected at least 2 x ({post.ndim} parameters + 1) = "
                         f"{least} for transponder {fit.transponder}, got {n_walkers}")
    return post, n_walkers


def sample_location(pings: pd.DataFrame, fit: LocateResult, *, n_walkers: int | None = None,
                    ci: float = 0.95, min_ess: float = 1000.0, max_steps: int = 20000,
                    n_draws: int = 4000, bending: str = "linear", rng: RNGLike = None,
                    progress="auto") -> LocationPosterior:
    """Sample the posterior of a transponder location and its ping classes, from the EM fit.

    Parameters
    ----------
    pings : pandas.DataFrame
        The pings table ``fit`` was located from (``beacon``, ``twtt``, ``x``, ``y``,
        ``depth``, and ``time`` for a time-varying speed).
    fit : LocateResult
        The EM fit (:func:`~bayes_mpem.survey_in.location.locate`): the model and the start.
    n_walkers : int, optional
        Walkers of each of the two ensembles; default ``max(32, 2 ndim + 2)``, the least
        that lets differential evolution reach every direction.
    ci : float, default 0.95
        Probability of the equal-tailed intervals.
    min_ess : float, default 1000
        Run until the smallest bulk ESS of the reported parameters reaches this and
        R-hat across the two ensembles < 1.01.
    max_steps : int, default 20000
        Step cap (``SamplingWarning`` when reached first).
    n_draws : int, default 4000
        Draws kept at least (a longer chain is thinned evenly) for the summaries and
        the class probabilities.
    bending : {"linear", "fixed"}
        Refracted rays only: the ray-bending correction held fixed at the EM
        solution (OBSrange's), or with its gradient there too (the default; see
        :class:`LocationLogPosterior`).
    rng : None, int or numpy.random.Generator
        The only source of randomness: same seed, same chain.
    progress : bool or "auto"
        Progress bar (``"auto"``: when standard error is a terminal).

    Returns
    -------
    LocationPosterior

    Raises
    ------
    TypeError
        When ``fit`` is not a :class:`LocateResult`.
    ValueError
        For invalid options, a fit with a position lag, or an EM solution outside
        the prior's support.

    Warns
    -----
    SamplingWarning
        When the chain reaches ``max_steps`` before its stopping rule.
    """
    check_location_options(n_walkers=n_walkers, ci=ci, min_ess=min_ess, max_steps=max_steps,
                           n_draws=n_draws)
    post, n_walkers = _location_posterior(pings, fit, n_walkers=n_walkers, bending=bending)
    from ..mcmc.moves import default_moves

    gen = as_generator(rng)
    t0 = time.perf_counter()
    starts = [post.start(n_walkers, gen) for _ in range(N_ENSEMBLES)]

    def natural(chain):
        return {k: v for k, v in post.natural(chain).items() if k in PARAMS}

    run = run_ensembles(post, starts, moves=default_moves(), gen=gen, min_ess=float(min_ess),
                        max_steps=int(max_steps), n_draws=int(n_draws), burn_in=True,
                        natural=natural, progress=progress,
                        label=f"transponder {fit.transponder}", stacklevel=2)
    seconds = time.perf_counter() - t0
    idx, thin = thin_index(run.chain.shape[0], N_ENSEMBLES * n_walkers, n_draws)
    theta = np.swapaxes(run.chain[idx], 0, 1)  # (walker, draw, ndim), ensemble by ensemble
    draws = {k: np.ascontiguousarray(v) for k, v in natural(theta).items()}
    ess = bulk_ess(draws)
    tau = {k: float(idx.size * thin * N_ENSEMBLES * n_walkers / ess[k]) for k in draws}
    rhat_ = {k: _rhat_across(draws[k]) for k in ess}
    draws["lp"] = np.ascontiguousarray(np.swapaxes(run.log_prob[idx], 0, 1))
    draws["theta"] = theta
    flat = theta.reshape(-1, post.ndim)
    _, p, p_sd = draw_moments(flat, lambda t: _true_probability(post, t))
    travel = ("straight rays (exact)" if post.profile is None else
              "refracted rays: fixed ray-bending correction at the EM solution")
    return LocationPosterior(
        transponder=fit.transponder, names=post.names, draws=draws, p_true=p[:, 0],
        p_true_sd=p_sd[:, 0], rows=np.asarray(fit.rows), shots=_shots(pings, fit),
        tau=tau, ess=ess, ess_bulk=ess,
        rhat=rhat_, em=fit,
        diagnostics={"n_walkers": n_walkers, "n_ensembles": N_ENSEMBLES,
                     "n_steps": run.n_steps, "burn": int(run.burn),
                     "thin": int(thin), "n_draws": int(flat.shape[0]),
                     "converged": bool(run.converged), "acceptance": run.acceptance,
                     "seconds": float(seconds), "min_ess": float(min_ess),
                     "moves": "DEMove 1.0 (differential evolution)", "travel_times": travel},
        ci=float(ci))


def _shots(pings: pd.DataFrame, fit: LocateResult) -> pd.DataFrame:
    """``line``, ``time``, ``transponder``, ``twtt`` of the pings ``fit`` used (the file's)."""
    sub = pings.iloc[np.asarray(fit.rows)]
    n = len(sub)
    return pd.DataFrame({
        "line": sub["line"].to_numpy() if "line" in sub.columns else np.asarray(fit.rows),
        "time": sub["time"].to_numpy(float) if "time" in sub.columns else np.full(n, np.nan),
        "transponder": np.full(n, str(fit.transponder)),
        "twtt": sub["twtt"].to_numpy(float)})


def _rhat_across(x) -> float:
    """ArviZ's R-hat across the :data:`N_ENSEMBLES` ensembles of ``(walker, draw)`` draws."""
    x = np.asarray(x).reshape(N_ENSEMBLES, -1, x.shape[1])  # (ensemble, walker, draw)
    return rhat(x.transpose(0, 2, 1).reshape(N_ENSEMBLES, -1))


def _merge(em: dict, post: LocationPosterior, ci: float, header: dict) -> dict:
    """Build a transponder's summary entry: the posterior's, the EM's kept under ``em``."""
    from ..io.geodesy import enu_to_geodetic

    d = post.to_dict(ci)
    out = {k: {**d[k], "interval_method": "posterior"}
           for k in ("east", "north", "depth", "sound_speed")}
    out["tat"] = {**d["tat"], **({"interval_method": "posterior"} if post.em.fit_tat else {})}
    out.update(sigma_ms=d["sigma_ms"]["mean"], weight_true=d["weight_true"]["mean"],
               n_spurious=d["n_spurious"], n=d["n"], ci=ci, interval_method="posterior",
               converged=post.converged)
    if em.get("lat") is not None:
        out["lat"], out["lon"], _ = enu_to_geodetic(d["east"]["mean"], d["north"]["mean"], 0.0,
                                                    header["lat"], header["lon"])
    else:
        out["lat"] = out["lon"] = None
    if "drift" in em:  # a deck-box log: the drift from the drop point, from the draws
        out.update(drift_from_draws(post.draws["east"], post.draws["north"], post.draws["depth"],
                                    header.get("depth"), ci=ci))
    out["posterior"] = {"sigma_ms": d["sigma_ms"], "weight_true": d["weight_true"],
                        "ess": d["ess"], "rhat": d["rhat"], "tau": d["tau"],
                        "diagnostics": d["diagnostics"]}
    out["em"] = em
    return out


def locate_survey_bayes(raw, *, tat=None, fit_tat=False, ci=0.95, outliers="uniform", ssp=None,
                        speed_intervals=0, n_walkers=None, min_ess=1000.0, max_steps=20000,
                        rng: RNGLike = None, progress="auto"):
    """Locate every transponder of a survey by EM, then sample each one's posterior.

    Parameters
    ----------
    raw : RawSurvey
    tat, fit_tat, ci, outliers, ssp, speed_intervals
        As for :func:`~bayes_mpem.survey_in.survey.locate_survey`.
    n_walkers, min_ess, max_steps, progress
        As for :func:`sample_location`.
    rng : None, int or numpy.random.Generator
        Seeds every transponder's chain (one stream, in table order).

    Returns
    -------
    summary : dict
        As :func:`~bayes_mpem.survey_in.survey.locate_survey`'s, each transponder's
        ``east``, ``north``, ``depth``, ``sound_speed`` (posterior mean, sd and
        equal-tailed interval, ``"interval_method": "posterior"``), ``n_spurious``,
        ``sigma_ms``, ``weight_true`` from the posterior, its ESS and
        diagnostics under ``posterior`` and the EM's entry under ``em``.
    classified : pandas.DataFrame
        As ``locate_survey``'s, with ``p_true``, ``p_spurious`` and ``label`` from
        the posterior and a ``p_true_sd`` column.
    posteriors : dict
        :class:`LocationPosterior` per transponder.
    """
    from .survey import locate_survey

    check_location_options(n_walkers=n_walkers, ci=ci, min_ess=min_ess, max_steps=max_steps)
    gen = as_generator(rng)
    located = locate_survey(raw, tat=tat, fit_tat=fit_tat, ci=ci, outliers=outliers, ssp=ssp,
                            speed_intervals=speed_intervals, one_at_a_time=True)
    summary, cls = located.summary, located.classified
    pings, _ = raw.to_pings()
    p_true = cls["p_true"].to_numpy(float).copy()
    p_sd = np.full(len(cls), np.nan)
    line_pos = pd.Series(np.arange(len(cls)), index=cls["line"].to_numpy())
    posteriors = {}
    for tid, fit in located.fits.items():
        em = summary["transponders"][tid]
        post = sample_location(pings, fit, n_walkers=n_walkers, ci=ci, min_ess=min_ess,
                               max_steps=max_steps, rng=gen, progress=progress)
        posteriors[tid] = post
        summary["transponders"][tid] = _merge(em, post, ci, raw.header)
        at = line_pos.loc[pings["line"].to_numpy()[post.rows]].to_numpy()
        p_true[at], p_sd[at] = post.p_true, post.p_true_sd
    cls = cls.copy()
    pinged = cls["label"] != "skipped"
    cls["p_true"], cls["p_spurious"] = p_true, 1.0 - p_true
    cls.loc[pinged, "label"] = np.where(p_true[pinged] >= 0.5, "true", "spurious")
    cls.insert(cls.columns.get_loc("p_spurious") + 1, "p_true_sd", p_sd)
    summary["method"] = (summary["method"].split(";")[0]
                         + "; emcee posterior from the EM solution, equal-tailed intervals")
    summary["interval_method"] = "posterior"
    summary["ci"] = ci
    return summary, cls, posteriors
