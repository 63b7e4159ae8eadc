"""Locate the transponders of a GNSS-acoustic array survey (GARPOS, GNATSS) together."""

from __future__ import annotations

import dataclasses
import warnings
from datetime import timedelta

import numpy as np
import pandas as pd
from scipy.stats import chi2

from ..exceptions import InputError, LocateWarning
from ..io.geodesy import MEAN_EARTH_RADIUS_M, earth_radius, enu_to_geodetic
from ..io.raw import ARRAY_FORMATS, skip_reasons
from .array import (
    KNOT_MINUTES,
    MIN_PRIOR_SD,
    describe,
    locate_array,
    prior_scale,
    prior_scale_spread,
)
from .result import SurveyInResult, classified_table
from .ssp import survey_profile
from .travel_times import speed_basis


def _shots_file(raw) -> str:
    """Name the file of a survey's shots (GARPOS's obs.csv, GNATSS's travel times)."""
    files = raw.header.get("files", {})
    return files.get("obs") or ", ".join(files.get("travel_times", [])) or raw.source


#: The longest a campaign's shots may span (days): more is two time scales mixed, or
#: several campaigns in one file (each is located on its own).
MAX_CAMPAIGN_DAYS = 30.0


def _largest_jump(pings, t):
    """Return the largest jump of the times ``t`` (s): ``(before, after)``, each ``(where, t)``.

    ``where`` names the shot: ``line N`` (with its file where the survey has several), else
    ``shot N``.
    """
    order = np.argsort(t, kind="stable")
    j = int(np.argmax(np.diff(t[order])))

    def at(k):
        row = pings.iloc[k]
        where = f"line {int(row['line'])}" if "line" in pings.columns else f"shot {row.name}"
        return f"{row['file']} {where}" if "file" in pings.columns else where

    return tuple((at(order[i]), float(t[order[i]])) for i in (j, j + 1))


def _check_span(raw) -> None:
    """Refuse shots spanning more than :data:`MAX_CAMPAIGN_DAYS`, naming the largest jump."""
    p = raw.pings
    t = p["t_tx"].to_numpy(float) if "t_tx" in p.columns else p["time"].to_numpy(float)
    if t.size < 2 or np.ptp(t) <= MAX_CAMPAIGN_DAYS * 86400.0:
        return
    (a, ta), (b, tb) = _largest_jump(p, t)
    raise InputError(f"{_shots_file(raw)}: the shots span {np.ptp(t) / 86400.0:,.0f} days; "
                     f"expected one campaign, its shots within {MAX_CAMPAIGN_DAYS:g} days. The "
                     f"largest jump in time, {tb - ta:.6g} s, is between "
                     f"{a} ({ta:.6g} s) and {b} ({tb:.6g} s): two "
                     "time scales mixed? (several campaigns: give each its own file)")


def _check_midnight(raw) -> None:
    """Warn where GARPOS's shot times look restarted at 0 after midnight.

    ``ST`` counts seconds from the start of the site file's day and goes on past 86,400 s;
    times restarted at midnight put the campaign's two halves at both ends of one day, with
    a gap of most of it between them. Read as given, such a campaign spans nearly 24 h.
    """
    if raw.format != "garpos" or "time" not in raw.pings.columns or len(raw.pings) < 2:
        return
    p = raw.pings
    t = p["time"].to_numpy(float)
    if not (t.min() >= 0.0 and t.min() < 3600.0 and 82800.0 < t.max() < 86400.0):
        return
    (a, ta), (b, tb) = _largest_jump(p, t)
    if tb - ta < 12 * 3600.0:
        return
    warnings.warn(f"{_shots_file(raw)}: the shots' times jump by {(tb - ta) / 3600.0:.1f} h, "
                  f"from {ta:.1f} s ({a}) to {tb:.1f} s ({b}), and reach both ends of the "
                  "day: times that "
                  "restart at 0 after midnight? GARPOS's ST counts on past 86,400 s; as read, "
                  f"the campaign spans {np.ptp(t) / 3600.0:.2f} h", LocateWarning, stacklevel=3)


def array_shots(raw) -> pd.DataFrame:
    """Return an array survey's shots with the transducer's east, north, up at transmit and receive.

    Parameters
    ----------
    raw : RawSurvey
        Of format ``garpos``, ``gnatss`` or ``seagap`` (whose 18 columns give the
        antenna and attitude at transmit and at receive).

    Returns
    -------
    pandas.DataFrame
        ``raw.pings`` with ``e/n/u_tx`` and ``e/n/u_rx`` replaced by the
        transducer's (:meth:`~bayes_mpem.io.raw.RawSurvey.transducer_positions`).

    Raises
    ------
    InputError
        For another format, shots all transmitted from one place, or shots spanning more than
        :data:`MAX_CAMPAIGN_DAYS`.
    """
    if raw.format not in (*ARRAY_FORMATS, "seagap"):
        raise InputError(f"{raw.source}: a {raw.format} survey is not an array survey "
                         f"({', '.join(ARRAY_FORMATS)}, seagap)")
    if max(np.ptp(raw.pings["e_tx"]), np.ptp(raw.pings["n_tx"])) < 1.0:
        n_skip = len(raw.skipped)
        raise InputError(f"{_shots_file(raw)}: every shot was transmitted within 1 m of one "
                         "place; an array cannot be located from one point (expected a ship's "
                         "track over the array)"
                         + (f"; {len(raw.pings)} shots read, {n_skip} lines or replies skipped: "
                            + skip_reasons(list(raw.skipped.itertuples(index=False)))
                            if n_skip else ""))
    _check_span(raw)
    _check_midnight(raw)
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
    lat, lon, h = _geodetic(e, n, u, origin)
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
    lat, lon, h = _geodetic(*m, origin)
    return {"enu": {c: describe(v, s, ci) for c, v, s in zip(("east", "north", "up"), m, sd,
                                                              strict=True)},
            "lat": lat, "lon": lon, "height": h,
            "transponders": [str(t) for t in fit.ids],
            "covariance": {"names": ["east", "north", "up"],
                           "matrix": [[float(v) for v in row] for row in C]}}


def _positions_entry(fit, ci, shift, priors, position_prior="site", scaling=None):
    """Return what was solved for the positions; with the rigid shift, the shift itself.

    The shift is GARPOS's ``dCentPos`` of a fixed-geometry solution: every located
    transponder minus its prior position (the same for all), with their sd (0 for a
    coordinate the site file holds). Where a transponder was not located, the geometry
    still places it: ``centre_of_all`` is the mean of every prior position plus the shift,
    comparable with a campaign that located them all. With GARPOS's take-over (a common
    shift beside each transponder's offset), ``common_shift`` gives the shift (its
    ``dCentPos``) on each axis solved. With a prior, ``prior["mostly_prior"]``
    names the coordinates whose posterior sd is above :data:`PRIOR_DOMINANT` of their prior's
    (the prior, not the shots, gives them over half of their precision).
    """
    out = dict(fit.model["positions"])
    if out.get("prior"):
        out["prior"] = dict(out["prior"], mostly_prior=_mostly_prior(fit, out["prior"]),
                            choice=position_prior, scaled=scaling)
        if scaling:
            out["prior"]["kind"] += (f", scaled up {scaling['sd_factor']:.4g} times where the fit "
                                     "moved the positions farther than they allow (the sds "
                                     "here are the scaled ones)")
    if out.get("common_axes"):  # GARPOS's dCentPos beside each transponder's dPos
        axes = out.pop("common_axes")
        phi, C = fit.model["position_params"], fit.model["position_params_cov"]
        out["common_shift"] = {a: describe(phi[j], np.sqrt(max(C[j, j], 0.0)), ci) for a, j in
                               zip(axes, range(phi.size - len(axes), phi.size), strict=True)}
        prior = out.get("prior")
        if prior:  # a shift its prior mostly determines, as a coordinate
            c = dict(zip(("east", "north", "up"), prior["centre_sd"], strict=True))
            prior["mostly_prior"] += [f"shift {a}" for a, v in out["common_shift"].items()
                                      if c[a] and v["sd"] > PRIOR_DOMINANT * c[a]]
    if shift:
        d, sd = fit.enu[0] - fit.start[0], fit.sd[0]
        out["shift"] = {c: describe(v, s, ci) for c, v, s in
                        zip(("east", "north", "up"), d, sd, strict=True)}
        if fit.skipped:
            mean = priors[["east", "north", "up"]].to_numpy(float).mean(axis=0) + d
            out["centre_of_all"] = {
                "transponders": [str(t) for t in priors.index],
                **{c: describe(v, s, ci) for c, v, s in
                   zip(("east", "north", "up"), mean, sd, strict=True)}}
    return out


