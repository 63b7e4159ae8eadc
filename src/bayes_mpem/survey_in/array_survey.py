"""Locate the transponders of a GNSS-acoustic array survey (GARPOS, GNATSS) together."""

from __future__ import annotations

import numpy as np
import pandas as pd
from scipy.stats import chi2

from ..exceptions import InputError
from ..io.geodesy import enu_to_geodetic
from ..io.raw import ARRAY_FORMATS
from .array import describe, locate_array
from .result import SurveyInResult, classified_table
from .ssp import survey_profile


def array_shots(raw) -> pd.DataFrame:
    """Return an array survey's shots with the transducer's east, north, up at transmit and receive.

    Parameters
    ----------
    raw : RawSurvey
        Of format ``garpos`` or ``gnatss``.

    Returns
    -------
    pandas.DataFrame
        ``raw.pings`` with ``e/n/u_tx`` and ``e/n/u_rx`` replaced by the
        transducer's (:meth:`~bayes_mpem.io.raw.RawSurvey.transducer_positions`).

    Raises
    ------
    InputError
        For another format.
    """
    if raw.format not in ARRAY_FORMATS:
        raise InputError(f"{raw.source}: a {raw.format} survey is not an array survey "
                         f"({', '.join(ARRAY_FORMATS)})")
    pos = raw.transducer_positions()
    shots = raw.pings.copy()
    for end in ("tx", "rx"):
        for c, v in zip("enu", pos[end], strict=True):
            shots[f"{c}_{end}"] = v
    return shots


def _transponder_entry(fit, k, ci, origin, n_shots):
    e, n, u = fit.enu[k]
    sd = fit.sd[k]
    C = fit.position_cov(k)
    lat, lon, h = enu_to_geodetic(e, n, u, *origin)
    start = fit.start[k]
    return {"east": describe(e, sd[0], ci), "north": describe(n, sd[1], ci),
            "depth": describe(-u, sd[2], ci),
            "sound_speed": describe(fit.sound_speed, fit.sound_speed_sd, ci),
            "tat": {"mean": 0.0, "sd": 0.0, "fitted": False},
            "sigma_ms": 1e3 * fit.sigma, "weight_true": float(fit.weights[k]),
            "n_spurious": fit.n_spurious(k), "n": int(n_shots), "iterations": fit.n_iter,
            "converged": fit.converged, "ci": ci, "lat": lat, "lon": lon, "height": h,
            "enu": {"east": describe(e, sd[0], ci), "north": describe(n, sd[1], ci),
                    "up": describe(u, sd[2], ci)},
            "covariance": {"names": ["east", "north", "up"],
                           "matrix": [[float(v) for v in row] for row in C]},
            "prior": {"east": float(start[0]), "north": float(start[1]), "up": float(start[2])},
            "moved_m": float(np.linalg.norm(fit.enu[k] - start))}


def _centre_entry(fit, ci, origin):
    m, C = fit.centre()
    sd = np.sqrt(np.clip(np.diag(C), 0.0, None))
    lat, lon, h = enu_to_geodetic(*m, *origin)
    return {"enu": {c: describe(v, s, ci) for c, v, s in zip(("east", "north", "up"), m, sd,
                                                              strict=True)},
            "lat": lat, "lon": lon, "height": h,
            "covariance": {"names": ["east", "north", "up"],
                           "matrix": [[float(v) for v in row] for row in C]}}


