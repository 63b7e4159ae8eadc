"""Locate every transponder of a ranging survey file (``bayes-mpem locate``)."""

from __future__ import annotations

import os

import numpy as np
import pandas as pd

from .._validate import check_probability, check_range
from ..exceptions import InputError
from ..io.boundary import LIMITS
from ..io.geodesy import MEAN_EARTH_RADIUS_M, earth_radius, enu_to_geodetic
from ..io.raw import ARRAY_FORMATS, RawSurvey
from .array_survey import locate_array_survey
from .drift import drift_from_fit
from .heldout import lag_check as heldout_lag_check
from .location import DEFAULT_TAT, locate
from .result import SurveyInResult, classified_table
from .ssp import survey_profile
from .travel_times import KNOT_MINUTES_RANGE

#: SeaGap's default depth of the ship's transducer below the sea surface (m)
#: (``XDUCER_DEPTH`` in SeaGap); it places the profile against the ellipsoidal heights.
SEAGAP_TRANSDUCER_DEPTH = 3.0


def is_array(raw, *, one_at_a_time=False) -> bool:
    """Whether ``locate_survey`` locates a survey's transponders together, as an array.

    GARPOS and GNATSS surveys always are; a SeaGap survey is when it has replies
    from two transponders or more (one ship track shared by the array), unless
    ``one_at_a_time``.

    Parameters
    ----------
    raw : RawSurvey
    one_at_a_time : bool, default False

    Returns
    -------
    bool
    """
    if raw.format in ARRAY_FORMATS:
        return True
    return (raw.format == "seagap" and not one_at_a_time
            and raw.pings["transponder"].astype(str).nunique() >= 2)


def seagap_surface_depth(raw) -> float:
    """Return the depth of a SeaGap array's sea surface in its frame (m below ``up = 0``).

    SeaGap's heights are not about the sea surface; the profile's surface is taken
    ``SEAGAP_TRANSDUCER_DEPTH`` (3 m) above the transducer's mean height (transmit and
    receive), as for one transponder at a time.

    Parameters
    ----------
    raw : RawSurvey
        A SeaGap survey.

    Returns
    -------
    float
        Negative where the surface is above the frame's origin.
    """
    up = raw.transducer_positions()
    return -0.5 * float(np.mean(up["tx"][2]) + np.mean(up["rx"][2])) - SEAGAP_TRANSDUCER_DEPTH


#: The options only an array survey takes, at their defaults (a survey of one transponder
#: refuses any other value: :func:`locate_survey`, and the batch's ``locate``).
ARRAY_ONLY_DEFAULTS = {"gradients": "auto", "knot_minutes": None, "flags": "honour",
                       "correlation": "auto", "position_prior": "auto"}


