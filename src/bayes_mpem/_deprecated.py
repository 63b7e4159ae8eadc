"""Old flat-layout import paths, kept working with a :class:`DeprecationWarning`.

Until version 0.2 the package was 23 modules in one folder (``bayes_mpem.em``,
``bayes_mpem.data``, ...). Each old module path is registered here as a small
module object whose attributes forward to the new home of each name, warning
once per access; nothing heavy is imported until a name is used. The table is
the map from the old layout to the new one (``docs/architecture.md``).
"""

from __future__ import annotations

import importlib
import sys
import types
import warnings

#: old module -> {public name: new module (relative to ``bayes_mpem``)}
MOVED: dict[str, dict[str, str]] = {
    'bayes': {
        'BeaconPosterior': 'lbl.posterior',
        'PARAMS': 'lbl.posterior',
        'PRIORS': 'lbl.posterior',
        'PosteriorResult': 'lbl.beacon_sampling',
        'SamplingWarning': 'exceptions',
        'UnusableStartError': 'exceptions',
        'check_sample_options': 'lbl.posterior',
        'run_ensemble': 'mcmc',
        'sample_beacon': 'lbl.beacon_sampling',
    },
    'bayes_plots': {
        'LABELS': 'plots.bayes',
        'plot_class_uncertainty': 'plots.bayes',
        'plot_intervals': 'plots.bayes',
        'plot_pair': 'plots.bayes',
        'plot_prior_comparison': 'plots.bayes',
        'plot_trace': 'plots.bayes',
    },
    'compare': {
        'CLEAR': 'lbl.loo',
        'LooResult': 'lbl.loo',
        'MIN_DIFF': 'lbl.loo',
        'PriorComparison': 'lbl.loo',
        'SurveyComparison': 'lbl.comparison',
        'compare': 'lbl.comparison',
        'compare_beacon': 'lbl.loo',
        'psis_loo': 'lbl.loo',
    },
    'data': {
        'BEACON_COLUMNS': 'io.tables',
        'BeaconData': 'io.survey',
        'InputError': 'exceptions',
        'MAX_LISTED': 'io.tables',
        'PING_COLUMNS': 'io.tables',
        'RESERVED_COLUMNS': 'io.tables',
        'Survey': 'io.survey',
        'load_survey': 'io.survey',
        'read_beacons': 'io.tables',
        'read_pings': 'io.tables',
    },
    'diagnose': {
        'Diagnosis': 'lbl.diagnosis.result',
        'EFFECTS': 'lbl.effects',
        'Effect': 'lbl.diagnosis.result',
        'JointFit': 'lbl.diagnosis.ecm',
        'MIN_SECOND_SHARE': 'lbl.diagnosis.evidence',
        'UNITS': 'lbl.effects',
        'covariates': 'lbl.diagnosis.residuals',
        'diagnose': 'lbl.diagnosis.driver',
        'fit_joint': 'lbl.diagnosis.ecm',
        'residual_checks': 'lbl.diagnosis.residuals',
    },
    'diagnose_plots': {
        'plot_candidates': 'plots.diagnose',
        'plot_classes_vs_time': 'plots.diagnose',
        'plot_residuals': 'plots.diagnose',
        'write_figures': 'plots.diagnose',
    },
    'em': {
        'ConvergenceWarning': 'exceptions',
        'EMResult': 'lbl.em_result',
        'FitQualityWarning': 'exceptions',
        'check_options': 'lbl.em_result',
        'estimate_sigma_dp': 'lbl.em_result',
        'fit_mixture_em': 'lbl.em_mixture',
        'fit_paper_em': 'lbl.em_paper',
        'histogram_modes': 'lbl.em_mixture',
        'mixture_m_step': 'lbl.em_mixture',
        'paper_e_step': 'lbl.em_paper',
        'paper_m_step': 'lbl.em_paper',
        'quality_flags': 'lbl.em_result',
    },
    'fitting': {
        'METHODS': 'lbl.fitting',
        'SkippedBeaconWarning': 'exceptions',
        'SurveyFit': 'lbl.fitting',
        'beacons_table': 'lbl.survey',
        'classified_table': 'lbl.survey',
        'fit': 'lbl.fitting',
        'fittable_beacons': 'lbl.survey',
    },
    'geometry': {
        'PATHS': 'lbl.geometry',
        'Path': 'lbl.geometry',
        'check_path': 'lbl.geometry',
        'direct_path': 'lbl.geometry',
        'elevation_angle': 'lbl.geometry',
        'horizontal_distance': 'lbl.geometry',
        'invert_plane_height': 'lbl.geometry',
        'multipath_derivative': 'lbl.geometry',
        'multipath_range': 'lbl.geometry',
        'reflected_leg': 'lbl.geometry',
    },
    'locate': {
        'DEFAULT_TAT': 'survey_in.location',
        'LocateResult': 'survey_in.location',
        'LocateWarning': 'exceptions',
        'OUTLIER_MODELS': 'survey_in.classes',
        'SEAGAP_TRANSDUCER_DEPTH': 'survey_in.survey',
        'earth_radius': 'io.geodesy',
        'enu_to_geodetic': 'io.geodesy',
        'heldout_logpdf': 'survey_in.heldout',
        'locate': 'survey_in.location',
        'locate_survey': 'survey_in.survey',
        'ship_velocity': 'survey_in.travel_times',
        'survey_profile': 'survey_in.survey',
    },
    'locate_bayes': {
        'BENDING': 'survey_in.posterior',
        'LocationLogPosterior': 'survey_in.posterior',
        'LocationPosterior': 'survey_in.location_sampling',
        'PARAMS': 'survey_in.posterior',
        'SIGMA_BOUNDS': 'survey_in.posterior',
        'SPEED_PRIOR_WIDTH': 'survey_in.posterior',
        'TAT_BOUNDS': 'survey_in.posterior',
        'check_location_options': 'survey_in.posterior',
        'locate_survey_bayes': 'survey_in.location_sampling',
        'sample_location': 'survey_in.location_sampling',
    },
    'readers': {
        'FORMATS': 'io.formats',
        'RawSurvey': 'io.raw',
        'antenna_to_transducer': 'io.geodesy',
        'enu_to_geodetic': 'io.geodesy',
        'geodetic_to_enu': 'io.geodesy',
        'read_obsrange_sio': 'io.obsrange',
        'read_obsrange_whoi': 'io.obsrange',
        'read_seagap': 'io.seagap',
        'read_survey': 'io.formats',
        'sample_file': 'io.formats',
    },
    'refraction': {
        'DirectRays': 'acoustics.turning',
        'NO_RAY': 'acoustics.turning',
        'PLANE_STEP': 'lbl.refracted',
        'RefractedBeaconGeometry': 'lbl.refracted',
        'RefractedRanges': 'lbl.refracted',
        'bounce_times': 'acoustics.turning',
        'check_profile': 'acoustics.profile_checks',
        'check_sound_speed': 'acoustics.profile_checks',
        'direct_times': 'acoustics.turning',
        'lbl_ranges': 'lbl.refracted',
        'nominal_sound_speed': 'acoustics.profile_checks',
    },
    'sampling': {
        'SurveyPosterior': 'lbl.sampling',
        'sample': 'lbl.sampling',
        'skip_beacon': 'lbl.survey',
    },
    'simcheck': {
        'GapResult': 'survey_in.simcheck',
        'STATISTICS': 'survey_in.gap_statistics',
        'TRACK_COLUMNS': 'survey_in.simcheck',
        'gap_statistics': 'survey_in.gap_statistics',
        'mc_pvalue': 'survey_in.gap_statistics',
        'refracted_twtt': 'survey_in.unabsorbed',
        'remove_common_drift': 'survey_in.gap_statistics',
        'residual_frame': 'survey_in.simcheck',
        'simulate_like': 'survey_in.simcheck',
        'simulation_gap': 'survey_in.simcheck',
        'unabsorbed': 'survey_in.unabsorbed',
    },
    'simulate': {
        'ABE58': 'lbl.presets',
        'EFFECTS': 'lbl.effects',
        'PRESETS': 'lbl.presets',
        'Simulation': 'lbl.simulate',
        'lawnmower_track': 'lbl.simulate',
        'simulate_lbl': 'lbl.simulate',
        'simulate_survey': 'lbl.simulate',
    },
}