#: A coordinate whose posterior sd is above this fraction of its prior sd is "mostly prior"
#: (:func:`_positions_entry`): the prior gives it more than half of its precision.
PRIOR_DOMINANT = float(np.sqrt(0.5))


def _mostly_prior(fit, rec):
    """Names (``"M11 east"``, ``"shift up"``) of the coordinates the prior mostly determines."""
    axes = ("east", "north", "up")
    if "shift_sd" in rec:
        return [f"shift {a}" for a, p, s in zip(axes, rec["shift_sd"], fit.sd[0], strict=True)
                if p and s > PRIOR_DOMINANT * p]
    c = np.array([np.inf if v is None else v for v in rec["centre_sd"]], float)
    out = []
    for k, t in enumerate(fit.ids):
        for j, a in enumerate(axes):
            p = rec["transponder_sd"][t][j]  # 0: held, moved only by the common shift
            if p is None or (p == 0 and not 0 < c[j] < np.inf):
                continue  # no prior of its own and none through the shift, or held still
            if fit.sd[k, j] > PRIOR_DOMINANT * np.hypot(p, c[j]):
                out.append(f"{t} {a}")
    return out


#: What ``t_tx`` counts in each format (``summary.json`` ``epoch``).
TIME_REFERENCES = {"garpos": "s of the day of the site file's Date(UTC) (GARPOS ST)",
                   "gnatss": "s since J2000 (2000-01-01 12:00:00)",
                   "seagap": "s in obsdata.inp's own time scale"}


def _epoch_entry(fmt, shots):
    """Return the campaign's epoch: the middle of its shots (``t_tx``), in the file's time scale."""
    t = shots["t_tx"].to_numpy(float) if "t_tx" in shots.columns else shots["time"].to_numpy()
    mid = 0.5 * (float(np.min(t)) + float(np.max(t)))
    out = {"t_tx_mid": mid, "t_tx_first": float(np.min(t)), "t_tx_last": float(np.max(t)),
           "time_reference": TIME_REFERENCES.get(fmt, "s"), "utc": None,
           "hours": (float(np.max(t)) - float(np.min(t))) / 3600.0}
    if fmt == "gnatss":
        from ..io.gnatss import J2000

        out["utc"] = (J2000 + timedelta(seconds=mid)).isoformat(timespec="seconds")
    return out


def _series_basis(fit, n=121):
    """Return ``n`` times over the fit's time range and its speed basis at them."""
    lo, hi = fit.model["time_range"]
    t = np.linspace(lo, hi, n)
    return t, speed_basis(pd.DataFrame({"time": t}), fit.model["speed_intervals"], (lo, hi),
                          fit.model.get("speed_breaks"))


def _band(B, coef, cov, scale):
    """Return the curve ``B coef`` and its pointwise sd, both times ``scale``, as lists."""
    sd = np.sqrt(np.clip(np.einsum("ij,jk,ik->i", B, cov, B), 0.0, None))
    return (B @ coef * scale).tolist(), (sd * scale).tolist()


def _speed_series(fit, n=121):
    """Return the fitted sound speed against time: ``time_s``, ``mean_m_s``, ``sd_m_s``."""
    t, B = _series_basis(fit, n)
    k, first = B.shape[1], 3 * len(fit.ids)
    mean, sd = _band(B, fit.speed_coef, fit.cov[first:first + k, first:first + k],
                     fit.model["unit"])
    return {"time_s": t.tolist(), "mean_m_s": mean, "sd_m_s": sd}


def _gradient_series(fit, n=121):
    """Return the fitted gradients against time, (m/s)/km: ``time_s``, each term's ``mean``, ``sd``.

    GARPOS's ``gradV`` (``a V0``, ``V0`` the survey's mean speed), as the time averages of
    ``summary.json``'s ``gradients``; None where they are not fitted.
    """
    if fit.gradient_coef is None:
        return None
    t, B = _series_basis(fit, n)
    k = B.shape[1]
    first = 3 * len(fit.ids) + k
    out = {"time_s": t.tolist()}
    for j, name in enumerate(fit.gradient_terms):
        sl = slice(first + j * k, first + (j + 1) * k)
        mean, sd = _band(B, fit.gradient_coef[j * k:(j + 1) * k], fit.cov[sl, sl],
                         fit.sound_speed)
        out[name] = {"mean": mean, "sd": sd}
    return out


def _gaps(model) -> list:
    """Return the intervals merged across gaps in the shots, ``[start_s, end_s]`` each."""
    breaks = model.get("speed_breaks")
    if breaks is None:
        return []
    width = (breaks[-1] - breaks[0]) / model["equal_intervals"]
    return [[float(a), float(b)] for a, b in zip(breaks[:-1], breaks[1:], strict=True)
            if b - a > 1.5 * width]


def _sound_speed_entry(fit, ci, prof) -> dict:
    """Return the ``sound_speed`` record of an array's ``summary.json``, a unit per field."""
    n_int = int(fit.model["speed_intervals"])
    sm = fit.model.get("smoothing")
    lo, hi = fit.model["time_range"]
    gaps = _gaps(fit.model)
    refracted = prof is not None
    return {
        **describe(fit.sound_speed, fit.sound_speed_sd, ci), "unit": "m/s",
        "quantity": ("harmonic mean of the fitted profile (the survey's profile times the "
                     "fitted scale) from the ship's to the transponders' mean depth, averaged "
                     "over the survey") if refracted else
                    "straight-ray speed, averaged over the survey",
        "model": ("one value for the survey" if not n_int else
                  (f"cubic B-spline in time, {fit.model.get('equal_intervals', n_int)} equal "
                   "intervals" if sm is None else
                   f"smooth cubic B-spline in time, knots every {sm['knot_minutes']:.3g} min, "
                   "roughness penalty weighted by maximum marginal likelihood"))
                 + (f"; {len(gaps)} gap(s) in the shots spanned by one interval each"
                    + (f", so {n_int} intervals in all"
                       if sm is None and n_int != fit.model.get("equal_intervals", n_int)
                       else "")
                    if gaps else ""),
        "speed_intervals": n_int,
        "interval_minutes": ((hi - lo) / 60.0 / fit.model.get("equal_intervals", n_int)
                             if n_int else None),
        "gaps_s": gaps,
        "smoothing": sm,
        "reference_m_s": float(fit.model["unit"]) if refracted else None,
        "coefficients": [float(v) for v in fit.speed_coef],
        "coefficients_unit": ("scale of the profile (dimensionless: speed = scale x profile)"
                              if refracted else "m/s"),
        "series": _speed_series(fit)}