def locate_survey(raw, *, tat=None, fit_tat=False, ci=0.95, outliers="uniform", ssp=None,
                  speed_intervals=None, fit_lag=False, lag_check=False, one_at_a_time=False,
                  gradients="auto", knot_minutes=None, flags="honour", correlation="auto",
                  position_prior="auto"):
    """Locate every transponder of a :class:`~bayes_mpem.io.raw.RawSurvey`.

    Parameters
    ----------
    raw : RawSurvey
        A survey read by :func:`~bayes_mpem.io.formats.read_survey` (not its path).
    tat : float, optional
        Default: the file's TAT, else :data:`DEFAULT_TAT` for deck-box logs and 0
        for SeaGap (whose travel times are already corrected).
    fit_tat : bool, default False
    ci : float, default 0.95
        The probability of the intervals, in ``(0, 1)``.
    outliers : {"uniform", "first_arrival"}
        The spurious-ping model (:func:`locate`).
    ssp : None, SoundSpeedProfile, str or path
        Refracted rays through a profile: a :class:`~bayes_mpem.acoustics.SoundSpeedProfile`,
        a two-column file (depth m, speed m/s), ``"woa09"`` (the atlas at the drop
        point) or ``"survey"`` (the profile that came with the survey, SeaGap's
        ``ss_prof.inp``); ``"straight"`` or None for straight rays (None is the
        survey's own profile for an array survey).
    speed_intervals : int, optional
        A sound speed varying in time (:func:`locate`). None (the default): the smooth
        spline for an array survey (:func:`~bayes_mpem.survey_in.array_survey.locate_array_survey`,
        as ``bayes-mpem locate``), one speed (0) for one transponder at a time.
    fit_lag : bool, default False
        Fit a lag of the acoustic position along the track (:func:`locate`).
    lag_check : bool, default False
        Without ``fit_lag``: also test whether a lag would predict held-out pings
        better (:func:`~bayes_mpem.survey_in.heldout.lag_check`); reported under
        each transponder's ``lag_check``.
    one_at_a_time : bool, default False
        A SeaGap survey: locate each transponder on its own, with its own sound
        speed (on SeaGap's sphere), instead of the array together
        (:func:`is_array`); refused for GARPOS and GNATSS.
    gradients : {"auto", "on", "shallow", "off"}, default "auto"
        An array survey: its horizontal gradients (:func:`locate_array_survey`).
    knot_minutes : float, optional
        An array survey: the smooth speed's knot spacing (default 5 min), in
        :data:`~bayes_mpem.survey_in.travel_times.KNOT_MINUTES_RANGE` (0.1-1440 min).
    flags : {"honour", "reclassify"}, default "honour"
        An array survey: GARPOS's flagged shots left out or classified
        (:func:`locate_array_survey`).
    correlation : {"auto", "off"} or tuple of float, default "auto"
        An array survey: the replies' noise correlated in time and across
        transponders (:func:`locate_array_survey`); a one-transponder survey takes only
        the default.
    position_prior : {"auto", "site", "off"}, default "auto"
        An array survey: the site file's sigmas as priors on the positions (scaled up where
        they understate the fit's moves, or as given), or none (:func:`locate_array_survey`).

    Returns
    -------
    SurveyInResult
        ``summary`` (``{"transponders": {id: {"lat", "lon", "depth",
        "sound_speed", ...}}, ...}``; for a deck-box log also ``drift``,
        ``azimuth`` and ``depth_change`` from the drop point, each with its
        interval) and ``classified`` (one row per ping line and per skipped line
        of the file, in file order: ``line``, ``transponder``, ``twtt``,
        ``p_true``, ``p_spurious``, ``label`` (``true``, ``spurious`` or
        ``skipped``), ``reason`` and :data:`~.result.PING_COLUMNS`); it writes
        both with ``write(out_dir)``; ``fits`` holds each transponder's
        :class:`~bayes_mpem.survey_in.location.LocateResult`.

    Raises
    ------
    InputError
        ``raw`` not a RawSurvey (a path, say), ``ci`` not in ``(0, 1)``, ``knot_minutes``
        outside 0.1-1440 min, a turn-around time or a lag asked of an array survey (GNSS-A
        travel times are already corrected for delays), ``one_at_a_time`` for GARPOS or
        GNATSS, or ``correlation``, ``gradients``, ``knot_minutes``, ``flags`` or
        ``position_prior`` other than the default for a survey that is not an array.
    """
    ci, knot_minutes = _check_arguments(raw, ci, knot_minutes)
    if one_at_a_time and raw.format in ARRAY_FORMATS:
        raise InputError(f"one_at_a_time: a {raw.format} survey is located as an array")
    if is_array(raw, one_at_a_time=one_at_a_time):
        for name, given in (("fit_tat", fit_tat), ("fit_lag", fit_lag),
                            ("tat", tat not in (None, 0, 0.0))):
            if given:
                also = " or locate one transponder at a time" if raw.format == "seagap" else ""
                raise InputError(f"{name}: not for a {raw.format} array survey (its travel "
                                 f"times are already corrected for the delays; a lag is not "
                                 f"modelled){also}")
        geo = {}
        if raw.format == "seagap":  # the profile's sea surface, as one at a time
            geo["surface_depth"] = seagap_surface_depth(raw)
            if ssp is None:  # the survey's own profile when it came with one
                ssp = "survey" if "ss_prof" in raw.header else "straight"
        if knot_minutes is not None:
            geo["knot_minutes"] = knot_minutes
        res = locate_array_survey(raw, ci=ci, outliers=outliers, ssp=ssp,
                                  speed_intervals=speed_intervals, gradients=gradients,
                                  flags=flags, correlation=correlation,
                                  position_prior=position_prior, **geo)
        _profile_files(res.summary, ssp)
        return res
    given = {"correlation": correlation, "gradients": gradients, "knot_minutes": knot_minutes,
             "flags": flags, "position_prior": position_prior}
    for name, default in ARRAY_ONLY_DEFAULTS.items():
        value = given[name]
        if value != default:  # read and dropped in silence before
            raise InputError(f"{name}={value!r}: for array surveys only (GARPOS, GNATSS, "
                             "SeaGap with two transponders or more, not one at a time)")
    if speed_intervals is None:
        speed_intervals = 0
    if tat is None:
        tat = raw.header.get("tat", 0.0 if raw.format == "seagap" else DEFAULT_TAT)
    twtt = raw.pings["twtt"].to_numpy(float) if "twtt" in raw.pings.columns else np.array([])
    twtt = twtt[np.isfinite(twtt)]
    if twtt.size and not fit_tat and tat >= np.median(twtt):  # every range 0 or negative
        raise InputError(f"tat (--tat) {tat:g} s: not shorter than the median two-way travel "
                         f"time ({np.median(twtt):.4g} s); expected the transponder's "
                         "turn-around time, a few milliseconds (in s)")
    pings, beacons = raw.to_pings()
    prof = survey_profile(raw, ssp)
    geo = {}
    if raw.format == "seagap":
        geo = {"earth_radius": earth_radius(raw.header["lat"]) if "lat" in raw.header
               else MEAN_EARTH_RADIUS_M,
               "surface_depth": float(pings["depth"].mean()) - SEAGAP_TRANSDUCER_DEPTH}
    n = len(pings)
    out, fits = {}, {}
    probs, resid, azim = np.full(n, np.nan), np.full(n, np.nan), np.full(n, np.nan)
    model = dict(tat=tat, fit_tat=fit_tat, outliers=outliers, ssp=prof,
                 speed_intervals=speed_intervals, **geo)
    skipped_tps = {}
    heard = set(pings["beacon"].astype(str))
    for tid in beacons["beacon"].astype(str):
        if tid not in heard:  # listed (SeaGap's pxp-ini.inp) but never heard: nothing to fit
            skipped_tps[tid] = "no replies in the survey"
            continue
        try:
            fits[tid] = r = locate(pings, beacons, tid, fit_lag=fit_lag, **model)
        except InputError as exc:
            hint = (f" (speed_intervals={speed_intervals} needs {speed_intervals} more)"
                    if speed_intervals and "need at least" in str(exc) else "")
            raise InputError(f"{raw.source}: {exc}{hint}") from None
        _check_located(raw, pings, tid, r)
        sub = pings.iloc[r.rows]
        probs[r.rows] = r.p_true
        resid[r.rows] = 1e3 * (sub["twtt"].to_numpy() - r.predict(sub))
        azim[r.rows] = np.degrees(np.arctan2(sub["x"].to_numpy() - r.east,
                                             sub["y"].to_numpy() - r.north)) % 360.0
        out[tid] = _entry(raw, r, ci)
        if lag_check and not fit_lag:
            out[tid]["lag_check"] = heldout_lag_check(pings, beacons, tid, **model)
    table = pd.DataFrame({"line": pings["line"], "transponder": pings["beacon"].astype(str),
                          "twtt": pings["twtt"], "time": pings["time"], "east": pings["x"],
                          "north": pings["y"], "residual_ms": resid, "azimuth_deg": azim})
    cls = classified_table(table, probs, raw.skipped)
    rays = "straight rays" if prof is None else f"refracted rays ({prof.source or 'profile'})"
    summary = {"transponders": out, "format": raw.format, "source": raw.source,
               "n_pings": int(n), "n_skipped_lines": int(len(raw.skipped)),
               "method": f"EM, {rays}; intervals approximate (Wald)",
               "outliers": outliers, "ssp": None if prof is None else prof.source,
               "speed_intervals": int(speed_intervals), "fit_lag": bool(fit_lag),
               "geometry": geo, "skipped_transponders": skipped_tps,
               "tat_fitted": bool(fit_tat), "tat_given": None if fit_tat else float(tat)}
    if "lat" in raw.header and raw.format != "seagap":
        summary["drop_point"] = {k: raw.header.get(k) for k in ("lat", "lon", "depth")}
    return SurveyInResult(summary=summary, classified=cls, fits=fits)


