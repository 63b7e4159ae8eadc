"""The emcee driver shared by both posteriors: one protocol, one loop, one set of summaries.

Both problems sample a log-posterior vectorised over walkers: the beacon of
:class:`bayes_mpem.lbl.posterior.BeaconPosterior` and the transponder location
of :class:`bayes_mpem.survey_in.posterior.LocationLogPosterior`. Each satisfies
:class:`LogPosterior` (parameter ``names``, ``ndim``, a ``label``, a
``start`` ball and ``__call__``), and this module does the rest:

- :func:`run_ensemble` runs one ensemble in blocks until the kept chain is
  ``tau_factor`` autocorrelation times long and its smallest ESS, by emcee's
  ``steps x walkers / tau`` and by ArviZ's bulk estimate, reaches ``min_ess``;
  :func:`run_ensembles` runs several, each from its own start ball and seed;
- the move policy: :func:`default_moves` (LBL) and :func:`de_moves` (location);
- the summaries of a kept chain: :func:`thin_index`, :func:`autocorr_ess`,
  :func:`bulk_ess`, :func:`hdi`, :func:`equal_tailed`, :func:`draw_moments`,
  :func:`to_datatree` and :func:`rhat_across_ensembles`.

Walkers are ArviZ chains throughout (the emcee convention). Same ``seed``,
same chain: emcee's random state is set from the seed, never from global state.

Examples
--------
>>> import numpy as np
>>> class Gauss:
...     names, ndim, label = ("x",), 1, "a unit Gaussian"
...     def start(self, n_walkers, gen):
...         return gen.standard_normal((n_walkers, 1))
...     def __call__(self, theta):
...         return -0.5 * theta[:, 0] ** 2
>>> post = Gauss()
>>> isinstance(post, LogPosterior)
True
>>> gen = np.random.default_rng(0)
>>> [run] = run_ensembles(post, n_walkers=8, gen=gen, min_ess=0, tau_factor=5,
...                       max_steps=2000, progress=False)
>>> run.converged, run.chain.shape[1:]
(True, (8, 1))
"""

from __future__ import annotations

import sys
import warnings
from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import emcee
import numpy as np

from .exceptions import SamplingWarning

#: How :func:`default_moves` is reported in a result's diagnostics.
DEFAULT_MOVES_LABEL = "default (DEMove 0.8, DESnookerMove 0.2)"
#: ArviZ's warning when there are more chains (walkers) than draws: expected here.
_CHAINS_WARNING = "Found chain dimension to be longer"


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
        """Return initial positions, ``(n_walkers, ndim)``, inside the support."""
        ...  # pragma: no cover

    def __call__(self, theta: np.ndarray) -> np.ndarray:
        """Return the log posterior (up to a constant) of ``(W, ndim)``: ``(W,)``, -inf outside."""
        ...  # pragma: no cover


# ------------------------------------------------------------------ move policy


def default_moves() -> list:
    """Differential evolution with a snooker update: the LBL posterior's moves.

    Differential evolution proposals (ter Braak & Vrugt 2008) with a snooker
    update: on the near-Gaussian, correlated 5-D beacon posterior they gave
    shorter autocorrelation times than emcee's default stretch move
    (``docs/bayes.md``).

    Returns
    -------
    list
        ``[(DEMove, 0.8), (DESnookerMove, 0.2)]``, emcee's ``moves`` argument.
    """
    return [(emcee.moves.DEMove(), 0.8), (emcee.moves.DESnookerMove(), 0.2)]


def de_moves() -> list:
    """Differential evolution only: the location posterior's moves.

    emcee 3.1.6's ``DESnookerMove`` (in :func:`default_moves`) weighs its
    Metropolis factor by ``(ndim - 1) / 2`` instead of ``ndim - 1`` and scales
    its step wrongly (fixed upstream in dfm/emcee#531): on SeaGap's
    23-parameter location posterior the mix gave depth sd 0.055 m where DE
    alone, the stretch move and the Laplace approximation give 0.066-0.067 m.

    Returns
    -------
    list
        ``[(DEMove, 1.0)]``, emcee's ``moves`` argument.
    """
    return [(emcee.moves.DEMove(), 1.0)]


# ------------------------------------------------------------------ the loop


def progress_bar(progress, desc: str):
    """Open a tqdm bar counting steps labelled ``desc``; None unless ``progress``.

    ``progress="auto"``: only when standard error is a terminal.
    """
    if progress == "auto":
        progress = sys.stderr.isatty()
    if not progress:
        return None
    try:
        from tqdm.auto import tqdm
    except ImportError:  # pragma: no cover - tqdm is a dependency
        return None
    return tqdm(desc=desc, unit="step", leave=False)


