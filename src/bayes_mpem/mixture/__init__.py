"""What the mixture models of both problems share: log-densities, EM loop, safeguarded step."""

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
from .em import EMModel, EMRun, best_run, run_em
from .gauss_newton import safeguarded_step

__all__ = ["CLASSES", "EPS_LATE", "EMModel", "EMRun", "best_run", "first_arrival_logpdf",
           "gaussian_logpdf", "log_mix", "responsibilities", "run_em", "safe_log",
           "safeguarded_step", "uniform_logpdf"]
