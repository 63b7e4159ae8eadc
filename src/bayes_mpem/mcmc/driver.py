"""The emcee driver: the :class:`LogPosterior` protocol, the moves and the sampling loop.

:func:`run_ensemble` runs one ensemble in blocks until the kept chain is long
enough, :func:`run_ensembles` several from their own start balls and seeds, and
:func:`place_walkers` fills a start ball inside the prior. See
:mod:`bayes_mpem.mcmc`.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Protocol, runtime_checkable

import numpy as np

from ..exceptions import SamplingWarning
from .convergence import ess_bulk
from .progress import SamplingProgress

if TYPE_CHECKING:  # emcee is imported when an ensemble runs (0.5 s)
    import emcee


@runtime_checkable
class LogPosterior(Protocol):
    """What :func:`run_ensemble` needs of a posterior.

    Attributes
    ----------
    names : tuple of str
        Parameter names, in the order of the columns of ``theta``.
    ndim : int
        Number of sampled parameters (``len(names)``).
    label : str
        Names the posterior in the progress bar and in messages.
    """

    names: tuple[str, ...]
    ndim: int
    label: str

    def start(self, n_walkers: int, gen: np.random.Generator) -> np.ndarray:
        """Return initial positions, ``(n_walkers, ndim)``, inside the support.

        Parameters
        ----------
        n_walkers : int
        gen : numpy.random.Generator
            The stream to draw the positions from.

        Returns
        -------
        numpy.ndarray
        """
        ...  # pragma: no cover

    def __call__(self, theta: np.ndarray) -> np.ndarray:
        """Return the log posterior (up to a constant) of ``(W, ndim)``: ``(W,)``, -inf outside."""
        ...  # pragma: no cover


# ------------------------------------------------------------------ the loop


def _bulk_ess_min(chain):
    """Smallest bulk ESS (ArviZ's estimator) of the columns of a ``(steps, walkers, dim)`` chain."""
    return float(min(ess_bulk(chain[:, :, i].T) for i in range(chain.shape[2])))


@dataclass(frozen=True)
class EnsembleRun:
    """One emcee ensemble run to its stopping rule (or to ``max_steps``).

    Attributes
    ----------
    sampler : emcee.EnsembleSampler
    burn : int
        Steps discarded as burn-in: ``ceil(2 max tau)``.
    tau : numpy.ndarray
        Autocorrelation time of each parameter on the kept chain.
    converged : bool
        Whether the stopping rule was met before ``max_steps``.
    status : str
        How far the run got against each stopping test (for the warning).
    """

    sampler: emcee.EnsembleSampler = field(repr=False)
    burn: int
    tau: np.ndarray
    converged: bool
    status: str

    @property
    def chain(self) -> np.ndarray:
        """The kept chain, ``(steps, walkers, ndim)``."""
        return self.sampler.get_chain(discard=self.burn)

    @property
    def log_prob(self) -> np.ndarray:
        """Log posterior of the kept chain, ``(steps, walkers)``."""
        return self.sampler.get_log_prob(discard=self.burn)

    @property
    def acceptance(self) -> float:
        """Mean acceptance fraction over the walkers."""
        return float(np.mean(self.sampler.acceptance_fraction))

    @property
    def n_steps(self) -> int:
        """Steps run, burn-in included."""
        return int(self.sampler.iteration)


def place_walkers(draw, inside, n_walkers: int, ndim: int, *, scale, rounds: int):
    """Fill a start ball with candidates inside the support, halving the scatter each round.

    Parameters
    ----------
    draw : callable
        ``draw(scale)`` returns ``(n_walkers, ndim)`` candidates scattered by ``scale``.
    inside : callable
        ``inside(candidates)`` returns a boolean mask of those inside the support.
    n_walkers, ndim : int
    scale : float or numpy.ndarray
        The first round's scatter (an array is halved in place).
    rounds : int
        Rounds of candidates before giving up.

    Returns
    -------
    numpy.ndarray or None
        ``(n_walkers, ndim)``, or None when ``rounds`` rounds left walkers unplaced.

    Examples
    --------
    >>> gen = np.random.default_rng(0)
    >>> ball = place_walkers(lambda s: s * gen.standard_normal((8, 2)),
    ...                      lambda c: np.all(c > -1.0, axis=1), 8, 2, scale=2.0, rounds=20)
    >>> ball.shape, bool(np.all(ball > -1.0))
    ((8, 2), True)
    """
    out = np.empty((n_walkers, ndim))
    filled = 0
    for _ in range(rounds):
        cand = draw(scale)
        good = cand[inside(cand)]
        take = min(len(good), n_walkers - filled)
        out[filled:filled + take] = good[:take]
        filled += take
        if filled == n_walkers:
            return out
        scale *= 0.5
    return None


#: fewest steps between two checks of the stopping rule (a check costs ~30 steps' work)
MIN_BLOCK = 50


def next_block(iteration: int, burn: int, tau: float, n_walkers: int, *, tau_factor: float,
               min_ess: float, ess_bulk: float, check_every: int) -> int:
    """Plan the next check: the steps to where the stopping rule should hold, plus 5 %.

    The kept chain needs ``tau_factor`` autocorrelation times and an ESS of
    ``min_ess`` (by emcee's ``steps x walkers / tau``, scaled up by the ratio of
    that estimate to ArviZ's bulk ESS when the bulk ESS fell short); at least
    :data:`MIN_BLOCK` steps and at most ``check_every``, so a poor early estimate of
    ``tau`` costs at most one block.

    Parameters
    ----------
    iteration, burn : int
        Steps run so far, and the burn-in at the current estimate.
    tau : float
        Largest autocorrelation time on the kept chain (inf when unknown).
    n_walkers : int
    tau_factor, min_ess : float
        The stopping rule.
    ess_bulk : float
        Smallest bulk ESS at the last check where it was computed, else 0.
    check_every : int
        The largest block.

    Returns
    -------
    int

    Examples
    --------
    >>> next_block(250, 30, 16.0, 24, tau_factor=50, min_ess=1000, ess_bulk=0.0,
    ...            check_every=250)
    250
    >>> next_block(750, 32, 16.0, 24, tau_factor=50, min_ess=1000, ess_bulk=0.0,
    ...            check_every=250)
    124
    """
    if not np.isfinite(tau):
        return check_every
    kept = max(iteration - burn, 1)
    scale = 1.0
    if ess_bulk > 0:
        scale = max(1.0, (kept * n_walkers / tau) / ess_bulk)
    need = burn + max(tau_factor * tau, scale * min_ess * tau / n_walkers)
    return int(np.clip(np.ceil(1.05 * need) - iteration, MIN_BLOCK, check_every))


def run_ensemble(post: LogPosterior, start, *, seed, moves=None, tau_factor=50.0,
                 min_ess=1000.0, max_steps=20000, check_every=250,
                 progress="auto"):
    """Run one emcee ensemble until it is long enough by three measures.

    The kept chain must be ``tau_factor`` autocorrelation times long, and its
    smallest ESS must reach ``min_ess`` both by emcee's ``steps x walkers / tau``
    and by ArviZ's rank-normalised bulk ESS (walkers as chains).

    Parameters
    ----------
    post : LogPosterior
        The target; only ``label`` and ``__call__`` are used here.
    start : numpy.ndarray
        ``(n_walkers, ndim)`` initial positions.
    seed : int
        Seeds emcee's random state.
    moves : list, optional
        emcee moves (default: :func:`default_moves`).
    tau_factor : float, default 50
        Kept steps needed, in autocorrelation times.
    min_ess : float, default 1000
        Per ensemble; 0 to stop on ``tau_factor`` alone.
    max_steps : int, default 20000
        Step cap.
    check_every : int, default 250
        The most steps between two checks of the stopping rule; after the first
        block, the next check is planned where the rule should hold
        (:func:`next_block`).
    progress : bool or {"auto", "bar", "log"}
        A bar with the expected steps as its total (``"bar"``, True), one line of
        progress every few seconds on standard error (``"log"``), either as standard
        error is a terminal or not (``"auto"``), or nothing (False); see
        :mod:`bayes_mpem.mcmc.progress`.

    Returns
    -------
    sampler : emcee.EnsembleSampler
    burn : int
        Steps discarded as burn-in: ``ceil(2 max tau)``.
    tau : numpy.ndarray
        Autocorrelation time of each parameter on the kept chain.
    converged : bool
    status : str
        How far the run got against each stopping test (for the warning).

    See Also
    --------
    run_ensembles : several ensembles, as an :class:`EnsembleRun` each.
    """
    import emcee  # here: importing emcee costs 0.5 s (scipy.stats), idle on independence chains

    from .moves import default_moves

    n_walkers, ndim = start.shape
    sampler = emcee.EnsembleSampler(n_walkers, ndim, post, vectorize=True,
                                    moves=moves or default_moves())
    sampler.random_state = np.random.RandomState(seed % 2**32).get_state()
    report = SamplingProgress(progress, post.label, n_walkers=n_walkers,
                              tau_factor=tau_factor, min_ess=min_ess, max_steps=max_steps,
                              check_every=check_every)
    state, burn, tau, converged = start, 0, np.full(ndim, np.inf), False
    ess_bulk, block = None, check_every
    try:
        while sampler.iteration < max_steps:
            block = min(block, max_steps - sampler.iteration)
            state = sampler.run_mcmc(state, block, progress=False)
            tau_all = sampler.get_autocorr_time(tol=0, quiet=True)
            burn = int(np.ceil(2.0 * np.max(tau_all)))
            kept = sampler.iteration - burn
            if kept > 0:
                tau = sampler.get_autocorr_time(discard=burn, tol=0, quiet=True)
            report.update(sampler.iteration, burn, float(np.max(tau)))
            long_enough = (kept > 0 and np.all(np.isfinite(tau))
                           and kept >= tau_factor * np.max(tau)
                           and kept * n_walkers / np.max(tau) >= min_ess)
            if long_enough:
                ess_bulk = (_bulk_ess_min(sampler.get_chain(discard=burn)) if min_ess > 0
                            else np.inf)
                if ess_bulk >= min_ess:
                    converged = True
                    break
            block = next_block(sampler.iteration, burn, np.max(tau), n_walkers,
                               tau_factor=tau_factor, min_ess=min_ess,
                               ess_bulk=ess_bulk or 0.0, check_every=check_every)
    finally:
        report.close()
    kept = sampler.iteration - burn
    ess = max(kept, 0) * n_walkers / np.max(tau)
    report.finish(step=sampler.iteration, converged=converged, ess=ess, ess_bulk=ess_bulk)
    status = (f"{sampler.iteration} steps, burn-in {burn}, kept {kept} = "
              f"{kept / np.max(tau):.1f} tau (needs {tau_factor:g}), emcee ESS "
              f"{ess:.0f} and bulk ESS {ess_bulk or 0:.0f} (need {min_ess:g})")
    return sampler, burn, tau, converged, status


def run_ensembles(post: LogPosterior, *, n_walkers: int, gen: np.random.Generator,
                  n_ensembles: int = 1, where: str = "", stacklevel: int = 2,
                  **options) -> list[EnsembleRun]:
    """Run independent ensembles, each from ``post.start`` and its own seed from ``gen``.

    Draws from ``gen`` in this order, per ensemble: the start ball, then the seed.

    Parameters
    ----------
    post : LogPosterior
        The target.
    n_walkers : int
        Walkers per ensemble.
    gen : numpy.random.Generator
        The only source of randomness.
    n_ensembles : int, default 1
        Independent ensembles.
    where : str, default ""
        Names the posterior in the warning (e.g. ``"beacon 4"``); default its ``label``.
    stacklevel : int, default 2
        Of the warning, counted from the caller of this function.
    **options
        ``moves``, ``tau_factor``, ``min_ess``, ``max_steps``, ``progress``, as
        for :func:`run_ensemble`.

    Returns
    -------
    list of EnsembleRun

    Warns
    -----
    SamplingWarning
        When an ensemble reaches ``max_steps`` before its stopping rule.
    """
    runs = []
    for _ in range(int(n_ensembles)):
        start = post.start(n_walkers, gen)
        runs.append(EnsembleRun(*run_ensemble(post, start, seed=int(gen.integers(2**63)),
                                              **options)))
    if not all(r.converged for r in runs):
        max_steps = options.get("max_steps", 20000)
        warnings.warn(f"{where or post.label}: the chain reached max_steps={max_steps} before "
                      "meeting its stopping rule: "
                      + "; ".join(r.status for r in runs if not r.converged)
                      + "; estimates may be unreliable",
                      SamplingWarning, stacklevel=stacklevel + 1)
    return runs