def _residual_entry(cls) -> dict:
    """Return the residual rms (ms) of the true replies, overall and per transponder."""
    pinged = cls[cls["label"].isin(["true", "spurious"])]
    true = pinged[pinged["label"] == "true"]

    def rms(x):
        x = np.asarray(x, float)
        return float(np.sqrt(np.mean(x**2))) if x.size else None

    return {"unit": "ms", "rms_true": rms(true["residual_ms"]), "n_true": int(len(true)),
            "n_spurious": int((pinged["label"] == "spurious").sum()),
            "n_skipped": int((cls["label"] == "skipped").sum()),
            "per_transponder": {str(t): {"rms_true": rms(g["residual_ms"]), "n_true": int(len(g))}
                                for t, g in true.groupby("transponder", sort=True)}}


def track_geometry(shots, enu) -> dict:
    """Return how well the ship's track surrounds the array (the gradients' identifiability).

    Parameters
    ----------
    shots : pandas.DataFrame
        The shots used (``transponder``, the transducer's ``e/n/u_tx`` and ``_rx``).
    enu : dict
        ``{id: (east, north, up)}`` of the transponders.

    Returns
    -------
    dict
        ``spread_over_depth``: the sd of the transducer's horizontal position
        along its least-spread direction over the mean water depth (the gradients
        are fitted from :data:`MIN_SPREAD`; a ship holding station has almost 0);
        ``central_fraction``: the share of shots within :data:`CENTRAL_RADIUS` depths
        of the array's centre (0 on a circle about it, about a quarter on transits
        across it); per transponder
        ``azimuth_coverage_deg`` (360 minus the largest gap between the azimuths
        of the ship seen from it) and
        ``max_incidence_deg`` (the largest angle of the ray from the vertical).

    Examples
    --------
    >>> import pandas as pd
    >>> a = np.radians(np.arange(0, 360, 10))
    >>> e, n = 1000 * np.sin(a), 1000 * np.cos(a)
    >>> shots = pd.DataFrame({"transponder": "A", "e_tx": e, "n_tx": n, "u_tx": 0.0,
    ...                       "e_rx": e, "n_rx": n, "u_rx": 0.0})
    >>> g = track_geometry(shots, {"A": (0.0, 0.0, -1000.0)})
    >>> round(g["spread_over_depth"], 2), round(g["transponders"]["A"]["azimuth_coverage_deg"])
    (0.72, 350)
    """
    e = 0.5 * (shots["e_tx"].to_numpy(float) + shots["e_rx"].to_numpy(float))
    n = 0.5 * (shots["n_tx"].to_numpy(float) + shots["n_rx"].to_numpy(float))
    u = 0.5 * (shots["u_tx"].to_numpy(float) + shots["u_rx"].to_numpy(float))
    tid = shots["transponder"].astype(str).to_numpy()
    depth = float(np.mean([u.mean() - p[2] for p in enu.values()]))
    lam = np.linalg.eigvalsh(np.cov(np.vstack([e, n]))) if e.size > 2 else np.zeros(2)
    centre = np.mean([p[:2] for p in enu.values()], axis=0)
    near = np.hypot(e - centre[0], n - centre[1]) < CENTRAL_RADIUS * depth
    out = {"spread_over_depth": float(np.sqrt(max(lam[0], 0.0)) / depth),
           "central_fraction": float(near.mean()) if near.size else 0.0, "transponders": {}}
    for t, p in enu.items():
        sel = tid == str(t)
        if not sel.any():
            continue
        de, dn = e[sel] - p[0], n[sel] - p[1]
        az = np.sort(np.degrees(np.arctan2(de, dn)) % 360.0)
        gaps = np.diff(np.concatenate([az, az[:1] + 360.0]))
        inc = np.degrees(np.arctan2(np.hypot(de, dn), u[sel] - p[2]))
        out["transponders"][str(t)] = {"azimuth_coverage_deg": float(360.0 - gaps.max()),
                                       "max_incidence_deg": float(inc.max())}
    return out


def _geodetic(e, n, u, origin):
    """Latitude, longitude, height of a local point; None each without an origin (SeaGap)."""
    if origin is None:
        return None, None, None
    return enu_to_geodetic(e, n, u, *origin)


def position_constraints(header, ids=None):
    """Return the fixed coordinates and the fixed-geometry mode from a site file's sigmas.

    GARPOS's convention: a sigma of 0 in ``<station>_dPos`` fixes that coordinate
    of that transponder (its own offset: with a ``dCentPos`` sigma above 0 on that axis
    it still moves with the common shift, :func:`site_priors`); when every ``_dPos`` sigma
    is 0 and ``dCentPos`` has a sigma above 0, the array moves as a rigid body (the shift's
    coordinates with a sigma of 0 fixed). Sigmas above 0 leave the coordinate free, with
    the prior of :func:`site_priors`.

    Parameters
    ----------
    header : dict
        A survey's header (``position_sigmas``, ``centre_sigmas``: absent means free).
    ids : list of str, optional
        The transponders, in the order of ``header["transponders"]`` (default its index).

    Returns
    -------
    fixed : numpy.ndarray or None
        ``(K, 3)`` bool; None when nothing is fixed.
    shift : bool

    Examples
    --------
    >>> import pandas as pd
    >>> sig = pd.DataFrame({"east": [0.0, 0.0], "north": [0.0, 0.0], "up": [0.0, 0.0]},
    ...                    index=["A", "B"])
    >>> fixed, shift = position_constraints({"position_sigmas": sig,
    ...                                      "centre_sigmas": [3.0, 3.0, 0.0]}, ["A", "B"])
    >>> shift, fixed[0].tolist()
    (True, [False, False, True])
    """
    s, cen = _header_sigmas(header, ids)
    if s is None:
        return None, False
    zero = s == 0.0  # NaN (absent) is free
    if zero.all() and (cen > 0).any():
        return np.tile(cen == 0.0, (len(s), 1)), True
    return (zero if zero.any() else None), False


def site_priors(header, ids=None, shift=False):
    """Return the site file's sigmas as the priors of :func:`~.array.locate_array`.

    GARPOS's a priori covariance of the positions: each ``<station>_dPos`` sigma above 0
    is the sd (m) of a Gaussian prior on that coordinate about the prior position, and
    ``dCentPos``'s sigmas are the sds of the array's common shift, felt by every
    transponder (with ``shift``, the shift's own prior). A sigma of 0 fixes the coordinate
    (:func:`position_constraints`); an absent one is no prior.

    Parameters
    ----------
    header : dict
        A survey's header (``position_sigmas``, ``centre_sigmas``).
    ids : list of str, optional
        The transponders, in the order of ``header["transponders"]`` (default its index).
    shift : bool, default False
        The fixed-geometry solution: only the shift's prior is returned.

    Returns
    -------
    prior_sd : numpy.ndarray or None
        ``(K, 3)``, inf where a coordinate has no prior (or is fixed); None where no
        coordinate has one, or with ``shift``.
    centre_sd : numpy.ndarray or None
        ``(3,)``, 0 where the shift has no spread; None where the file gives none above 0.

    Examples
    --------
    >>> import pandas as pd
    >>> sig = pd.DataFrame({"east": [3.0, 0.0], "north": [3.0, 0.0], "up": [1.0, 0.0]},
    ...                    index=["A", "B"])
    >>> sd, c = site_priors({"position_sigmas": sig, "centre_sigmas": [0.0] * 3},
    ...                     ["A", "B"])
    >>> sd.tolist(), c
    ([[3.0, 3.0, 1.0], [inf, inf, inf]], None)
    """
    s, cen = _header_sigmas(header, ids)
    _check_sharp(header, "dCentPos", cen)
    cen = np.where(np.isfinite(cen) & (cen > 0), cen, 0.0)
    centre = cen if (cen > 0).any() else None
    if shift or s is None:
        return None, centre
    ids = list(header["transponders"].index) if ids is None else ids
    for i, row in zip(ids, s, strict=True):
        _check_sharp(header, f"{i}_dPos", row)
    s = np.where(np.isfinite(s) & (s > 0), s, np.inf)
    return (s if np.isfinite(s).any() else None), centre