def moved_attribute(old: str, name: str, new: str):
    """Return ``name`` from its new module ``new``, warning that ``old`` moved.

    Parameters
    ----------
    old : str
        The old dotted path of the module, e.g. ``"bayes_mpem.em"``.
    name : str
        The attribute asked for.
    new : str
        Its new module, relative to ``bayes_mpem`` (``"lbl.em_mixture"``).

    Returns
    -------
    object
    """
    warnings.warn(f"{old}.{name} has moved to bayes_mpem.{new}.{name}; the old path will be "
                  "removed in a future release", DeprecationWarning, stacklevel=3)
    return getattr(importlib.import_module(f"bayes_mpem.{new}"), name)


class _MovedModule(types.ModuleType):
    """A module path of the old layout whose names now live elsewhere."""

    def __init__(self, old: str) -> None:
        super().__init__(f"bayes_mpem.{old}", f"Deprecated: the names of the old "
                         f"``bayes_mpem.{old}`` (see ``bayes_mpem._deprecated.MOVED``).")
        self._table = MOVED[old]

    def __getattr__(self, name):
        if name.startswith("__") or name not in self._table:
            raise AttributeError(f"module {self.__name__!r} has no attribute {name!r}")
        return moved_attribute(self.__name__, name, self._table[name])

    def __dir__(self):
        return sorted(self._table)


def old_module(old: str) -> types.ModuleType:
    """Return the module object registered for the old path ``bayes_mpem.<old>``.

    Parameters
    ----------
    old : str
        A key of :data:`MOVED`, e.g. ``"em"``.

    Returns
    -------
    types.ModuleType
    """
    return sys.modules.setdefault(f"bayes_mpem.{old}", _MovedModule(old))


def figures_keyword(result, out_dir, value, where: str) -> dict:
    """Honour the old ``figures=``/``figure=`` keyword of a result's ``write()``.

    Results used to draw their own figures; now ``write()`` writes data and
    :func:`bayes_mpem.report.write_figures` the figures. The keyword still works,
    with a DeprecationWarning; ``True`` draws the figures through the report,
    looked up by name (results may not import it).

    Parameters
    ----------
    result : object
        The result being written.
    out_dir : str or pathlib.Path
    value : bool
        The keyword's value.
    where : str
        The call, for the message, e.g. ``"Diagnosis.write(figures=...)"``.

    Returns
    -------
    dict
        Figure paths keyed by file stem (empty for ``False``).
    """
    warnings.warn(f"{where} is deprecated: write() writes the data and "
                  "bayes_mpem.report.write_figures(result, out_dir) the figures",
                  DeprecationWarning, stacklevel=3)
    if not value:
        return {}
    report = importlib.import_module("bayes_mpem.report")
    return {p.stem: p for p in report.write_figures(result, out_dir)}


def install() -> None:
    """Register the old module paths (``import bayes_mpem.em`` keeps working)."""
    for old in MOVED:
        sys.modules.setdefault(f"bayes_mpem.{old}", _MovedModule(old))
