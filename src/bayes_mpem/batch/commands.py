"""The commands a batch runs, one entry each: how to run one on a survey, and what to keep.

Adding a command to ``bayes-mpem batch`` is one more entry of :data:`COMMANDS`, with its
option builder in :data:`bayes_mpem.cli.batch.KWARGS` and its name in the parser's choices.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass, field

from ..exceptions import InputError

LBL_INPUTS = ("pings", "beacons")
SURVEY_INPUTS = ("survey", "format")
#: the options of an array survey's location (GARPOS, GNATSS): no TAT or lag
ARRAY_OPTIONS = ("ci", "outliers", "ssp", "speed_intervals")


def _run_fit(inputs, options):
    from ..lbl.survey.fitting import fit

    return fit(inputs["pings"], inputs["beacons"], **options)


def _run_sample(inputs, options):
    from ..lbl.survey.sampling import sample

    return sample(inputs["pings"], inputs["beacons"], **{"progress": False, **options})


def _run_diagnose(inputs, options):
    from ..lbl.diagnosis.driver import diagnose

    return diagnose(inputs["pings"], inputs["beacons"], **{"progress": False, **options})


def _run_navigate(inputs, options):
    from ..lbl.navigate import navigate

    return navigate(inputs["pings"], inputs["beacons"], **options)


def locate_raw(raw, options: dict):
    """Locate the transponders of a read survey, sampling their posteriors if asked.

    Parameters
    ----------
    raw : RawSurvey
    options : dict
        Keyword arguments of :func:`~bayes_mpem.survey_in.survey.locate_survey`,
        and ``sample``: None, or those of
        :func:`~bayes_mpem.survey_in.location_sampling.locate_survey_bayes`'s sampler;
        ``lag_check``: look for a lag along the track (deck-box logs only, not sampled).
        An array survey (:data:`~bayes_mpem.io.raw.ARRAY_FORMATS`) takes only
        :data:`ARRAY_OPTIONS` (and ``sample``: those of
        :func:`~bayes_mpem.survey_in.array_sampling.locate_array_survey_bayes`).

    Returns
    -------
    SurveyInResult

    Raises
    ------
    InputError
        For TAT or lag options given for an array survey.
    """
    from ..io.raw import ARRAY_FORMATS
    from ..survey_in.location_sampling import locate_survey_bayes
    from ..survey_in.result import SurveyInResult
    from ..survey_in.survey import locate_survey

    options = dict(options)
    sampling = options.pop("sample", None)
    lag_check = options.pop("lag_check", False)
    if raw.format in ARRAY_FORMATS:
        given = sorted(k for k, v in options.items()
                       if k not in ARRAY_OPTIONS and v not in (None, False))
        if given:
            raise InputError(f"{', '.join(given)}: not for a {raw.format} array survey (its "
                             "travel times are corrected for the delays)")
        array = {k: v for k, v in options.items() if k in ARRAY_OPTIONS}
        if sampling is None:
            return locate_survey(raw, **array)
        from ..survey_in.array_sampling import locate_array_survey_bayes

        return locate_array_survey_bayes(raw, **array, **sampling)
    if sampling is None:
        return locate_survey(raw, **options,
                             lag_check=bool(lag_check) and raw.format.startswith("obsrange"))
    summary, classified, posteriors = locate_survey_bayes(raw, **options, **sampling)
    return SurveyInResult(summary=summary, classified=classified, posteriors=posteriors)


def _run_locate(inputs, options):
    from ..io.formats import read_survey

    return locate_raw(read_survey(inputs["survey"], inputs["format"]), options)


@dataclass(frozen=True)
class Command:
    """How the batch runs one command on one survey.

    Attributes
    ----------
    name : str
    inputs : tuple of str
        Manifest columns naming the survey's inputs (files, or the ``format``).
    files : tuple of str
        Those of ``inputs`` that are files (hashed, resolved against the manifest).
    run : callable
        ``run(inputs, options)`` returns the command's result (with ``write``).
    beacons : callable
        ``beacons(result)`` returns ``{beacon id: summary dict}``.
    classified : callable or None
        ``classified(result)`` returns the classified table, if the command has one.
    """

    name: str
    inputs: tuple
    files: tuple
    run: Callable = field(repr=False)
    beacons: Callable = field(repr=False)
    classified: Callable | None = field(default=None, repr=False)


def _diagnosis_beacons(result) -> dict:
    d = result.to_dict()
    effects = ",".join(e["name"] for e in d["effects"]) or "none"
    return {b: {**v, "effects": effects} for b, v in d["final_model"]["beacons"].items()}


#: The commands a batch can run, by name (``bayes-mpem batch --command``).
COMMANDS = {
    "fit": Command("fit", LBL_INPUTS, LBL_INPUTS, _run_fit,
                   lambda r: r.summary()["beacons"], lambda r: r.classified()),
    "sample": Command("sample", LBL_INPUTS, LBL_INPUTS, _run_sample,
                      lambda r: r.summary()["beacons"], lambda r: r.classified()),
    "diagnose": Command("diagnose", LBL_INPUTS, LBL_INPUTS, _run_diagnose, _diagnosis_beacons),
    "navigate": Command("navigate", LBL_INPUTS, LBL_INPUTS, _run_navigate,
                        lambda r: r.summary()["beacons"], lambda r: r.classified()),
    "locate": Command("locate", SURVEY_INPUTS, ("survey",), _run_locate,
                      lambda r: r.summary["transponders"], lambda r: r.classified),
}


def flatten(d: dict, prefix: str = "") -> dict:
    """Flatten a nested summary into one row: keys joined by ``_``, short lists numbered.

    Parameters
    ----------
    d : dict
    prefix : str, default ""

    Returns
    -------
    dict
        Scalars (and JSON text for what is neither a scalar nor a short list of them).

    Examples
    --------
    >>> flatten({"d0": {"mean": 1.0, "interval": [0.5, 1.5]}, "flags": []})
    {'d0_mean': 1.0, 'd0_interval_0': 0.5, 'd0_interval_1': 1.5, 'flags': '[]'}
    """
    out = {}
    for k, v in d.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict):
            out.update(flatten(v, key + "_"))
        elif (isinstance(v, (list, tuple)) and 0 < len(v) <= 4
              and all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in v)):
            out.update({f"{key}_{i}": x for i, x in enumerate(v)})
        elif isinstance(v, (list, tuple)):
            out[key] = json.dumps(v, default=str)
        else:
            out[key] = v
    return out


