"""Residual structure the fitted joint model leaves: a check for effects outside the vocabulary.

After the diagnosis has kept its effects, :func:`residual_checks` bins the
standardised residuals of the confidently classified direct-path and
multipath replies of every beacon against each covariate of
:func:`covariates` (time, range, elevation, vehicle depth, bearing) and tests
the bin means against zero. A significant check is structure no effect of
:data:`~bayes_mpem.lbl.effects.EFFECTS` explains.
"""

from __future__ import annotations

import numpy as np

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
        ``time`` (s), ``range`` (direct-path length, m), ``elevation`` (deg,
        positive when the vehicle is above the beacon), ``vehicle_depth`` (m),
        ``bearing`` (deg clockwise from +y, of the vehicle seen from the beacon).
    """
    ex, ey, h, dz = offsets(d)
    return {"time": d.time, "range": np.hypot(h, dz),
            "elevation": np.degrees(np.arctan2(dz, h)), "vehicle_depth": d.vdepth,
            "bearing": np.degrees(np.arctan2(ex, ey)) % 360.0}


def residual_checks(fit: JointFit, d: Ranges, *, n_bins=10, alpha=1e-4) -> list:
    """Residual structure the model leaves, class by class, against each covariate.

    For the direct-path and multipath replies (class probability above 0.9) the
    standardised residuals are binned into ``n_bins`` quantile bins of each
    covariate (time, range, elevation angle, vehicle depth, bearing from the
    beacon) per beacon; the bin means are tested against zero with a
    chi-square test. A check is ``significant`` when its p-value is below
    ``alpha`` divided by the number of checks (Bonferroni).

    Parameters
    ----------
    fit : JointFit
    d : Ranges
    n_bins : int, default 10
    alpha : float, default 1e-4

    Returns
    -------
    list of dict
        ``beacon``, ``class``, ``against``, ``chi2``, ``dof``, ``p_value``,
        ``max_bin_mean`` (m), ``significant``, ``message``.
    """
    from scipy import stats

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
                v = cov[cname][sel]
                if np.ptp(v) <= 0:
                    continue
                edges = np.unique(np.quantile(v, np.linspace(0, 1, n_bins + 1)))
                idx = np.clip(np.searchsorted(edges, v, side="right") - 1, 0, edges.size - 2)
                nbin = np.bincount(idx, minlength=edges.size - 1)
                ok = nbin > 0
                means = np.bincount(idx, weights=r, minlength=edges.size - 1)[ok] / nbin[ok]
                chi2 = float(np.sum(means ** 2 * nbin[ok] / sig ** 2))
                dof = int(ok.sum())
                pval = float(stats.chi2.sf(chi2, dof))
                checks.append({"beacon": bid, "class": name, "against": cname, "chi2": chi2,
                               "dof": dof, "p_value": pval,
                               "max_bin_mean": float(np.max(np.abs(means)))})
    limit = alpha / max(len(checks), 1)
    for ch in checks:
        ch["significant"] = ch["p_value"] < limit
        ch["message"] = (f"beacon {ch['beacon']}: {ch['class']} residuals vary with "
                         f"{ch['against']} (bin means up to {ch['max_bin_mean']:.2f} m, "
                         f"p = {ch['p_value']:.1e})")
    return checks