def _header_sigmas(header, ids=None):
    """Return ``(dpos, centre)``: the site file's sigmas as the GARPOS reader keeps them.

    ``dpos`` the ``(K, 3)`` ``_dPos`` sigmas in ``ids``' order (None without them), ``centre``
    ``dCentPos``'s three (NaN where absent).
    """
    cen = header.get("centre_sigmas")
    cen = np.array([np.nan if v is None else v for v in (cen or [None] * 3)], float)
    sig = header.get("position_sigmas")
    if sig is None:
        return None, cen
    ids = list(header["transponders"].index) if ids is None else ids
    return sig.reindex([str(i) for i in ids])[["east", "north", "up"]].to_numpy(float), cen


def _check_sharp(header, key, sigmas):
    """Refuse a sigma above 0 and below :data:`~.array.MIN_PRIOR_SD`, naming the site file's key."""
    for name, v in zip(("sigma_E", "sigma_N", "sigma_U"), sigmas, strict=True):
        if 0.0 < v < MIN_PRIOR_SD:
            site = (header.get("files") or {}).get("site", "the site file")
            raise InputError(f"{site}: {key} {name} {v:g}: a prior sd above 0 and below "
                             f"{MIN_PRIOR_SD:g} m holds the coordinate to below round-off; "
                             "give 0 to fix it")


#: The choices of ``position_prior`` (``locate --position-prior``).
POSITION_PRIORS = ("auto", "site", "off")
def _fit_scaled(fit_with, position_prior):
    """Return ``(fit, scaled)``: the fit with the site file's sigmas, or scaled by the data.

    With ``"auto"``, where :func:`prior_scale` says the sigmas understate the fit's moves, it is
    fitted again with them scaled (``scaled`` the record, else None). ``fit_with(factor)`` fits
    with every prior sd times ``factor``.
    """
    fit = fit_with(1.0)
    k = prior_scale(fit) if position_prior == "auto" else 1.0
    if k <= 1.0:
        return fit, None
    first = fit.model["positions"]["prior"]["check"]
    fit = fit_with(float(np.sqrt(k)))
    fit.model["positions"]["prior"]["sd_factor"] = float(np.sqrt(k))  # the sampler's label
    extra, spread = prior_scale_spread(fit, k)
    return _widened(fit, extra), {"sd_factor": float(np.sqrt(k)), "check_as_given": first,
                                  "scale_uncertainty": spread}


def _widened(fit, extra):
    """Return ``fit`` with ``extra`` added to its position parameters' covariance."""
    m = fit.model
    G = m["position_map"]
    cov = fit.cov.copy()
    cov[:G.shape[0], :G.shape[0]] += G @ extra @ G.T
    m["position_params_cov"] = m["position_params_cov"] + extra
    return dataclasses.replace(fit, cov=0.5 * (cov + cov.T))


#: Least ``spread_over_depth`` of the track (:func:`track_geometry`) for the gradients.
MIN_SPREAD = 0.1
#: Horizontal distance from the array's centre, in depths, of a shot "over the array".
CENTRAL_RADIUS = 0.3
#: Least share of the shots within :data:`CENTRAL_RADIUS` depths of the array's centre for
#: the deep gradient (:func:`deep_gradient_gate`).
MIN_CENTRAL_FRACTION = 0.05
#: Shortest campaign (hours of shots) on which the gradients are fitted by default.
MIN_GRADIENT_HOURS = 1.0
#: Least hours of a circle (the deep gate failed) on which ``auto`` fits the shallow term
#: (:func:`auto_gradients`).
MIN_CIRCLE_HOURS = 3.0
#: The choices of ``gradients`` (``locate --gradients``): ``on`` both terms, ``shallow`` the
#: shallow one only.
GRADIENT_CHOICES = ("auto", "on", "shallow", "off")


def gradient_gate(shots, priors, speed_intervals=None):
    """Return whether the survey can fit the horizontal gradients, and why (not).

    The conditions (the smooth speed, three transponders, :data:`MIN_GRADIENT_HOURS`, a
    track spread of :data:`MIN_SPREAD`) and their reasons: ``docs/gnssa.md``.

    Parameters
    ----------
    shots : pandas.DataFrame
        The shots (``transponder``, ``time``, the transducer's ``e/n/u_tx`` and ``_rx``).
    priors : pandas.DataFrame
        ``east``, ``north``, ``up`` by transponder id.
    speed_intervals : int, optional
        As for :func:`locate_array_survey` (None: the smooth speed).

    Returns
    -------
    fit : bool
    reason : str
    """
    if speed_intervals == 0:
        return False, "one sound speed for the survey (speed_intervals=0)"
    if speed_intervals is not None:
        return False, (f"an unpenalised speed spline ({speed_intervals} intervals asked for): "
                       "the gradients would be unpenalised too and trade against the "
                       "positions by decimetres")
    ids = _heard(shots, priors)
    if len(ids) < 3:
        return False, f"{len(ids)} transponders located; the deep gradient needs 3 or more"
    if "time" in shots.columns and len(shots):
        hours = _span_hours(shots)
        if hours < MIN_GRADIENT_HOURS:
            return False, (f"the shots span {hours:.2f} h with the interval between them "
                           f"(need {MIN_GRADIENT_HOURS:g}): the gradients' constant and trend "
                           "would trade against the positions")
    spread = track_geometry(shots, _prior_enu(priors, ids))["spread_over_depth"]
    if spread < MIN_SPREAD:
        return False, (f"the track spreads over {spread:.2f} of the depth (need "
                       f"{MIN_SPREAD}): the shallow gradient is not identifiable, and the "
                       "intervals assume water without horizontal gradients")
    return True, f"the track spreads over {spread:.2f} of the depth, {len(ids)} transponders"


def _span_hours(shots) -> float:
    """Return the hours the shots span, with the interval between them.

    An hour of shots every 20 s is an hour.
    """
    t = np.unique(shots["time"].to_numpy(float))
    step = float(np.median(np.diff(t))) if t.size > 1 else 0.0
    return (t[-1] - t[0] + step) / 3600.0


def auto_gradients(gate, deep, shots):
    """Return what ``--gradients auto`` fits, and why: True (both terms), "shallow" or False.

    Both terms where :func:`gradient_gate` and :func:`deep_gradient_gate` pass; the shallow
    term alone on a circle (the deep gate failed) of :data:`MIN_CIRCLE_HOURS` or more; none
    otherwise. On the simulator's circles of 1 and 2 hours the shallow term put the part of
    the water's gradient that GARPOS's model gives the deep term into the centre, along the
    gradient: the centre erred as much or more (median 2.2-2.6 against 1.5-2.6 cm where the
    water has gradients) and its intervals covered 82-92 % against 92-98 % without them; at 3
    hours the two agree, and from 4 hours the shallow term covers where leaving it out does
    not (docs/gnssa.md, "Circles: the shallow gradient only").

    Parameters
    ----------
    gate, deep : tuple of (bool, str)
        :func:`gradient_gate`'s and :func:`deep_gradient_gate`'s answers.
    shots : pandas.DataFrame
        The shots fitted (``time``).

    Returns
    -------
    fit : bool or str
    reason : str
    """
    if not gate[0]:
        return False, f"auto: {gate[1]}"
    if deep[0]:
        return True, f"auto: {gate[1]}; {deep[1]}"
    hours = _span_hours(shots)
    if hours < MIN_CIRCLE_HOURS:
        return False, (f"auto: {gate[1]}; {deep[1]}; but the circle spans {hours:.2f} h (need "
                       f"{MIN_CIRCLE_HOURS:g}): there the shallow term puts the deep "
                       "gradient's part into the centre, so none (docs/gnssa.md)")
    return "shallow", f"auto: {gate[1]}; {deep[1]}"


