"""Model checks of one beacon's fit: whether the paper's model describes these ranges.

Details: ``docs/model-checks.md``.
"""

from __future__ import annotations

import warnings

import numpy as np

from ...exceptions import ModelCheckWarning
from ..model.beacon_geometry import BeaconGeometry

#: A mean residual or a count this many standard errors off is flagged: a
#: two-sided normal tail of 6e-7 per check on data that fit the model.
Z_LIMIT = 5.0
#: A plane this many m above or below the sea surface is flagged (the
#: quality flags already flag one this far above it).
PLANE_TOLERANCE = 10.0
#: Family-wise level of the binned trend checks of one beacon (Bonferroni).
TREND_ALPHA = 1e-4
#: Covariates the residuals are binned against.
COVARIATES = ("time", "range", "elevation", "vehicle_depth", "bearing")
#: Where a flagged check sends the user.
ADVICE = ("run 'bayes-mpem diagnose' to find which of the model's assumptions the data break "
          "(a range bias, a sound speed, a drifting plane or navigation, a beacon position)")
#: Where a flagged check of the paper's EM sends the user: that EM misses the plane on data
#: the model describes too (``docs/paper-em.md``), so its flags say little about the data.
PAPER_ADVICE = ("the paper's EM fails this way on data the model describes too "
                "(docs/paper-em.md): fit with the mixture EM (--method mixture) and read "
                "its checks before looking for a cause in the data")
#: What each fit is called in the warnings.
FIT_NAMES = {"mixture": "the mixture EM", "paper": "the paper's EM", "posterior": "the posterior"}


def covariates(ex, ey, dz, time, vehicle_depth) -> dict:
    """Per-range covariates the residuals are checked against.

    Parameters
    ----------
    ex, ey, dz : numpy.ndarray
        Vehicle minus beacon, east and north, and beacon minus vehicle depth (m).

    Returns
    -------
    dict of numpy.ndarray
        ``time``, ``range``, ``elevation`` (deg), ``vehicle_depth``, ``bearing`` (deg).
    """
    h = np.hypot(ex, ey)
    return {"time": np.asarray(time, float), "range": np.hypot(h, dz),
            "elevation": np.degrees(np.arctan2(dz, h)),
            "vehicle_depth": np.asarray(vehicle_depth, float),
            "bearing": np.degrees(np.arctan2(ex, ey)) % 360.0}


