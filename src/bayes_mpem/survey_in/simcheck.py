"""Measured survey residuals against simulated ones (docs/simulation-gap.md)."""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from scipy.optimize import least_squares

from .._rng import as_generator
from .._validate import check_choice, check_int
from ..acoustics.turning import direct_times
from ..exceptions import InputError, LocateWarning
from .location import LocateResult, locate

#: Columns of the pings table that :func:`simulate_like` keeps (``line`` when present).
TRACK_COLUMNS = ("beacon", "x", "y", "depth", "time", "line")


def _check_straight(fit):
    """Check that ``fit`` is a straight-ray, one-speed, flat-frame :class:`LocateResult`."""
    if not isinstance(fit, LocateResult):
        raise TypeError(f"fit: expected a LocateResult, got {type(fit).__name__}")
    m = getattr(fit, "model", None) or {}
    if (m.get("ssp") is not None or m.get("speed_intervals") or m.get("earth_radius")
            is not None):
        raise ValueError(f"transponder {fit.transponder}: the fit uses refracted rays, a "
                         "time-varying sound speed or a spherical geometry; this check "
                         "compares with the simulator's straight rays at one sound speed in "
                         "a flat frame (locate without ssp, speed_intervals, earth_radius)")


def _fits(fit):
    fits = [fit] if isinstance(fit, LocateResult) else list(fit)
    if not fits:
        raise ValueError("fit: expected a LocateResult or a non-empty sequence of them")
    for f in fits:
        _check_straight(f)
    names = [f.transponder for f in fits]
    if len(set(names)) != len(names):
        raise ValueError(f"fit: transponders repeated ({names})")
    return fits


def _ping_rows(pings, fit):
    """Find the fit's pings in ``pings``, checking that the table is the fit's."""
    need = {"beacon", "x", "y", "depth"}
    missing = need - set(pings.columns)
    if missing:
        raise InputError(f"pings: missing column(s) {sorted(missing)} (expected {sorted(need)})")
    rows = np.asarray(fit.rows)
    if rows.size != np.asarray(fit.p_true).size:
        raise ValueError(f"transponder {fit.transponder}: fit.rows and fit.p_true differ in size")
    if rows.size and (rows.min() < 0 or rows.max() >= len(pings)):
        raise InputError(f"transponder {fit.transponder}: the fit's rows are not rows of this "
                         f"pings table ({len(pings)} rows); pass the table it was located from")
    beacon = pings["beacon"].astype(str).to_numpy()[rows]
    if np.any(beacon != fit.transponder):
        raise InputError(f"transponder {fit.transponder}: the fit's rows hold other beacons in "
                         "this pings table; pass the table it was located from")
    return rows


def _straight_twtt(x, y, z, fit):
    return 2.0 * np.sqrt((x - fit.east) ** 2 + (y - fit.north) ** 2
                         + (z - fit.depth) ** 2) / fit.sound_speed + fit.tat


