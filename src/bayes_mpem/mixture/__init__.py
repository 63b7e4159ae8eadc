"""What the mixture models of both problems share (log space, broadcasting).

:mod:`.densities` holds the component log-densities (Gaussian, uniform and
first-arrival outliers) and the log-sum-exp of a mixture; :mod:`.gauss_newton`
the safeguard of a Gauss-Newton M-step.
"""

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