def binned_trend(r, sigma, v, n_bins=10, *, centred=False):
    """Chi-square test of the residuals' bin means against a covariate.

    Parameters
    ----------
    r : numpy.ndarray
        Residuals (m) of one class.
    sigma : float
        Their assumed scatter (m).
    v : numpy.ndarray
        The covariate at each residual.
    centred : bool, default False
        Test against the residuals' mean (a trend alone) instead of zero.

    Returns
    -------
    dict or None
        ``chi2``, ``dof``, ``p_value``, ``max_bin_mean``; None when ``v`` is constant.
    """
    from scipy.special import chdtrc  # chi2.sf, without importing scipy.stats (0.7 s)

    if np.ptp(v) <= 0:
        return None
    # bin edges at the covariate's quantiles (from every k-th value beyond 50,000: the bins
    # depend on the covariate alone, so the test stays exact; only their counts even out less)
    step = -(-v.size // 50_000)
    edges = np.unique(np.quantile(v[::step], np.linspace(0, 1, n_bins + 1)))
    if edges.size < 2:  # the values sampled were all equal: one bin of the whole range
        edges = np.array([np.min(v), np.max(v)])
    idx = np.clip(np.searchsorted(edges, v, side="right") - 1, 0, edges.size - 2)
    nbin = np.bincount(idx, minlength=edges.size - 1)
    ok = nbin > 0
    centre = float(np.mean(r)) if centred else 0.0
    means = np.bincount(idx, weights=r - centre, minlength=edges.size - 1)[ok] / nbin[ok]
    chi2 = float(np.sum(means ** 2 * nbin[ok] / sigma ** 2))
    dof = int(ok.sum()) - (1 if centred else 0)
    return {"chi2": chi2, "dof": dof, "p_value": float(chdtrc(dof, chi2)),
            "max_bin_mean": float(np.max(np.abs(means)))}


def _finite(v):
    """Return a float, or None where it is not finite (JSON has no NaN or infinity)."""
    return float(v) if v is not None and np.isfinite(v) else None


def _check(name, value, z, flagged, message, **extra):
    return {"name": name, "value": _finite(value), "z": _finite(z), "flagged": bool(flagged),
            "message": message, **{k: _finite(v) for k, v in extra.items()}}


def _offset(r, w, sigma):
    """Weighted mean residual and its z (standard error sigma / sqrt(n_eff))."""
    sw, sw2 = float(w.sum()), float((w * w).sum())
    if sw < 5:
        return None
    mean = float((w * r).sum() / sw)
    se = sigma / np.sqrt(sw * sw / sw2)
    return mean, mean / se, se


def direct_path_checks(r_dp, resp_dp, sigma_dp, *, sigma_fixed=False):
    """Check the direct-path class's offset and (for a fixed ``sigma_DP``) its scatter.

    Parameters
    ----------
    r_dp : numpy.ndarray
        Range minus predicted direct path (m).
    """
    out = []
    off = _offset(r_dp, resp_dp, sigma_dp)
    if off is not None:
        mean, z, se = off
        out.append(_check(
            "direct_path_offset", mean, z, abs(z) > Z_LIMIT,
            f"direct-path ranges are {abs(mean):.2f} ± {se:.2f} m "
            f"{'longer' if mean > 0 else 'shorter'} than the straight line to the beacon "
            f"({abs(z):.0f} standard errors): a range bias (turn-around time), a sound-speed "
            "error or a wrong beacon position", se=se))
    sw = float(resp_dp.sum())
    if sigma_fixed and sw >= 5:
        ratio = float(np.sqrt((resp_dp * r_dp * r_dp).sum() / sw) / sigma_dp)
        z = (ratio ** 2 - 1.0) / np.sqrt(2.0 / sw)
        out.append(_check(
            "direct_path_scatter", ratio, z, abs(z) > Z_LIMIT,
            f"direct-path ranges scatter {ratio:.2f} times the fixed sigma_DP = {sigma_dp:.2f} m "
            "(--sigma-dp): fit sigma_DP instead, or check the sensor's noise"))
    return out


def trend_checks(residuals, sigmas, resp, cov, *, n_bins=10, alpha=TREND_ALPHA, min_per_bin=5):
    """Binned trend checks of the confident ranges (p > 0.9) of each class against each covariate.

    Parameters
    ----------
    residuals, sigmas, resp : dict
        Per class (``"dp"``, ``"mp"``): residuals, scatter and probabilities.
    cov : dict of str to numpy.ndarray
        :func:`covariates`.
    alpha : float, default :data:`TREND_ALPHA`
        Family-wise level (Bonferroni).
    """
    found = []
    for cls, r in residuals.items():
        sel = resp[cls] > 0.9
        if sel.sum() < min_per_bin * n_bins:
            continue
        for against in COVARIATES:
            t = binned_trend(r[sel], sigmas[cls], cov[against][sel], n_bins, centred=True)
            if t is not None:
                found.append((cls, against, t))
    limit = alpha / max(len(found), 1)
    out = []
    for cls, against, t in found:
        what = "direct-path" if cls == "dp" else "multipath"
        out.append({"name": f"{'direct_path' if cls == 'dp' else 'multipath'}_trend",
                    "class": cls, "against": against, **t, "value": t["max_bin_mean"],
                    "z": None, "flagged": t["p_value"] < limit,
                    "message": f"{what} residuals vary with {against} (bin means up to "
                               f"{t['max_bin_mean']:.2f} m from their mean, "
                               f"p = {t['p_value']:.1e})"})
    return out


def outlier_timing_check(z, direct, resp_ol, lo, hi):
    """Share of the outliers before the direct path against a uniform window's share.

    Parameters
    ----------
    lo, hi : float
        The listening window (m).

    Returns
    -------
    list of dict
        One check, or none when fewer than 20 ranges' worth are outliers.
    """
    w = np.asarray(resp_ol, float)
    if w.sum() < 20 or hi <= lo:
        return []
    e = np.clip((direct - lo) / (hi - lo), 0.0, 1.0)  # uniform: P(before the direct path)
    obs = float((w * (z < direct)).sum())
    exp = float((w * e).sum())
    sd = float(np.sqrt(max((w * w * e * (1 - e)).sum(), 1e-12)))
    zz = (obs - exp) / sd
    share, want = obs / w.sum(), exp / w.sum()
    why = ("a first-arrival detector (outliers only before the true reply)" if zz > 0
           else "late spurious replies (reverberation, a second reflector)")
    return [_check("outliers_before_direct", share, zz, abs(zz) > Z_LIMIT,
                   f"{100 * share:.0f} % of the outliers arrive before the direct path, "
                   f"{100 * want:.0f} % expected if they spread over the listening window: "
                   f"{why}", expected=want)]


def plane_check(plane_depth, interval=None):
    """Check the plane against the sea surface, in either direction.

    Parameters
    ----------
    interval : tuple of float, optional
        Its credible interval (the end nearer the surface is used).
    """
    lo, hi = interval if interval is not None else (plane_depth, plane_depth)
    near = 0.0 if lo <= 0.0 <= hi else (lo if lo > 0 else hi)
    off = abs(near) > PLANE_TOLERANCE
    where = "below" if plane_depth > 0 else "above"
    return [_check("plane_off_surface", plane_depth, None, off,
                   f"the plane is {abs(plane_depth):.1f} m {where} the sea surface (more than "
                   f"{PLANE_TOLERANCE:g} m): a range bias, a sound-speed error, a wrong "
                   "beacon depth, a drifting plane or navigation can move it")]


def check_beacon(geom: BeaconGeometry, time, depth, *, d0, sigma_dp, sigma_mp, resp, path,
                 plane_depth, sigma_dp_fixed=False, plane_interval=None, ex=None,
                 ey=None, method="mixture") -> list:
    """Every check of one beacon's straight-ray fit (the paper's EM: offset, trend, plane only).

    Parameters
    ----------
    ex, ey : numpy.ndarray, optional
        Vehicle minus beacon east and north, for the bearing.
    """
    paper = method == "paper"
    r_dp = geom.z - geom.direct
    r_mp = geom.z - geom.multipath(d0, path)
    ex = geom.h if ex is None else ex
    ey = np.zeros_like(geom.h) if ey is None else ey
    cov = covariates(ex, ey, geom.dz, time, depth)
    out = direct_path_checks(r_dp, resp[:, 0], sigma_dp, sigma_fixed=sigma_dp_fixed and not paper)
    out += trend_checks({"dp": r_dp, "mp": r_mp}, {"dp": sigma_dp, "mp": sigma_mp},
                        {"dp": resp[:, 0], "mp": resp[:, 1]}, cov)
    if not paper:
        out += outlier_timing_check(geom.z, geom.direct, resp[:, 2], geom.lo, geom.hi)
    out += plane_check(plane_depth, plane_interval)
    return out


def check_fit(data, result, *, plane_interval=None, params=None, resp=None) -> list:
    """Run :func:`check_beacon` on a fit of one beacon (an EM result, or a posterior's).

    Parameters
    ----------
    params : dict, optional
        ``d0``, ``sigma_dp``, ``sigma_mp`` instead of the result's.
    resp : numpy.ndarray, optional
        Class probabilities instead of the result's.
    """
    geom = BeaconGeometry.from_data(data)
    p = params or {"d0": result.d0, "sigma_dp": result.sigma_dp, "sigma_mp": result.sigma_mp}
    bx, by, bz = (float(v) for v in data.position)
    fixed = bool(result.settings.get("sigma_dp_fixed")) if result.settings else False
    return check_beacon(geom, data.time, data.depth, d0=p["d0"], sigma_dp=p["sigma_dp"],
                        sigma_mp=p["sigma_mp"], resp=result.resp if resp is None else resp,
                        path=result.path, plane_depth=bz - p["d0"], sigma_dp_fixed=fixed,
                        plane_interval=plane_interval, ex=data.x - bx, ey=data.y - by,
                        method=result.method)


def check_posterior(data, result) -> list:
    """Run :func:`check_beacon` at a beacon's posterior means, the plane with its interval."""
    s = result.summary
    depth = float(data.position[2])
    lo, hi = s["d0"]["interval"]
    params = {k: s[k]["mean"] for k in ("d0", "sigma_dp", "sigma_mp")}
    return check_fit(data, result.em, params=params, resp=result.class_probs,
                     plane_interval=(depth - hi, depth - lo))


def checks_record(checks, method="mixture") -> dict:
    """Return the record of a beacon's checks in ``summary.json``: ``flags``, then ``checks``."""
    msgs = flagged(checks)
    return {"flags": msgs + ([advice(method)] if msgs else []), "checks": list(checks)}


def advice(method) -> str:
    """Return what a flagged check of a fit by ``method`` suggests doing next."""
    return PAPER_ADVICE if method == "paper" else ADVICE


def flagged(checks) -> list:
    """Return the messages of the flagged checks, the trends of one class in one message."""
    out, trends = [], {}
    for c in checks:
        if not c["flagged"]:
            continue
        if c["name"].endswith("_trend"):
            trends.setdefault(c["class"], []).append(c)
        else:
            out.append(c["message"])
    for cls, cs in trends.items():
        what = "direct-path" if cls == "dp" else "multipath"
        out.append(f"{what} residuals vary with {', '.join(c['against'] for c in cs)} (bin "
                   f"means up to {max(c['value'] for c in cs):.2f} m from their mean, "
                   f"p <= {max(c['p_value'] for c in cs):.1e})")
    return out


def warn_misfit(beacon, checks, *, method="mixture", stacklevel=2):
    """Warn (ModelCheckWarning) once for a beacon whose checks flag a misfit, naming the fit."""
    msgs = flagged(checks)
    if msgs:
        if method == "paper":  # its own failure is the likelier cause: no claim on the model
            text = (f"the fit does not describe these ranges: {'; '.join(msgs)}. "
                    f"{PAPER_ADVICE[0].upper()}{PAPER_ADVICE[1:]}")
        else:
            text = (f"the model does not describe these ranges: {'; '.join(msgs)}. The "
                    f"interval of d0 assumes it does: {ADVICE}")
        warnings.warn(f"beacon {beacon} ({FIT_NAMES.get(method, method)}): {text}",
                      ModelCheckWarning, stacklevel=stacklevel + 1)
