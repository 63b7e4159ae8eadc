"""The chains of one beacon's posterior: independence chains from a Laplace proposal, or emcee.

:func:`beacon_chains` is the sampler choice of
:func:`~bayes_mpem.lbl.bayes.beacon_sampling.sample_beacon` and of the
simulation-based calibration (:mod:`bayes_mpem.lbl.bayes.sbc`):

``"independence"``
    Independence Metropolis-Hastings (:mod:`bayes_mpem.mcmc.independence`)
    in free coordinates (:class:`FreeCoordinates`: ``d0`` and the log scales as
    they are, the weights as log-ratios to ``w_ol``, with the Jacobian), from a
    Student-t (10 degrees of freedom) at the posterior mode with the inverse
    Hessian as its scale; four chains, each started at a draw of the proposal,
    until the smallest bulk ESS reaches ``min_ess`` and R-hat < 1.01.
``"ensemble"``
    emcee's differential evolution from a ball around the EM solution
    (:func:`bayes_mpem.mcmc.run_ensembles`), as before this choice existed.
``"auto"`` (the default)
    Independence chains when the proposal fits: a pilot (4 chains of
    ``n_draws / 8`` draws, 4 x 250 by default, then discarded, so that the draws
    kept play no part in the choice) must give at least
    :data:`MIN_ESS_PER_DRAW` bulk ESS per draw and R-hat below
    :data:`MAX_FIRST_RHAT`; otherwise (no Gaussian approximation at the mode, a
    skewed or multimodal posterior, typically a beacon with few multipath
    replies) the ensemble, from scratch. Either sampler is exact: the
    choice only decides how fast the draws come; it is recorded in the result's
    diagnostics (``sampler``, and ``fallback`` with the reason).
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass, field

import numpy as np

from ...exceptions import SamplingWarning
from ...mcmc.independence import laplace_proposal, run_independence
from ...mcmc.progress import progress_bar, progress_mode, say
from .posterior import SAMPLERS, BeaconPosterior

__all__ = ["SAMPLERS", "BeaconChains", "FreeCoordinates", "beacon_chains"]
#: independence chains are used ("auto") when their pilot gives at least this
#: bulk ESS per draw (a well-fitting proposal gives 0.6-0.9; a sticky one below 0.1)
MIN_ESS_PER_DRAW = 0.2
#: ... and R-hat below this over the four chains of the pilot
MAX_FIRST_RHAT = 1.05
#: degrees of freedom of the Student-t proposal
PROPOSAL_DF = 10.0
#: independence chains
N_CHAINS = 4
#: the target is evaluated in chunks of at most this many proposals x ranges
_CHUNK_CELLS = 4_000_000


class FreeCoordinates:
    """The beacon posterior in unconstrained coordinates: the weights as log-ratios to ``w_ol``.

    ``u = (d0, log_sigma_mp[, log_sigma_dp][, log(w_dp / w_ol), log(w_mp / w_ol)])``;
    the density in ``u`` is the posterior times the Jacobian
    ``|d(w_dp, w_mp) / d(a_dp, a_mp)| = w_dp w_mp w_ol``.

    Parameters
    ----------
    post : BeaconPosterior

    Attributes
    ----------
    on_chunk : callable or None
        Called with the number of points after each chunk is evaluated (progress).
    """

    def __init__(self, post: BeaconPosterior):
        self.post = post
        self.weights = post.priors == "learned"
        self.on_chunk = None
        self._chunk = max(16, _CHUNK_CELLS // max(post.geom.n, 1))

    def to_free(self, theta) -> np.ndarray:
        """Free coordinates of points in the sampler's coordinates.

        Parameters
        ----------
        theta : array_like
            ``(n, ndim)``, inside the support.

        Returns
        -------
        numpy.ndarray
            ``(n, ndim)``.
        """
        u = np.array(np.atleast_2d(theta), dtype=float)
        if self.weights:
            w_ol = 1.0 - u[:, -2] - u[:, -1]
            u[:, -2:] = np.log(u[:, -2:] / w_ol[:, None])
        return u

    def from_free(self, u):
        """Sampler coordinates of points in free coordinates, and the log-Jacobian.

        Parameters
        ----------
        u : array_like
            ``(n, ndim)``.

        Returns
        -------
        theta : numpy.ndarray
            ``(n, ndim)``.
        log_jac : numpy.ndarray
            ``(n,)``: ``log(w_dp w_mp w_ol)`` (0 with equal priors).
        """
        theta = np.array(np.atleast_2d(u), dtype=float)
        log_jac = np.zeros(theta.shape[0])
        if self.weights:
            a = np.column_stack([theta[:, -2], theta[:, -1], np.zeros(theta.shape[0])])
            a -= a.max(axis=1, keepdims=True)
            w = np.exp(a)
            w /= w.sum(axis=1, keepdims=True)
            theta[:, -2:] = w[:, :2]
            with np.errstate(divide="ignore"):
                log_jac = np.log(w).sum(axis=1)
        return theta, log_jac

    def __call__(self, u) -> np.ndarray:
        """Log density in free coordinates of ``(n, ndim)`` points, in chunks."""
        u = np.atleast_2d(u)
        out = np.empty(u.shape[0])
        for i in range(0, u.shape[0], self._chunk):
            theta, log_jac = self.from_free(u[i:i + self._chunk])
            out[i:i + self._chunk] = self.post(theta) + log_jac
            if self.on_chunk is not None:
                self.on_chunk(theta.shape[0])
        return out

    def rough_sd(self) -> np.ndarray:
        """Large-sample standard deviations at the EM solution, in free coordinates."""
        post, em = self.post, self.post.em
        sd = post.rough_sd()
        if self.weights:
            n = max(em.n, 1)
            w = {c: max(em.weights[c], 1e-3) for c in ("dp", "mp", "ol")}
            sd[-2:] = [min(3.0, np.sqrt(1 / (n * w[c]) + 1 / (n * w["ol"]))) for c in ("dp", "mp")]
        return sd


@dataclass(frozen=True)
class BeaconChains:
    """Kept draws of one beacon, in the sampler's coordinates, by whichever sampler ran.

    Attributes
    ----------
    sampler : {"independence", "ensemble"}
    groups : list of numpy.ndarray
        ``(steps, chains, ndim)`` per independent group: one group of four
        independence chains, or one per emcee ensemble (its walkers as chains).
    log_prob : list of numpy.ndarray
        ``(steps, chains)`` log posterior (sampler's coordinates) of each group.
    info : dict
        ``n_chains`` (per group), ``n_steps``, ``burn``, ``acceptance``,
        ``converged``, ``fallback`` (the reason the independence chains were
        not kept, or None) and, for the independence chains, ``proposal_df``.
    """

    sampler: str
    groups: list = field(repr=False)
    log_prob: list = field(repr=False)
    info: dict = field(default_factory=dict)


def _independence(post: BeaconPosterior, gen, *, min_ess, max_steps, first, check, progress):
    """Independence chains, or ``(None, reason)`` when the proposal does not fit."""
    free = FreeCoordinates(post)
    start = free.to_free(post._inside(post.theta_from(post.em.to_dict())))[0]
    proposal = laplace_proposal(free, start, free.rough_sd(), df=PROPOSAL_DF)
    if proposal is None:
        return None, "no Gaussian approximation at the mode (Hessian not negative definite)"

    mode = progress_mode(progress)
    t0 = time.perf_counter()
    pilot = max(4, first // 2) if check else 0
    bar = (progress_bar(mode, post.label, total=N_CHAINS * (pilot + first)) if mode == "bar"
           else None)
    if bar is not None:
        free.on_chunk = bar.update
    try:
        if check:  # decided on a pilot, then discarded: the kept draws do not choose
            test = run_independence(free, proposal, gen=gen, n_chains=N_CHAINS, first=pilot,
                                    min_ess=np.inf, max_draws=pilot)
            per_draw = test.ess / test.chain[:, :, 0].size
            if per_draw < MIN_ESS_PER_DRAW or not test.rhat < MAX_FIRST_RHAT:
                reason = (f"the Laplace proposal fits poorly (pilot of {N_CHAINS} x {pilot} "
                          f"draws: ESS {per_draw:.2f} per draw, R-hat {test.rhat:.3f}, "
                          f"acceptance {test.acceptance:.2f})")
                _say(mode, post.label, f"{reason}; sampling with the ensemble instead")
                return None, reason
        run = run_independence(free, proposal, gen=gen, n_chains=N_CHAINS, first=first,
                               min_ess=min_ess, max_draws=max_steps)
    finally:
        if bar is not None:
            bar.close()
    d, c, k = run.chain.shape
    how = "done" if run.converged else f"stopped at max_steps={max_steps}"
    _say(mode, post.label, f"{how}, {d} draws x {c} independence chains, bulk ESS {run.ess:.0f} "
                           f"of {min_ess:g}, {time.perf_counter() - t0:.1f} s")
    theta, log_jac = free.from_free(run.chain.reshape(-1, k))
    theta = theta.reshape(d, c, k)
    return BeaconChains(
        sampler="independence", groups=[theta], log_prob=[run.log_prob - log_jac.reshape(d, c)],
        info={"n_chains": c, "n_steps": d, "burn": 0, "acceptance": run.acceptance,
              "converged": run.converged, "fallback": None, "proposal_df": PROPOSAL_DF,
              "status": f"{d} draws x {c} chains, bulk ESS {run.ess:.0f} (need {min_ess:g}), "
                        f"R-hat {run.rhat:.3f} (need < 1.01)"}), None


def _say(mode, label, text):
    """One progress line, in log mode (:func:`bayes_mpem.mcmc.progress.say`)."""
    if mode == "log":
        say(label, text)


def beacon_chains(post: BeaconPosterior, gen: np.random.Generator, *, sampler="auto",
                  n_walkers=None, moves=None, tau_factor=50.0, min_ess=1000.0,
                  max_steps=20000, n_ensembles=1, n_draws=2000, progress="auto", where="",
                  stacklevel=3) -> BeaconChains:
    """Sample ``post`` (its :attr:`~BeaconPosterior.em` set) with the sampler chosen by ``sampler``.

    Parameters
    ----------
    post : BeaconPosterior
    gen : numpy.random.Generator
    sampler : {"auto", "independence", "ensemble"}
        See the module's description. Moves, a number of walkers or more than one
        ensemble imply the ensemble.
    n_walkers, moves, tau_factor, n_ensembles, progress
        Of the ensemble (:func:`~bayes_mpem.mcmc.run_ensembles`).
    min_ess, max_steps
        The stopping rule of either (``max_steps``: draws per independence chain).
    n_draws : int, default 2000
        The independence chains run at least ``n_draws`` draws in all (so that
        the draws kept need no thinning), more if their ESS falls short.
    where : str
        Names the beacon in warnings.
    stacklevel : int
        Of the ensemble's :class:`~bayes_mpem.exceptions.SamplingWarning`.

    Returns
    -------
    BeaconChains
    """
    fallback = None
    if sampler != "ensemble" and moves is None and n_walkers is None and n_ensembles == 1:
        first = max(4, min(max_steps, -(-int(n_draws) // N_CHAINS)))
        chains, fallback = _independence(post, gen, min_ess=min_ess, max_steps=max_steps,
                                         first=first, check=sampler == "auto",
                                         progress=progress)
        if chains is not None:
            if not chains.info["converged"]:
                warnings.warn(f"{where}: the independence chains reached max_steps={max_steps} "
                              f"before meeting their stopping rule: {chains.info['status']}; "
                              "estimates may be unreliable", SamplingWarning,
                              stacklevel=stacklevel)
            return chains
    from ...mcmc import run_ensembles

    n_walkers = int(n_walkers or max(24, 4 * post.ndim))
    runs = run_ensembles(post, n_walkers=n_walkers, gen=gen, n_ensembles=n_ensembles,
                         where=where, stacklevel=stacklevel, moves=moves,
                         tau_factor=tau_factor, min_ess=min_ess, max_steps=max_steps,
                         progress=progress)
    return BeaconChains(
        sampler="ensemble", groups=[r.chain for r in runs], log_prob=[r.log_prob for r in runs],
        info={"n_chains": n_walkers, "n_steps": max(r.n_steps for r in runs),
              "burn": int(max(r.burn for r in runs)),
              "acceptance": float(np.mean([r.acceptance for r in runs])),
              "converged": bool(all(r.converged for r in runs)), "fallback": fallback})
