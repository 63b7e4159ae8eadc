"""bayes_mpem: acoustic multipath identification for LBL ranging.

Classify every acoustic range as direct path, multipath or outlier, and
identify each beacon's reflector (height of the reflecting plane ``d0`` and
the multipath scatter ``sigma_MP``), with the paper's EM or a proper
mixture-likelihood EM.
"""

__version__ = "0.1.0"

from .data import BeaconData, InputError, Survey, load_survey  # noqa: E402
from .em import ConvergenceWarning, EMResult, fit_mixture_em, fit_paper_em  # noqa: E402
from .fitting import SkippedBeaconWarning, SurveyFit, fit  # noqa: E402
from .simulate import Simulation, simulate_survey  # noqa: E402

__all__ = [
    "BeaconData",
    "ConvergenceWarning",
    "EMResult",
    "InputError",
    "Simulation",
    "SkippedBeaconWarning",
    "Survey",
    "SurveyFit",
    "__version__",
    "fit",
    "fit_mixture_em",
    "fit_paper_em",
    "load_survey",
    "simulate_survey",
]