def _bulk_ess_min(chain):
    """Smallest ArviZ bulk ESS over the columns of a ``(steps, walkers, ndim)`` chain."""
    import arviz_stats as azs

    arr = np.transpose(chain, (1, 0, 2))  # (walker = chain, step = draw, ndim)
    return float(np.min(azs.ess(arr, method="bulk", chain_axis=0, draw_axis=1)))


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
        Steps between checks of the stopping rule.
    progress : bool or "auto"
        Progress bar (``"auto"``: when standard error is a terminal).

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
    n_walkers, ndim = start.shape
    sampler = emcee.EnsembleSampler(n_walkers, ndim, post, vectorize=True,
                                    moves=moves or default_moves())
    sampler.random_state = np.random.RandomState(seed % 2**32).get_state()
    bar = progress_bar(progress, post.label)
    state, burn, tau, converged = start, 0, np.full(ndim, np.inf), False
    ess_bulk = 0.0
    try:
        while sampler.iteration < max_steps:
            state = sampler.run_mcmc(state, min(check_every, max_steps - sampler.iteration),
                                     progress=False)
            tau_all = sampler.get_autocorr_time(tol=0, quiet=True)
            burn = int(np.ceil(2.0 * np.max(tau_all)))
            kept = sampler.iteration - burn
            if kept > 0:
                tau = sampler.get_autocorr_time(discard=burn, tol=0, quiet=True)
            if bar is not None:
                bar.update(check_every)
                bar.set_postfix(tau=f"{np.max(tau):.0f}",
                                ess=f"{kept * n_walkers / np.max(tau):.0f}")
            long_enough = (kept > 0 and np.all(np.isfinite(tau))
                           and kept >= tau_factor * np.max(tau)
                           and kept * n_walkers / np.max(tau) >= min_ess)
            if long_enough:
                ess_bulk = (_bulk_ess_min(sampler.get_chain(discard=burn)) if min_ess > 0
                            else np.inf)
                if ess_bulk >= min_ess:
                    converged = True
                    break
    finally:
        if bar is not None:
            bar.close()
    kept = sampler.iteration - burn
    status = (f"{sampler.iteration} steps, burn-in {burn}, kept {kept} = "
              f"{kept / np.max(tau):.1f} tau (needs {tau_factor:g}), emcee ESS "
              f"{max(kept, 0) * n_walkers / np.max(tau):.0f} and bulk ESS "
              f"{ess_bulk:.0f} (need {min_ess:g})")
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


# ------------------------------------------------------------------ summaries of a chain


