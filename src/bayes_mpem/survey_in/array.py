"""Locating an array of transponders at once (GNSS-acoustic surveys), by EM.

Every shot is a two-way travel time from the ship's transducer at transmit to
one transponder and back to the transducer at receive. The transponders share
the sound speed (one value, or a B-spline in time: ``speed_intervals``; with a
profile, the factor its speeds are scaled by) and the ship's geometry (the
transducer positions, from the antenna, the antenna-transducer offset and the
attitude, computed by :meth:`~bayes_mpem.io.raw.RawSurvey.transducer_positions`).
The model of a true reply is

    ``twtt = (T(transducer at transmit, P_k) + T(P_k, transducer at receive)) / s(t)``

with ``T`` the straight chord at speed 1 (or the eigenray time through the
profile; :class:`~bayes_mpem.survey_in.travel_times.TravelTimes` for each
leg) and ``s(t)`` the speed. A shot is either true, ``N(twtt, sigma)`` (one
``sigma`` for the array), or spurious (uniform over the transponder's window,
or before the true arrival: the models of
:func:`~bayes_mpem.survey_in.classes.log_classes`), each transponder with its own
share of true replies. The EM is that of :func:`~bayes_mpem.survey_in.location.locate`
(:class:`~bayes_mpem.survey_in.location.TravelTimeEM`), from a Cauchy-loss fit
from the prior positions.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from scipy.optimize import least_squares
from scipy.stats import norm

from .._validate import check_choice, check_int
from ..exceptions import InputError, LocateWarning
from .classes import OUTLIER_MODELS
from .location import TravelTimeEM, weighted_residuals
from .travel_times import TravelTimes, speed_basis

#: Fewest shots a transponder needs to be located.
MIN_SHOTS = 6
#: Columns :func:`locate_array` needs.
SHOT_COLUMNS = ("transponder", "twtt", "time", "e_tx", "n_tx", "u_tx", "e_rx", "n_rx", "u_rx")


class ArrayTravelTimes:
    """Two-way travel times of shots to several transponders, and their Jacobian.

    ``theta = [east_1, north_1, up_1, ..., east_K, north_K, up_K, *speed]``.

    Parameters
    ----------
    shots : pandas.DataFrame
        :data:`SHOT_COLUMNS`: the transducer at transmit (``_tx``) and receive (``_rx``).
    index : numpy.ndarray
        Transponder number (0 to ``n_transponders - 1``) of each shot.
    n_transponders : int
    basis : numpy.ndarray
        ``(n, k)`` design matrix of the speed in time (:func:`speed_basis`).
    profile : SoundSpeedProfile, optional
        Refracted rays (the speed is then the profile's scale); straight if None.
    surface_depth : float, default 0
        Depth (``-up``) of the profile's sea surface in the frame.
    """

    def __init__(self, shots, index, n_transponders, basis, *, profile=None, surface_depth=0.0):
        self.index, self.K, self.basis = np.asarray(index), int(n_transponders), basis
        self.rows = [np.flatnonzero(self.index == k) for k in range(self.K)]
        self.legs = []
        for rows in self.rows:
            sub = shots.iloc[rows]
            self.legs.append([TravelTimes(sub[f"e_{end}"].to_numpy(float),
                                          sub[f"n_{end}"].to_numpy(float),
                                          -sub[f"u_{end}"].to_numpy(float), 0.0,
                                          profile=profile, surface_depth=surface_depth)
                              for end in ("tx", "rx")])

    @property
    def n_params(self) -> int:
        """Number of parameters: 3 per transponder and the speed coefficients."""
        return 3 * self.K + self.basis.shape[1]

    def _paths(self, theta):
        """Per shot: summed leg times (or lengths), their position derivatives, invalid count."""
        n = self.index.size
        T, dE, dN, dU, bad = np.empty(n), np.empty(n), np.empty(n), np.empty(n), 0
        for k, (rows, legs) in enumerate(zip(self.rows, self.legs, strict=True)):
            e, nn, u = theta[3 * k:3 * k + 3]
            th = np.array([e, nn, -u])
            parts = [leg.rays(th) for leg in legs]
            T[rows] = parts[0][0] + parts[1][0]
            dE[rows] = parts[0][1] + parts[1][1]
            dN[rows] = parts[0][2] + parts[1][2]
            dU[rows] = -(parts[0][3] + parts[1][3])
            bad += parts[0][4] + parts[1][4]
        return T, dE, dN, dU, bad

    def speed(self, theta):
        """Return the speed (or the profile's scale) at each shot, given ``theta``."""
        return self.basis @ theta[3 * self.K:]

    def predict(self, theta):
        """Return the two-way travel time (s) of a true reply to each shot, given ``theta``."""
        return self._paths(theta)[0] / self.speed(theta)

    def jac(self, theta):
        """Return d(prediction)/d(theta), ``(shots, n_params)``."""
        T, dE, dN, dU, _ = self._paths(theta)
        s = self.speed(theta)
        J = np.zeros((T.size, self.n_params))
        rows = np.arange(T.size)
        for c, d in enumerate((dE, dN, dU)):
            J[rows, 3 * self.index + c] = d / s
        J[:, 3 * self.K:] = (-T / s**2)[:, None] * self.basis
        return J

    def n_invalid(self, theta) -> int:
        """Count the legs no eigenray reaches at ``theta`` (0 for straight rays)."""
        return int(self._paths(theta)[4])


@dataclass(frozen=True)
class ArrayLocateResult:
    """An array of transponders located together.

    Attributes
    ----------
    ids : tuple of str
        The transponders located (in the order of :attr:`enu`).
    enu : numpy.ndarray
        ``(K, 3)`` east, north, up (m) in the survey's frame.
    cov : numpy.ndarray
        Covariance of all parameters (positions first, then the speed
        coefficients): cluster-robust, replies to one interrogation as a cluster
        (:func:`robust_covariance`).
    cov_model : numpy.ndarray
        The model-based ``sigma^2 (J^T W J)^-1``, for comparison.
    start : numpy.ndarray
        ``(K, 3)`` the prior positions the fit started from.
    sound_speed, sound_speed_sd : float
        The speed averaged over the shots (m/s; with a profile the scaled
        profile's harmonic mean from the mean transducer to the mean transponder
        depth), and its standard deviation.
    speed_coef : numpy.ndarray
    sigma : float
        Scatter of the true replies (s), shared.
    weights : numpy.ndarray
        Share of true replies, per transponder.
    p_true : numpy.ndarray
        Probability that each shot used is a true reply.
    residual : numpy.ndarray
        Observed minus predicted travel time of each shot used (s).
    rows : numpy.ndarray
        Positions of the shots used in the input table.
    index : numpy.ndarray
        Transponder number of each shot used.
    windows : numpy.ndarray
        ``(K, 2)`` listening window of each transponder's spurious density (s).
    skipped : dict
        Transponders left out, with the reason.
    n_iter : int
    converged : bool
    outliers : str
    model : dict
        ``profile``, ``surface_depth``, ``speed_intervals``, ``time_range``, ``unit``
        (m/s per unit of speed coefficient), ``n_invalid``.
    """

    ids: tuple
    enu: np.ndarray
    cov: np.ndarray = field(repr=False)
    start: np.ndarray = field(repr=False)
    cov_model: np.ndarray = field(default=None, repr=False)
    sound_speed: float = 0.0
    sound_speed_sd: float = 0.0
    speed_coef: np.ndarray = field(default=None, repr=False)
    sigma: float = 0.0
    weights: np.ndarray = field(default=None, repr=False)
    p_true: np.ndarray = field(default=None, repr=False)
    residual: np.ndarray = field(default=None, repr=False)
    rows: np.ndarray = field(default=None, repr=False)
    index: np.ndarray = field(default=None, repr=False)
    windows: np.ndarray = field(default=None, repr=False)
    skipped: dict = field(default_factory=dict)
    n_iter: int = 0
    converged: bool = True
    outliers: str = "uniform"
    model: dict = field(default_factory=dict, repr=False)

    @property
    def sd(self) -> np.ndarray:
        """``(K, 3)`` standard deviations of east, north, up."""
        return np.sqrt(np.clip(np.diag(self.cov)[:3 * len(self.ids)], 0.0, None)).reshape(-1, 3)

    def centre(self):
        """Return the array centre (the transponders' mean east, north, up) and its covariance."""
        K = len(self.ids)
        G = np.zeros((3, self.cov.shape[0]))
        for k in range(K):
            G[:, 3 * k:3 * k + 3] = np.eye(3) / K
        return self.enu.mean(axis=0), G @ self.cov @ G.T

    def position_cov(self, k: int) -> np.ndarray:
        """Return the ``(3, 3)`` covariance of east, north, up of transponder number ``k``."""
        return self.cov[3 * k:3 * k + 3, 3 * k:3 * k + 3]

    def n_spurious(self, k: int) -> int:
        """Count the shots of transponder number ``k`` more likely spurious than true."""
        return int(np.sum(self.p_true[self.index == k] < 0.5))


def describe(mean, sd, ci):
    """Return ``{"mean", "sd", "interval"}``, a Wald interval with probability ``ci``.

    Examples
    --------
    >>> describe(1.0, 0.5, 0.95)["interval"]
    [0.020018, 1.979982]
    """
    half = float(norm.ppf(0.5 + ci / 2)) * float(sd)
    return {"mean": float(mean), "sd": float(sd),
            "interval": [round(float(mean) - half, 6), round(float(mean) + half, 6)]}


def _check_shots(shots, transponders):
    missing = [c for c in SHOT_COLUMNS if c not in shots.columns]
    if missing:
        raise InputError(f"shots: missing column(s) {missing} (expected {list(SHOT_COLUMNS)})")
    need = {"east", "north", "up"} - set(transponders.columns)
    if need:
        raise InputError(f"transponders: missing column(s) {sorted(need)}")
    tid = shots["transponder"].astype(str).to_numpy()
    ids, skipped = [], {}
    for t in map(str, transponders.index):
        n = int(np.sum(tid == t))
        if n < MIN_SHOTS:
            skipped[t] = f"{n} shots, need at least {MIN_SHOTS}"
        else:
            ids.append(t)
    if not ids:
        raise InputError(f"no transponder has {MIN_SHOTS} shots or more ({skipped})")
    k_of = {t: k for k, t in enumerate(ids)}
    index = np.array([k_of.get(t, -1) for t in tid])
    return ids, skipped, index


def locate_array(shots: pd.DataFrame, transponders: pd.DataFrame, *, profile=None,
                 surface_depth=0.0, speed_intervals=0, sound_speed=None, outliers="uniform",
                 time_range=None, max_iter=200, tol=1e-10) -> ArrayLocateResult:
    """Locate every transponder of an array by EM, classifying each shot true or spurious.

    Parameters
    ----------
    shots : pandas.DataFrame
        One row per reply: ``transponder``, ``twtt`` (s), ``time`` (s), and the
        transducer's ``e/n/u`` at transmit (``_tx``) and receive (``_rx``), m.
    transponders : pandas.DataFrame
        Indexed by id: ``east``, ``north``, ``up`` (m), the prior positions
        (where the fit starts). A transponder with fewer than :data:`MIN_SHOTS`
        shots is left out (:attr:`ArrayLocateResult.skipped`).
    profile : SoundSpeedProfile, optional
        Refracted rays through it, its speeds scaled by the fitted speed
        coefficient(s); default straight rays.
    surface_depth : float, default 0
        Depth (``-up``) in the frame of the profile's 0 m.
    speed_intervals : int, default 0
        The speed (or the profile's scale) as a cubic B-spline in time with this
        many intervals (0: one value), shared by every transponder.
    sound_speed : float, optional
        Starting straight-ray speed (m/s); default the profile's harmonic mean
        over the water column, else 1500.
    outliers : {"uniform", "first_arrival"}
    time_range : tuple of float, optional
        Span of the B-spline; default the shots'.
    max_iter : int, default 200
    tol : float, default 1e-10
        Stop when sigma (s) changes by less than this.

    Returns
    -------
    ArrayLocateResult

    Raises
    ------
    InputError
        A missing column, or no transponder with enough shots.
    """
    check_choice("outliers", outliers, OUTLIER_MODELS)
    check_int("speed_intervals", speed_intervals, minimum=0)
    ids, skipped, index = _check_shots(shots, transponders)
    rows = np.flatnonzero(index >= 0)
    sub, index = shots.iloc[rows].reset_index(drop=True), index[rows]
    K, t = len(ids), sub["twtt"].to_numpy(float)
    if time_range is None:
        time_range = (float(sub["time"].min()), float(sub["time"].max()))
    if speed_intervals and not time_range[1] > time_range[0]:
        raise InputError("shots: a time-varying sound speed needs shots at more than one time")
    start = transponders.loc[list(ids), ["east", "north", "up"]].to_numpy(float)
    z_ship = float(-0.5 * (sub["u_tx"].mean() + sub["u_rx"].mean()))
    z_tp = float(-start[:, 2].mean())
    unit = 1.0
    if profile is not None:
        unit = float(profile.harmonic_mean(z_ship - surface_depth, z_tp - surface_depth))
    c0 = float(sound_speed or (unit if profile is not None else 1500.0))
    # the robust start: straight rays, one speed
    straight = ArrayTravelTimes(sub, index, K, np.ones((len(sub), 1)))
    resid, jac = weighted_residuals(t, straight)
    theta = least_squares(resid, np.concatenate([start.ravel(), [c0]]), jac=jac,
                          loss="cauchy", f_scale=1e-3,
                          x_scale=np.array([10.0] * 3 * K + [1.0])).x
    basis = speed_basis(sub, speed_intervals, time_range)
    model = ArrayTravelTimes(sub, index, K, basis, profile=profile,
                             surface_depth=surface_depth)
    coef0 = theta[-1] / unit
    theta = np.concatenate([theta[:3 * K], np.full(basis.shape[1], coef0)])
    x_scale = np.array([1.0] * 3 * K + [abs(coef0) / 1500.0] * basis.shape[1])
    resid, jac = weighted_residuals(t, model)
    windows = np.array([[t[index == k].min(), t[index == k].max()] for k in range(K)])
    run = TravelTimeEM(t, resid, jac, x_scale, windows, index, outliers).run(
        theta, sigma_min=1e-7, tol=tol, max_iter=max_iter)
    (theta, _, sigma, weights), p = run.params, run.resp
    clusters = sub["t_tx"].to_numpy() if "t_tx" in sub.columns else np.arange(len(sub))
    J = jac(theta, p)
    cov = robust_covariance(J, resid(theta, p), clusters)
    cov_model = np.linalg.pinv(J.T @ J) * sigma**2
    g = basis.mean(axis=0)
    kk = slice(3 * K, None)
    n_bad = model.n_invalid(theta)
    _warn(n_bad, 2 * t.size, run.converged, run.n_iter)
    return ArrayLocateResult(
        ids=tuple(ids), enu=theta[:3 * K].reshape(K, 3).copy(), cov=cov, start=start,
        cov_model=cov_model,
        sound_speed=float(g @ theta[kk]) * unit,
        sound_speed_sd=float(np.sqrt(max(g @ cov[kk, kk] @ g, 0.0))) * unit,
        speed_coef=theta[kk].copy(), sigma=sigma, weights=weights, p_true=p,
        residual=resid(theta), rows=rows, index=index, windows=windows, skipped=skipped,
        n_iter=run.n_iter, converged=run.converged, outliers=outliers,
        model={"profile": profile, "surface_depth": float(surface_depth),
               "speed_intervals": int(speed_intervals), "time_range": time_range,
               "unit": unit, "n_invalid": n_bad})


def robust_covariance(J, r, clusters) -> np.ndarray:
    """Cluster-robust (sandwich) covariance of a weighted least-squares fit.

    ``A^-1 B A^-1`` with ``A = J^T J`` and ``B`` the sum over clusters of the
    outer product of each cluster's score ``sum_i J_i r_i``, scaled by
    ``G / (G - P)`` (``G`` clusters, ``P`` parameters). Replies to one
    interrogation share the transducer's GNSS error, a correlation the
    model-based ``sigma^2 (J^T J)^-1`` ignores (``docs/gnssa.md``).

    Parameters
    ----------
    J : numpy.ndarray
        ``(n, P)`` Jacobian of the weighted residuals.
    r : numpy.ndarray
        ``(n,)`` weighted residuals.
    clusters : array_like
        ``(n,)`` label of each row's cluster (e.g. its transmit time).

    Returns
    -------
    numpy.ndarray
        ``(P, P)``.

    Examples
    --------
    >>> import numpy as np
    >>> gen = np.random.default_rng(0)
    >>> J = np.ones((4000, 1)); r = gen.normal(0.0, 2.0, 4000)
    >>> round(float(robust_covariance(J, r, np.arange(4000))[0, 0] * 4000), 1)
    4.0
    """
    codes = np.unique(np.asarray(clusters), return_inverse=True)[1]
    G, P = int(codes.max()) + 1, J.shape[1]
    S = np.zeros((G, P))
    np.add.at(S, codes, J * r[:, None])
    Ainv = np.linalg.pinv(J.T @ J)
    return Ainv @ (S.T @ S) @ Ainv * (G / max(G - P, 1))


def _warn(n_bad, n_legs, converged, it):
    """Emit the :class:`LocateWarning` of an array fit (invalid rays, no convergence)."""
    if n_bad:
        warnings.warn(f"array: {n_bad} of {n_legs} legs have no direct eigenray through the "
                      "profile; their travel times are the straight chord at the profile's "
                      "mean speed", LocateWarning, stacklevel=3)
    if not converged:
        warnings.warn(f"array: location EM did not converge in {it} iterations", LocateWarning,
                      stacklevel=3)