def _heard(shots, priors) -> list:
    """Return the ids of the transponders with 6 shots or more (those the gates count)."""
    tid = shots["transponder"].astype(str)
    return [t for t in map(str, priors.index) if int(np.sum(tid == t)) >= 6]


def _prior_enu(priors, ids) -> dict:
    """Return ``{id: (east, north, up)}`` of the prior positions of ``ids``."""
    return {t: priors.loc[t, ["east", "north", "up"]].to_numpy(float) for t in ids}


def deep_gradient_gate(shots, priors, shift=False):
    """Return whether the track determines the deep gradient beside the shallow one, and why.

    The deep term (the transponder's prior offset across the array) needs shots over the
    array where the transponders are free: on a track with fewer than
    :data:`MIN_CENTRAL_FRACTION` of its shots within :data:`CENTRAL_RADIUS` depths of the
    array's centre (a circle about it) it trades with the centre's horizontal position (sds
    of metres on the simulator's circles, against a centimetre with the shallow term only;
    one shot over the array was not enough, four of 663 were). Under a rigid shift of a held
    geometry it does not trade, and leaving it out there biased the centre by 7-15 cm on
    circles (``docs/gnssa.md``, "Circles: the shallow gradient only").

    Parameters
    ----------
    shots : pandas.DataFrame
        As for :func:`gradient_gate`.
    priors : pandas.DataFrame
        ``east``, ``north``, ``up`` by transponder id.
    shift : bool, default False
        The horizontal geometry is held: the array moves as a rigid body from the priors,
        or every transponder's east and north offsets are held (:func:`locate_array_survey`).

    Returns
    -------
    fit : bool
    reason : str
    """
    if shift:
        return True, ("the horizontal geometry is held (a rigid shift, or every east and north "
                      "offset held), so the deep gradient too")
    ids = _heard(shots, priors)
    share = track_geometry(shots, _prior_enu(priors, ids))["central_fraction"] if ids else 0.0
    over = f"{100 * share:.1f} % of the shots within {CENTRAL_RADIUS:g} depths of the centre"
    if share >= MIN_CENTRAL_FRACTION:
        return True, over
    return False, (f"{over} (need {100 * MIN_CENTRAL_FRACTION:g} %): the deep gradient would "
                   "trade with its horizontal position, so the shallow one only")


def gradient_choice(gradients) -> str:
    """Return the ``gradients`` argument as one of :data:`GRADIENT_CHOICES`.

    Parameters
    ----------
    gradients : None, bool or str
        None is ``"auto"``; True (or a NumPy True) ``"on"``, False ``"off"``; a string of
        :data:`GRADIENT_CHOICES` as it is.

    Returns
    -------
    str

    Raises
    ------
    InputError
        For any other value.
    """
    if gradients is None:
        return "auto"
    if isinstance(gradients, bool | np.bool_):
        return "on" if gradients else "off"
    if not isinstance(gradients, str) or gradients not in GRADIENT_CHOICES:
        raise InputError(f"gradients: expected one of {', '.join(GRADIENT_CHOICES)} (or "
                         f"True, False, None), got {gradients!r}")
    return gradients


def _geometry_entry(origin, surface_depth, radius, cartesian) -> dict:
    """``summary.json``'s ``geometry``: the frame, its origin and the Earth's shape."""
    return {"frame": "local east, north, up about the origin (m)",
            "origin": None if origin is None else dict(
                zip(("lat", "lon", "height"), map(float, origin), strict=True)),
            "surface_depth": float(surface_depth),
            "earth": ("flat: straight or refracted rays in the local frame, no Earth "
                      "curvature") if radius is None else
                     (f"sphere of radius {radius:.1f} m (the WGS84 Gaussian radius at "
                      "the site's latitude): the profile's layers follow it"
                      + ("; the rays traced in its frame (east, north along it, "
                         "height above it), the positions Cartesian"
                         if cartesian else "; the frame is along it (SeaGap's)")),
            "earth_radius_m": radius}


def _noise_entry(fit, correlation) -> dict:
    """``summary.json`` ``noise``: the replies' noise model, how it was chosen."""
    return {**(fit.model.get("noise") or {"model": "independent", "correlation_s": 0.0,
                                          "share": None, "white": None, "grid": None}),
            "choice": "auto" if correlation == "auto" else
            "off" if correlation in (None, "off") else "given"}


def _method(fit, rays, noise) -> str:
    """``summary.json`` ``method`` of an array fit."""
    gls = (noise["correlation_s"] or 0) > 0
    return (f"array EM, {rays}"
            + ("; the true replies refitted by generalised least squares under correlated "
               "noise; intervals approximate (Wald" if gls else
               "; intervals approximate (Wald, cluster-robust by interrogation")
            + (", averaged over the sound speed's smoothing weights)"
               if fit.model.get("smoothing") else ")"))


def _check_fit(raw, fit, shots, shift) -> None:
    """Refuse an array's fit that the checks below refuse; warn as they warn, in that order."""
    _check_below_transducer(raw, fit, shots)
    _check_labels(raw, fit, shots)
    _check_replies_explained(raw, fit)
    _warn_unlocated(raw, fit, shift)
    _check_moved(raw, fit)
    _check_intervals(raw, fit)


def _check_below_transducer(raw, fit, shots) -> None:
    """Refuse a fit that puts a transponder above the transducer: the ranges' mirror image.

    Ranges alone are symmetric about the transducer's level; a prior position far too
    shallow (given in km, say) lets the fit converge to the mirror image, with small sds.
    """
    level = float(np.mean(shots[["u_tx", "u_rx"]].to_numpy()))
    for k, tid in enumerate(fit.ids):
        up = float(fit.enu[k, 2])
        if up > level:
            priors = raw.header["transponders"]
            prior = float(priors["up"].to_numpy()[[str(t) for t in priors.index].index(tid)])
            raise InputError(
                f"{raw.source}: transponder {tid} was located {up - level:,.0f} m above the "
                f"transducer (up {up:+.2f} m), the mirror image of its ranges: its prior up "
                f"{prior:+.3f} m is far from the depth its ranges give; check the prior "
                f"positions in {_positions_file(raw)} (metres, up negative below the sea "
                "surface)")


#: Shots more than this (s) from every shot outside their group, in a group of fewer than
#: :data:`ISOLATED_SHOTS`, are left out of an array's fit (:func:`isolated_shots`).
ISOLATED_GAP_S = 3600.0
#: See :data:`ISOLATED_GAP_S`.
ISOLATED_SHOTS = 10


