"""Statistics of a transponder's travel-time residuals, for the simulation-gap check.

Their definitions: ``docs/simulation-gap.md``.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from .._validate import check_choice, check_int

#: Statistic name -> (residual column, Monte-Carlo side, description).
STATISTICS = {
    "elevation": ("residual", "upper", "binned mean residual vs elevation angle (chi-square)"),
    "slant_range": ("residual", "upper", "binned mean residual vs slant range (chi-square)"),
    "time": ("residual", "upper", "binned mean residual vs time (chi-square)"),
    "lag1": ("residual", "two-sided", "lag-1 autocorrelation in time order"),
    "noise_elevation": ("residual", "two-sided",
                        "log(sd low elevations / sd high elevations), thirds"),
    "kurtosis": ("residual", "two-sided", "excess kurtosis of the true residuals"),
    "along_track": ("residual", "two-sided", "fitted along-course position offset (m)"),
    "late_share": ("residual", "two-sided",
                   "share of spurious pings after the predicted true arrival"),
    "common_drift": ("detrended", "upper",
                     "share of residual variance predicted by the other transponders"),
    "elevation_detrended": ("detrended", "upper",
                            "elevation statistic after removing the common drift"),
    "slant_range_detrended": ("detrended", "upper",
                              "slant-range statistic after removing the common drift"),
    "lag1_detrended": ("detrended", "two-sided",
                       "lag-1 autocorrelation after removing the common drift"),
}


def remove_common_drift(frames) -> dict:
    """Predict each true residual from the other transponders pinged at the same time.

    Parameters
    ----------
    frames : dict or sequence of pandas.DataFrame
        :func:`residual_frame` of several transponders of one survey.

    Returns
    -------
    dict
        Transponder -> a copy of its frame with a ``detrended`` column (s): NaN for
        spurious pings and where no other transponder has a true ping at that time.
    """
    items = list(frames.items()) if isinstance(frames, dict) else \
        [(str(f["beacon"].iloc[0]) if len(f) else str(k), f) for k, f in enumerate(frames)]
    if not items:
        return {}
    allf = pd.concat([f.assign(_k=k) for k, (_, f) in enumerate(items)], ignore_index=True)
    tr = allf["true"].to_numpy(bool)
    rel = np.where(tr, allf["residual"].to_numpy(float) / allf["pred"].to_numpy(float), 0.0)
    key = allf["time"].to_numpy()
    tot = pd.Series(rel).groupby(key).transform("sum").to_numpy(float)
    cnt = pd.Series(tr.astype(float)).groupby(key).transform("sum").to_numpy(float)
    others = cnt - tr
    with np.errstate(invalid="ignore", divide="ignore"):
        eps = (tot - rel) / others
    det = np.where(tr & (others > 0), allf["residual"].to_numpy(float)
                   - eps * allf["pred"].to_numpy(float), np.nan)
    out = {}
    for k, (name, f) in enumerate(items):
        f = f.copy()
        f["detrended"] = det[allf["_k"].to_numpy() == k]
        out[name] = f
    return out


def _binned_chi2(v, r, n_bins):
    ok = np.isfinite(v) & np.isfinite(r)
    v, r = v[ok], r[ok]
    if r.size < 2 * n_bins:
        return np.nan
    s2 = float(np.mean(r * r))
    if s2 <= 0:
        return np.nan
    groups = np.array_split(np.argsort(v, kind="stable"), n_bins)
    return float(sum(g.size * np.mean(r[g]) ** 2 for g in groups) / s2)


def _lag1(t, r):
    ok = np.isfinite(t) & np.isfinite(r)
    if ok.sum() < 3:
        return np.nan
    r = r[ok][np.argsort(t[ok], kind="stable")]
    r0 = r - r.mean()
    d = float(np.sum(r0 * r0))
    return float(np.sum(r0[:-1] * r0[1:]) / d) if d > 0 else np.nan


def gap_statistics(frame: pd.DataFrame, *, n_bins: int = 6) -> dict:
    """Compute the statistics of :data:`STATISTICS` for one transponder's residuals.

    Parameters
    ----------
    frame : pandas.DataFrame
        :func:`residual_frame`, optionally with the ``detrended`` column of
        :func:`remove_common_drift` (else the ``*_detrended`` statistics and
        ``common_drift`` are NaN).
    n_bins : int, default 6
        Equal-count bins of the binned statistics.

    Returns
    -------
    dict
        Statistic name -> value (NaN where undefined: too few pings, no
        spurious ping, no detrended column).
    """
    n_bins = check_int("n_bins", n_bins, minimum=2)
    tr = frame["true"].to_numpy(bool)
    f = frame.loc[tr]
    r = f["residual"].to_numpy(float)
    el, sr, tm = (f[c].to_numpy(float) for c in ("elevation", "slant_range", "time"))
    out = {k: np.nan for k in STATISTICS}
    out["elevation"] = _binned_chi2(el, r, n_bins)
    out["slant_range"] = _binned_chi2(sr, r, n_bins)
    out["time"] = _binned_chi2(tm, r, n_bins)
    out["lag1"] = _lag1(tm, r)
    if r.size >= 9:
        thirds = np.array_split(np.argsort(el, kind="stable"), 3)
        lo, hi = np.std(r[thirds[0]]), np.std(r[thirds[-1]])
        if lo > 0 and hi > 0:
            out["noise_elevation"] = float(np.log(lo / hi))
        r0 = r - r.mean()
        m2 = np.mean(r0**2)
        if m2 > 0:
            out["kurtosis"] = float(np.mean(r0**4) / m2**2 - 3.0)
        g = f["dtwtt_dforward"].to_numpy(float)
        if np.any(g != 0):
            a = np.column_stack([g, np.ones_like(g)])
            coef, *_ = np.linalg.lstsq(a, r, rcond=None)
            out["along_track"] = float(coef[0])
    spur = ~tr
    if spur.any():
        out["late_share"] = float(np.mean(frame.loc[spur, "residual"].to_numpy(float) > 0))
    if "detrended" in frame.columns:
        d = f["detrended"].to_numpy(float)
        ok = np.isfinite(d)
        if ok.sum() >= 2 * n_bins:
            out["common_drift"] = float(1.0 - np.mean(d[ok] ** 2) / np.mean(r[ok] ** 2))
            out["elevation_detrended"] = _binned_chi2(el[ok], d[ok], n_bins)
            out["slant_range_detrended"] = _binned_chi2(sr[ok], d[ok], n_bins)
            out["lag1_detrended"] = _lag1(tm[ok], d[ok])
    return out


def mc_pvalue(measured: float, simulated, side: str = "two-sided") -> float:
    """Monte-Carlo p-value of a measured statistic against simulated replicates.

    ``upper = (1 + #{sim >= measured}) / (N + 1)``, ``lower`` likewise; two-sided is
    ``min(1, 2 min(upper, lower))``. NaN replicates are dropped.

    Parameters
    ----------
    measured : float
    simulated : array_like
    side : {"upper", "lower", "two-sided"}

    Examples
    --------
    >>> mc_pvalue(5.0, [0.0, 1.0, 2.0, 3.0], "upper")
    0.2
    >>> mc_pvalue(1.5, [0.0, 1.0, 2.0, 3.0])
    1.0
    """
    check_choice("side", side, ("upper", "lower", "two-sided"), words=True)
    sim = np.asarray(simulated, float)
    sim = sim[np.isfinite(sim)]
    if not np.isfinite(measured) or sim.size == 0:
        return np.nan
    n = sim.size
    up = (1 + np.sum(sim >= measured)) / (n + 1)
    lo = (1 + np.sum(sim <= measured)) / (n + 1)
    if side == "upper":
        return float(up)
    if side == "lower":
        return float(lo)
    return float(min(1.0, 2.0 * min(up, lo)))
