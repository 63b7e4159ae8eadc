"""Locate every transponder of a ranging survey file (``bayes-mpem locate``).

:func:`locate_survey` takes a :class:`~bayes_mpem.io.raw.RawSurvey` (a deck-box
log or a SeaGap folder), picks the sound-speed profile it names
(:func:`survey_profile`) and the geometry of its format, runs
:func:`~.location.locate` on each transponder and returns a
:class:`~.result.SurveyInResult`.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..exceptions import InputError
from ..io.geodesy import MEAN_EARTH_RADIUS_M, earth_radius, enu_to_geodetic
from .location import DEFAULT_TAT, locate
from .result import SurveyInResult

#: SeaGap's default depth of the ship's transducer below the sea surface (m)
#: (``XDUCER_DEPTH`` in SeaGap); it places the profile against the ellipsoidal heights.
SEAGAP_TRANSDUCER_DEPTH = 3.0


def survey_profile(raw, ssp):
    """Return the sound-speed profile ``ssp`` names for a survey.

    Parameters
    ----------
    raw : RawSurvey
    ssp : None, SoundSpeedProfile, str or path
        As for :func:`locate_survey`.

    Returns
    -------
    SoundSpeedProfile or None
        ``None`` for straight rays.

    Raises
    ------
    bayes_mpem.InputError
        When the survey lacks what ``ssp`` asks for (its own profile, a position).
    """
    from ..acoustics.profile import SoundSpeedProfile

    if ssp is None or isinstance(ssp, SoundSpeedProfile):
        return ssp
    if str(ssp) == "survey":
        prof = raw.header.get("ss_prof")
        if prof is None:
            raise InputError(f"ssp='survey': {raw.source} came with no sound-speed profile "
                             "(SeaGap's ss_prof.inp); give a file or 'woa09'")
        return SoundSpeedProfile(prof["depth"], prof["sound_speed"], source="ss_prof.inp")
    if str(ssp) == "woa09":
        if "lat" not in raw.header:
            raise InputError(f"ssp='woa09': {raw.source} has no latitude/longitude to look the "
                             "atlas up at; give a profile file")
        return SoundSpeedProfile.from_woa09(raw.header["lat"], raw.header["lon"])
    return SoundSpeedProfile.from_file(ssp)


def locate_survey(raw, *, tat=None, fit_tat=False, ci=0.95, outliers="uniform", ssp=None,
                  speed_intervals=0, fit_lag=False):
    """Locate every transponder of a :class:`~bayes_mpem.io.raw.RawSurvey`.

    Parameters
    ----------
    raw : RawSurvey
    tat : float, optional
        Default: the file's TAT, else :data:`DEFAULT_TAT` for deck-box logs and 0
        for SeaGap (whose travel times are already corrected).
    fit_tat : bool, default False
    ci : float, default 0.95
    outliers : {"uniform", "first_arrival"}
        The spurious-ping model (:func:`locate`).
    ssp : None, SoundSpeedProfile, str or path
        Refracted rays through a profile: a :class:`~bayes_mpem.acoustics.SoundSpeedProfile`,
        a two-column file (depth m, speed m/s), ``"woa09"`` (the atlas at the drop
        point) or ``"survey"`` (the profile that came with the survey, SeaGap's
        ``ss_prof.inp``). Default: straight rays.
    speed_intervals : int, default 0
        A sound speed varying in time (:func:`locate`).
    fit_lag : bool, default False
        Fit a lag of the acoustic position along the track (:func:`locate`).

    Returns
    -------
    SurveyInResult
        ``summary`` (``{"transponders": {id: {"lat", "lon", "depth",
        "sound_speed", ...}}, ...}``) and ``classified`` (one row per ping line
        and per skipped line of the file, in file order: ``line``,
        ``transponder``, ``twtt``, ``p_true``, ``p_spurious``, ``label``
        (``true``, ``spurious`` or ``skipped``) and ``reason``); it writes
        both with ``write(out_dir)``; ``fits`` holds each transponder's
        :class:`~bayes_mpem.survey_in.location.LocateResult`.

    Notes
    -----
    SeaGap positions are distances along the Earth and ellipsoidal heights, so
    its surveys are located on a sphere (:func:`earth_radius`, at the header's
    latitude, else 6,371 km), with the sea surface
    :data:`SEAGAP_TRANSDUCER_DEPTH` above the mean transducer.
    """
    if tat is None:
        tat = raw.header.get("tat", 0.0 if raw.format == "seagap" else DEFAULT_TAT)
    pings, beacons = raw.to_pings()
    prof = survey_profile(raw, ssp)
    geo = {}
    if raw.format == "seagap":
        geo = {"earth_radius": earth_radius(raw.header["lat"]) if "lat" in raw.header
               else MEAN_EARTH_RADIUS_M,
               "surface_depth": float(pings["depth"].mean()) - SEAGAP_TRANSDUCER_DEPTH}
    out, fits, probs = {}, {}, np.full(len(pings), np.nan)
    for tid in beacons["beacon"].astype(str):
        try:
            fits[tid] = r = locate(pings, beacons, tid, tat=tat, fit_tat=fit_tat,
                                   outliers=outliers, ssp=prof, speed_intervals=speed_intervals,
                                   fit_lag=fit_lag, **geo)
        except InputError as exc:
            hint = (f" (speed_intervals={speed_intervals} needs {speed_intervals} more)"
                    if speed_intervals and "need at least" in str(exc) else "")
            raise InputError(f"{raw.source}: {exc}{hint}") from None
        probs[r.rows] = r.p_true
        d = r.to_dict(ci)
        if "lat" in raw.header:
            d["lat"], d["lon"], _ = enu_to_geodetic(r.east, r.north, 0.0, raw.header["lat"],
                                                    raw.header["lon"])
        else:
            d["lat"] = d["lon"] = None  # SeaGap: local frame only
        out[tid] = d
    cls = _classified(pings, probs, raw.skipped)
    rays = "straight rays" if prof is None else f"refracted rays ({prof.source or 'profile'})"
    summary = {"transponders": out, "format": raw.format, "source": raw.source,
               "n_pings": int(len(pings)), "n_skipped_lines": int(len(raw.skipped)),
               "method": f"EM, {rays}; intervals approximate (Wald)",
               "outliers": outliers, "ssp": None if prof is None else prof.source,
               "speed_intervals": int(speed_intervals), "fit_lag": bool(fit_lag),
               "geometry": geo,
               "tat_fitted": bool(fit_tat), "tat_given": None if fit_tat else float(tat)}
    return SurveyInResult(summary=summary, classified=cls, fits=fits)


def _classified(pings, probs, skipped):
    """Per line of the file: the ping's class probabilities, or why it was skipped."""
    lab = np.where(probs >= 0.5, "true", "spurious").astype(object)
    cls = pd.DataFrame({"line": pings["line"], "transponder": pings["beacon"].astype(str),
                        "twtt": pings["twtt"], "p_true": probs, "p_spurious": 1.0 - probs,
                        "label": lab, "reason": ""})
    if len(skipped):
        cls = pd.concat([cls, pd.DataFrame({"line": skipped["line"], "transponder": "",
                                            "twtt": np.nan, "p_true": np.nan,
                                            "p_spurious": np.nan, "label": "skipped",
                                            "reason": skipped["reason"]})], ignore_index=True)
    return cls.sort_values("line", kind="stable").reset_index(drop=True)
