"""Locating a seafloor transponder from a ranging survey by EM (docs/measured-data.md)."""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
import pandas as pd
from scipy.optimize import least_squares

from .._validate import check_choice, check_int
from ..exceptions import InputError, LocateWarning
from ..mixture.em import EMModel, run_em
from .classes import OUTLIER_MODELS, log_classes, true_probability
from .travel_times import TravelTimes, ship_velocity, speed_basis

#: Turn-around time used when the file gives none (s): the WHOI EdgeTech log's
#: stated TAT; with it our CC03 fit matches OBSrange's solution (docs/measured-data.md).
DEFAULT_TAT = 0.013


@dataclass(frozen=True)
class LocateResult:
    """Transponder location from one survey.

    Attributes
    ----------
    transponder : str
    east, north, depth : float
        Position in the survey's local frame (m; depth positive down).
    sound_speed : float
        Effective straight-ray sound speed (m/s); with a profile, the scaled
        profile's harmonic mean from the transducer to the transponder; when
        the speed varies in time, its mean over the pings.
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
    outliers : str
    window : tuple of float
        The listening window of the spurious-ping density (s).
    model : dict
        How travel times were predicted: ``ssp`` (profile or None),
        ``surface_depth``, ``earth_radius``, ``speed_intervals``, ``time_range``,
        ``lag`` (s) and ``fit_lag``.
    speed_coef : numpy.ndarray
        The fitted speed parameter(s): the sound speed (m/s), or with a profile
        the factor its speeds are scaled by; one per B-spline coefficient when
        the speed varies in time.
    cov : numpy.ndarray
        ``(3, 3)`` approximate covariance of ``east``, ``north``, ``depth`` (the
        drift's and azimuth's intervals, the solution ellipse).
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
    model: dict = field(default_factory=dict, repr=False)
    speed_coef: np.ndarray = field(default=None, repr=False)
    cov: np.ndarray = field(default=None, repr=False)

    @property
    def refracted(self) -> bool:
        """Whether travel times follow refracted rays through a profile."""
        return self.model.get("ssp") is not None

    def travel_times(self, pings):
        """Return the :class:`TravelTimes` of this fit on ``pings``, and its ``theta``.

        Parameters
        ----------
        pings : pandas.DataFrame
            ``x``, ``y``, ``depth`` (and ``time`` for a lag or a speed in time).
        """
        x, y, z = (pings[c].to_numpy(float) for c in ("x", "y", "depth"))
        m = self.model
        basis = speed_basis(pings, m.get("speed_intervals", 0), m.get("time_range"))
        lag = m.get("lag", 0.0)
        tt = TravelTimes(x, y, z, self.tat, basis=basis, profile=m.get("ssp"),
                          surface_depth=m.get("surface_depth", 0.0),
                          earth_radius=m.get("earth_radius"), lag=lag,
                          velocity=ship_velocity(pings) if lag else None)
        coef = np.atleast_1d(self.sound_speed if self.speed_coef is None else self.speed_coef)
        return tt, np.concatenate([[self.east, self.north, self.depth], coef])

    def predict(self, pings: pd.DataFrame) -> np.ndarray:
        """Return the two-way travel time (s) of a true arrival for each of ``pings``.

        Parameters
        ----------
        pings : pandas.DataFrame
            ``x``, ``y``, ``depth`` (and ``time`` for a lag or a speed in time).

        Returns
        -------
        numpy.ndarray
        """
        model, theta = self.travel_times(pings)
        return model.predict(theta)

    def logpdf(self, pings: pd.DataFrame) -> np.ndarray:
        """Return the log density (1/s) of the ``twtt`` of each of ``pings`` (e.g. held out).

        Parameters
        ----------
        pings : pandas.DataFrame
            ``x``, ``y``, ``depth`` ``twtt`` (and ``time`` for a lag or a speed in time).

        Returns
        -------
        numpy.ndarray
        """
        t = pings["twtt"].to_numpy(float)
        pred = self.predict(pings)
        ld, lu = log_classes(t, pred, self.sigma, self.weight, self.window, self.outliers)
        return np.logaddexp(ld, lu)

    @property
    def n_spurious(self) -> int:
        """Pings more likely spurious than true."""
        return int(np.sum(self.p_true < 0.5))

    def interval(self, name: str, ci: float = 0.95) -> list:
        """Return the Wald interval ``[lower, upper]`` of parameter ``name``, probability ``ci``.

        Parameters
        ----------
        name : str
            A fitted parameter (``east``, ``north``, ``depth``, ``sound_speed``, ...).
        ci : float, default 0.95

        Returns
        -------
        list of float
        """
        from scipy.stats import norm

        v = {"east": self.east, "north": self.north, "depth": self.depth,
             "sound_speed": self.sound_speed, "tat": self.tat}[name]
        half = norm.ppf(0.5 + ci / 2) * self.sd.get(name, 0.0)
        return [v - half, v + half]

    def to_dict(self, ci: float = 0.95) -> dict:
        """Return a JSON-ready summary, with Wald intervals of probability ``ci``.

        Parameters
        ----------
        ci : float, default 0.95

        Returns
        -------
        dict
        """
        out = {k: {"mean": getattr(self, k), "sd": self.sd.get(k, 0.0),
                   "interval": self.interval(k, ci)}
               for k in ("east", "north", "depth", "sound_speed")}
        out["tat"] = {"mean": self.tat, "sd": self.sd.get("tat", 0.0), "fitted": self.fit_tat,
                      **({"interval": self.interval("tat", ci)} if self.fit_tat else {})}
        if self.model.get("fit_lag"):
            out["lag"] = {"mean": self.model["lag"], "sd": self.sd.get("lag", 0.0)}
        out.update(sigma_ms=1e3 * self.sigma, weight_true=self.weight,
                   n_spurious=self.n_spurious, n=int(self.p_true.size),
                   iterations=self.n_iter, converged=self.converged, ci=ci)
        return out


def locate(pings: pd.DataFrame, beacons: pd.DataFrame, transponder=None, *, tat=None,
           fit_tat=False, sound_speed=1500.0, outliers="uniform", window=None, ssp=None,
           surface_depth=0.0, earth_radius=None, speed_intervals=0, time_range=None,
           fit_lag=False, max_iter=200, tol=1e-10) -> LocateResult:
    """Locate one transponder by EM from pings with two-way travel times.

    Parameters
    ----------
    pings : pandas.DataFrame
        ``beacon``, ``twtt`` (s), ``x``, ``y``, ``depth`` (ship transducer, m),
        as :meth:`bayes_mpem.io.raw.RawSurvey.to_pings` returns (and ``time``,
        s, for a time-varying sound speed).
    beacons : pandas.DataFrame
        ``beacon``, ``x``, ``y``, ``depth``: the starting position (drop point).
    transponder : str, optional
        Which beacon (default: the only one).
    tat : float, optional
        Turn-around time (s); default :data:`DEFAULT_TAT`. The start value when
        ``fit_tat`` is true.
    fit_tat : bool, default False
        Fit the turn-around time too; it trades off against depth and sound
        speed, and a :class:`LocateWarning` says when the depth is lost.
    sound_speed : float, default 1500
        Starting sound speed (m/s).
    outliers : {"uniform", "first_arrival"}
        Spurious pings uniform over the listening window, or (a detector that
        reports the first threshold crossing) before the true arrival
        (:func:`~bayes_mpem.survey_in.classes.log_classes`).
    window : tuple of float, optional
        Listening window (s); default the smallest and largest travel time of
        the transponder's pings.
    ssp : SoundSpeedProfile, optional
        Travel times along refracted eigenrays through this profile
        (:mod:`bayes_mpem.acoustics`), its speeds scaled by one fitted factor,
        instead of straight rays at one speed. ``sound_speed`` is then reported
        as the scaled profile's harmonic mean from the mean transducer depth to
        the transponder. The start is the straight-ray fit.
    surface_depth : float, default 0
        Depth, in the pings' frame, of the profile's 0 m (the sea surface).
        SeaGap's heights are ellipsoidal: :func:`locate_survey` sets it.
    earth_radius : float, optional
        Take ``x, y`` as distances along a sphere of this radius (m) and depth
        as below it, as SeaGap does; default: a Cartesian local frame.
    speed_intervals : int, default 0
        Let the sound speed (or the profile's scale) vary in time as a cubic
        B-spline with this many equal intervals over ``time_range`` (0: one
        constant speed).
    time_range : tuple of float, optional
        Span of the B-spline (s); default the pings' own.
    fit_lag : bool, default False
        Fit a time lag (s) of the acoustic position behind the logged one: the
        ship is taken at ``(x, y) + lag * velocity`` (:func:`ship_velocity`): a
        fix logged at another moment than the ping, or a transducer ahead of the
        GPS antenna on a ship holding its course.
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
    check_choice("outliers", outliers, OUTLIER_MODELS)
    check_int("speed_intervals", speed_intervals, minimum=0)
    transponder, start, rows, sub = _select_pings(pings, beacons, transponder, speed_intervals)
    t = sub["twtt"].to_numpy(float)
    x, y, z = (sub[c].to_numpy(float) for c in ("x", "y", "depth"))
    if speed_intervals and "time" not in sub.columns:
        raise InputError("pings: a time-varying sound speed needs a 'time' column (s)")
    if time_range is None and speed_intervals:
        time_range = (float(sub["time"].min()), float(sub["time"].max()))
    basis = speed_basis(sub, speed_intervals, time_range)
    k = basis.shape[1]
    tat0 = DEFAULT_TAT if tat is None else float(tat)
    geo = dict(fit_tat=fit_tat, surface_depth=surface_depth, earth_radius=earth_radius)
    if fit_lag:
        geo["velocity"] = ship_velocity(sub)
    # the robust start: straight rays at one speed
    theta = np.array([start["x"], start["y"], start["depth"], sound_speed]
                     + ([tat0] if fit_tat else []), float)
    if not np.isfinite(theta).all() or not np.isfinite(t).all():
        raise InputError(f"transponder {transponder}: the start (x, y, depth, sound speed"
                         f"{', tat' if fit_tat else ''}) = {theta.tolist()} or a travel time "
                         "is not finite; check the survey's header and pings")
    x_scale = [10.0, 10.0, 10.0, 1.0] + ([1e-3] if fit_tat else [])
    resid, jac = weighted_residuals(t, TravelTimes(x, y, z, tat0, **geo))
    theta = least_squares(resid, theta, jac=jac, loss="cauchy", f_scale=2e-3,
                          x_scale=np.array(x_scale)).x
    speed0 = theta[3]
    if ssp is not None:  # refracted rays from the straight-ray solution: c -> profile scale
        speed0 /= float(ssp.harmonic_mean(np.mean(z) - surface_depth, theta[2] - surface_depth))
    theta = np.concatenate([theta[:3], np.full(k, speed0), [0.0] if fit_lag else [],
                            theta[4:]])
    x_scale = np.array([10.0] * 3 + [abs(speed0) / 1500.0] * k + ([1.0] if fit_lag else [])
                       + ([1e-3] if fit_tat else []))
    model = TravelTimes(x, y, z, tat0, basis=basis, profile=ssp, fit_lag=fit_lag, **geo)
    resid, jac = weighted_residuals(t, model)
    window = (float(t.min()), float(t.max())) if window is None else tuple(map(float, window))
    run = TravelTimeEM(t, resid, jac, x_scale, [window], None, outliers).run(
        theta, sigma_min=1e-6, tol=tol, max_iter=max_iter)
    (theta, _, sigma, weight), p = run.params, run.resp
    J = jac(theta, p)
    cov = np.linalg.pinv(J.T @ J) * sigma**2
    sd = {name: float(np.sqrt(max(cov[i, i], 0.0)))
          for i, name in enumerate(("east", "north", "depth"))}
    # the reported speed: the mean over the pings (scaled profile: its harmonic mean)
    g = basis.mean(axis=0)
    unit = 1.0
    if ssp is not None:
        unit = float(ssp.harmonic_mean(np.mean(z) - surface_depth, theta[2] - surface_depth))
    coef = theta[3:3 + k]
    speed = float(g @ coef) * unit
    sd["sound_speed"] = float(np.sqrt(max(g @ cov[3:3 + k, 3:3 + k] @ g, 0.0))) * unit
    if fit_tat:
        sd["tat"] = float(np.sqrt(max(cov[-1, -1], 0.0)))
    lag = float(theta[3 + k]) if fit_lag else 0.0
    if fit_lag:
        sd["lag"] = float(np.sqrt(max(cov[3 + k, 3 + k], 0.0)))
    _warn(transponder, model.n_invalid(theta), t.size, run.converged, run.n_iter, sd, fit_tat)
    return LocateResult(
        transponder=str(transponder), east=float(theta[0]), north=float(theta[1]),
        depth=float(theta[2]), sound_speed=speed,
        tat=float(theta[-1]) if fit_tat else tat0, sigma=sigma, weight=float(weight[0]), sd=sd,
        p_true=p, rows=rows, n_iter=run.n_iter, converged=run.converged, fit_tat=fit_tat,
        outliers=outliers, window=window,
        model={"ssp": ssp, "surface_depth": float(surface_depth), "earth_radius": earth_radius,
               "speed_intervals": int(speed_intervals), "time_range": time_range,
               "lag": lag, "fit_lag": bool(fit_lag)},
        speed_coef=coef.copy(), cov=cov[:3, :3].copy())


def _select_pings(pings, beacons, transponder, speed_intervals):
    """Check the tables; return ``(transponder, start row, ping rows, its pings)``."""
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
    if rows.size < 6 + speed_intervals:
        raise InputError(f"transponder {transponder}: {rows.size} pings, need at least "
                         f"{6 + speed_intervals}")
    return transponder, start, rows, pings.iloc[rows]


def weighted_residuals(t, model):
    """Residual and Jacobian functions of a travel-time model for ``least_squares``.

    Parameters
    ----------
    t : numpy.ndarray
        Observed two-way travel times (s).
    model : object
        With ``predict(theta)`` and ``jac(theta)`` (:class:`TravelTimes`, or an
        array's :class:`~bayes_mpem.survey_in.array.ArrayTravelTimes`).

    Returns
    -------
    resid, jac : callable
        ``resid(theta, w=None)`` (observed minus predicted, times ``sqrt(w)``
        when weights are given) and ``jac(theta, w=None)`` its Jacobian.
    """

    def resid(th, w=None):
        r = t - model.predict(th)
        return r if w is None else np.sqrt(w) * r

    def jac(th, w=None):
        J = model.jac(th)  # one pass over the (large) Jacobian: the sign goes with the weight
        return -J if w is None else J * -np.sqrt(w)[:, None]

    return resid, jac


class _Fit(NamedTuple):
    theta: np.ndarray
    r: np.ndarray  # residuals at theta
    sigma: float
    weights: np.ndarray  # share of true arrivals, per transponder


class TravelTimeEM(EMModel):
    """The EM of :func:`locate` and :func:`~bayes_mpem.survey_in.array.locate_array`.

    E-step: the probability that each ping is true (:func:`.classes.log_classes`);
    M-step: weighted least squares (``scipy.optimize.least_squares``) from the
    current point, so the weighted sum of squares does not increase, then
    ``sigma`` and each transponder's share of true pings in closed form;
    converged when ``sigma`` changes by less than ``tol`` (s). The probabilities
    returned are the weights of the last M-step, those of the covariance.

    Parameters
    ----------
    t : numpy.ndarray
        Two-way travel times (s).
    resid, jac : callable
        Of :func:`weighted_residuals`.
    x_scale : numpy.ndarray
        Parameter scales for ``least_squares``.
    windows : list of tuple
        Listening window of each transponder (s).
    index : numpy.ndarray or None
        Transponder of each ping (None: one transponder).
    outliers : {"uniform", "first_arrival"}
    """

    final_e_step = False

    def __init__(self, t, resid, jac, x_scale, windows, index, outliers):
        self.t, self.resid, self.jac, self.x_scale = t, resid, jac, x_scale
        self.windows, self.index, self.outliers = windows, index, outliers
        self.rows = [slice(None)] if index is None else [index == k for k in range(len(windows))]

    def run(self, theta, *, sigma_min, **kw):
        """Return the :func:`~bayes_mpem.mixture.em.run_em` (``**kw``) of the EM from ``theta``.

        The first ``sigma`` is the MAD of the residuals, at least ``sigma_min`` (s).

        Parameters
        ----------
        theta : numpy.ndarray
            The start.
        sigma_min : float
            Floor of the first ``sigma`` (s).
        **kw
            Passed to :func:`~bayes_mpem.mixture.em.run_em`.

        Returns
        -------
        EMRun
        """
        r = self.resid(theta)
        sigma = max(1.4826 * float(np.median(np.abs(r - np.median(r)))), sigma_min)
        return run_em(self, _Fit(theta, r, sigma, np.full(len(self.windows), 0.9)), **kw)

    def e_step(self, fit):
        """Return ``(None, probability that each ping is true)``.

        Parameters
        ----------
        fit : object
            The current parameters (``theta``, residuals ``r``, ``sigma``, weight).

        Returns
        -------
        tuple
        """
        p, pred = np.empty_like(self.t), self.t - fit.r
        for k, sel in enumerate(self.rows):
            ld, lu = log_classes(self.t[sel], pred[sel], fit.sigma, fit.weights[k],
                                 self.windows[k], self.outliers)
            p[sel] = true_probability(ld, lu)
        return None, p

    def m_step(self, fit, p):
        """Return the new parameters given the probabilities ``p`` of true pings.

        Parameters
        ----------
        fit : object
            The current parameters.
        p : numpy.ndarray
            Probability that each ping is true.

        Returns
        -------
        object
        """
        theta = self.solve(fit, p)
        r = self.resid(theta)
        sigma = float(np.sqrt(np.sum(p * r * r) / p.sum()))
        if self.index is None:
            shares = np.array([np.clip(p.mean(), 1e-6, 1 - 1e-6)])
        else:
            k = len(self.rows)
            shares = np.clip(np.bincount(self.index, p, k) / np.bincount(self.index, minlength=k),
                             1e-6, 1 - 1e-6)
        return _Fit(theta, r, sigma, shares)

    def solve(self, fit, p):
        """Return the weighted least-squares parameters from ``fit``'s (the M-step's solve).

        Parameters
        ----------
        fit : object
            The current parameters (the start).
        p : numpy.ndarray
            Probability that each ping is true (the weights).

        Returns
        -------
        numpy.ndarray
        """
        return least_squares(self.resid, fit.theta, jac=self.jac, args=(p,),
                             x_scale=self.x_scale).x

    def change(self, old, new, gain):
        """Return the change of ``sigma`` (s).

        Parameters
        ----------
        old, new : object
            The parameters before and after an iteration.
        gain : float or None
            Unused (the EM has no log-likelihood gain to measure).

        Returns
        -------
        float
        """
        return abs(new.sigma - old.sigma)


def _warn(transponder, n_bad, n, converged, it, sd, fit_tat):
    """Emit the :class:`LocateWarning` of a fit (invalid rays, no convergence, depth)."""
    if n_bad:
        warnings.warn(f"transponder {transponder}: {n_bad} of {n} pings have no direct "
                      "eigenray through the profile, even a turning one; their travel times "
                      "are the straight chord at the profile's mean speed", LocateWarning,
                      stacklevel=3)
    if not converged:
        warnings.warn(f"transponder {transponder}: location EM did not converge in {it} "
                      "iterations", LocateWarning, stacklevel=3)
    if sd["depth"] > 50.0:
        warnings.warn(f"transponder {transponder}: depth poorly constrained (sd {sd['depth']:.0f}"
                      " m)" + ("; the turn-around time trades off against depth and sound "
                               "speed: fix it (tat=...)" if fit_tat else ""),
                      LocateWarning, stacklevel=3)
