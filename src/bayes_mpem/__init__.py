"""bayes_mpem: acoustic multipath identification for LBL ranging.

Classify every acoustic range as direct path, multipath or outlier, and
identify each beacon's reflector (height of the reflecting plane ``d0`` and
the multipath scatter ``sigma_MP``), with the paper's EM or a proper
mixture-likelihood EM; sample the same likelihood with emcee for posterior
intervals, and compare equal with learned mixing priors by PSIS-LOO; find which
assumption a survey breaks (:func:`diagnose`).
"""

__version__ = "0.1.0"

from .bayes import PosteriorResult, SamplingWarning, sample_beacon  # noqa: E402
from .compare import SurveyComparison, compare, compare_beacon  # noqa: E402
from .data import BeaconData, InputError, Survey, load_survey  # noqa: E402
from .diagnose import Diagnosis, diagnose  # noqa: E402
from .em import (  # noqa: E402
    ConvergenceWarning,
    EMResult,
    FitQualityWarning,
    fit_mixture_em,
    fit_paper_em,
)
from .fitting import SkippedBeaconWarning, SurveyFit, fit  # noqa: E402
from .sampling import SurveyPosterior, sample  # noqa: E402
from .simulate import Simulation, simulate_survey  # noqa: E402

__all__ = [
    "BeaconData",
    "ConvergenceWarning",
    "Diagnosis",
    "EMResult",
    "FitQualityWarning",
    "InputError",
    "PosteriorResult",
    "SamplingWarning",
    "Simulation",
    "SkippedBeaconWarning",
    "Survey",
    "SurveyComparison",
    "SurveyFit",
    "SurveyPosterior",
    "__version__",
    "compare",
    "compare_beacon",
    "diagnose",
    "fit",
    "fit_mixture_em",
    "fit_paper_em",
    "load_survey",
    "sample",
    "sample_beacon",
    "simulate_survey",
]
