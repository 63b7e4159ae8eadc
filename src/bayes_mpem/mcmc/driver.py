"""The emcee driver: the :class:`LogPosterior` protocol, the sampling loop and the start ball."""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np

from ..exceptions import SamplingWarning
from .progress import SamplingProgress
from .summaries import ess_and_rhat


@runtime_checkable
class LogPosterior(Protocol):
    """What the samplers need of a posterior.

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

        Returns
        -------
        numpy.ndarray
        """
        ...  # pragma: no cover

    def __call__(self, theta: np.ndarray) -> np.ndarray:
        """Return the log posterior (up to a constant) of ``(W, ndim)``: ``(W,)``, -inf outside."""
        ...  # pragma: no cover


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


#: fewest steps between two checks of the stopping rule
MIN_BLOCK = 10


@dataclass(frozen=True)
class EnsembleRun:
    """One run of :func:`run_ensembles`: the kept chain and its diagnostics.

    Attributes
    ----------
    chain : numpy.ndarray
        ``(steps, walkers, ndim)`` after burn-in, the walkers of every ensemble side by side.
    log_prob : numpy.ndarray
        ``(steps, walkers)`` target log density of the kept chain.
    n_ensembles, n_walkers : int
        Ensembles, and walkers per ensemble.
    n_steps, burn : int
        Steps run per ensemble, and steps discarded as burn-in.
    acceptance : float
        Mean acceptance fraction.
    ess, rhat : float
        The smallest bulk ESS and the largest R-hat (ArviZ) at the last check.
    ess_by, rhat_by : dict
        Each checked series' bulk ESS and R-hat at the last check.
    converged : bool
        Whether the stopping rule was met before ``max_steps``.
    status : str
        The stopping rule's state, in words.
    """

    chain: np.ndarray = field(repr=False)
    log_prob: np.ndarray = field(repr=False)
    n_ensembles: int
    n_walkers: int
    n_steps: int
    burn: int
    acceptance: float
    ess: float
    rhat: float
    converged: bool
    status: str
    ess_by: dict = field(default_factory=dict, repr=False)
    rhat_by: dict = field(default_factory=dict, repr=False)