def _check_arguments(raw, ci, knot_minutes):
    """Return ``ci`` and ``knot_minutes`` as floats, refusing what ``locate`` refuses too.

    Before any work: a ``raw`` that is not a survey read (a path), a ``ci`` outside (0, 1),
    a ``knot_minutes`` outside :data:`KNOT_MINUTES_RANGE`. Unchecked, ``ci=95`` or NaN gave
    intervals of NaN written as a "9500 % region", 0 or 1 zero-width or infinite ones,
    ``"0.95"`` a TypeError deep inside (now read as 0.95, as every check of ``_validate``
    reads a number); ``knot_minutes=1e-9`` asked 445 GiB before the fit's size check (which,
    within these bounds, runs before any large array).
    """
    if not isinstance(raw, RawSurvey):
        if isinstance(raw, (str, os.PathLike)):
            got = (f"the path {os.fspath(raw)!r}; read it first: "
                   "locate_survey(read_survey(path))")
        else:
            got = f"a {type(raw).__name__}"
        raise InputError("raw: expected a RawSurvey (what bayes_mpem.io.formats.read_survey "
                         f"returns), got {got}")
    try:
        ci = check_probability("ci", ci)
    except ValueError as exc:
        raise InputError(str(exc)) from None
    low, high = KNOT_MINUTES_RANGE
    if knot_minutes is not None:
        try:
            knot_minutes = check_range("knot_minutes", knot_minutes, low=low, high=high,
                                       include_low=True, include_high=True)
        except ValueError as exc:
            raise InputError(f"{exc} (a knot spacing in minutes; below {low:g} it only "
                             "costs memory)") from None
    return ci, knot_minutes