def locate_array_survey(raw, *, ci=0.95, outliers="uniform", ssp=None,
                        speed_intervals=0) -> SurveyInResult:
    """Locate every transponder of a GNSS-A array survey together.

    Parameters
    ----------
    raw : RawSurvey
        Of format ``garpos`` or ``gnatss``.
    ci : float, default 0.95
    outliers : {"uniform", "first_arrival"}
    ssp : None, SoundSpeedProfile, str or path
        None (default): the survey's own profile; ``"straight"``: straight rays;
        otherwise as for :func:`~.ssp.survey_profile`.
    speed_intervals : int, default 0
        The sound speed (the profile's scale) as a cubic B-spline in time with
        this many intervals, shared by the array. GNSS-A surveys last hours and
        the ocean changes in that time: one interval per 15-30 minutes.

    Returns
    -------
    SurveyInResult
        ``summary``: ``transponders`` (as :func:`~.survey.locate_survey`, plus
        ``enu``, ``height``, ``covariance``, ``prior``, ``moved_m``),
        ``array_centre``, ``sound_speed``, the survey's ``origin`` and files;
        ``classified``: one row per shot and per skipped line.
    """
    shots = array_shots(raw)
    prof = survey_profile(raw, "survey" if ssp is None else ssp)
    h = raw.header
    fit = locate_array(shots, h["transponders"], profile=prof,
                       surface_depth=float(h.get("surface_depth", 0.0)),
                       speed_intervals=speed_intervals, outliers=outliers)
    origin = (h["lat"], h["lon"], h.get("height", 0.0))
    counts = np.bincount(fit.index, minlength=len(fit.ids))
    out = {tid: _transponder_entry(fit, k, ci, origin, counts[k])
           for k, tid in enumerate(fit.ids)}
    n = len(shots)
    probs, resid, azim = np.full(n, np.nan), np.full(n, np.nan), np.full(n, np.nan)
    probs[fit.rows], resid[fit.rows] = fit.p_true, 1e3 * fit.residual
    sub = shots.iloc[fit.rows]
    e_mid = 0.5 * (sub["e_tx"].to_numpy() + sub["e_rx"].to_numpy())
    n_mid = 0.5 * (sub["n_tx"].to_numpy() + sub["n_rx"].to_numpy())
    azim[fit.rows] = np.degrees(np.arctan2(e_mid - fit.enu[fit.index, 0],
                                           n_mid - fit.enu[fit.index, 1])) % 360.0
    reasons = np.full(n, "", dtype=object)
    tid = shots["transponder"].astype(str).to_numpy()
    for t, why in fit.skipped.items():
        reasons[tid == t] = f"transponder {t} not located: {why}"
    table = pd.DataFrame({"line": shots["line"], "transponder": tid, "twtt": shots["twtt"],
                          "time": shots["time"],
                          "east": 0.5 * (shots["e_tx"] + shots["e_rx"]),
                          "north": 0.5 * (shots["n_tx"] + shots["n_rx"]),
                          "residual_ms": resid, "azimuth_deg": azim})
    extra = [c for c in ("file_flag",) if c in shots.columns]
    for c in (*extra, "file"):
        if c in shots.columns:
            table[c] = shots[c].to_numpy()
    cls = classified_table(table, probs, raw.skipped, reasons=reasons, extra=extra)
    rays = "straight rays" if prof is None else f"refracted rays ({prof.source or 'profile'})"
    summary = {
        "transponders": out, "array_centre": _centre_entry(fit, ci, origin),
        "sound_speed": {**describe(fit.sound_speed, fit.sound_speed_sd, ci),
                        "coefficients": [float(v) for v in fit.speed_coef],
                        "unit": "m/s" if prof is None else "scale of the profile"},
        "format": raw.format, "source": raw.source, "files": h.get("files", {}),
        "n_pings": int(n), "n_skipped_lines": int(len(raw.skipped)),
        "skipped_transponders": dict(fit.skipped),
        "method": f"array EM, {rays}; intervals approximate (Wald, cluster-robust by "
                  "interrogation)",
        "outliers": outliers, "ssp": None if prof is None else prof.source,
        "speed_intervals": int(speed_intervals), "fit_lag": False,
        "geometry": {"frame": "local east, north, up about the origin (m)",
                     "origin": dict(zip(("lat", "lon", "height"), map(float, origin),
                                        strict=True)),
                     "surface_depth": float(h.get("surface_depth", 0.0))},
        "tat_fitted": False, "tat_given": 0.0,
        "position_region": f"a transponder's {100 * ci:g} % region is the ellipsoid of its "
                           f"covariance with squared radius {chi2.ppf(ci, 3):.4f}"}
    if "file_flag" in shots.columns:
        flagged = shots["file_flag"].to_numpy(bool)
        summary["file_flags"] = {"n_flagged": int(flagged.sum()),
                                 "n_flagged_called_spurious": int(np.sum(flagged & (probs < 0.5)))}
    return SurveyInResult(summary=summary, classified=cls, fits={"array": fit})