def isolated_shots(shots):
    """Return which shots lie isolated in time, and why: a mask and a reason per shot.

    A group of fewer than :data:`ISOLATED_SHOTS` shots (replies) separated from every other
    shot by more than :data:`ISOLATED_GAP_S` cannot tell its own sound speed (the smooth speed
    is free across a gap), so the fit explains it whatever its time and calls it true; and it
    stretches the campaign's span, on which ``--gradients auto`` decides. One mistyped ``ST``
    ten hours off moved a simulated centre by 4-7 cm. Such shots are left out, each named.

    Parameters
    ----------
    shots : pandas.DataFrame
        With ``time`` (s).

    Returns
    -------
    mask : numpy.ndarray of bool
    reasons : numpy.ndarray of object
        The reason of each shot left out ("" elsewhere).

    Examples
    --------
    >>> shots = pd.DataFrame({"time": [0.0, 20.0, 40.0, 60.0, 80.0, 100.0, 120.0, 140.0,
    ...                                160.0, 180.0, 200.0, 36200.0]})
    >>> isolated_shots(shots)[0].nonzero()[0].tolist()
    [11]
    """
    t = shots["time"].to_numpy(float)
    mask, reasons = np.zeros(t.size, bool), np.full(t.size, "", dtype=object)
    order = np.argsort(t, kind="stable")
    groups = np.split(order, np.flatnonzero(np.diff(t[order]) > ISOLATED_GAP_S) + 1)
    if len(groups) < 2:
        return mask, reasons
    for g in groups:
        if g.size >= ISOLATED_SHOTS or 2 * g.size >= t.size:
            continue
        others = np.setdiff1d(order, g)
        gap = float(np.min(np.abs(t[others][:, None] - t[g][None, :])))
        mask[g] = True
        reasons[g] = (f"isolated in time: {g.size} shot{'s' * (g.size != 1)} {gap / 3600.0:.1f} "
                      f"h from every other (more than {ISOLATED_GAP_S / 3600.0:g} h, fewer than "
                      f"{ISOLATED_SHOTS}): left out of the fit (a time mistyped?)")
    return mask, reasons


def _warn_held(raw) -> None:
    """Warn where the site file asks for what the fit holds.

    GARPOS's ``ATDoffset`` sigmas above 0 ask for the antenna-transducer offset to be
    estimated; it is held as given.
    """
    atd = [v for v in (raw.header.get("atd_sigmas") or []) if v is not None]
    if any(v > 0 for v in atd):
        site = (raw.header.get("files") or {}).get("site", raw.source)
        off = ", ".join(f"{v:g}" for v in raw.header["atd_offset"])
        warnings.warn(f"{site}: ATDoffset sigmas {', '.join(f'{v:g}' for v in atd)}: GARPOS "
                      f"estimates the offset where they are above 0; locate holds it at ({off})"
                      " m as given", LocateWarning, stacklevel=3)


def _isolated(raw):
    """Return :func:`array_shots` and their :func:`isolated_shots`, warned of with their lines.

    Also :func:`_warn_held`.
    """
    shots = array_shots(raw)
    _warn_held(raw)
    mask, reasons = isolated_shots(shots)
    if mask.any():
        lines = shots["line"].to_numpy()[mask] if "line" in shots.columns else []
        why = "; ".join(dict.fromkeys(reasons[mask]))  # one reason per group, in order
        warnings.warn(f"{_shots_file(raw)} line{'s' * (len(lines) != 1)} "
                      f"{', '.join(map(str, lines[:10]))}{', ...' if len(lines) > 10 else ''}: "
                      f"{why}", LocateWarning, stacklevel=3)
    return shots, (mask, reasons)


#: A transponder of at least :data:`MIN_REPLIES_CHECKED` replies of which the fit calls fewer
#: than this share true is refused (:func:`_check_replies_explained`).
MIN_TRUE_SHARE = 0.1
#: A transponder whose fit calls more than this share of its replies spurious is warned of
#: (:func:`_check_replies_explained`).
MAX_SPURIOUS_SHARE = 0.5
#: Replies a transponder needs before :func:`_check_replies_explained` judges its share
#: (below it, a transponder none of whose replies is true is refused).
MIN_REPLIES_CHECKED = 10


def _positions_file(raw) -> str:
    """Name where a survey's prior positions come from (site file, config, pxp-ini)."""
    files = raw.header.get("files", {})
    return files.get("site") or files.get("config") or files.get("positions") or raw.source


def _check_replies_explained(raw, fit) -> None:
    """Refuse a fit that calls nearly all of one transponder's replies spurious.

    Its position is then the prior's alone and the array's centre carries it: a slip in the
    prior position (a sign, a digit) or another transponder's replies. Where the prior is
    hundreds of metres off, the robust start cannot reach the replies and the EM calls them
    all spurious, at exit 0 with a centre hundreds of metres off. Below
    :data:`MIN_REPLIES_CHECKED` replies only a transponder none of whose replies is true is
    refused (six replies, all spurious, left a centre 259 m off). A transponder not refused,
    more than :data:`MAX_SPURIOUS_SHARE` of whose replies are spurious, is warned of.
    """
    mostly = []  # not refused, but said once none is refused
    for k, tid in enumerate(fit.ids):
        sel = fit.index == k
        n = int(sel.sum())
        true = n - fit.n_spurious(k)  # as the transponder's line counts them
        if n == 0 or true >= MIN_TRUE_SHARE * n or (n < MIN_REPLIES_CHECKED and true > 0):
            if n and n - true > MAX_SPURIOUS_SHARE * n:
                mostly.append(f"{_shots_file(raw)}: transponder {tid}: {n - true} of its {n} "
                              f"replies called spurious (more than {100 * MAX_SPURIOUS_SHARE:g}"
                              " %): its position rests on the rest; check that these replies "
                              "are its own (late multipath arrivals, another array's or "
                              "another campaign's concatenated?)")
            continue
        med = float(np.median(fit.residual[sel]))
        e, nn, u = fit.start[k]
        raise InputError(
            f"{_positions_file(raw)}: transponder {tid}: {n - true} of its {n} replies called "
            f"spurious (fewer than {100 * MIN_TRUE_SHARE:g} % true): their travel times are "
            f"{1e3 * med:+,.1f} ms (median; about {abs(med) * 750.0:,.0f} m of range) from "
            f"what its prior position (east {e:.3f}, north {nn:.3f}, up {u:.3f} m) predicts. "
            "Check that position (a sign or a digit slipped?) and that these replies are "
            f"{tid}'s; to locate the array without it, leave it out of the prior positions "
            "(GARPOS's Stations, GNATSS's transponders)")
    for message in mostly:
        warnings.warn(message, LocateWarning, stacklevel=4)


#: A spurious reply arrives when another transponder's would where its travel time is within
#: this (s) of the other's prediction at the same transmit time, or :data:`LABEL_MATCH_SIGMAS`
#: of the fit's sigmas where more: the swapped replies pull both positions, so the fit's
#: predictions of the pair were 3 and 13 ms from the replies swapped (a hunt's campaign),
#: against 250-830 ms for the other transponders'.
LABEL_MATCH_S = 0.02
#: See :data:`LABEL_MATCH_S`.
LABEL_MATCH_SIGMAS = 5.0
#: ... and only where it is this many times closer to the other's prediction than to its own:
#: a late multipath reply (ms after its own) of a ship above the middle of the array, where
#: every transponder's time is nearly the same, is not another's.
LABEL_CLOSER = 4.0


