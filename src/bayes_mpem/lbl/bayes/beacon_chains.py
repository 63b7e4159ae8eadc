"""The chains of one beacon's posterior: emcee, an independence proposal or DE (docs/bayes.md)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ...mcmc import laplace_proposal, run_ensembles
from ...mcmc.progress import progress_mode, say
from .posterior import PARAMS, SAMPLERS, BeaconPosterior

__all__ = ["SAMPLERS", "BeaconChains", "FreeCoordinates", "beacon_chains"]
#: the pilot keeps the independence move at or above this bulk ESS per draw
MIN_ESS_PER_DRAW = 0.2
#: ... and at or below this R-hat (over 32 chains of 32 draws: 1.02-1.04 for a good fit)
MAX_PILOT_RHAT = 1.1
#: walkers and steps of the pilot (discarded)
PILOT_WALKERS, PILOT_STEPS = 32, 32
#: with ``"auto"``, an independence move that has not met the stopping rule after this many
#: steps (a proposal that fits poorly in a region the pilot missed) hands over to DE
INDEPENDENCE_BUDGET = 2000
#: degrees of freedom of the Student-t proposal
PROPOSAL_DF = 10.0
#: walkers of the independence move
N_WALKERS = 16
#: the target is evaluated in chunks of at most this many points x ranges
_CHUNK_CELLS = 4_000_000


class FreeCoordinates:
    """The beacon posterior in unconstrained coordinates: the weights as log-ratios to ``w_ol``.

    The density there is the posterior times the Jacobian ``w_dp w_mp w_ol``.
    """

    def __init__(self, post: BeaconPosterior):
        self.post = post
        self.weights = post.priors == "learned"
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
        if not self.weights:
            return theta, np.zeros(theta.shape[0])
        a_dp, a_mp = theta[:, -2], theta[:, -1]
        top = np.maximum(np.maximum(a_dp, a_mp), 0.0)
        e_dp, e_mp, e_ol = np.exp(a_dp - top), np.exp(a_mp - top), np.exp(-top)
        total = e_dp + e_mp + e_ol
        log_jac = a_dp + a_mp - 3.0 * (top + np.log(total))  # log(w_dp w_mp w_ol)
        theta[:, -2], theta[:, -1] = e_dp / total, e_mp / total
        return theta, log_jac

    def __call__(self, u) -> np.ndarray:
        """Log density in free coordinates of ``(n, ndim)`` points, in chunks."""
        u = np.atleast_2d(u)
        out = np.empty(u.shape[0])
        for i in range(0, u.shape[0], self._chunk):
            theta, log_jac = self.from_free(u[i:i + self._chunk])
            out[i:i + self._chunk] = self.post(theta) + log_jac
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
    """The kept chain of one beacon, in the posterior's coordinates.

    Attributes
    ----------
    sampler : {"independence", "ensemble"}
    chain : numpy.ndarray
        ``(steps, walkers, ndim)`` in :attr:`BeaconPosterior.names` coordinates.
    log_prob : numpy.ndarray
        ``(steps, walkers)`` log posterior in those coordinates.
    run : EnsembleRun
        The driver's record (ESS, R-hat, steps, acceptance, status).
    info : dict
        ``moves``, ``fallback`` (why the independence move was not kept, or None),
        ``proposal_df`` and ``pilot`` (its ESS per draw and R-hat) when one ran.
    """

    sampler: str
    chain: np.ndarray = field(repr=False)
    log_prob: np.ndarray = field(repr=False)
    run: object = field(repr=False)
    info: dict = field(default_factory=dict)


def sampled(post: BeaconPosterior) -> list:
    """List the natural parameters that vary over the draws, in :data:`PARAMS` order."""
    return [k for k in PARAMS if k in ("d0", "sigma_mp")
            or (k == "sigma_dp" and post.sigma_dp is None)
            or (k.startswith("w_") and post.priors == "learned")]


def _natural(post: BeaconPosterior, free: FreeCoordinates):
    """``natural(chain)``: the sampled natural parameters of a free-coordinates chain."""
    names = sampled(post)

    def natural(chain):
        theta, _ = free.from_free(chain.reshape(-1, chain.shape[-1]))
        nat = post.unpack(theta)
        return {k: nat[k][:, 0].reshape(chain.shape[:2]) for k in names}

    return natural


def _proposal_start(free: FreeCoordinates, proposal, n: int, gen, rounds: int = 1000):
    """``n`` proposal draws inside the support, and the target there: no burn-in needed."""
    out = proposal.draw(n, gen)
    lp = free(out)
    for _ in range(rounds):
        bad = np.flatnonzero(~np.isfinite(lp))
        if bad.size == 0:
            return out, lp
        out[bad] = proposal.draw(bad.size, gen)
        lp[bad] = free(out[bad])
    raise ValueError(f"the proposal put {rounds} draws in a row outside the support")


def beacon_chains(post: BeaconPosterior, gen: np.random.Generator, *, sampler="auto",
                  n_walkers=None, min_ess=1000.0, max_steps=20000, n_ensembles=None,
                  n_draws=2000, progress="auto", where="", stacklevel=3) -> BeaconChains:
    """Sample ``post`` (its :attr:`~BeaconPosterior.em` set) with the move ``sampler`` chooses.

    Parameters
    ----------
    sampler : {"auto", "independence", "ensemble"}
        The move (``docs/bayes.md``, Which move); ``n_ensembles > 1`` implies the ensemble.
    n_walkers : int, optional
        Default :data:`N_WALKERS` (independence) or ``max(24, 4 ndim)`` (ensemble).
    min_ess, max_steps, n_draws
        The stopping rule (:func:`~bayes_mpem.mcmc.run_ensembles`).
    n_ensembles : int, optional
        Independent ensembles of differential evolution (R-hat compares them; default
        2); more than one implies differential evolution.
    where : str
        Names the beacon in progress lines and warnings (default its label).
    stacklevel : int
        Of the :class:`~bayes_mpem.exceptions.SamplingWarning`.
    """
    from ...mcmc.moves import (
        DEFAULT_MOVES_LABEL,
        INDEPENDENCE_LABEL,
        default_moves,
        independence_move,
    )

    free = FreeCoordinates(post)
    natural = _natural(post, free)
    opts = {"gen": gen, "min_ess": min_ess, "max_steps": max_steps, "n_draws": n_draws,
            "natural": natural, "stacklevel": stacklevel, "label": where or post.label}
    info = {"fallback": None}
    if sampler != "ensemble" and (n_ensembles or 1) == 1:
        start = free.to_free(post._inside(post.theta_from(post.em.to_dict())))[0]
        proposal = laplace_proposal(free, start, free.rough_sd(), df=PROPOSAL_DF)
        walkers = int(n_walkers or N_WALKERS)
        if proposal is None:
            info["fallback"] = ("no Gaussian approximation at the mode (Hessian not negative "
                                "definite)")
        elif sampler == "auto":
            start, lp = _proposal_start(free, proposal, PILOT_WALKERS, gen)
            pilot = run_ensembles(free, [start], start_log_prob=[lp],
                                  moves=independence_move(proposal), gen=gen,
                                  min_ess=np.inf, max_steps=PILOT_STEPS,
                                  n_draws=PILOT_WALKERS * PILOT_STEPS, natural=natural,
                                  progress=False, warn=False)
            per_draw = pilot.ess / pilot.chain[:, :, 0].size
            info["pilot"] = {"ess_per_draw": per_draw, "rhat": pilot.rhat,
                             "draws": int(pilot.chain[:, :, 0].size)}
            if per_draw < MIN_ESS_PER_DRAW or not pilot.rhat <= MAX_PILOT_RHAT:
                info["fallback"] = (
                    f"the Laplace proposal fits poorly (pilot of {PILOT_WALKERS} x {PILOT_STEPS} "
                    f"draws: ESS {per_draw:.2f} per draw, R-hat {pilot.rhat:.3f}, "
                    f"acceptance {pilot.acceptance:.2f})")
        if info["fallback"] is None:
            budget = sampler == "auto" and max_steps > INDEPENDENCE_BUDGET
            start, lp = _proposal_start(free, proposal, walkers, gen)
            run = run_ensembles(free, [start], start_log_prob=[lp],
                                moves=independence_move(proposal), progress=progress,
                                **{**opts, "max_steps": INDEPENDENCE_BUDGET if budget
                                   else max_steps, "warn": not budget})
            if run.converged or not budget:
                info.update(moves=INDEPENDENCE_LABEL, proposal_df=PROPOSAL_DF)
                return _chains("independence", free, run, info)
            info["fallback"] = (f"the independence move did not meet the stopping rule in "
                                f"{INDEPENDENCE_BUDGET} steps ({run.status})")
        if progress_mode(progress) == "log":
            say(post.label, f"{info['fallback']}; differential evolution instead")
    walkers = int(n_walkers or max(24, 4 * post.ndim))
    starts = [free.to_free(post.start(walkers, gen)) for _ in range(int(n_ensembles or 2))]
    run = run_ensembles(free, starts, moves=default_moves(), burn_in=True, progress=progress,
                        **opts)
    info.update(moves=DEFAULT_MOVES_LABEL)
    return _chains("ensemble", free, run, info)


def _chains(sampler, free, run, info) -> BeaconChains:
    """Return the run's chain in the posterior's coordinates, with its log density there."""
    steps, walkers, ndim = run.chain.shape
    theta, log_jac = free.from_free(run.chain.reshape(-1, ndim))
    return BeaconChains(sampler=sampler, chain=theta.reshape(steps, walkers, ndim),
                        log_prob=run.log_prob - log_jac.reshape(steps, walkers), run=run,
                        info=info)
