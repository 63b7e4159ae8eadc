"""What the mixture models of both problems share (log space, broadcasting).

:mod:`.densities` holds the component log-densities (Gaussian, uniform and
first-arrival outliers) and the log-sum-exp of a mixture; :mod:`.gauss_newton`
the safeguard of a Gauss-Newton M-step.
"""

from .._deprecated import moved_attribute
from .densities import (
    CLASSES,
    EPS_LATE,
    first_arrival_logpdf,
    gaussian_logpdf,
    log_mix,
    responsibilities,
    safe_log,
    uniform_logpdf,
)
from .gauss_newton import safeguarded_step

__all__ = ["CLASSES", "EPS_LATE", "first_arrival_logpdf", "gaussian_logpdf", "log_mix",
           "responsibilities", "safe_log", "safeguarded_step", "uniform_logpdf"]

# the LBL-specific names that lived in the old ``bayes_mpem.mixture`` module
_MOVED = {"BeaconGeometry": "lbl.beacon_geometry", "component_logpdf": "lbl.likelihood",
          "e_step": "lbl.likelihood", "loglik_per_range": "lbl.likelihood",
          "total_loglik": "lbl.likelihood", "weighted_densities": "lbl.likelihood"}


def __getattr__(name):
    if name in _MOVED:
        return moved_attribute(__name__, name, _MOVED[name])
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
