"""Locating a seafloor transponder from a ranging survey, by EM (straight rays).

The survey-in every LBL deployment starts with, and what OBSrange does: the
transponder position ``(east, north, depth)`` and the mean sound speed ``c``
(and the turn-around time ``tat`` where it is not known) are estimated jointly
with the class of every ping. Each two-way travel time is either a true
arrival, ``N(2 |ship - transponder| / c + tat, sigma)``, or spurious, uniform
over the observed window; spurious pings are weighted by their probability
instead of cut by a threshold.

E-step: class probabilities in log space. M-step: weighted nonlinear least
squares for the geometry (``scipy.optimize.least_squares`` from the current
point, so the weighted sum of squares does not increase), then ``sigma`` and the
weight in closed form. The start is a Cauchy-loss robust fit from the drop
point. Standard deviations are from the weighted Gauss-Newton information
(approximate; the Bayesian version is for later).

Spurious pings are uniform over the listening window or, with
``outliers="first_arrival"``, only before the true arrival (a detector that
reports the first threshold crossing); :func:`heldout_logpdf` compares the two
by cross-validation.

Refraction (rays bending through the sound-speed profile) is not modelled yet:
``c`` is an effective straight-ray speed (the eigenray solver is in
:mod:`bayes_mpem.acoustics`).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from scipy.optimize import least_squares

from .data import InputError
from .readers import enu_to_geodetic  # re-exported: locate reports lat/lon

#: Turn-around time used when the file gives none (s): the WHOI EdgeTech log's
#: stated TAT; with it our CC03 fit matches OBSrange's solution (docs/measured-data.md).
DEFAULT_TAT = 0.013


class LocateWarning(UserWarning):
    """A location fit is poorly constrained or did not converge."""


@dataclass(frozen=True)
class LocateResult:
    """Transponder location from one survey.

    Attributes
    ----------
    transponder : str
    east, north, depth : float
        Position in the survey's local frame (m; depth positive down).
    sound_speed : float
        Effective straight-ray sound speed (m/s).
    tat : float
        Turn-around time (s), fitted or as given.
    sigma : float
        Scatter of the true arrivals (s).
    weight : float
        Fraction of true arrivals.
    sd : dict
        Approximate standard deviations of ``east``, ``north``, ``depth``,
        ``sound_speed`` (and ``tat`` when fitted).
    p_true : numpy.ndarray
        Probability that each ping is a true arrival (file order).
    rows : numpy.ndarray
        Positions of the pings in the input table.
    n_iter : int
    converged : bool
    fit_tat : bool
    """

    transponder: str
    east: float
    north: float
    depth: float
    sound_speed: float
    tat: float
    sigma: float
    weight: float
    sd: dict
    p_true: np.ndarray = field(repr=False)
    rows: np.ndarray = field(repr=False)
    n_iter: int = 0
    converged: bool = True
    fit_tat: bool = False
    outliers: str = "uniform"
    window: tuple = (0.0, 1.0)

    def logpdf(self, pings: pd.DataFrame) -> np.ndarray:
        """Log density (1/s) of each ping's two-way travel time under this fit.

        Parameters
        ----------
        pings : pandas.DataFrame
            ``twtt``, ``x``, ``y``, ``depth`` of this transponder's pings (e.g. held out).

        Returns
        -------
        numpy.ndarray
        """
        t = pings["twtt"].to_numpy(float)
        x, y, z = (pings[c].to_numpy(float) for c in ("x", "y", "depth"))
        theta = np.array([self.east, self.north, self.depth, self.sound_speed])
        pred = _predict(theta, x, y, z, self.tat)
        ld, lu = _log_classes(t, pred, self.sigma, self.weight, self.window, self.outliers)
        return np.logaddexp(ld, lu)

    @property
    def n_spurious(self) -> int:
        """Pings more likely spurious than true."""
        return int(np.sum(self.p_true < 0.5))

    def interval(self, name: str, ci: float = 0.95) -> list:
        """Approximate (Wald) interval of a parameter with probability ``ci``."""
        from scipy.stats import norm

        v = {"east": self.east, "north": self.north, "depth": self.depth,
             "sound_speed": self.sound_speed, "tat": self.tat}[name]
        half = norm.ppf(0.5 + ci / 2) * self.sd.get(name, 0.0)
        return [v - half, v + half]

    def to_dict(self, ci: float = 0.95) -> dict:
        """JSON-ready summary; intervals are approximate (Wald, from the EM)."""
        out = {k: {"mean": getattr(self, k), "sd": self.sd.get(k, 0.0),
                   "interval": self.interval(k, ci)}
               for k in ("east", "north", "depth", "sound_speed")}
        out["tat"] = {"mean": self.tat, "sd": self.sd.get("tat", 0.0), "fitted": self.fit_tat}
        out.update(sigma_ms=1e3 * self.sigma, weight_true=self.weight,
                   n_spurious=self.n_spurious, n=int(self.p_true.size),
                   iterations=self.n_iter, converged=self.converged, ci=ci)
        return out


def _predict(theta, x, y, z, tat):
    e, n, d, c = theta[:4]
    t0 = theta[4] if theta.size > 4 else tat
    return 2.0 * np.sqrt((x - e) ** 2 + (y - n) ** 2 + (z - d) ** 2) / c + t0


OUTLIER_MODELS = ("uniform", "first_arrival")
_EPS_LATE = 1e-3  # share of the first-arrival outlier density left over the whole window


def _log_classes(t, pred, sigma, weight, window, outliers):
    """Weighted log densities (true, spurious) of travel times ``t`` given predictions."""
    lo, hi = window
    ld = np.log(weight) - 0.5 * ((t - pred) / sigma) ** 2 - np.log(sigma * np.sqrt(2 * np.pi))
    if weight >= 1:
        return ld, np.full_like(t, -np.inf)
    width = max(hi - lo, 1e-9)
    if outliers == "uniform":
        lu = np.full_like(t, -np.log(width))
    else:  # a detector reporting the first threshold crossing: spurious before the true arrival
        early = np.maximum(pred - lo, 1e-6)
        lu = np.where(t <= pred, np.log((1 - _EPS_LATE) / early + _EPS_LATE / width),
                      np.log(_EPS_LATE / width))
    return ld, np.log1p(-weight) + lu


def locate(pings: pd.DataFrame, beacons: pd.DataFrame, transponder=None, *, tat=None,
           fit_tat=False, sound_speed=1500.0, outliers="uniform", window=None, max_iter=200,
           tol=1e-10) -> LocateResult:
    """Locate one transponder by EM from pings with two-way travel times.

    Parameters
    ----------
    pings : pandas.DataFrame
        ``beacon``, ``twtt`` (s), ``x``, ``y``, ``depth`` (ship transducer, m),
        as :meth:`bayes_mpem.readers.RawSurvey.to_pings` returns.
    beacons : pandas.DataFrame
        ``beacon``, ``x``, ``y``, ``depth``: the starting position (drop point).
    transponder : str, optional
        Which beacon (default: the only one).
    tat : float, optional
        Turn-around time (s); default :data:`DEFAULT_TAT`. The start value when
        ``fit_tat`` is true.
    fit_tat : bool, default False
        Fit the turn-around time too. On the OBSrange samples it is not
        identifiable (it trades off against depth and sound speed: 2 sd of
        depth ~290 m), and a :class:`LocateWarning` says so when that happens.
    sound_speed : float, default 1500
        Starting sound speed (m/s).
    outliers : {"uniform", "first_arrival"}
        Spurious pings uniform over the listening window (the simulator's
        assumption), or uniform between the window start and the true arrival:
        a detector that reports the first threshold crossing cannot report a
        false detection after the true one (a share ``1e-3`` of the density
        stays spread over the window).
    window : tuple of float, optional
        Listening window (s); default the smallest and largest travel time of
        the transponder's pings.
    max_iter : int, default 200
    tol : float, default 1e-10
        Stop when sigma (s) changes by less than this.

    Returns
    -------
    LocateResult

    Raises
    ------
    InputError
        For a missing column, an unknown transponder or too few pings.
    """
    if outliers not in OUTLIER_MODELS:
        raise ValueError(f"outliers: expected one of {OUTLIER_MODELS}, got {outliers!r}")
    need = {"beacon", "twtt", "x", "y", "depth"}
    missing = need - set(pings.columns)
    if missing:
        raise InputError(f"pings: missing column(s) {sorted(missing)} (expected {sorted(need)})")
    ids = [str(b) for b in beacons["beacon"]]
    if transponder is None:
        if len(ids) != 1:
            raise InputError(f"transponder: several in the beacons table ({ids}); name one")
        transponder = ids[0]
    if str(transponder) not in ids:
        raise InputError(f"transponder {transponder!r} not in the beacons table {ids}")
    start = beacons.loc[[i == str(transponder) for i in ids]].iloc[0]
    sel = (pings["beacon"].astype(str) == str(transponder)).to_numpy()
    rows = np.flatnonzero(sel)
    if rows.size < 6:
        raise InputError(f"transponder {transponder}: {rows.size} pings, need at least 6")
    t = pings["twtt"].to_numpy(float)[sel]
    x, y, z = (pings[c].to_numpy(float)[sel] for c in ("x", "y", "depth"))
    tat0 = DEFAULT_TAT if tat is None else float(tat)
    theta = np.array([start["x"], start["y"], start["depth"], sound_speed]
                     + ([tat0] if fit_tat else []), float)
    scale = np.array([10.0, 10.0, 10.0, 1.0] + ([1e-3] if fit_tat else []))

    def resid(th, w=None):
        r = t - _predict(th, x, y, z, tat0)
        return r if w is None else np.sqrt(w) * r

    theta = least_squares(resid, theta, loss="cauchy", f_scale=2e-3, x_scale=scale).x
    r = resid(theta)
    sigma = max(1.4826 * float(np.median(np.abs(r - np.median(r)))), 1e-6)
    weight = 0.9
    window = (float(t.min()), float(t.max())) if window is None else tuple(map(float, window))
    converged, it = False, 0
    for it in range(1, max_iter + 1):
        ld, lu = _log_classes(t, t - r, sigma, weight, window, outliers)
        p = 1.0 / (1.0 + np.exp(np.clip(lu - ld, -700.0, 700.0)))
        fit = least_squares(resid, theta, args=(p,), x_scale=scale)
        theta = fit.x
        r = resid(theta)
        new = float(np.sqrt(np.sum(p * r * r) / p.sum()))
        weight = float(np.clip(p.mean(), 1e-6, 1 - 1e-6))
        done = abs(new - sigma) < tol
        sigma = new
        if done:
            converged = True
            break
    jac = fit.jac
    cov = np.linalg.pinv(jac.T @ jac) * sigma**2
    names = ["east", "north", "depth", "sound_speed"] + (["tat"] if fit_tat else [])
    sd = {k: float(np.sqrt(max(cov[i, i], 0.0))) for i, k in enumerate(names)}
    if not converged:
        warnings.warn(f"transponder {transponder}: location EM did not converge in {it} "
                      "iterations", LocateWarning, stacklevel=2)
    if sd["depth"] > 50.0:
        warnings.warn(f"transponder {transponder}: depth poorly constrained (sd {sd['depth']:.0f}"
                      " m)" + ("; the turn-around time trades off against depth and sound "
                               "speed: fix it (tat=...)" if fit_tat else ""),
                      LocateWarning, stacklevel=2)
    return LocateResult(
        transponder=str(transponder), east=float(theta[0]), north=float(theta[1]),
        depth=float(theta[2]), sound_speed=float(theta[3]),
        tat=float(theta[4]) if fit_tat else tat0, sigma=sigma, weight=weight, sd=sd,
        p_true=p, rows=rows, n_iter=it, converged=converged, fit_tat=fit_tat,
        outliers=outliers, window=window)


def heldout_logpdf(pings: pd.DataFrame, beacons: pd.DataFrame, transponder=None, *,
                   outliers="uniform", n_folds=5, rng=0, **kwargs) -> np.ndarray:
    """K-fold cross-validated log predictive density of every ping of one transponder.

    Each fold is located from the other pings (same listening window: the
    whole file's) and scores its own pings with :meth:`LocateResult.logpdf`.

    Parameters
    ----------
    pings, beacons, transponder
        As for :func:`locate`.
    outliers : {"uniform", "first_arrival"}
    n_folds : int, default 5
    rng : None, int or numpy.random.Generator
        Assigns the pings to folds.
    **kwargs
        Passed to :func:`locate` (``tat``, ``sound_speed``, ...).

    Returns
    -------
    numpy.ndarray
        One value (log 1/s) per ping of the transponder, in table order.
    """
    from ._rng import as_generator

    full = locate(pings, beacons, transponder, outliers=outliers, **kwargs)
    sub = pings.iloc[full.rows]
    folds = as_generator(rng).permutation(np.arange(full.rows.size) % int(n_folds))
    out = np.empty(full.rows.size)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LocateWarning)
        for k in range(int(n_folds)):
            test = folds == k
            fit_k = locate(sub[~test], beacons, full.transponder, outliers=outliers,
                           window=full.window, **kwargs)
            out[test] = fit_k.logpdf(sub[test])
    return out


def locate_survey(raw, *, tat=None, fit_tat=False, ci=0.95, outliers="uniform"):
    """Locate every transponder of a :class:`~bayes_mpem.readers.RawSurvey`.

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

    Returns
    -------
    summary : dict
        ``{"transponders": {id: {"lat", "lon", "depth", "sound_speed", ...}}, ...}``.
    classified : pandas.DataFrame
        One row per ping line and per skipped line of the file, in file order:
        ``line``, ``transponder``, ``twtt``, ``p_true``, ``p_spurious``, ``label``
        (``true``, ``spurious`` or ``skipped``) and ``reason``.
    """
    if tat is None:
        tat = raw.header.get("tat", 0.0 if raw.format == "seagap" else DEFAULT_TAT)
    pings, beacons = raw.to_pings()
    out, probs = {}, np.full(len(pings), np.nan)
    for tid in beacons["beacon"].astype(str):
        r = locate(pings, beacons, tid, tat=tat, fit_tat=fit_tat, outliers=outliers)
        probs[r.rows] = r.p_true
        d = r.to_dict(ci)
        if "lat" in raw.header:
            d["lat"], d["lon"], _ = enu_to_geodetic(r.east, r.north, 0.0, raw.header["lat"],
                                                    raw.header["lon"])
        else:
            d["lat"] = d["lon"] = None  # SeaGap: local frame only
        out[tid] = d
    lab = np.where(probs >= 0.5, "true", "spurious").astype(object)
    cls = pd.DataFrame({"line": pings["line"], "transponder": pings["beacon"].astype(str),
                        "twtt": pings["twtt"], "p_true": probs, "p_spurious": 1.0 - probs,
                        "label": lab, "reason": ""})
    sk = raw.skipped
    if len(sk):
        cls = pd.concat([cls, pd.DataFrame({"line": sk["line"], "transponder": "",
                                            "twtt": np.nan, "p_true": np.nan,
                                            "p_spurious": np.nan, "label": "skipped",
                                            "reason": sk["reason"]})], ignore_index=True)
    cls = cls.sort_values("line", kind="stable").reset_index(drop=True)
    summary = {"transponders": out, "format": raw.format, "source": raw.source,
               "n_pings": int(len(pings)), "n_skipped_lines": int(len(sk)),
               "method": "EM, straight rays; intervals approximate (Wald)",
               "outliers": outliers,
               "tat_fitted": bool(fit_tat), "tat_given": None if fit_tat else float(tat)}
    return summary, cls


__all__ = ["DEFAULT_TAT", "OUTLIER_MODELS", "LocateResult", "LocateWarning", "enu_to_geodetic",
           "heldout_logpdf", "locate", "locate_survey"]
