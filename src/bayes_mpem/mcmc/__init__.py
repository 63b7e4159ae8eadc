"""The emcee driver shared by every posterior, with ArviZ's diagnostics (``docs/bayes.md``)."""

from .driver import EnsembleRun, LogPosterior, place_walkers, run_ensembles
from .progress import SamplingProgress, progress_mode
from .proposal import TProposal, laplace_proposal
from .summaries import (
    bulk_ess,
    draw_moments,
    draw_summary,
    equal_tailed,
    ess,
    ess_and_rhat,
    hdi,
    rhat,
    thin_index,
    to_datatree,
)

__all__ = ["DEFAULT_MOVES_LABEL", "EnsembleRun", "INDEPENDENCE_LABEL", "IndependenceMove",
           "LogPosterior", "SamplingProgress", "TProposal", "bulk_ess", "default_moves",
           "draw_moments", "draw_summary", "equal_tailed", "ess", "ess_and_rhat", "hdi",
           "independence_move", "laplace_proposal", "place_walkers", "progress_mode", "rhat",
           "run_ensembles", "thin_index", "to_datatree"]

_MOVES = ("DEFAULT_MOVES_LABEL", "INDEPENDENCE_LABEL", "IndependenceMove", "default_moves",
          "independence_move")


def __getattr__(name):
    """Import the moves, and with them emcee, on first use."""
    if name in _MOVES:
        from . import moves

        return getattr(moves, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
