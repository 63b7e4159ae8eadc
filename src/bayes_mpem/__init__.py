"""bayes_mpem: acoustic multipath identification for LBL ranging (layout: docs/architecture.md)."""

__version__ = "0.1.0"

import importlib  # noqa: E402

#: public name -> the module that defines it, imported on first use (PEP 562; keeps --help fast)
_PUBLIC: dict[str, str] = {
    **dict.fromkeys(("ConvergenceWarning", "FitQualityWarning", "InputError", "LocateWarning",
                     "ModelCheckWarning", "NavigationWarning", "PathChoiceWarning",
                     "SamplingWarning", "SkippedBeaconWarning"),
                    "exceptions"),
    **dict.fromkeys(("BeaconData", "Survey", "load_survey"), "io.survey"),
    **dict.fromkeys(("PosteriorResult", "sample_beacon"), "lbl.bayes.beacon_sampling"),
    **dict.fromkeys(("SurveyComparison", "compare"), "lbl.survey.comparison"),
    "diagnose": "lbl.diagnosis.driver",
    "Diagnosis": "lbl.diagnosis.result",
    "fit_mixture_em": "lbl.em.em_mixture",
    "fit_paper_em": "lbl.em.em_paper",
    "EMResult": "lbl.em.em_result",
    **dict.fromkeys(("SurveyFit", "fit"), "lbl.survey.fitting"),
    "compare_beacon": "lbl.bayes.loo",
    **dict.fromkeys(("SurveyPosterior", "sample"), "lbl.survey.sampling"),
    **dict.fromkeys(("Simulation", "simulate_survey"), "lbl.simulation.simulate"),
    **dict.fromkeys(("DiveSimulation", "Navigation", "navigate", "simulate_dive"),
                    "lbl.navigate"),
}

def __getattr__(name):
    """Import a public name on first use."""
    if name in _PUBLIC:
        value = getattr(importlib.import_module(f"{__name__}.{_PUBLIC[name]}"), name)
        globals()[name] = value  # later look-ups skip this function
        return value
    raise AttributeError(f"module 'bayes_mpem' has no attribute {name!r}")


def __dir__():
    return sorted({*globals(), *_PUBLIC})


__all__ = [
    "BeaconData",
    "ConvergenceWarning",
    "Diagnosis",
    "DiveSimulation",
    "EMResult",
    "FitQualityWarning",
    "InputError",
    "LocateWarning",
    "ModelCheckWarning",
    "Navigation",
    "NavigationWarning",
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
    "navigate",
    "sample",
    "sample_beacon",
    "simulate_dive",
    "simulate_survey",
]