def simulate_like(pings: pd.DataFrame, beacons: pd.DataFrame, fit, rng=None) -> pd.DataFrame:
    """Simulate a measured survey under the simulator's assumptions, from the located fit(s).

    Parameters
    ----------
    pings : pandas.DataFrame
        The table the fit(s) were located from (``beacon``, ``x``, ``y``,
        ``depth``, ``time``, optionally ``line``).
    beacons : pandas.DataFrame
        The beacons table the fit(s) were located with.
    fit : LocateResult or sequence of LocateResult
        One transponder, or several of the same survey.
    rng : None, int or numpy.random.Generator

    Returns
    -------
    pandas.DataFrame
        The fitted transponders' pings in table order: ``beacon``, ``twtt`` (s), ``x``, ``y``,
        ``depth``, ``time``, ``line`` (when present), ``spurious`` (bool).

    Raises
    ------
    InputError
        A missing column, a transponder not in ``beacons``, or a fit not located from ``pings``.
    ValueError
        A fit with refracted rays or a time-varying sound speed.
    """
    fits = _fits(fit)
    if "time" not in pings.columns:
        raise InputError("pings: missing column(s) ['time'] (s; needed to keep the track)")
    ids = set(beacons["beacon"].astype(str))
    for f in fits:
        if f.transponder not in ids:
            raise InputError(f"transponder {f.transponder!r} not in the beacons table "
                             f"{sorted(ids)}")
    rows = [_ping_rows(pings, f) for f in fits]
    gen = as_generator(rng)
    cols = [c for c in TRACK_COLUMNS if c in pings.columns]
    twtt = np.full(len(pings), np.nan)
    spur = np.zeros(len(pings), bool)
    for f, r in zip(fits, rows, strict=True):
        sub = pings.iloc[r]
        pred = _straight_twtt(*(sub[c].to_numpy(float) for c in ("x", "y", "depth")), f)
        t = pred + f.sigma * gen.standard_normal(r.size)
        bad = gen.random(r.size) >= f.weight
        lo, hi = f.window
        t[bad] = gen.uniform(lo, hi, int(bad.sum()))
        twtt[r], spur[r] = t, bad
    keep = np.sort(np.concatenate(rows))
    out = pings.iloc[keep][cols].copy()
    out.insert(1, "twtt", twtt[keep])
    out["spurious"] = spur[keep]
    return out.reset_index(drop=True)


def residual_frame(pings: pd.DataFrame, fit: LocateResult) -> pd.DataFrame:
    """Residuals and geometry of every ping of the fit's transponder.

    Parameters
    ----------
    pings : pandas.DataFrame
        The table the fit was located from.
    fit : LocateResult
        A straight-ray, one-speed fit.

    Returns
    -------
    pandas.DataFrame
        One row per ping: ``row``, ``beacon``, ``time``, ``x``, ``y``, ``depth``, ``twtt``,
        ``pred`` (straight ray plus TAT), ``residual``, ``ratio`` (``twtt / pred``), ``p_true``,
        ``true``, ``elevation`` (deg), ``slant_range``, ``horizontal_range`` (m) and
        ``dtwtt_dforward`` (s/m along the ship's course).

    Raises
    ------
    InputError, ValueError
        As :func:`simulate_like`.

    Examples
    --------
    >>> import pandas as pd
    >>> from bayes_mpem.survey_in.location import locate
    >>> import numpy as np
    >>> a = np.linspace(0, 2 * np.pi, 24, endpoint=False)
    >>> pings = pd.DataFrame({"beacon": "T", "x": np.r_[0.0, 3000 * np.cos(a)],
    ...                       "y": np.r_[0.0, 3000 * np.sin(a)], "depth": 0.0,
    ...                       "time": 60.0 * np.arange(25)})
    >>> noise = 1e-4 * np.sin(7.0 * np.arange(25))
    >>> pings["twtt"] = 2 * np.sqrt(pings.x**2 + pings.y**2 + 4000.0**2) / 1500.0 + noise
    >>> beacons = pd.DataFrame({"beacon": ["T"], "x": [0.0], "y": [0.0], "depth": [4000.0]})
    >>> fr = residual_frame(pings, locate(pings, beacons, tat=0.0))
    >>> fr[["elevation", "slant_range"]].round(0).iloc[:2].values.tolist()
    [[90.0, 4000.0], [53.0, 5000.0]]
    """
    _check_straight(fit)
    rows = _ping_rows(pings, fit)
    for c in ("twtt", "time"):
        if c not in pings.columns:
            raise InputError(f"pings: missing column(s) [{c!r}]")
    sub = pings.iloc[rows]
    x, y, z, t, tm = (sub[c].to_numpy(float) for c in ("x", "y", "depth", "twtt", "time"))
    dx, dy, dz = x - fit.east, y - fit.north, fit.depth - z
    h = np.hypot(dx, dy)
    s = np.sqrt(h * h + dz * dz)
    pred = 2.0 * s / fit.sound_speed + fit.tat
    # the ship's course: direction between the neighbouring pings in time
    order = np.argsort(tm, kind="stable")
    cx, cy = np.zeros_like(x), np.zeros_like(y)
    if x.size >= 2:
        xo, yo = x[order], y[order]
        ex = np.concatenate([[xo[1] - xo[0]], xo[2:] - xo[:-2], [xo[-1] - xo[-2]]])
        ey = np.concatenate([[yo[1] - yo[0]], yo[2:] - yo[:-2], [yo[-1] - yo[-2]]])
        norm = np.hypot(ex, ey)
        ok = norm > 0
        cx[order[ok]], cy[order[ok]] = ex[ok] / norm[ok], ey[ok] / norm[ok]
    with np.errstate(invalid="ignore", divide="ignore"):
        dfwd = np.where(s > 0, 2.0 * (cx * dx + cy * dy) / (s * fit.sound_speed), 0.0)
    p = np.asarray(fit.p_true, float)
    return pd.DataFrame({
        "row": rows, "beacon": fit.transponder, "time": tm, "x": x, "y": y, "depth": z,
        "twtt": t, "pred": pred, "residual": t - pred, "ratio": t / pred, "p_true": p,
        "true": p >= 0.5, "elevation": np.degrees(np.arctan2(dz, h)), "slant_range": s,
        "horizontal_range": h, "dtwtt_dforward": dfwd})


