"""The emcee driver shared by both posteriors: one protocol, one loop, one set of summaries.

Both problems sample a log-posterior vectorised over walkers: the beacon of
:class:`bayes_mpem.lbl.bayes.posterior.BeaconPosterior` and the transponder location
of :class:`bayes_mpem.survey_in.posterior.LocationLogPosterior`. Each satisfies
:class:`LogPosterior` (parameter ``names``, ``ndim``, a ``label``, a
``start`` ball and ``__call__``), and this package does the rest
(:mod:`.driver`, :mod:`.moves`, :mod:`.summaries`):

- :func:`run_ensemble` runs one ensemble in blocks until the kept chain is
  ``tau_factor`` autocorrelation times long and its smallest ESS, by emcee's
  ``steps x walkers / tau`` and by ArviZ's bulk estimate, reaches ``min_ess``;
  :func:`run_ensembles` runs several, each from its own start ball and seed;
- the move policy, :func:`default_moves` (differential evolution, for both), and an exact
  snooker update, :class:`SnookerMove` (imported on first use: emcee's import costs
  0.5 s);
- independence Metropolis-Hastings from a Laplace (Student-t) proposal
  (:mod:`.independence`: :func:`laplace_proposal`, :func:`run_independence`), the
  beacon posterior's default sampler;
- ArviZ's rank-normalised ESS and R-hat and the nearest-draws HDI, written against the
  paper (:mod:`.convergence`; checked against :mod:`arviz_stats` in the tests);
- the summaries of a kept chain: :func:`thin_index`, :func:`autocorr_ess`,
  :func:`bulk_ess`, :func:`hdi`, :func:`equal_tailed`, :func:`draw_moments`,
  :func:`to_datatree` and :func:`rhat_across_ensembles`;
- the rank statistics of simulation-based calibration and their tests (:mod:`.sbc`).

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

from .driver import (
    EnsembleRun,
    LogPosterior,
    place_walkers,
    run_ensemble,
    run_ensembles,
)
from .independence import IndependenceRun, TProposal, laplace_proposal, run_independence
from .progress import SamplingProgress, progress_bar, progress_mode
from .summaries import (
    autocorr_ess,
    bulk_ess,
    draw_moments,
    equal_tailed,
    hdi,
    rhat_across_ensembles,
    thin_index,
    to_datatree,
)

__all__ = ["DEFAULT_MOVES_LABEL", "EnsembleRun", "IndependenceRun", "LogPosterior", "TProposal",
           "autocorr_ess", "bulk_ess", "default_moves", "draw_moments", "equal_tailed", "hdi",
           "laplace_proposal", "run_independence",
           "place_walkers", "progress_bar", "progress_mode", "SamplingProgress", "SnookerMove",
           "rhat_across_ensembles", "run_ensemble",
           "run_ensembles", "thin_index", "to_datatree"]

_MOVES = ("DEFAULT_MOVES_LABEL", "SnookerMove", "default_moves")


def __getattr__(name):
    """Import the move policy on first use: :mod:`.moves` imports emcee (0.5 s)."""
    if name in _MOVES:
        from . import moves

        return getattr(moves, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
