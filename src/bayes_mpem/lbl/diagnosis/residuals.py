"""Residual structure the fitted joint model leaves: a check for effects outside the vocabulary."""

from __future__ import annotations

import numpy as np

from ..em.em_result import reflector_flags
from ..survey.model_checks import (
    binned_trend,
    direct_path_checks,
    outlier_timing_check,
    plane_check,
)
from ..survey.model_checks import covariates as _covariates
from .ecm import JointFit
from .model import Ranges, offsets, predict

# --------------------------------------------------------------------------- residual checks

_COVARIATES = ("time", "range", "elevation", "vehicle_depth", "bearing")


def covariates(d: Ranges) -> dict:
    """Per-reply covariates the residuals are checked against (reported navigation).

    Parameters
    ----------
    d : Ranges
        ``Diagnosis.data``.

    Returns
    -------
    dict of numpy.ndarray
        Those of :func:`bayes_mpem.lbl.survey.model_checks.covariates` (time, range,
        elevation, vehicle depth, bearing).
    """
    ex, ey, _, dz = offsets(d)
    return _covariates(ex, ey, dz, d.time, d.vdepth)


def residual_checks(fit: JointFit, d: Ranges, *, n_bins=10, alpha=1e-4) -> list:
    """Residual structure the model leaves, class by class, against each covariate.

    Parameters
    ----------
    alpha : float, default 1e-4
        Family-wise level (Bonferroni over the checks).

    Returns
    -------
    list of dict
        ``beacon``, ``class``, ``against``, ``chi2``, ``dof``, ``p_value``,
        ``max_bin_mean`` (m), ``significant``, ``message``.
    """
    mu = predict(d, fit.params, fit.effects, fit.path)
    p = fit.params
    cov = covariates(d)
    checks = []
    for c, name in enumerate(("dp", "mp")):
        for j, bid in enumerate(d.ids):
            sel = (d.bi == j) & (fit.resp[:, c] > 0.9)
            if sel.sum() < 5 * n_bins:
                continue
            sig = p.sigma[j, c]
            r = (d.z[sel] - mu[name][sel])
            for cname in _COVARIATES:
                t = binned_trend(r, sig, cov[cname][sel], n_bins)
                if t is not None:
                    checks.append({"beacon": bid, "class": name, "against": cname, **t})
    limit = alpha / max(len(checks), 1)
    for ch in checks:
        ch["significant"] = ch["p_value"] < limit
        ch["message"] = (f"beacon {ch['beacon']}: {ch['class']} residuals vary with "
                         f"{ch['against']} (bin means up to {ch['max_bin_mean']:.2f} m, "
                         f"p = {ch['p_value']:.1e})")
    return checks


def beacon_flags(fit, data, sigma_floor: float = 0.05) -> dict:
    """Why each beacon's fit is not credible: the per-beacon EM's quality checks, jointly.

    Parameters
    ----------
    fit : JointFit
        The final joint fit.
    data : Ranges
        The replies the fit saw.
    sigma_floor : float, default 0.05
        The scale floor of the fit.

    Returns
    -------
    dict
        Beacon id to a list of reasons; empty lists for credible beacons.
    """
    p = fit.params
    mu = predict(data, p, fit.effects, fit.path)
    out = {}
    for j, bid in enumerate(data.ids):
        sel = data.bi == j
        s_mp = float(p.sigma[j, 1])
        flags = reflector_flags(fit.resp[sel], s_mp, float(p.plane[j]), sigma_floor=sigma_floor)
        gap = float(np.median(mu["mp"][sel] - mu["dp"][sel])) if sel.any() else np.inf
        if gap < 2.0 * s_mp:
            flags.append(f"the multipath family lies on the direct path (median "
                         f"separation {gap:.1f} m, sigma_MP = {s_mp:.1f} m; plane depth "
                         f"{p.plane[j]:.0f} m)")
        checks = (direct_path_checks(data.z[sel] - mu["dp"][sel], fit.resp[sel, 0],
                                     float(p.sigma[j, 0]))
                  + ([] if "early_outliers" in fit.effects else outlier_timing_check(
                      data.z[sel], mu["dp"][sel], fit.resp[sel, 3], float(data.lo[j]),
                      float(data.hi[j])))
                  + ([] if p.plane[j] < -10.0 else plane_check(float(p.plane[j]))))
        flags += [c["message"] for c in checks if c["flagged"]]
        out[bid] = flags
    return out