def _check_labels(raw, fit, shots) -> None:
    """Refuse replies of one transponder labelled another's.

    A deck unit re-cabled mid-survey swaps two transponders' labels: the fit calls the
    swapped replies spurious (not below :data:`MIN_TRUE_SHARE`, so not refused there) and
    carries the other replies' positions, 29 m off at sds under 1 m, the centre 5 m off at
    exit 0 (a hunt, session 48). A reply labelled A that arrives when B's would at the same
    transmit time (within :data:`LABEL_MATCH_S` of B's prediction, :data:`LABEL_CLOSER`
    times closer to it than to A's, and B's own reply to that shot not true: a swap takes it
    away, where a late multipath of A beside a close B leaves it) is B's;
    where most of A's spurious replies (10 at least) are so, the labels are refused, naming
    the lines (:func:`_check_replies_explained` warns of a transponder mostly spurious
    otherwise).
    """
    t_tx = shots["t_tx"].to_numpy(float)[fit.rows]
    twtt = shots["twtt"].to_numpy(float)[fit.rows]
    pred = twtt - fit.residual
    lines = (shots["line"].to_numpy()[fit.rows] if "line" in shots.columns
             else np.asarray(fit.rows) + 1)
    keys, shot = np.unique(t_tx, return_inverse=True)
    table = np.full((keys.size, len(fit.ids)), np.nan)  # prediction per shot and transponder
    table[shot, fit.index] = pred
    heard = np.zeros((keys.size, len(fit.ids)), bool)  # the shot's own reply of each, true
    heard[shot, fit.index] = fit.p_true >= 0.5
    spurious = fit.p_true < 0.5
    tol = max(LABEL_MATCH_S, LABEL_MATCH_SIGMAS * fit.sigma)
    for k, tid in enumerate(fit.ids):
        mine = np.flatnonzero((fit.index == k) & spurious)
        n = int((fit.index == k).sum())
        if mine.size < MIN_REPLIES_CHECKED:
            continue
        off = np.abs(twtt[mine, None] - table[shot[mine]])
        off[:, k] = np.inf
        own = np.abs(fit.residual[mine])[:, None]  # a late multipath is near its own
        with np.errstate(invalid="ignore"):
            match = ((off <= tol)
                     & (LABEL_CLOSER * off < own) & ~heard[shot[mine]])
        for j in np.flatnonzero(match.sum(axis=0) >= max(MIN_REPLIES_CHECKED,
                                                         0.5 * mine.size)):
            hit = mine[match[:, j]]
            raise InputError(
                f"{_shots_file(raw)}: {hit.size} of the {n} replies labelled {tid} (lines "
                f"{lines[hit[0]]} to {lines[hit[-1]]}) arrive when {fit.ids[j]}'s would at the "
                f"same transmit time (within {1e3 * tol:.3g} ms), and the fit calls "
                f"them spurious: replies of {fit.ids[j]} labelled {tid} (the labels swapped "
                "part of the way, a deck unit re-cabled?); correct the labels, or locate the "
                "parts before and after separately")


def _warn_unlocated(raw, fit, shift=False) -> None:
    """Warn of transponders of the prior positions not located (too few replies).

    The array centre is then the mean of the others, another point of the seafloor: a batch
    recorded such a campaign as done without a warning, and a centre averaged from its
    transponders' rows was 250 m from the full array's (a hunt, session 48).
    """
    if not fit.skipped:
        return
    why = "; ".join(f"{t}: {w}" for t, w in fit.skipped.items())
    n = len(fit.ids) + len(fit.skipped)
    warnings.warn(f"{_positions_file(raw)}: {len(fit.skipped)} transponder"
                  f"{'s' * (len(fit.skipped) != 1)} not located ({why}): the array centre is "
                  f"the mean of {', '.join(map(str, fit.ids))} only, not comparable with a "
                  f"centre of all {n}"
                  + (f" (the rigid shift moves the prior geometry: positions.centre_of_all is "
                     f"that of all {n})" if shift else ""), LocateWarning, stacklevel=4)


#: The farthest (in depths) a transponder may be located from its prior position.
MAX_MOVE_DEPTHS = 0.2


def _check_moved(raw, fit) -> None:
    """Refuse a transponder located farther than :data:`MAX_MOVE_DEPTHS` depths from its prior.

    The gradients' deep term and the robust start use the prior positions: SeaGap's
    ``pxp-ini.inp`` with two lines swapped moved two transponders by 1,956 m and the centre
    by up to 11 cm with the same shots, at exit 0.
    """
    for k, tid in enumerate(fit.ids):
        moved = float(np.linalg.norm(fit.enu[k] - fit.start[k]))
        depth = abs(float(fit.start[k][2]))
        if moved > MAX_MOVE_DEPTHS * depth:
            e, n, u = fit.start[k]
            le, ln, lu = fit.enu[k]
            raise InputError(
                f"{_positions_file(raw)}: transponder {tid} was located {moved:,.0f} m from its "
                f"prior position (east {e:.3f}, north {n:.3f}, up {u:.3f} m; located at "
                f"{le:.3f}, {ln:.3f}, {lu:.3f} m), more than "
                f"{MAX_MOVE_DEPTHS:g} of its depth: the fit uses the priors (the gradients' "
                "deep term, the start); check that each position is its transponder's (lines "
                "swapped or a transponder missing?)")


def _check_intervals(raw, fit) -> None:
    """Refuse a fit whose positions' sds could not be computed (NaN intervals at exit 0)."""
    bad = [tid for k, tid in enumerate(fit.ids) if not np.all(np.isfinite(fit.sd[k]))]
    if bad:
        raise InputError(f"{raw.source}: the intervals of {', '.join(bad)} could not be "
                         "computed (the normal matrix is not positive definite): the shots do "
                         "not determine the positions as given; "
                         "check the prior positions and the shots")


def _classified(raw, shots, fit, flagged, honour, isolated=None):
    """Return ``classified.csv``'s table, each shot's probability of being true, the fitted.

    The fitted shots are the rows of ``fit`` (``fit.rows``); a shot not fitted has a NaN
    probability and the reason (a transponder not located, flagged in the file).
    """
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
    for t, skip_why in fit.skipped.items():
        reasons[tid == t] = f"transponder {t} not located: {skip_why}"
    if isolated is not None:
        why = (isolated[1] != "") & (reasons == "")
        reasons[why] = isolated[1][why]
    if honour:
        reasons[flagged & (reasons == "")] = ("flagged in the file: left out of the fit "
                                              "(--flags reclassify fits and classifies it)")
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
    return cls, probs, sub


