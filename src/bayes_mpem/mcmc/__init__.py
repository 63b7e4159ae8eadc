"""The emcee driver shared by every posterior, with ArviZ's diagnostics.

Each posterior satisfies :class:`LogPosterior`; :func:`run_ensembles` samples it with
``emcee.EnsembleSampler`` until ArviZ's bulk ESS reaches its target and R-hat is below
1.01. The moves are in :mod:`.moves` (imported on first use), the summaries from
:mod:`arviz_stats` and :mod:`arviz_base` in :mod:`.summaries`, the rank statistics of
simulation-based calibration in :mod:`.sbc`.

Examples
--------
>>> import numpy as np
>>> from bayes_mpem.mcmc.moves import default_moves
>>> gen = np.random.default_rng(0)
>>> target = lambda x: -0.5 * (x ** 2).sum(axis=1)
>>> run = run_ensembles(target, [gen.standard_normal((16, 1))], moves=default_moves(),
...                     gen=gen, min_ess=400, burn_in=True, progress=False)
>>> run.converged, run.ess >= 400
(True, True)
"""

from .driver import EnsembleRun, LogPosterior, place_walkers, run_ensembles
from .progress import SamplingProgress, progress_bar, progress_mode
from .proposal import TProposal, laplace_proposal
from .summaries import (
    bulk_ess,
    draw_moments,
    equal_tailed,
    ess,
    hdi,
    rhat,
    rhat_across_ensembles,
    thin_index,
    to_datatree,
)

__all__ = ["DEFAULT_MOVES_LABEL", "EnsembleRun", "INDEPENDENCE_LABEL", "IndependenceMove",
           "LogPosterior",
           "SamplingProgress", "TProposal", "bulk_ess", "default_moves", "draw_moments",
           "equal_tailed", "ess", "hdi", "independence_move", "laplace_proposal",
           "place_walkers", "progress_bar", "progress_mode", "rhat", "rhat_across_ensembles",
           "run_ensembles", "thin_index", "to_datatree"]

_MOVES = ("DEFAULT_MOVES_LABEL", "INDEPENDENCE_LABEL", "IndependenceMove", "default_moves",
          "independence_move")


def __getattr__(name):
    """Import the moves on first use: :mod:`.moves` imports emcee (0.5 s)."""
    if name in _MOVES:
        from . import moves

        return getattr(moves, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