@dataclass
class GapResult:
    """Measured statistics against their distribution over simulated replicates.

    Attributes
    ----------
    fits : dict
        Transponder -> the measured :class:`~bayes_mpem.survey_in.location.LocateResult`.
    frames : dict
        Transponder -> measured :func:`residual_frame`.
    table : pandas.DataFrame
        One row per transponder and statistic: ``measured``, ``sim_q05``, ``sim_median``,
        ``sim_q95``, ``p_value``, ``side``, ``n_sim``.
    simulated : dict
        ``(transponder, statistic)`` -> the replicate values.
    example : dict
        Transponder -> the residual frame of the first replicate.
    spurious_ratio : dict
        Transponder -> per replicate, ``twtt / pred`` of the pings classified spurious.
    n_sim : int
    n_warned : int
        Replicate fits that raised a :class:`~bayes_mpem.exceptions.LocateWarning`.
    """

    fits: dict
    frames: dict
    table: pd.DataFrame
    simulated: dict = field(repr=False)
    example: dict = field(repr=False)
    spurious_ratio: dict = field(repr=False)
    n_sim: int = 0
    n_warned: int = 0

    def pvalues(self) -> pd.DataFrame:
        """Monte-Carlo p-values, transponders by statistics."""
        return self.table.pivot(index="transponder", columns="statistic", values="p_value")


def _survey_stats(pings, fits, n_bins, common_drift):
    frames = {tid: residual_frame(pings, f) for tid, f in fits.items()}
    if common_drift:
        frames = remove_common_drift(frames)
    return frames, {tid: gap_statistics(fr, n_bins=n_bins) for tid, fr in frames.items()}