#: The keys of ``input_files`` that name a survey's own sound-speed profile (GARPOS's
#: ``svp.csv``, GNATSS's ``sound_speed`` files, SeaGap's ``ss_prof.inp``).
SURVEY_PROFILE_FILES = ("svp", "sound_speed", "ss_prof")


def _profile_files(summary: dict, ssp) -> None:
    """Make an array summary's ``input_files`` name the profile the fit used.

    With ``ssp`` other than the survey's own, the survey's profile file was read but not
    used: it moves to ``input_files["not_used"]``, and a profile file ``ssp`` names is listed
    as ``input_files["ssp"]`` (before, ``svp.csv`` was listed and the file used was not).
    """
    files = summary.get("input_files")
    if not isinstance(files, dict) or ssp is None or str(ssp) == "survey":
        return
    unused = {k: files.pop(k) for k in SURVEY_PROFILE_FILES if files.get(k)}
    if unused:
        files["not_used"] = unused
    if isinstance(ssp, (str, os.PathLike)) and str(ssp) not in ("straight", "woa09"):
        files["ssp"] = os.fspath(ssp)


def _check_located(raw, pings, tid, r) -> None:
    """Refuse a transponder located above the transducers, or with a speed no water has.

    Ranges cannot tell a point below the transducers from its mirror above them; from a
    drop position some kilometres off (a slipped digit or sign) the fit went to the mirror,
    4.7 km above the sea at exit 0 with a tight interval, or called every ping spurious with
    a sound speed of 742,025 m/s.
    """
    drop = (f"the drop position in {raw.source} (lat {raw.header['lat']}, lon "
            f"{raw.header['lon']})" if "lat" in raw.header else f"the start in {raw.source}")
    shallowest = float(np.nanmin(pings["depth"].to_numpy(float)))  # depths positive down
    if not r.depth > shallowest:
        raise InputError(
            f"transponder {tid}: located at depth {r.depth:,.1f} m, above the transducers "
            f"(the shallowest at {shallowest:,.1f} m): the mirror of a position below them. "
            "Its ranges do not fit "
            f"a transponder near {drop}, {np.hypot(r.east, r.north) / 1e3:,.1f} km from where "
            "the fit went; check that position (a digit or a sign slipped?)")
    low, high = LIMITS["sound_speed"].low, LIMITS["sound_speed"].high
    if not low <= r.sound_speed <= high:
        raise InputError(
            f"transponder {tid}: fitted sound speed {r.sound_speed:,.1f} m/s, outside "
            f"{low:g}-{high:g} m/s ({r.n_spurious} of its {r.p_true.size} pings called "
            f"spurious): its ranges do not fit a transponder near {drop}; check that position "
            "(a digit or a sign slipped?) and the turn-around time")


def _entry(raw, r, ci):
    """Build a transponder's summary entry: the fit, its position and its drift."""
    d = r.to_dict(ci)
    d["covariance"] = {"names": ["east", "north", "depth"],
                       "matrix": [[float(v) for v in row] for row in r.cov]}
    if "lat" in raw.header:
        d["lat"], d["lon"], _ = enu_to_geodetic(r.east, r.north, 0.0, raw.header["lat"],
                                                raw.header["lon"])
    else:
        d["lat"] = d["lon"] = None  # SeaGap: local frame only
    if "lat" in raw.header and raw.format != "seagap":  # the frame's origin is the drop point
        d.update(drift_from_fit(r.east, r.north, r.depth, r.cov, raw.header.get("depth"),
                                ci=ci))
    return d