def thin_index(kept: int, n_chains: int, n_draws: int) -> tuple[np.ndarray, int]:
    """Evenly spaced steps, ending at the last, giving about ``n_draws`` draws over all chains.

    Parameters
    ----------
    kept : int
        Steps in the kept chain.
    n_chains : int
        Chains (walkers, over all ensembles) sharing the draws.
    n_draws : int
        Draws wanted in all.

    Returns
    -------
    idx : numpy.ndarray
        Steps to keep.
    thin : int
        Their spacing.

    Examples
    --------
    >>> idx, thin = thin_index(1000, 50, 400)
    >>> idx.tolist(), thin
    ([124, 249, 374, 499, 624, 749, 874, 999], 125)
    """
    per_chain = max(1, min(kept, int(np.ceil(n_draws / n_chains))))
    thin = max(1, kept // per_chain)
    idx = np.arange(kept - (per_chain - 1) * thin - 1, kept, thin)[-per_chain:]
    return idx, thin


def autocorr_ess(series) -> tuple[float, float]:
    """Integrated autocorrelation time (emcee, steps) of a ``(steps, walkers)`` series.

    Returns ``(tau, ess)``, with ``ess = steps x walkers / tau``.
    """
    tau = float(emcee.autocorr.integrated_time(series[:, :, None], tol=0, quiet=True)[0])
    return tau, float(series.shape[0] * series.shape[1] / tau)


def bulk_ess(series: dict) -> dict:
    """ArviZ's rank-normalised bulk ESS of each ``(chain, draw)`` array of a dict.

    Walkers as chains; returns name -> float.
    """
    import arviz_stats as azs

    return {k: float(azs.ess(np.asarray(v), method="bulk", chain_axis=0, draw_axis=1))
            for k, v in series.items()}


def hdi(x, ci: float) -> list:
    """Highest-density interval ``[lower, upper]`` (ArviZ) of all values of ``x``.

    With probability ``ci``.
    """
    import arviz_stats as azs

    return [float(v) for v in azs.hdi(np.ravel(x), prob=ci)]


def equal_tailed(x, ci: float) -> list:
    """Equal-tailed interval ``[lower, upper]`` of all values of ``x``, probability ``ci``.

    The ``(1 - ci) / 2`` and ``(1 + ci) / 2`` quantiles.

    Examples
    --------
    >>> equal_tailed(range(101), 0.5)
    [25.0, 75.0]
    """
    lo, hi = np.quantile(np.ravel(x), [0.5 - ci / 2, 0.5 + ci / 2])
    return [float(lo), float(hi)]


def draw_moments(flat, fn, *, chunk: int = 64):
    """Pointwise values and the mean and sd of per-item probabilities over draws, in chunks.

    One pass over chunks of draws: never a draws x items x classes array.

    Parameters
    ----------
    flat : numpy.ndarray
        ``(draws, ndim)``.
    fn : callable
        ``fn(theta)`` of a ``(W, ndim)`` chunk returns ``(pointwise, probs)``:
        a ``(W, n)`` array (e.g. the log-likelihood of each item) or None, and a
        sequence of ``k`` probability arrays, each ``(W, n)``.
    chunk : int, default 64
        Draws per call of ``fn``.

    Returns
    -------
    pointwise : numpy.ndarray or None
        ``(draws, n)``, when ``fn`` returns one.
    mean, sd : numpy.ndarray
        ``(n, k)``, over the draws.

    Examples
    --------
    >>> flat = np.array([[0.2], [0.4]])
    >>> _, m, s = draw_moments(flat, lambda t: (None, [np.repeat(t, 3, axis=1)]))
    >>> m[:, 0].round(3).tolist(), s[:, 0].round(3).tolist()
    ([0.3, 0.3, 0.3], [0.1, 0.1, 0.1])
    """
    n_draws = flat.shape[0]
    pointwise = s1 = s2 = None
    for i in range(0, n_draws, chunk):
        values, probs = fn(flat[i:i + chunk])
        if s1 is None:
            n = probs[0].shape[1]
            s1, s2 = np.zeros((n, len(probs))), np.zeros((n, len(probs)))
            if values is not None:
                pointwise = np.empty((n_draws, n))
        if values is not None:
            pointwise[i:i + chunk] = values
        for j, r in enumerate(probs):
            s1[:, j] += r.sum(axis=0)
            s2[:, j] += (r * r).sum(axis=0)
    m = s1 / n_draws
    return pointwise, m, np.sqrt(np.maximum(s2 / n_draws - m * m, 0.0))


def to_datatree(groups: dict, **kwargs):
    """ArviZ data from a dict of groups, walkers as chains.

    ``groups`` and ``kwargs`` as for :func:`arviz_base.from_dict`: group name ->
    {variable -> ``(chain, draw, ...)`` array}; ArviZ's warning about more chains
    than draws is silenced. Returns an ``xarray.DataTree``.
    """
    import arviz_base as azb

    with warnings.catch_warnings():
        # walkers are ArviZ chains by design (emcee convention); with many walkers and
        # few kept draws each, ArviZ's dimension-name heuristic would misfire
        warnings.filterwarnings("ignore", message=_CHAINS_WARNING)
        return azb.from_dict(groups, **kwargs)


def rhat_across_ensembles(ds, n_ens: int) -> dict:
    """Rank-normalised split R-hat (ArviZ) across independent ensembles.

    The walkers of one ensemble are not independent chains: each ensemble's
    walkers are regrouped into one chain (draws = walkers x kept draws) first.

    Parameters
    ----------
    ds : xarray.Dataset
        ``(chain, draw)`` variables, the walkers of each ensemble consecutive.
    n_ens : int
        Number of ensembles (at least 2).

    Returns
    -------
    dict
        Variable -> R-hat.
    """
    import arviz_stats as azs
    import xarray as xr

    out = {}
    for k, v in ds.data_vars.items():
        a = v.values  # (chain, draw)
        a = a.reshape(n_ens, -1, a.shape[1])  # (ensemble, walker, draw)
        out[k] = xr.DataArray(a.transpose(0, 2, 1).reshape(n_ens, -1), dims=("chain", "draw"))
    rh = azs.rhat(xr.Dataset(out))
    return {k: float(rh[k]) for k in out}