def locate_array_survey(raw, *, ci=0.95, outliers="uniform", ssp=None,
                        speed_intervals=None, surface_depth=None,
                        knot_minutes=KNOT_MINUTES, shift=None,
                        gradients="auto", earth="sphere", flags="honour",
                        correlation="auto", position_prior="auto") -> SurveyInResult:
    """Locate every transponder of a GNSS-A array survey together.

    Parameters
    ----------
    raw : RawSurvey
        Of format ``garpos``, ``gnatss`` or ``seagap``.
    ci : float, default 0.95
    outliers : {"uniform", "first_arrival"}
    ssp : None, SoundSpeedProfile, str or path
        None (default): the survey's own profile; ``"straight"``: straight rays;
        otherwise as for :func:`~.ssp.survey_profile`.
    speed_intervals : int, optional
        None (default): the sound speed (the profile's scale) is a smooth cubic
        B-spline in time, knots every ``knot_minutes``, its smoothness chosen by
        maximum marginal likelihood (:func:`~.array.locate_array`). An integer: an
        unpenalised B-spline with this many intervals (0: one speed).
    surface_depth : float, optional
        Depth (``-up``) of the profile's sea surface in the survey's frame;
        default the header's (0 without one).
    knot_minutes : float, default 5
    shift : bool, optional
        Solve a rigid shift of the prior geometry; default from the site file's
        sigmas (:func:`position_constraints`), which also fix the coordinates
        whose sigma is 0.
    gradients : {"auto", "on", "shallow", "off"}, default "auto"
        GARPOS's shallow and deep horizontal gradients (``summary.json``
        ``gradients``: their time averages in (m/s)/km): ``"auto"`` fits them where
        :func:`gradient_gate` says the track constrains them, the deep one only where
        :func:`deep_gradient_gate` says so too, and records its reasons; ``"on"`` (or
        True: both), ``"shallow"`` and ``"off"`` (or False) force the choice (None is
        ``"auto"``).
    earth : {"sphere", "flat"}, default "sphere"
        ``"sphere"``: the profile's layers follow the Earth (a sphere of the WGS84
        Gaussian radius at the site's latitude): SeaGap's frame is already along the
        sphere; GARPOS's and GNATSS's Cartesian east-north-up frames are turned into it
        (:func:`~.array.to_sphere`) and the result back. ``"flat"``: the frame as
        given, flat layers (the model before curvature).
    flags : {"honour", "reclassify"}, default "honour"
        GARPOS's ``flag`` column: ``"honour"`` leaves the flagged shots out of the fit
        (listed in ``classified.csv`` with the reason, as GARPOS does);
        ``"reclassify"`` fits them with the others and lets the EM classify them.
    correlation : {"auto", "off"} or tuple of float, default "auto"
        The replies' noise (:func:`~.array.locate_array`; ``summary.json`` ``noise``):
        ``"auto"`` GARPOS's correlation in time and across transponders where the
        likelihood prefers it to independent replies; ``"off"`` (or None) independent
        (intervals cluster-robust by interrogation); ``(mu_t, mu_mt)`` given.
    position_prior : {"auto", "site", "off"}, default "auto"
        ``"site"``: the site file's sigmas above 0 are Gaussian priors on the positions
        (and on the array's shift), as GARPOS uses them (:func:`site_priors`);
        ``"auto"``: the same, then, where the fit moved the positions farther from the site
        file's than those sigmas allow and the priors matter (:func:`prior_scale`), fitted
        again with every sigma scaled up by that factor's square root (the sigmas are a
        floor; ``positions.prior.scaled``); ``"off"``: every coordinate not fixed is free.
        Only GARPOS's site files give sigmas (``summary.json`` ``positions.prior``).

    Returns
    -------
    SurveyInResult
        ``summary``: ``transponders`` (as :func:`~.survey.locate_survey`, plus
        ``enu``, ``height``, ``covariance``, ``prior``, ``moved_m``),
        ``array_centre``, ``sound_speed``, the survey's ``origin`` and files;
        ``classified``: one row per shot and per skipped line.
    """
    if "transponders" not in raw.header:
        raise InputError(f"{raw.source}: no prior transponder positions were read (SeaGap's "
                         "pxp-ini.inp beside it); the array's fit starts from them")
    shots, isolated = _isolated(raw)
    timed = shots[~isolated[0]]  # the gates judge the shots fitted
    prof = survey_profile(raw, "survey" if ssp is None else ssp)
    h = raw.header
    if surface_depth is None:
        surface_depth = float(h.get("surface_depth", 0.0))
    fixed, auto_shift = position_constraints(h)
    shift = auto_shift if shift is None else bool(shift)
    if shift and not auto_shift:
        fixed = None
    if position_prior not in POSITION_PRIORS:
        raise InputError(f"position_prior: expected 'auto', 'site' or 'off', got "
                         f"{position_prior!r}")
    prior_sd, centre_sd = (site_priors(h, shift=shift) if position_prior != "off"
                           else (None, None))
    choice = gradient_choice(gradients)
    gate = gradient_gate(timed, h["transponders"], speed_intervals)
    # the horizontal geometry held (a rigid shift, or every east and north offset held, as
    # GARPOS's take-over may): the deep gradient cannot trade with it
    held_h = shift or (fixed is not None and bool(fixed[:, :2].all()))
    deep, why_deep = deep_gradient_gate(timed, h["transponders"], held_h)
    if choice == "auto":
        gradients, why = auto_gradients(gate, (deep, why_deep), timed)
    else:
        gradients = {"on": True, "shallow": "shallow", "off": False}[choice]
        why = f"gradients={choice} asked for (the gate: {gate[1]})"
    if flags not in ("honour", "reclassify"):
        raise InputError(f"flags: expected 'honour' or 'reclassify', got {flags!r}")
    flagged = (shots["file_flag"].to_numpy(bool) if "file_flag" in shots.columns
               else np.zeros(len(shots), bool))
    honour = flags == "honour" and flagged.any()
    left_out = (flagged if honour else False) | isolated[0]
    if earth not in ("sphere", "flat"):
        raise InputError(f"earth: expected 'sphere' or 'flat', got {earth!r}")
    radius = None if earth == "flat" else (earth_radius(h["lat"]) if "lat" in h
                                           else MEAN_EARTH_RADIUS_M)
    cartesian = radius is not None and raw.format != "seagap"
    def fit_with(scale):
        try:
            return locate_array(
                shots, h["transponders"], profile=prof, surface_depth=float(surface_depth),
                speed_intervals=speed_intervals, outliers=outliers, knot_minutes=knot_minutes,
                fixed=fixed, shift=shift, gradients=gradients, earth_radius=radius,
                along_sphere=not cartesian, exclude=left_out if left_out.any() else None,
                correlation=correlation,
                prior_sd=None if prior_sd is None else prior_sd * scale,
                centre_sd=None if centre_sd is None else centre_sd * scale)
        except InputError as exc:  # too few shots: name the shots file
            raise InputError(f"{_shots_file(raw)}: {exc}") from None

    fit, scaling = _fit_scaled(fit_with, position_prior)
    _check_fit(raw, fit, shots, shift)
    origin = (h["lat"], h["lon"], h.get("height", 0.0)) if "lat" in h else None
    counts = np.bincount(fit.index, minlength=len(fit.ids))
    out = {tid: _transponder_entry(fit, k, ci, origin, counts[k])
           for k, tid in enumerate(fit.ids)}
    cls, probs, sub = _classified(raw, shots, fit, flagged, honour, isolated)
    rays = "straight rays" if prof is None else f"refracted rays ({prof.source or 'profile'})"
    noise = _noise_entry(fit, correlation)
    summary = {
        "transponders": out, "array_centre": _centre_entry(fit, ci, origin),
        "sound_speed": _sound_speed_entry(fit, ci, prof),
        "residuals": _residual_entry(cls),
        "track": track_geometry(sub, {t: fit.enu[k] for k, t in enumerate(fit.ids)}),
        "site": h.get("site"), "campaign": h.get("campaign"),
        "epoch": _epoch_entry(raw.format, shots),
        "format": raw.format, "source": raw.source, "input_files": h.get("files", {}),
        "n_pings": int(len(shots)), "n_skipped_lines": int(len(raw.skipped)),
        "skipped_transponders": dict(fit.skipped),
        "method": _method(fit, rays, noise), "noise": noise,
        "outliers": outliers, "ssp": None if prof is None else prof.source,
        "speed_intervals": int(fit.model["speed_intervals"]), "fit_lag": False,
        "positions": _positions_entry(fit, ci, shift, h["transponders"], position_prior,
                                      scaling),
        "gradients": {"fitted": bool(gradients), "choice": choice, "reason": why,
                      "terms": list(fit.gradient_terms),
                      "deep_gate": {"fit": bool(deep), "reason": why_deep},
                      **(fit.model.get("gradients") or {}), "series": _gradient_series(fit)},
        "geometry": _geometry_entry(origin, surface_depth, radius, cartesian),
        "tat_fitted": False, "tat_given": 0.0,
        "position_region": f"a transponder's {100 * ci:g} % region is the ellipsoid of its "
                           f"covariance with squared radius {chi2.ppf(ci, 3):.4f}"}
    unlocated = np.isin(shots["transponder"].astype(str).to_numpy(), list(fit.skipped))
    summary["not_fitted"] = {"transponder_not_located": int(unlocated.sum()),
                             "flagged": int(np.sum(flagged & ~unlocated & ~isolated[0]))
                             if honour else 0,
                             "isolated_in_time": int(np.sum(isolated[0] & ~unlocated))}
    if "file_flag" in shots.columns:
        summary["file_flags"] = {"n_flagged": int(flagged.sum()), "flags": flags,
                                 "honoured": bool(honour),
                                 "n_flagged_called_spurious": int(np.sum(flagged & (probs < 0.5)))}
    return SurveyInResult(summary=summary, classified=cls, fits={"array": fit})
