"""Mixture densities shared by both problems (log space, broadcasting).

:mod:`.densities` holds the component log-densities and the log-sum-exp of a
mixture.
"""

from .._deprecated import moved_attribute
from .densities import CLASSES, gaussian_logpdf, log_mix, safe_log

__all__ = ["CLASSES", "gaussian_logpdf", "log_mix", "safe_log"]

# the LBL-specific names that lived in the old ``bayes_mpem.mixture`` module
_MOVED = {"BeaconGeometry": "lbl.beacon_geometry", "component_logpdf": "lbl.likelihood",
          "e_step": "lbl.likelihood", "loglik_per_range": "lbl.likelihood",
          "total_loglik": "lbl.likelihood", "weighted_densities": "lbl.likelihood"}


def __getattr__(name):
    if name in _MOVED:
        return moved_attribute(__name__, name, _MOVED[name])
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