def simulation_gap(pings: pd.DataFrame, beacons: pd.DataFrame, transponders=None, *,
                   n_sim: int = 200, rng=None, n_bins: int = 6, common_drift=None,
                   progress=None, **locate_kwargs) -> GapResult:
    """Compare a measured survey's residual statistics with simulated replicates.

    Parameters
    ----------
    pings, beacons : pandas.DataFrame
        As for :func:`~bayes_mpem.survey_in.location.locate` (with ``time``).
    transponders : sequence of str, optional
        Default: every beacon with pings.
    n_sim : int, default 200
        Replicates.
    rng : None, int or numpy.random.Generator
    n_bins : int, default 6
    common_drift : bool, optional
        Remove the drift common to the transponders; default: when there are several.
    progress : callable, optional
        Called with the replicate number after each replicate.
    **locate_kwargs
        Passed to every ``locate`` call; not ``ssp``, ``speed_intervals`` or ``earth_radius``.

    Raises
    ------
    InputError
        No transponder with pings, or as :func:`~bayes_mpem.survey_in.location.locate`.
    ValueError
        ``n_sim`` < 1 or a non-straight-ray option.
    """
    check_int("n_sim", n_sim, minimum=1)
    for k in ("ssp", "speed_intervals", "earth_radius", "transponder"):
        if locate_kwargs.get(k):
            raise ValueError(f"{k}: not supported here (the simulator's straight rays at one "
                             "sound speed; transponders are given by 'transponders')")
    if transponders is None:
        have = set(pings["beacon"].astype(str))
        transponders = [b for b in beacons["beacon"].astype(str) if b in have]
    transponders = [str(t) for t in transponders]
    if not transponders:
        raise InputError("no transponder of the beacons table has pings")
    if common_drift is None:
        common_drift = len(transponders) > 1
    fits = {tid: locate(pings, beacons, tid, **locate_kwargs) for tid in transponders}
    frames, measured = _survey_stats(pings, fits, n_bins, common_drift)
    gen = as_generator(rng)
    sims = {(tid, k): np.full(n_sim, np.nan) for tid in transponders for k in STATISTICS}
    ratios = {tid: [] for tid in transponders}
    example, n_warned = {}, 0
    for i in range(n_sim):
        sim = simulate_like(pings, beacons, list(fits.values()), rng=gen)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", LocateWarning)
            sfits = {tid: locate(sim, beacons, tid, **locate_kwargs) for tid in transponders}
        n_warned += sum(issubclass(w.category, LocateWarning) for w in caught)
        for w in caught:
            if not issubclass(w.category, LocateWarning):
                warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
        sframes, stats = _survey_stats(sim, sfits, n_bins, common_drift)
        for tid in transponders:
            for k, v in stats[tid].items():
                sims[(tid, k)][i] = v
            fr = sframes[tid]
            ratios[tid].append(fr.loc[~fr["true"], "ratio"].to_numpy(float))
        if i == 0:
            example = sframes
        if progress is not None:
            progress(i + 1)
    rows = []
    for tid in transponders:
        for k, (_, side, _) in STATISTICS.items():
            v, s = measured[tid][k], sims[(tid, k)]
            fin = s[np.isfinite(s)]
            q = np.quantile(fin, [0.05, 0.5, 0.95]) if fin.size else [np.nan] * 3
            rows.append({"transponder": tid, "statistic": k, "measured": v,
                         "sim_q05": float(q[0]), "sim_median": float(q[1]),
                         "sim_q95": float(q[2]), "p_value": mc_pvalue(v, s, side),
                         "side": side, "n_sim": int(fin.size)})
    return GapResult(fits=fits, frames=frames, table=pd.DataFrame(rows), simulated=sims,
                     example=example,
                     spurious_ratio=ratios,
                     n_sim=int(n_sim), n_warned=int(n_warned))


# ------------------------------------------------------------ residual statistics

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


# ------------------------------------------------ what a straight-ray fit cannot absorb

