"""bayes_mpem: acoustic multipath identification for LBL ranging.

Classify every acoustic range as direct path, multipath or outlier, and
identify each beacon's reflector (height of the reflecting plane ``d0`` and
the multipath scatter ``sigma_MP``), with the paper's EM or a proper
mixture-likelihood EM; sample the same likelihood with emcee for posterior
intervals, and compare equal with learned mixing priors by PSIS-LOO; find which
assumption a survey breaks (:func:`diagnose`); locate a transponder from a
survey-in (:func:`bayes_mpem.survey_in.location.locate`).

The package has two wings, which never import each other: :mod:`bayes_mpem.lbl`
(the paper's problem: one-way ranges to beacons at known positions) and
:mod:`bayes_mpem.survey_in` (two-way travel times from a ship to one
transponder). What they share lives below them: :mod:`bayes_mpem.io`,
:mod:`bayes_mpem.acoustics`, :mod:`bayes_mpem.mixture` and
:mod:`bayes_mpem.mcmc`. See ``docs/architecture.md``.
"""

__version__ = "0.1.0"

from . import _deprecated  # noqa: E402
from .exceptions import (  # noqa: E402
    ConvergenceWarning,
    FitQualityWarning,
    InputError,
    LocateWarning,
    ModelCheckWarning,
    PathChoiceWarning,
    SamplingWarning,
    SkippedBeaconWarning,
)
from .io.survey import BeaconData, Survey, load_survey  # noqa: E402
from .lbl.beacon_sampling import PosteriorResult, sample_beacon  # noqa: E402
from .lbl.comparison import SurveyComparison, compare  # noqa: E402
from .lbl.diagnosis.driver import diagnose  # noqa: E402
from .lbl.diagnosis.result import Diagnosis  # noqa: E402
from .lbl.em_mixture import fit_mixture_em  # noqa: E402
from .lbl.em_paper import fit_paper_em  # noqa: E402
from .lbl.em_result import EMResult  # noqa: E402
from .lbl.fitting import SurveyFit, fit  # noqa: E402
from .lbl.loo import compare_beacon  # noqa: E402
from .lbl.sampling import SurveyPosterior, sample  # noqa: E402
from .lbl.simulate import Simulation, simulate_survey  # noqa: E402

_deprecated.install()


def __getattr__(name):
    """Serve ``bayes_mpem.em`` and the other old module paths as attributes too."""
    if name in _deprecated.MOVED:
        return _deprecated.old_module(name)
    raise AttributeError(f"module 'bayes_mpem' has no attribute {name!r}")

__all__ = [
    "BeaconData",
    "ConvergenceWarning",
    "Diagnosis",
    "EMResult",
    "FitQualityWarning",
    "InputError",
    "LocateWarning",
    "ModelCheckWarning",
    "PathChoiceWarning",
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
