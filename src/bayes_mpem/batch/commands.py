"""How a batch runs a command on one survey (its ``Batch`` entry), and what it keeps of it."""

from __future__ import annotations

import json

from ..commands import COMMANDS as ALL
from ..commands import load
from ..exceptions import InputError

#: The commands a batch can run, by name (``bayes-mpem batch --command``): their batch entries.
COMMANDS = {name: c.batch for name, c in ALL.items() if c.batch is not None}
#: the options of an array survey's location (GARPOS, GNATSS): no TAT or lag
ARRAY_OPTIONS = ("ci", "outliers", "ssp", "speed_intervals", "gradients", "knot_minutes",
                 "flags", "correlation", "position_prior")


def run(command: str, inputs: dict, options: dict):
    """Return the result of a batch command on one survey.

    Parameters
    ----------
    command : str
        A key of :data:`COMMANDS`.
    inputs, options : dict
        The survey's manifest inputs; the library call's keyword arguments.
    """
    spec = COMMANDS[command]
    if spec.quiet:
        options = {"progress": False, **options}
    return load(spec.run)(*(inputs[c] for c in spec.inputs), **options)


def survey_rows(result):
    """Per-beacon summaries and the classified table of a fit, a posterior or a navigation."""
    return result.summary()["beacons"], result.classified()


def locate_rows(result):
    """Per-transponder summaries and the classified table of a located survey; an array's centre.

    The third item holds the survey's own fields (``surveys.parquet``): an array survey's
    centre (``centre_enu_east_mean`` ...; ``centre_transponders``) and ``centre_note`` where a
    transponder was not located (the centre is then another point: averaged from the
    transponders' rows, a campaign without M04 was 250 m from the full array's).
    """
    from ..survey_in.result import centre_note

    s = result.summary
    fields = {}
    if "array_centre" in s:
        c = s["array_centre"]
        fields = {"centre": {"enu": c["enu"], "lat": c.get("lat"), "lon": c.get("lon"),
                             "height": c.get("height"),
                             "transponders": ",".join(map(str, c.get("transponders", [])))},
                  "centre_note": centre_note(s) or ""}
    return s["transponders"], result.classified, fields


def diagnosis_rows(result):
    """Per-beacon final-model summaries of a diagnosis, with the effects found; no table."""
    d = result.to_dict()
    effects = ",".join(e["name"] for e in d["effects"]) or "none"
    return {b: {**v, "effects": effects} for b, v in d["final_model"]["beacons"].items()}, None


def locate_raw(raw, options: dict):
    """Locate the transponders of a read survey, sampling their posteriors if asked.

    Parameters
    ----------
    raw : RawSurvey
    options : dict
        Keyword arguments of :func:`~bayes_mpem.survey_in.survey.locate_survey`;
        ``sample``: None or the sampler's of
        :func:`~bayes_mpem.survey_in.location_sampling.locate_survey_bayes` (an array's:
        :func:`~bayes_mpem.survey_in.array_sampling.locate_array_survey_bayes`);
        ``lag_check`` (deck-box logs, not sampled). An array survey takes only
        :data:`ARRAY_OPTIONS`.

    Returns
    -------
    SurveyInResult

    Raises
    ------
    InputError
        For TAT or lag options given for an array survey.
    """
    from ..survey_in.location_sampling import locate_survey_bayes
    from ..survey_in.result import SurveyInResult
    from ..survey_in.survey import ARRAY_ONLY_DEFAULTS, is_array, locate_survey

    options = dict(options)
    sampling = options.pop("sample", None)
    lag_check = options.pop("lag_check", False)
    if is_array(raw, one_at_a_time=bool(options.get("one_at_a_time"))):
        options.pop("one_at_a_time", None)
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
    # a SeaGap survey read as an array may have one transponder: the array's options at
    # their defaults are dropped (one speed for the smooth one), any other refused
    given = []
    for key, default in ARRAY_ONLY_DEFAULTS.items():
        if key in options and options.pop(key) != default:
            given.append(key)
    if given:
        raise InputError(f"{', '.join(given)}: for array surveys only (this {raw.format} "
                         "survey has one transponder)")
    if "speed_intervals" in options and options["speed_intervals"] is None:
        options["speed_intervals"] = 0
    if sampling is None:
        return locate_survey(raw, **options,
                             lag_check=bool(lag_check) and raw.format.startswith("obsrange"))
    summary, classified, posteriors = locate_survey_bayes(raw, **options, **sampling)
    return SurveyInResult(summary=summary, classified=classified, posteriors=posteriors)


def locate_file(survey, format, **options):  # noqa: A002 - the manifest's column
    """Read a survey file and locate it.

    Parameters
    ----------
    survey, format : str
        The manifest's columns: the file and its format.
    **options
        As :func:`locate_raw`'s ``options``.
    """
    from ..io.formats import read_survey

    return locate_raw(read_survey(survey, format), options)


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