def unabsorbed(pings: pd.DataFrame, fit: LocateResult, twtt) -> tuple:
    """Find the part of noise-free travel times that a straight-ray fit cannot absorb.

    Parameters
    ----------
    pings : pandas.DataFrame
        The table the fit was located from.
    fit : LocateResult
    twtt : array_like
        Two-way travel times (s) of the fit's pings (``fit.rows`` order), from
        another model, e.g. :func:`refracted_twtt`.

    Returns
    -------
    residual : numpy.ndarray
        ``twtt`` minus the best straight-ray fit (s).
    shift : dict
        ``east``, ``north``, ``depth``, ``sound_speed`` of that fit minus the
        fit's own: how the straight-ray parameters absorb the model.

    Examples
    --------
    Straight-ray times from another position are absorbed completely:

    >>> import numpy as np, pandas as pd
    >>> from bayes_mpem.survey_in.location import locate
    >>> a = np.linspace(0, 2 * np.pi, 40, endpoint=False)
    >>> rad = np.linspace(300.0, 3000.0, 40)
    >>> pings = pd.DataFrame({"beacon": "T", "x": rad * np.cos(a), "y": rad * np.sin(a),
    ...                       "depth": 0.0, "time": np.arange(40.0)})
    >>> noise = 1e-4 * np.sin(7.0 * np.arange(40))
    >>> pings["twtt"] = 2 * np.sqrt(pings.x**2 + pings.y**2 + 4000.0**2) / 1500.0 + noise
    >>> beacons = pd.DataFrame({"beacon": ["T"], "x": [0.0], "y": [0.0], "depth": [4000.0]})
    >>> fit = locate(pings, beacons, tat=0.0)
    >>> other = 2 * np.sqrt((pings.x - 5) ** 2 + pings.y**2 + 4002.0**2) / 1501.0
    >>> res, shift = unabsorbed(pings, fit, other)
    >>> bool(np.abs(res).max() < 1e-9)
    True
    >>> round(fit.east + shift["east"], 3), round(fit.depth + shift["depth"], 3)
    (5.0, 4002.0)
    """
    _check_straight(fit)
    rows = _ping_rows(pings, fit)
    target = np.asarray(twtt, float)
    if target.shape != (rows.size,):
        raise ValueError(f"twtt: expected {rows.size} values (the fit's pings), got shape "
                         f"{target.shape}")
    if not np.all(np.isfinite(target)):
        raise ValueError("twtt: non-finite values")
    sub = pings.iloc[rows]
    x, y, z = (sub[c].to_numpy(float) for c in ("x", "y", "depth"))
    th0 = np.array([fit.east, fit.north, fit.depth, fit.sound_speed])

    def resid(th):
        return target - (2.0 * np.sqrt((x - th[0]) ** 2 + (y - th[1]) ** 2 + (z - th[2]) ** 2)
                         / th[3] + fit.tat)

    sol = least_squares(resid, th0, x_scale=np.array([10.0, 10.0, 10.0, 1.0]), xtol=1e-15,
                        ftol=1e-15, gtol=1e-15)
    d = sol.x - th0
    return resid(sol.x), {"east": float(d[0]), "north": float(d[1]), "depth": float(d[2]),
                          "sound_speed": float(d[3])}


def refracted_twtt(pings: pd.DataFrame, fit: LocateResult, profile, *,
                   surface_depth: float = 0.0) -> np.ndarray:
    """Two-way travel times along refracted eigenrays, at the fit's position.

    Parameters
    ----------
    pings : pandas.DataFrame
        The table the fit was located from.
    fit : LocateResult
    profile : bayes_mpem.acoustics.SoundSpeedProfile
    surface_depth : float, default 0
        Depth, in the pings' frame, of the profile's 0 m.

    Returns
    -------
    numpy.ndarray
        ``2 T + fit.tat`` (s) for the fit's pings (``fit.rows`` order), ``T`` the
        one-way time of the direct eigenray
        (:func:`bayes_mpem.acoustics.turning.direct_times`, with a turning point
        where the straight-through ray does not reach).

    Raises
    ------
    ValueError
        Some ping is reached by no direct eigenray at all (a speed maximum
        between the ends, or a turning depth beyond the profile); the message
        gives how many and the first.
    """
    rows = _ping_rows(pings, fit)
    sub = pings.iloc[rows]
    x, y, z = (sub[c].to_numpy(float) for c in ("x", "y", "depth"))
    h = np.hypot(x - fit.east, y - fit.north)
    ray = direct_times(profile, z - surface_depth, fit.depth - surface_depth, h)
    bad = np.flatnonzero(~ray.valid)
    if bad.size:
        i = bad[0]
        raise ValueError(f"transponder {fit.transponder}: {bad.size} of {rows.size} pings have "
                         f"no direct eigenray through the profile, even turning (first: row "
                         f"{rows[i]}, horizontal {h[i]:.1f} m, depth {z[i]:g} m)")
    return 2.0 * ray.time + fit.tat