def _burn(samplers) -> int:
    """Burn-in: twice the largest autocorrelation time (emcee's estimate) over the ensembles.

    A coordinate that has not moved (a short chain whose walkers all rejected) has no
    autocorrelation (0/0 in emcee): its time is NaN, without NumPy's warning, and the burn
    falls back to half the chain.
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        tau = max(float(np.max(s.get_autocorr_time(tol=0, quiet=True))) for s in samplers)
    return int(math.ceil(2.0 * tau)) if math.isfinite(tau) else samplers[0].iteration // 2


def _sampler_class():
    """Return emcee's ``EnsembleSampler`` reading ``random_state`` as None (no snapshots).

    The chain is the same, seed for seed; why: ``docs/bayes.md`` (One driver).
    """
    import emcee

    class EnsembleSampler(emcee.EnsembleSampler):
        random_state = property(lambda self: None, emcee.EnsembleSampler.random_state.fset)

    return EnsembleSampler


class _HeldInterrupt:
    """emcee's target: a Ctrl-C inside the log density is held to the end of the block.

    emcee prints the parameters and a traceback for any exception its target raises,
    KeyboardInterrupt included. Here the interrupt is recorded, every later call returns
    ``-inf`` at once (the block's remaining steps reject every proposal and cost nothing),
    and :func:`run_ensembles` raises it again once ``run_mcmc`` returns, with the chain of
    that block discarded.
    """

    def __init__(self, target):
        self.target, self.interrupted = target, False

    def __call__(self, x):
        if not self.interrupted:
            try:
                return self.target(x)
            except KeyboardInterrupt:
                self.interrupted = True
        return np.full(np.shape(x)[0], -np.inf)


def _plan(moves, steps):
    """Tell the moves that can use it (:meth:`IndependenceMove.plan`) the steps ahead."""
    for m in moves:
        plan = getattr(m[0] if isinstance(m, tuple) else m, "plan", None)
        if plan is not None:
            plan(steps)


def _check(chain, natural, n_ens):
    """Bulk ESS and R-hat of each series of the kept chain (walkers as chains): two dicts."""
    series = (natural(chain) if natural is not None
              else {i: chain[:, :, i] for i in range(chain.shape[2])})
    return ess_and_rhat({k: np.ascontiguousarray(np.asarray(v).T) for k, v in series.items()},
                        n_ens)


def run_ensembles(target, starts, *, moves, gen: np.random.Generator, min_ess=1000.0,
                  max_rhat=1.01, n_draws=2000, max_steps=20000, check_every=500,
                  burn_in=False, natural=None, progress="auto", label="", warn=True,
                  stacklevel=2, start_log_prob=None) -> EnsembleRun:
    """Run emcee ensembles until the bulk ESS reaches ``min_ess`` and R-hat < ``max_rhat``.

    ESS and R-hat are ArviZ's over the kept chain, walkers as chains; with several
    ensembles R-hat compares the ensembles.

    Parameters
    ----------
    target : callable
        Log density of ``(W, ndim)`` points (``-inf`` outside the support).
    starts : list of numpy.ndarray
        ``(walkers, ndim)`` start of each ensemble.
    moves : list
        emcee's ``moves`` (:mod:`bayes_mpem.mcmc.moves`).
    gen : numpy.random.Generator
        Seeds each ensemble's emcee random state: same seed, same chain.
    min_ess : float, default 1000
        Target of the smallest bulk ESS (0: no target).
    max_rhat : float, default 1.01
        Bound of the largest R-hat.
    n_draws : int, default 2000
        The kept chain has at least this many draws (walkers x steps) before it stops.
    max_steps : int, default 20000
        Step cap per ensemble.
    check_every : int, default 500
        The most steps between two checks; between, the steps to the target are
        extrapolated from the ESS per step so far.
    burn_in : bool, default False
        Discard twice the autocorrelation time (emcee's estimate) as burn-in; an
        independence move started at proposal draws needs none.
    natural : callable, optional
        ``natural(chain)`` returns the ``(steps, walkers)`` series whose ESS and
        R-hat are checked (default: the coordinates).
    progress : bool or {"auto", "bar", "log"}
        See :mod:`bayes_mpem.mcmc.progress`.
    label : str
        Names the posterior in progress lines and the warning.
    warn : bool, default True
        Warn when ``max_steps`` is reached first.
    stacklevel : int, default 2
        Of the warning.
    start_log_prob : list of numpy.ndarray, optional
        ``target`` at each ensemble's start, when the caller has it (default: evaluated).

    Returns
    -------
    EnsembleRun

    Warns
    -----
    SamplingWarning
        When ``max_steps`` is reached before the stopping rule (and ``warn``).

    Examples
    --------
    >>> from bayes_mpem.mcmc.moves import default_moves
    >>> gen = np.random.default_rng(0)
    >>> target = lambda x: -0.5 * (x ** 2).sum(axis=1)
    >>> run = run_ensembles(target, [gen.standard_normal((16, 1))], moves=default_moves(),
    ...                     gen=gen, min_ess=400, burn_in=True, progress=False)
    >>> run.converged, run.ess >= 400
    (True, True)
    """
    import emcee

    n_ens, (n_walkers, ndim) = len(starts), starts[0].shape
    total_walkers = n_ens * n_walkers
    sampler_class = _sampler_class()
    samplers, states = [], []
    held = _HeldInterrupt(target)
    for i, start in enumerate(starts):
        sampler = sampler_class(n_walkers, ndim, held, vectorize=True, moves=moves)
        sampler.random_state = np.random.RandomState(int(gen.integers(2**32))).get_state()
        samplers.append(sampler)
        lp = target(start) if start_log_prob is None else np.asarray(start_log_prob[i], float)
        states.append(emcee.State(np.array(start, float), log_prob=lp))
    report = SamplingProgress(progress, label, min_ess=min_ess, max_rhat=max_rhat,
                              max_steps=max_steps, n_walkers=total_walkers)
    block = max(MIN_BLOCK, math.ceil(n_draws / total_walkers))
    burn, ess_min, rhat_max, converged = 0, 0.0, np.inf, False
    try:
        while True:
            block = min(block, max_steps - samplers[0].iteration)
            for i, sampler in enumerate(samplers):
                _plan(moves, block)
                states[i] = sampler.run_mcmc(states[i], block, skip_initial_state_check=True)
                if held.interrupted:
                    raise KeyboardInterrupt
            steps = samplers[0].iteration
            burn = min(_burn(samplers), steps - 4) if burn_in else 0
            kept = steps - burn
            chain = np.concatenate([s.get_chain(discard=burn) for s in samplers], axis=1)
            ess_by, rhat_by = _check(chain, natural, n_ens)
            ess_min, rhat_max = min(ess_by.values()), max(rhat_by.values())
            converged = bool(kept * total_walkers >= n_draws and ess_min >= min_ess
                             and rhat_max < max_rhat)
            per_step = max(ess_min, 1.0) / kept
            need = burn + max(1.1 * min_ess / per_step, n_draws / total_walkers)
            if ess_min >= min_ess and not rhat_max < max_rhat:
                need = max(need, 1.5 * steps)
            need = min(need, float(max_steps))
            report.update(steps, ess_min, rhat_max, expected=need)
            if converged or steps >= max_steps:
                break
            block = int(np.clip(math.ceil(need - steps), max(MIN_BLOCK, steps // 10),
                                check_every))
    finally:
        report.close()
    steps = samplers[0].iteration
    report.finish(steps=steps, converged=converged, ess=ess_min, rhat=rhat_max)
    status = (f"{steps} steps x {total_walkers} walkers, burn-in {burn}, bulk ESS "
              f"{ess_min:,.0f} (target {min_ess:,.0f}), R-hat {rhat_max:.3f} "
              f"(target < {max_rhat:g})")
    if warn and not converged:
        warnings.warn(f"{label}: the chain reached max_steps={max_steps} before meeting its "
                      f"stopping rule: {status}; estimates may be unreliable",
                      SamplingWarning, stacklevel=stacklevel + 1)
    log_prob = np.concatenate([s.get_log_prob(discard=burn) for s in samplers], axis=1)
    return EnsembleRun(chain=chain, log_prob=log_prob, n_ensembles=n_ens, n_walkers=n_walkers,
                       n_steps=steps, burn=burn,
                       acceptance=float(np.mean([s.acceptance_fraction for s in samplers])),
                       ess=ess_min, rhat=rhat_max, converged=converged, status=status,
                       ess_by=ess_by, rhat_by=rhat_by)
