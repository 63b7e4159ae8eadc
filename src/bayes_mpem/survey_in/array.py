"""Locating an array of transponders at once (GNSS-A) by EM; the model: docs/gnssa.md."""

from __future__ import annotations

import functools
import warnings
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
import pandas as pd
from scipy.linalg import cho_factor, cho_solve
from scipy.linalg.lapack import dpotri
from scipy.optimize import least_squares
from scipy.sparse import csr_matrix
from scipy.stats import chi2, norm

from .._threads import thread_map, with_one_blas_thread
from .._validate import check_choice, check_int
from ..exceptions import InputError, LocateWarning
from .arrowhead import arrowhead, forgetting, gram
from .classes import OUTLIER_MODELS
from .location import TravelTimeEM, weighted_residuals
from .noise import WHITES, Whitener, choose_correlation
from .travel_times import (
    TravelTimes,
    smooth_intervals,
    speed_basis,
    speed_breaks,
    speed_penalty,
)

#: Fewest shots a transponder needs to be located.
MIN_SHOTS = 6
#: Default knot spacing (minutes) of the smooth sound speed.
KNOT_MINUTES = 5.0
#: Decades about the best smoothing weight over which the intervals average (step 0.25).
WEIGHT_GRID = np.arange(-2.0, 2.0001, 0.25)
#: Decades about the data's information over the penalty within which a weight is searched.
WEIGHT_BOUNDS = (-10.0, 7.0)
#: M-steps after which the smoothing weights are held (:class:`_SmoothArrayEM`).
FREEZE_AFTER = 12
#: Most rounds of the refit under correlated noise (the weights chosen, then the penalised
#: step): it stops once no weight moves by more than 1 %, as the EM does.
REFIT_ROUNDS = 12
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
    gradients : numpy.ndarray, optional
        ``(n, m)`` design of the horizontal gradient terms (:func:`gradient_design`):
        the prediction is multiplied by ``exp(-gradients @ g)``, ``g`` the last ``m``
        entries of ``theta``.
    earth_radius : float, optional
        The profile's layers follow a sphere of this radius (m) touching the frame's
        origin: the shots and the transponders are turned into the sphere's frame
        (:func:`to_sphere`; ``theta`` stays Cartesian); None (default) flat layers.
    along_sphere : bool, default False
        With ``earth_radius``: the frame is already along the sphere (east and north
        distances along it, up the height above it: SeaGap's frame), not turned.
    """

    def __init__(self, shots, index, n_transponders, basis, *, profile=None, surface_depth=0.0,
                 gradients=None, earth_radius=None, along_sphere=False):
        self.index, self.K, self.basis = np.asarray(index), int(n_transponders), basis
        self.grad = gradients
        self.k = basis.shape[1]
        # B-splines: a few non-zeros per row; products and the Jacobian's columns from them
        self._basis, self._grad = _SparseDesign(basis), (None if gradients is None else
                                                         _SparseDesign(gradients))
        self.rows = [np.flatnonzero(self.index == k) for k in range(self.K)]
        # a Cartesian frame with a radius: the shots along the sphere, the transponders
        # turned into it at every evaluation (_sphere_point)
        self.R = None if earth_radius is None or along_sphere else float(earth_radius)
        self.legs = []
        for rows in self.rows:
            sub = shots.iloc[rows]
            ends = {}
            for end in ("tx", "rx"):
                e, n, u = (sub[f"{c}_{end}"].to_numpy(float) for c in "enu")
                ends[end] = (e, n, u) if self.R is None else to_sphere(e, n, u, self.R)
            self.legs.append([TravelTimes(ends[end][0], ends[end][1], -ends[end][2], 0.0,
                                          profile=profile, surface_depth=surface_depth,
                                          earth_radius=earth_radius)
                              for end in ("tx", "rx")])

    @property
    def n_params(self) -> int:
        """Number of parameters: 3 per transponder and the speed coefficients."""
        return 3 * self.K + self.k + (0 if self.grad is None else self.grad.shape[1])

    def _paths(self, theta):
        """Per shot: summed leg times (or lengths), their position derivatives, invalid count."""
        n = self.index.size
        T, dE, dN, dU, bad = np.empty(n), np.empty(n), np.empty(n), np.empty(n), 0
        for k, (rows, legs) in enumerate(zip(self.rows, self.legs, strict=True)):
            point, M = self._sphere_point(theta[3 * k:3 * k + 3])
            th = np.array([point[0], point[1], -point[2]])
            parts = [leg.rays(th) for leg in legs]
            T[rows] = parts[0][0] + parts[1][0]
            d = np.vstack([parts[0][1] + parts[1][1], parts[0][2] + parts[1][2],
                           -(parts[0][3] + parts[1][3])])
            if M is not None:  # chain rule: d(sphere point) / d(Cartesian point)
                d = M.T @ d
            dE[rows], dN[rows], dU[rows] = d
            bad += parts[0][4] + parts[1][4]
        return T, dE, dN, dU, bad

    def _sphere_point(self, enu):
        """Return a transponder in the rays' frame, and the derivative matrix (None if flat)."""
        enu = np.asarray(enu, float)
        if self.R is None:
            return enu, None
        point = np.array(to_sphere(*enu, self.R), float)
        M = np.empty((3, 3))
        for c in range(3):
            d = np.zeros(3)
            d[c] = 1e-3
            M[:, c] = (np.array(to_sphere(*(enu + d), self.R)) -
                       np.array(to_sphere(*(enu - d), self.R))) / 2e-3
        return point, M

    def speed(self, theta):
        """Return the speed (or the profile's scale) at each shot, given ``theta``.

        Parameters
        ----------
        theta : numpy.ndarray
            The parameter vector (positions, speed coefficients, ...).

        Returns
        -------
        numpy.ndarray
        """
        return self._basis.matrix @ theta[3 * self.K:3 * self.K + self.k]

    def _gain(self, theta):
        """``exp(-gamma)`` of the gradient terms at each shot (1 without them)."""
        if self.grad is None:
            return 1.0
        return np.exp(-(self._grad.matrix @ theta[3 * self.K + self.k:]))

    def predict(self, theta):
        """Return the two-way travel time (s) of a true reply to each shot, given ``theta``.

        Parameters
        ----------
        theta : numpy.ndarray
            The parameter vector (positions, speed coefficients, ...).

        Returns
        -------
        numpy.ndarray
        """
        return self._paths(theta)[0] / self.speed(theta) * self._gain(theta)

    def jac(self, theta):
        """Return d(prediction)/d(theta), ``(shots, n_params)``.

        Parameters
        ----------
        theta : numpy.ndarray
            The parameter vector (positions, speed coefficients, ...).

        Returns
        -------
        numpy.ndarray
        """
        T, dE, dN, dU, _ = self._paths(theta)
        s = self.speed(theta)
        J = np.zeros((T.size, self.n_params))
        rows = np.arange(T.size)
        for c, d in enumerate((dE, dN, dU)):
            J[rows, 3 * self.index + c] = d / s
        self._basis.scatter(J, 3 * self.K, -T / s**2)
        if self.grad is not None:
            gain = self._gain(theta)
            J[:, :3 * self.K + self.k] *= gain[:, None]
            self._grad.scatter(J, 3 * self.K + self.k, -T / s * gain)
        return J

    def n_invalid(self, theta) -> int:
        """Count the legs no eigenray reaches at ``theta`` (0 for straight rays).

        Parameters
        ----------
        theta : numpy.ndarray
            The parameter vector (positions, speed coefficients, ...).

        Returns
        -------
        int
        """
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
    gradient_terms : tuple of str
        The gradient series fitted (:data:`GRADIENT_NAMES`, or its shallow two), empty
        where none are.
    gradient_coef : numpy.ndarray or None
        The gradient terms' spline coefficients (``a``, dimensionless), ``k`` per term in
        the order of :attr:`gradient_terms`; None where the gradients are not fitted.
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
        (m/s per unit of speed coefficient), ``n_invalid``, ``earth_radius`` (None: flat
        layers), ``along_sphere``, ``smoothing``, ``gradients``, ``positions`` (with its
        ``prior`` record and check), and the position parameters: ``position_map`` ``G``
        (positions = priors + ``G phi``), ``position_params`` ``phi``, their covariances
        ``position_params_cov`` (as :attr:`cov`) and ``position_params_cov_model``, and
        ``position_prior``, their prior precision (None: flat).
    """

    ids: tuple
    enu: np.ndarray
    cov: np.ndarray = field(repr=False)
    start: np.ndarray = field(repr=False)
    cov_model: np.ndarray = field(default=None, repr=False)
    sound_speed: float = 0.0
    sound_speed_sd: float = 0.0
    speed_coef: np.ndarray = field(default=None, repr=False)
    gradient_coef: np.ndarray = field(default=None, repr=False)
    gradient_terms: tuple = ()
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
        """Return the ``(3, 3)`` covariance of east, north, up of transponder number ``k``.

        Parameters
        ----------
        k : int
            The transponder's number (its order in the result).

        Returns
        -------
        numpy.ndarray
        """
        return self.cov[3 * k:3 * k + 3, 3 * k:3 * k + 3]

    def n_spurious(self, k: int) -> int:
        """Count the shots of transponder number ``k`` more likely spurious than true.

        Parameters
        ----------
        k : int
            The transponder's number (its order in the result).

        Returns
        -------
        int
        """
        return int(np.sum(self.p_true[self.index == k] < 0.5))


def describe(mean, sd, ci):
    """Return ``{"mean", "sd", "interval"}``, a Wald interval with probability ``ci``.

    Parameters
    ----------
    mean, sd : float
    ci : float
        Probability of the interval, in (0, 1).

    Returns
    -------
    dict

    Examples
    --------
    >>> describe(1.0, 0.5, 0.95)["interval"]
    [0.020018, 1.979982]
    """
    half = float(norm.ppf(0.5 + ci / 2)) * float(sd)
    return {"mean": float(mean), "sd": float(sd),
            "interval": [round(float(mean) - half, 6), round(float(mean) + half, 6)]}


def _check_shots(shots, transponders, exclude=None):
    missing = [c for c in SHOT_COLUMNS if c not in shots.columns]
    if missing:
        raise InputError(f"shots: missing column(s) {missing} (expected {list(SHOT_COLUMNS)})")
    need = {"east", "north", "up"} - set(transponders.columns)
    if need:
        raise InputError(f"transponders: missing column(s) {sorted(need)}")
    tid = shots["transponder"].astype(str).to_numpy()
    use = np.ones(tid.size, bool) if exclude is None else ~np.asarray(exclude, bool)
    ids, skipped = [], {}
    for t in map(str, transponders.index):
        n = int(np.sum((tid == t) & use))
        if n < MIN_SHOTS:
            skipped[t] = (f"{n} shots" + ("" if use.all() else " not flagged")
                          + f", need at least {MIN_SHOTS}")
        else:
            ids.append(t)
    if not ids:
        raise InputError(f"no transponder has {MIN_SHOTS} shots or more ({skipped})")
    k_of = {t: k for k, t in enumerate(ids)}
    index = np.array([k_of.get(t, -1) for t in tid])
    index[~use] = -1
    return ids, skipped, index


@with_one_blas_thread
@forgetting
# The steps of the array's fit (checks, robust start, model, EM, covariance, result) read
# long function: each step is a few lines and they read best in sequence
def locate_array(shots: pd.DataFrame, transponders: pd.DataFrame, *, profile=None,
                 surface_depth=0.0, speed_intervals=None, knot_minutes=KNOT_MINUTES,
                 sound_speed=None, outliers="uniform", time_range=None, fixed=None,
                 shift=False, gradients=False, max_iter=200, tol=1e-10,
                 earth_radius=None, along_sphere=False, exclude=None,
                 correlation=None, prior_sd=None, centre_sd=None) -> ArrayLocateResult:
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
    speed_intervals : int, optional
        None (default): the speed (or the profile's scale) is a smooth function of
        time, a cubic B-spline with knots every ``knot_minutes`` and a roughness
        penalty (the integrated squared second derivative) whose weight maximises the
        marginal likelihood (:func:`choose_smoothing`); the intervals average over
        the weights near the best (``model["smoothing"]``). An integer: an
        unpenalised B-spline with this many equal intervals (0: one value).
    knot_minutes : float, default :data:`KNOT_MINUTES`
        Largest knot spacing of the smooth speed (min).
    sound_speed : float, optional
        Starting straight-ray speed (m/s); default the profile's harmonic mean
        over the water column, else 1500.
    outliers : {"uniform", "first_arrival"}
    time_range : tuple of float, optional
        Span of the B-spline; default the shots'.
    fixed : array_like of bool, optional
        ``(K, 3)`` (rows in ``transponders``' order): the east, north, up held at
        the prior position (GARPOS's sigma of 0).
    shift : bool, default False
        Fixed geometry: the transponders keep their prior positions relative to
        each other and the array moves as a rigid body (3 parameters); ``fixed``
        then applies to the shift's east, north, up (its first row).
    gradients : bool or {"shallow"}, default False
        Also fit GARPOS's horizontal gradient terms (:func:`gradient_design`): the
        shallow ``a1`` (east, north; felt as the ship moves) and the deep ``a2`` (across
        the array), each a spline on the speed's knots; with the smooth speed their
        roughness penalty has its own weight, chosen the same way. Needs a track
        that surrounds the array (``track_geometry``); the deep term also needs shots over
        the array (on a circle about it, it trades with the horizontal position).
        ``"shallow"``: the shallow terms only.
    max_iter : int, default 200
    tol : float, default 1e-10
        Stop when sigma (s) changes by less than this (and the smoothing weight by
        less than 1 %).
    earth_radius : float, optional
        The profile's layers follow a sphere of this radius (m) touching the frame's
        origin (:class:`ArrayTravelTimes`; the positions stay in the frame's Cartesian
        east, north, up); None (default) flat layers.
    along_sphere : bool, default False
        With ``earth_radius``: the frame is already along the sphere (SeaGap's).
    exclude : array_like of bool, optional
        Shots left out of the fit (GARPOS's flagged shots); ``rows`` never holds them.
    correlation : None, "auto" or tuple of float, optional
        The replies' noise: None (default) independent (the intervals cluster-robust by
        interrogation); ``(mu_t, mu_mt[, white])`` GARPOS's covariance correlated in time
        and across transponders, plus a white share (:mod:`~bayes_mpem.survey_in.noise`;
        ``white`` default 0, GARPOS's own), the true replies of the EM refitted by
        generalised least squares; ``"auto"`` the three chosen by likelihood
        (:func:`~.noise.choose_correlation`), independent replies among the choices
        (``model["noise"]`` records the choice).
    prior_sd : array_like, optional
        ``(K, 3)`` (rows in ``transponders``' order): sds (m) of a Gaussian prior on each
        transponder's east, north, up about its prior position (GARPOS's ``_dPos``
        sigmas); inf or NaN: none (default, every coordinate free). Not used with
        ``shift``.
    centre_sd : array_like, optional
        ``(3,)`` sds (m) of the array's common shift (GARPOS's ``dCentPos`` sigmas; inf: a
        shift without a prior): with ``shift`` the shift's prior; else, on each axis with
        an sd above 0, a shift of every transponder alike is solved too, with that prior,
        and it moves the coordinates ``fixed`` holds as well (GARPOS's array take-over:
        :func:`_position_parameters`). The priors enter the EM's M-step, the choice of the
        smoothing weights and the intervals (``model["positions"]["prior"]``;
        docs/gnssa.md, "Priors on the positions").

    Returns
    -------
    ArrayLocateResult

    Raises
    ------
    InputError
        A missing column, or no transponder with enough shots.

    Warns
    -----
    LocateWarning
        Where the refit under correlated noise stops at :data:`REFIT_ROUNDS` with a
        smoothing weight still moving by more than 1 % (``model["noise"]`` records
        ``refit_rounds`` and ``refit_converged``), or with its last Gauss-Newton solve out of
        steps (``refit_gauss_newton_converged``; ``converged`` False); where legs have no
        direct eigenray through the profile (their times the chord's); where the EM does not
        converge, or its last M-step's Gauss-Newton ran out of steps.

    Notes
    -----
    The BLAS runs on one thread during the fit unless the environment sets a thread count
    (:mod:`bayes_mpem._threads`: its many small and banded factors are slower threaded).
    """
    check_choice("outliers", outliers, OUTLIER_MODELS)
    smooth = speed_intervals is None
    if not smooth:
        check_int("speed_intervals", speed_intervals, minimum=0)
    ids, skipped, index = _check_shots(shots, transponders, exclude)
    rows = np.flatnonzero(index >= 0)
    sub, index = shots.iloc[rows].reset_index(drop=True), index[rows]
    K, t = len(ids), sub["twtt"].to_numpy(float)
    if time_range is None:
        time_range = (float(sub["time"].min()), float(sub["time"].max()))
    varying = smooth or speed_intervals
    if varying and not time_range[1] > time_range[0]:
        if not smooth:
            raise InputError("shots: a time-varying sound speed needs shots at more than one "
                             "time")
        smooth, speed_intervals = False, 0
    if smooth:
        if not float(knot_minutes) > 0:
            raise InputError(f"knot_minutes: expected a positive number, got {knot_minutes}")
        speed_intervals = smooth_intervals(time_range, knot_minutes)
    equal = int(speed_intervals)
    breaks = speed_breaks(sub["time"], time_range, equal) if equal else None
    if breaks is not None and breaks.size == equal + 1:
        breaks = None  # no gap: the equal intervals, as recorded
    if breaks is not None:
        speed_intervals = breaks.size - 1
    start = transponders.loc[list(ids), ["east", "north", "up"]].to_numpy(float)
    z_ship = float(-0.5 * (sub["u_tx"].mean() + sub["u_rx"].mean()))
    z_tp = float(-start[:, 2].mean())
    unit = 1.0
    if profile is not None:
        unit = float(profile.harmonic_mean(z_ship - surface_depth, z_tp - surface_depth))
    c0 = float(sound_speed or (unit if profile is not None else 1500.0))
    terms = gradient_terms(gradients)
    if terms and not (smooth or speed_intervals):
        raise InputError("gradients: need a time-varying sound speed (the smooth default or "
                         "speed_intervals > 0)")
    mask = _fixed_mask(fixed, transponders, ids, K)
    G, prior = _position_parameters(prior_sd, centre_sd, transponders, ids, mask, shift)
    basis = speed_basis(sub, speed_intervals, time_range, breaks)
    _check_size(t.size, G.shape[1], basis.shape[1], 1 + len(terms), smooth,
                speed_intervals, knot_minutes, time_range)  # before any work
    # the robust start: straight rays, one speed
    straight = ArrayTravelTimes(sub, index, K, np.ones((len(sub), 1)))
    resid, jac = _mapped(*weighted_residuals(t, straight), G, start, 1)
    x0 = np.concatenate([np.zeros(G.shape[1]), [c0]])
    x_scale = np.array([10.0] * G.shape[1] + [1.0])
    theta = least_squares(resid, x0, jac=jac, args=(_gross_screen(resid(x0), index, K),),
                          loss="cauchy", f_scale=1e-3, x_scale=x_scale).x
    design = gradient_design(sub, index, start, basis, terms) if terms else None
    model = ArrayTravelTimes(sub, index, K, basis, profile=profile,
                             surface_depth=surface_depth, gradients=design,
                             earth_radius=earth_radius, along_sphere=along_sphere)
    k = basis.shape[1]
    kg = 0 if design is None else design.shape[1]
    nf = G.shape[1]
    coef0 = theta[-1] / unit
    phi = np.concatenate([theta[:nf], np.full(k, coef0), np.zeros(kg)])
    x_scale = np.array([1.0] * nf + [abs(coef0) / 1500.0] * k + [1e-4] * kg)
    resid, jac = _mapped(*weighted_residuals(t, model), G, start, k + kg)
    windows = np.array([[t[index == j].min(), t[index == j].max()] for j in range(K)])
    H = Hg = Pr = None
    if prior is not None:  # the positions' prior precision among all the parameters
        Pr = np.zeros((nf + k + kg,) * 2)
        Pr[:nf, :nf] = prior
        Pr.flags.writeable = False
    if smooth:
        P = nf + k + kg
        H = np.zeros((P, P))
        H0 = speed_penalty(speed_intervals, time_range, breaks=breaks)
        H[nf:nf + k, nf:nf + k] = H0
        if kg:
            Hg = np.zeros((P, P))
            for j in range(kg // k):
                a = nf + k + j * k
                Hg[a:a + k, a:a + k] = H0
            Hg.flags.writeable = False
        H.flags.writeable = False  # (the arrowhead keeps the parts of read-only matrices)
        em = _SmoothArrayEM(t, resid, jac, x_scale, windows, index, outliers, H, coef0, Hg,
                            Pr)
    elif Pr is not None:
        em = _PriorTravelTimeEM(t, resid, jac, x_scale, windows, index, outliers, prior)
    else:
        em = TravelTimeEM(t, resid, jac, x_scale, windows, index, outliers)
    run = em.run(phi, sigma_min=1e-7, tol=tol, max_iter=max_iter)
    (phi, _, sigma, weights), p = run.params[:4], run.resp
    lam, lam_g = (run.params.lam, run.params.lam_g) if smooth else (None, None)
    clusters = sub["t_tx"].to_numpy() if "t_tx" in sub.columns else np.arange(len(sub))
    refit, noise = _correlated_refit(correlation, resid, jac, phi, p, sub, index, H, Hg, lam,
                                     lam_g, sigma, Pr)
    if refit is not None:
        phi, sigma, lam, lam_g, J, r = refit
        clusters = np.arange(len(r))  # whitened rows: independent
    else:
        J, r = jac(phi, p), resid(phi, p)
    smoothing = None
    if smooth:
        cov_phi, cov_model_phi, smoothing = _smooth_covariance(
            J, r, phi, H, sigma, lam, clusters, Hg, lam_g, Pr, nf)
        if Hg is not None:
            smoothing.update(gradient_weight=float(lam_g),
                             log10_gradient_weight=float(np.log10(lam_g)))
        smoothing.update(knot_minutes=(time_range[1] - time_range[0]) / 60.0 / equal,
                         knot_minutes_asked=float(knot_minutes))
    elif Pr is not None:
        cov_phi, cov_model_phi = _prior_covariance(J, r, clusters, sigma, Pr)
    else:
        cov_phi = robust_covariance(J, r, clusters)
        cov_model_phi = np.linalg.pinv(J.T @ J) * sigma**2
    theta = _expand(phi, G, start, k + kg)
    cov, cov_model = _full_cov(G, cov_phi), _full_cov(G, cov_model_phi)
    g = basis.mean(axis=0)
    kk = slice(3 * K, 3 * K + k)
    grad_record = None if not kg else _gradient_record(
        theta, cov, 3 * K + k, g, unit * float(g @ theta[kk]) if profile is not None
        else float(g @ theta[kk]), gradient_origins(sub, start), terms)
    n_bad = model.n_invalid(theta)
    gn_ok = em.gn.get("converged", True) if smooth else True  # the last M-step's own steps
    refit_ok = noise is None or noise.get("refit_gauss_newton_converged", True)
    _warn(n_bad, 2 * t.size, run.converged, run.n_iter, gn_ok)
    return ArrayLocateResult(
        ids=tuple(ids), enu=theta[:3 * K].reshape(K, 3).copy(), cov=cov, start=start,
        cov_model=cov_model,
        sound_speed=float(g @ theta[kk]) * unit,
        sound_speed_sd=float(np.sqrt(max(g @ cov[kk, kk] @ g, 0.0))) * unit,
        speed_coef=theta[kk].copy(), gradient_coef=theta[kk.stop:].copy() if kg else None,
        gradient_terms=terms,
        sigma=sigma, weights=weights, p_true=p,
        residual=resid(phi), rows=rows, index=index, windows=windows, skipped=skipped,
        n_iter=run.n_iter, converged=run.converged and gn_ok and refit_ok, outliers=outliers,
        model={"profile": profile, "surface_depth": float(surface_depth),
               "speed_intervals": int(speed_intervals), "time_range": time_range,
               "speed_breaks": None if breaks is None else breaks.tolist(),
               "equal_intervals": equal,
               "unit": unit, "n_invalid": n_bad, "smoothing": smoothing,
               "earth_radius": None if earth_radius is None else float(earth_radius),
               "along_sphere": bool(along_sphere), "gradients": grad_record,
               "positions": _positions_record(G, K, shift, prior, prior_sd, centre_sd, mask,
                                              transponders, ids,
                                              _prior_check(phi[:nf], cov_model_phi[:nf, :nf],
                                                           prior)),
               "position_prior": prior, "position_map": G,
               "position_params": phi[:nf].copy(), "position_params_cov": cov_phi[:nf, :nf],
               "position_params_cov_model": cov_model_phi[:nf, :nf],
               "noise": noise})


def to_sphere(east, north, up, radius):
    """Return a Cartesian east-north-up point in the spherical frame tangent at its origin.

    The sphere of radius ``radius`` touches the frame's origin (its centre at
    ``up = -radius``); the point's east and north become distances along the sphere
    (azimuthal equidistant about the origin) and its up the height above the sphere: the
    frame of :class:`ArrayTravelTimes` with ``earth_radius``, in which the profile's
    layers follow the Earth. :func:`from_sphere` is the inverse.

    Parameters
    ----------
    east, north, up : array_like
        Metres, in a Cartesian (tangent-plane) frame.
    radius : float
        The sphere's radius (m; e.g. :func:`~bayes_mpem.io.geodesy.earth_radius`).

    Returns
    -------
    x, y, height : numpy.ndarray

    Examples
    --------
    >>> x, y, h = to_sphere(1500.0, 0.0, 0.0, 6371000.0)
    >>> round(float(h), 4), round(float(x), 4)
    (0.1766, 1500.0)
    """
    e, n, u = (np.asarray(v, float) for v in (east, north, up))
    rho, w = np.hypot(e, n), u + radius
    psi = np.arctan2(rho, w)
    with np.errstate(invalid="ignore", divide="ignore"):
        s = np.where(rho > 0, radius * psi / np.where(rho > 0, rho, 1.0), radius / w)
    return e * s, n * s, np.hypot(rho, w) - radius


def from_sphere(x, y, height, radius):
    """Return the Cartesian east, north, up of a point of :func:`to_sphere`'s frame.

    Parameters
    ----------
    x, y, height : array_like
        Distances along the sphere and the height above it (m).
    radius : float

    Returns
    -------
    east, north, up : numpy.ndarray

    Examples
    --------
    >>> e, n, u = from_sphere(*to_sphere(900.0, -1200.0, -1500.0, 6371000.0), 6371000.0)
    >>> [round(float(v), 9) for v in (e, n, u)]
    [900.0, -1200.0, -1500.0]
    """
    x, y, h = (np.asarray(v, float) for v in (x, y, height))
    a = np.hypot(x, y)
    psi, r = a / radius, radius + h
    s = np.where(a > 0, r * np.sin(psi) / np.where(a > 0, a, 1.0), r / radius)
    return x * s, y * s, r * np.cos(psi) - radius


#: Length (m) the gradient regressors are divided by (GARPOS's L).
GRADIENT_LENGTH = 1000.0
#: Names of the gradient series, in ``theta``'s order.
GRADIENT_NAMES = ("shallow_east", "shallow_north", "deep_east", "deep_north")


def gradient_terms(gradients) -> tuple:
    """Return the gradient series a ``gradients`` argument fits, in ``theta``'s order.

    Parameters
    ----------
    gradients : bool or {"shallow"}
        False (or None): none; True: all of :data:`GRADIENT_NAMES`; ``"shallow"``: the
        shallow east and north.

    Returns
    -------
    tuple of str

    Raises
    ------
    InputError
        For any other value.
    """
    if gradients is None or isinstance(gradients, bool | np.bool_):
        return GRADIENT_NAMES if gradients else ()
    if isinstance(gradients, str) and gradients == "shallow":
        return GRADIENT_NAMES[:2]
    raise InputError(f"gradients: expected True, False or 'shallow', got {gradients!r}")


class _SparseDesign:
    """A design matrix of B-splines (a few non-zeros per row), kept sparse.

    Parameters
    ----------
    X : numpy.ndarray
        ``(n, m)``.
    """

    def __init__(self, X):
        self.matrix = csr_matrix(X)
        self.rows = np.repeat(np.arange(X.shape[0]), np.diff(self.matrix.indptr))

    def scatter(self, J, first, factor):
        """Set ``J[:, first:first + m]`` to ``factor[:, None] * X`` (``J``'s block all zero).

        Parameters
        ----------
        J : numpy.ndarray
            ``(n, P)``, zero in the block.
        first : int
            The block's first column.
        factor : numpy.ndarray
            ``(n,)``.
        """
        M = self.matrix
        J[self.rows, first + M.indices] = factor[self.rows] * M.data


def gradient_design(shots, index, start, basis, terms=GRADIENT_NAMES) -> np.ndarray:
    """Return the design of GARPOS's gradient terms (``gamma`` linear in their coefficients).

    ``gamma = a1 . dp / L + a2 . dx / L``.

    ``dp`` is the transducer's horizontal offset (mean of transmit and receive) from its
    mean over the shots, ``dx`` the transponder's prior offset from the priors' mean
    (held fixed, so ``gamma`` is linear in the coefficients), ``L`` = 1 km; ``a1`` and
    ``a2`` (east, north) are splines on ``basis``.

    Parameters
    ----------
    shots : pandas.DataFrame
        ``e/n_tx``, ``e/n_rx``.
    index : numpy.ndarray
        Transponder number of each shot.
    start : numpy.ndarray
        ``(K, 3)`` prior positions.
    basis : numpy.ndarray
        ``(n, k)`` the speed's basis.
    terms : tuple of str, default :data:`GRADIENT_NAMES`
        The series wanted (:func:`gradient_terms`), in this order.

    Returns
    -------
    numpy.ndarray
        ``(n, k len(terms))``: the columns of each term (all four: ``a1`` east, north,
        then ``a2`` east, north).
    """
    pe = 0.5 * (shots["e_tx"].to_numpy(float) + shots["e_rx"].to_numpy(float))
    pn = 0.5 * (shots["n_tx"].to_numpy(float) + shots["n_rx"].to_numpy(float))
    origins = gradient_origins(shots, start)
    dx = start[index, :2] - origins["deep"]
    regs = dict(zip(GRADIENT_NAMES, (pe - origins["shallow"][0], pn - origins["shallow"][1],
                                     dx[:, 0], dx[:, 1]), strict=True))
    return np.hstack([basis * (regs[name] / GRADIENT_LENGTH)[:, None] for name in terms])


def gradient_origins(shots, start) -> dict:
    """Return the points the gradient terms are about (east, north in the frame, m).

    ``shallow``: the transducer's mean position over the shots (``p_mean`` of
    :func:`gradient_design`); ``deep``: the prior positions' mean (``x_mean``). The speed's
    series (``a0``) is the speed there: a gradient moves it by ``gradV`` times the distance
    from another point.

    Parameters
    ----------
    shots : pandas.DataFrame
        ``e/n_tx``, ``e/n_rx`` of the shots located.
    start : numpy.ndarray
        ``(K, 3)`` prior positions.

    Returns
    -------
    dict
        ``{"shallow": [east, north], "deep": [east, north]}``.
    """
    p = [float(np.mean(0.5 * (shots[f"{c}_tx"].to_numpy(float)
                              + shots[f"{c}_rx"].to_numpy(float)))) for c in "en"]
    return {"shallow": p, "deep": [float(v) for v in np.asarray(start)[:, :2].mean(axis=0)]}


def _gradient_record(theta, cov, first, g, v0, origins, terms):
    """Return the time-averaged gradients (m/s)/km with their sds (``summary.json``)."""
    k = g.size
    deep = "deep_east" in terms
    out = {"unit": "(m/s)/km", "quantity": "time average over the survey of GARPOS's gradV "
           "(a V0): shallow a1 (ship's offset)" + (", deep a2 (transponder's offset)" if deep
                                                   else "; the deep a2 not fitted"),
           "origins_m": origins if deep else {"shallow": origins["shallow"]}}
    for j, name in enumerate(terms):
        sl = slice(first + j * k, first + (j + 1) * k)
        out[name] = {"mean": float(g @ theta[sl]) * v0,
                     "sd": float(np.sqrt(max(g @ cov[sl, sl] @ g, 0.0))) * v0}
    return out


def _fixed_mask(fixed, transponders, ids, K):
    """Return the ``(K, 3)`` mask of fixed coordinates, in the order of those located."""
    if fixed is None:
        return np.zeros((K, 3), bool)
    return _per_transponder(fixed, transponders, ids, "fixed", bool)


#: Smallest prior sd of a position (m): below it the prior's precision swamps the data's by
#: more than round-off allows (hold the coordinate with ``fixed`` instead); an sd above
#: :data:`MAX_PRIOR_SD` is no prior (its square overflows, its precision is 0 to round-off).
MIN_PRIOR_SD = 1e-6
MAX_PRIOR_SD = 1e100


def _position_parameters(prior_sd, centre_sd, transponders, ids, mask, shift):
    """Return ``(G, prior)``: the map from the position parameters and their prior precision.

    GARPOS's model of the positions (``setup_model.init_position``, read to learn it): each
    transponder's offset ``dPos`` from its prior position, plus the array's common shift
    ``dCentPos``, each coordinate solved where its sigma is above 0, with the a priori
    covariance ``diag(sigma^2)``. So the parameters are the free offsets (``mask`` False: the
    position is ``start + G phi``) and, where ``centre_sd`` is above 0 on an axis (not with
    ``shift``, whose three parameters are the shift itself), a common shift on that axis,
    which also moves a coordinate whose own sigma is 0 (GARPOS's "array take-over"). The
    prior precision is diagonal: ``prior_sd^-2`` on the offsets (none where inf, NaN or
    above :data:`MAX_PRIOR_SD`) and ``centre_sd^-2`` on the shift (on the shift's own
    parameters with ``shift``); None where no parameter has one.
    """
    K = len(ids)
    G = _free_map(K, mask, shift)
    if prior_sd is None and centre_sd is None:
        return G, None
    c = np.zeros(3) if centre_sd is None else np.asarray(centre_sd, float)
    if c.shape != (3,) or np.any(np.isnan(c)) or np.any(c < 0):
        raise InputError(f"centre_sd: expected three sds of 0 or more (m; inf: none), got "
                         f"{centre_sd!r}")
    if np.any((c > 0) & (c < MIN_PRIOR_SD)):
        raise InputError(f"centre_sd: {sorted(set(c[(c > 0) & (c < MIN_PRIOR_SD)].tolist()))} "
                         f"m, below {MIN_PRIOR_SD:g} m: give 0 (no common shift) instead")
    if shift:
        sd = c[~mask[0]]
    else:
        sd = (np.full((K, 3), np.inf) if prior_sd is None
              else _per_transponder(prior_sd, transponders, ids, "prior_sd", float))
        bad = ~(np.isnan(sd) | (sd > 0))
        if np.any(bad & ~mask):
            raise InputError("prior_sd: expected sds above 0 (m; inf or NaN: no prior; a "
                             "coordinate held at its prior is given by fixed), got "
                             f"{sorted(set(sd[bad & ~mask].tolist()))}")
        tiny = (sd > 0) & (sd < MIN_PRIOR_SD) & ~mask
        if np.any(tiny):
            raise InputError(f"prior_sd: {sorted(set(sd[tiny].tolist()))} m, below "
                             f"{MIN_PRIOR_SD:g} m, would hold the coordinates to below "
                             "round-off: hold them with fixed instead")
        common = c > 0
        G = np.column_stack([G, np.tile(np.eye(3), (K, 1))[:, common]])
        sd = np.concatenate([sd.ravel()[~mask.ravel()], c[common]])
    has = (sd > 0) & (sd <= MAX_PRIOR_SD)  # NaN and inf fail: no prior
    if not has.any():
        return G, None
    return G, np.diag(np.where(has, 1.0 / np.where(has, sd, 1.0) ** 2, 0.0))


def _per_transponder(values, transponders, ids, name, dtype):
    """Return ``(K, 3)`` rows of ``values`` (in ``transponders``' order) for the ``ids`` located."""
    arr = np.asarray(values, dtype)
    if arr.shape != (len(transponders), 3):
        raise InputError(f"{name}: expected a ({len(transponders)}, 3) array (east, north, up "
                         f"of each transponder), got shape {arr.shape}")
    order = {str(t): i for i, t in enumerate(transponders.index)}
    return arr[[order[t] for t in ids]]


def _free_map(K, mask, shift):
    """``(3K, F)`` map from the free parameters to the position offsets from the priors."""
    if shift:
        M = np.tile(np.eye(3), (K, 1))
        return M[:, ~mask[0]]
    return np.eye(3 * K)[:, ~mask.ravel()]


def _full_cov(G, C):
    """Covariance of (positions, coefficients) from that of (free parameters, coefficients).

    ``Gf C Gf'`` with ``Gf`` the block-diagonal ``diag(G, I)``, formed block by block: the
    coefficients' block is ``C``'s own, and only the positions' rows and columns are mapped
    (two dense products of the whole matrix cost ``4 P^3``; the same numbers where ``G``
    selects coordinates, round-off where it sums them, as for a rigid shift).
    """
    nf, n3 = G.shape[1], G.shape[0]
    k = C.shape[0] - nf
    out = np.empty((n3 + k, n3 + k))
    out[:n3, :n3] = G @ C[:nf, :nf] @ G.T
    out[:n3, n3:] = G @ C[:nf, nf:]
    out[n3:, :n3] = C[nf:, :nf] @ G.T
    out[n3:, n3:] = C[nf:, nf:]
    # products such as the grid's spread (dev' W dev) or the sandwich are symmetric only to
    # round-off, which depends on the BLAS kernel of the machine's CPU: made exact here
    return 0.5 * (out + out.T)


def _expand(phi, G, start, k):
    """Full ``theta`` (positions, speed) from the free parameters ``phi``."""
    nf = G.shape[1]
    return np.concatenate([start.ravel() + G @ phi[:nf], phi[nf:nf + k]])


#: a shot whose residual at the prior positions is this many robust sds (and at least
#: GROSS_FLOOR s) from its transponder's median is left out of the robust start
GROSS_MADS = 20.0
GROSS_FLOOR = 0.01


#: The most parameters a fit takes per reply: under a roughness penalty, unpenalised, and
#: unpenalised with the gradients' series.
MAX_PARAMS_PER_REPLY = {"smooth": 1.0, "unpenalised": 1.0, "unpenalised_gradients": 0.5}
#: A smooth fit is refused only above this many parameters too (it is well posed; the limit
#: is its time: SeaGap's 902 took 7 s, 2,200 took 53 s and 4,300 took 188 s).
MAX_SMOOTH_PARAMS = 3000


def _check_size(n, n_pos, k, n_series, smooth, speed_intervals, knot_minutes, time_range):
    """Refuse a speed (and gradient) spline with more coefficients than the replies carry.

    Unpenalised, more parameters than replies are not determined, and with the gradients
    more than one per two replies crawled (a half-hour campaign with 50 intervals and the
    gradients ran past 7 minutes; 30 took 25 s). Smooth, the fit is well posed but its dense
    factors grow as the cube: above :data:`MAX_SMOOTH_PARAMS` parameters and one a reply it
    is refused (SeaGap's 14.6 h with knots every 0.1 min: 8,612 parameters for 3,347
    replies, past 5 minutes). The spacing suggested is checked to pass. ``k`` coefficients
    per series, ``n_series`` series (the speed and the gradients').
    """
    P = n_pos + k * n_series
    kind = "smooth" if smooth else "unpenalised_gradients" if n_series > 1 else "unpenalised"
    limit = MAX_PARAMS_PER_REPLY[kind] * n
    if smooth:
        limit = max(limit, MAX_SMOOTH_PARAMS)
    if P <= limit:
        return
    most = int((limit - n_pos) // n_series) - 3  # intervals that pass (before merging)
    if smooth:
        span = (time_range[1] - time_range[0]) / 60.0
        need = span / max(most, 1)
        e = 10.0 ** (np.floor(np.log10(need)) - 1)
        need = float(np.ceil(need / e - 1e-9) * e)  # up, at two significant figures
        raise InputError(f"knot_minutes (--knot-minutes) {float(knot_minutes):g}: {P:,} "
                         f"parameters for {n:,} replies; expected at most "
                         f"{int(limit):,} (the fit would take many minutes): give knots every "
                         f"{need:g} min or more")
    most_is = "one per two replies with the gradients" if n_series > 1 else "one a reply"
    raise InputError(f"speed_intervals (--speed-intervals) {int(speed_intervals)}: {P:,} "
                     f"parameters for {n:,} replies, unpenalised; expected at most {most_is}: "
                     f"give {max(most, 0)} intervals or fewer"
                     + (", or leave the gradients out" if n_series > 1 else ""))


def _gross_screen(r, index, K) -> np.ndarray:
    """Return 0/1 weights that leave the grossly wrong shots out of the robust start."""
    w = np.ones_like(r)
    for k in range(K):
        sel = index == k
        if not sel.any():
            continue
        med = np.median(r[sel])
        mad = 1.4826 * np.median(np.abs(r[sel] - med))
        w[sel] = np.abs(r[sel] - med) <= max(GROSS_MADS * mad, GROSS_FLOOR)
    return w


def _mapped(resid, jac, G, start, k):
    """Residual and Jacobian functions of the free parameters (positions = prior + G phi)."""
    def r(phi, w=None):
        return resid(_expand(phi, G, start, k), w)

    free = G.shape[0] == G.shape[1] and np.array_equal(G, np.eye(G.shape[0]))

    def j(phi, w=None):
        J = jac(_expand(phi, G, start, k), w)
        if free:  # every coordinate free: J @ I is J itself (no copy of the whole Jacobian)
            return J
        return np.column_stack([J[:, :G.shape[0]] @ G, J[:, G.shape[0]:]])

    return r, j


def _prior_check(phi, cov, prior):
    """Return how far the fit moved the parameters from their priors, against the priors' sds.

    A prior-data conflict check (Box 1980; Evans & Moshonov 2006): where the prior is right,
    the posterior mean of the parameters that have one is ``N(0, V)`` with ``V`` the prior's
    covariance less the posterior's (linear-Gaussian), so ``phi' V^+ phi`` is chi-squared on
    ``rank(V)`` degrees of freedom. ``cov`` is the model-based posterior covariance
    ``(J'J / sigma^2 + Q)^-1``: ``V`` is a difference of nearly equal matrices where the prior
    dominates, and the cluster-robust, grid-averaged one (whose ``V`` is not this difference)
    made the statistic several-fold too large there. A small p-value says the site file's
    positions are farther off than its sigmas say, and the intervals lean on those sigmas.
    None without a prior.
    """
    if prior is None:
        return None
    idx = np.flatnonzero(np.diag(prior) > 0)
    V = np.diag(1.0 / np.diag(prior)[idx]) - cov[np.ix_(idx, idx)]
    vals, vecs = np.linalg.eigh(0.5 * (V + V.T))
    keep = vals > 1e-9 * max(vals.max(), 0.0)
    if not keep.any():
        return None
    z = vecs[:, keep].T @ phi[idx]
    stat = float(np.sum(z**2 / vals[keep]))
    dof = int(keep.sum())
    return {"chi2": stat, "dof": dof, "p_value": float(chi2.sf(stat, dof)),
            "test": "the fitted moves from the prior positions against the prior's covariance "
                    "less the posterior's (a prior-data conflict check)"}


#: :func:`prior_scale` scales the priors only where one gives a parameter at least this share
#: of its precision (below it the refit would change the answer by less) ...
MIN_PRIOR_INFLUENCE = 0.01
#: ... and where the check of the sigmas as given has a p-value below this.
PRIOR_SCALE_P = 0.05
#: The largest variance factor :func:`prior_scale` returns (sds times 100).
MAX_PRIOR_SCALE = 1e4


def prior_scale(fit) -> float:
    """Return the variance factor by which a fit's position priors understate its moves (>= 1).

    The factor ``kappa`` of the prior's covariance at which the prior-data check
    (:func:`_prior_check`) of the fit, moved to that prior, has its chi-squared equal to its
    degrees of freedom: the moment estimate of the prior's scale. The move is linear
    (``phi_kappa = C_kappa (C^-1) phi`` with ``C_kappa = (C^-1 - P + P / kappa)^-1``, ``C`` the
    model-based covariance), so no refit is needed to find it; the check's chi-squared over its
    degrees of freedom at the sigmas as given tends to 1 where the prior carries the
    parameters, and under-states ``kappa`` there. 1 where the fit has no prior, where the check
    of the sigmas as given has a p-value of :data:`PRIOR_SCALE_P` or more, and where no
    parameter has :data:`MIN_PRIOR_INFLUENCE` of its precision from the prior; at most
    :data:`MAX_PRIOR_SCALE`. The site file's sigmas are a floor: never below 1.

    Parameters
    ----------
    fit : ArrayLocateResult

    Returns
    -------
    float
    """
    from scipy.optimize import brentq

    m = fit.model
    P, C, phi = (m.get(k) for k in ("position_prior", "position_params_cov_model",
                                    "position_params"))
    check = ((m.get("positions") or {}).get("prior") or {}).get("check")
    if P is None or C is None or not check or check["p_value"] >= PRIOR_SCALE_P:
        return 1.0
    if (np.diag(C) * np.diag(P)).max() < MIN_PRIOR_INFLUENCE:  # the prior's share of each
        return 1.0
    A = _scaled_inverse(C)  # the posterior precision, M + P
    b = A @ phi

    def excess(log_kappa):
        Pk = P / np.exp(log_kappa)
        Ck = _scaled_inverse(A - P + Pk)
        out = _prior_check(Ck @ b, Ck, Pk)
        return np.nan if out is None else out["chi2"] / out["dof"] - 1.0

    top = np.log(MAX_PRIOR_SCALE)
    lo, hi = excess(0.0), excess(top)
    if not lo > 0 or not np.isfinite(hi):  # no conflict, or no scale can be bracketed
        return 1.0
    if hi > 0:
        return MAX_PRIOR_SCALE
    return float(np.exp(brentq(excess, 0.0, top, xtol=1e-3)))


#: Points of the grid of ``log kappa`` over ``[0, log MAX_PRIOR_SCALE]`` on which
#: :func:`prior_scale_spread` averages the positions.
SCALE_GRID = 241


def prior_scale_spread(fit, kappa):
    """Return what the uncertainty of a prior scale adds to the position parameters' covariance.

    Where ``--position-prior auto`` scaled the site file's prior covariance by ``kappa``
    (:func:`prior_scale`, a moment estimate from the fit's moves of a dozen coordinates), the
    positions the prior carries (a circle's depths) lean on an estimate of a variance from a
    dozen numbers: fixed at it, their intervals covered 60 % (docs/gnssa.md). Here the scale
    ``k`` has its linear-Gaussian log marginal likelihood, up to a constant,
    ``b'(M + P/k)^-1 b / 2 - log|M + P/k| / 2 - r log(k) / 2`` (``M`` the data's
    information on the parameters, ``b = M phi_data``, ``P`` the site file's prior precision
    of rank ``r``), and a flat prior on ``log k`` over ``[0, log MAX_PRIOR_SCALE]`` (the
    site file's sigmas a floor); the positions' posterior averaged over it has the mean
    ``phi_bar`` and the covariance ``C_mix``. Returned: ``C_mix + (phi_bar - phi)(...)' - C``
    (``phi``, ``C`` the fit's, at ``kappa``), its negative part dropped (never narrowed).

    Parameters
    ----------
    fit : ArrayLocateResult
        Fitted with the prior covariance scaled by ``kappa``.
    kappa : float
        The scale it was fitted with (> 1).

    Returns
    -------
    extra : numpy.ndarray
        ``(n, n)`` to add to the position parameters' covariance.
    record : dict
        ``kappa_mean`` and ``kappa_interval`` (95 %) of the scale's posterior.

    References
    ----------
    Gelman, A. et al. (2013), Bayesian Data Analysis, 3rd ed., section 5.3 (hierarchical
    normal models: the scale's posterior and the estimates averaged over it).
    """
    m = fit.model
    P = np.asarray(m["position_prior"], float) * kappa  # the site file's own precision
    C, phi = m["position_params_cov_model"], m["position_params"]
    A = _scaled_inverse(C)
    b, M = A @ phi, A - np.asarray(m["position_prior"], float)
    r = int(np.sum(np.diag(P) > 0))
    grid = np.linspace(0.0, np.log(MAX_PRIOR_SCALE), SCALE_GRID)
    ll, means, covs = np.full(grid.size, -np.inf), [], []
    for i, lk in enumerate(grid):
        Ak = M + P * np.exp(-lk)
        sign, logdet = np.linalg.slogdet(0.5 * (Ak + Ak.T))
        Ck = _scaled_inverse(Ak)
        means.append(Ck @ b)
        covs.append(Ck)
        if sign > 0:
            ll[i] = 0.5 * b @ means[-1] - 0.5 * logdet - 0.5 * r * lk
    w = np.exp(ll - ll.max())
    w /= w.sum()
    mean = sum(wi * mi for wi, mi in zip(w, means, strict=True))
    cmix = sum(wi * (ci + np.outer(mi - mean, mi - mean))
               for wi, ci, mi in zip(w, covs, means, strict=True))
    extra = cmix + np.outer(mean - phi, mean - phi) - C
    vals, vecs = np.linalg.eigh(0.5 * (extra + extra.T))
    extra = (vecs * np.clip(vals, 0.0, None)) @ vecs.T
    k = np.exp(grid)
    cdf = np.cumsum(w)
    record = {"kappa_mean": float(w @ k),
              "kappa_interval": [float(np.interp(0.025, cdf, k)), float(np.interp(0.975, cdf, k))],
              "method": "the positions averaged over the prior scale's posterior (its "
                        "linear-Gaussian likelihood, a flat prior on log kappa from 1 to "
                        f"{MAX_PRIOR_SCALE:g})"}
    return extra, record


def _positions_record(G, K, shift, prior, prior_sd, centre_sd, mask, transponders, ids,
                      check=None):
    """Return what was solved for the positions (``summary.json``), with their prior."""
    held = int(np.sum(~np.any(G != 0.0, axis=1)))  # coordinates no parameter moves
    common = not shift and G.shape[1] > int(np.sum(~mask))
    out = {"mode": ("rigid shift of the prior geometry" if shift else
                    "each transponder and a common shift" if common else "each transponder"),
           "n_free": int(G.shape[1]), "n_fixed": (3 - G.shape[1]) if shift else held,
           "n_coordinates": 3 * K}
    if common:  # GARPOS's array take-over: held offsets that the common shift still moves
        out["n_moved_by_shift_only"] = int(np.sum(mask.ravel() & np.any(G != 0.0, axis=1)))
        # the shift's parameters are G's last columns, one per axis where it is solved
        n_common = G.shape[1] - int(np.sum(~mask))
        out["common_axes"] = [("east", "north", "up")[int(np.argmax(G[:3, j]))]
                              for j in range(G.shape[1] - n_common, G.shape[1])]
    if prior is None:
        out["prior"] = None
        return out

    def sds(v, fixed):  # 0: held (GARPOS's sigma of 0); None: no prior
        return [0.0 if f else float(x) if np.isfinite(x) and x > 0 else None for x, f in
                zip(v, fixed, strict=True)]

    c = np.zeros(3) if centre_sd is None else np.asarray(centre_sd, float)
    rec = {"n_with_prior": int(np.count_nonzero(np.diag(prior) > 0)), "check": check,
           "kind": "Gaussian about the prior positions, sds in m (GARPOS's a priori covariance "
                   "of the site file's sigmas)"}
    if shift:
        rec["shift_sd"] = sds(c, mask[0])
    else:
        sd = (np.full((K, 3), np.inf) if prior_sd is None
              else _per_transponder(prior_sd, transponders, ids, "prior_sd", float))
        rec["transponder_sd"] = {t: sds(np.where(np.isnan(sd[j]), np.inf, sd[j]), mask[j])
                                 for j, t in enumerate(ids)}
        rec["centre_sd"] = [float(x) if np.isfinite(x) else None for x in c]  # None: no prior
    out["prior"] = rec
    return out


class _SmoothFit(NamedTuple):
    theta: np.ndarray
    r: np.ndarray
    sigma: float
    weights: np.ndarray
    lam: float  # smoothing weight: prior precision lam * H on the coefficients
    lam_g: float = None  # the gradients' weight


def log_evidence(J, r, theta, H, sigma, lam, rank=None, H_fixed=None, blocks=None):
    """Linearised log marginal likelihood of a penalised weighted least-squares fit.

    The model ``r(theta + d) = r + J d`` (weighted residuals), Gaussian noise of sd
    ``sigma`` and the prior ``N(0, (lam H)^+)`` on ``theta`` (flat where ``H`` is
    zero): ``-(||r + J d||^2 / sigma^2 + lam th' H th) / 2 + rank log(lam) / 2 -
    log|J'J / sigma^2 + lam H| / 2`` at the posterior mode ``th = theta + d``, up to
    a constant that does not depend on ``lam`` (minus half of GARPOS's ABIC).

    Parameters
    ----------
    J : numpy.ndarray or tuple
        ``(n, P)`` Jacobian of the weighted residuals, or ``(J'J, J'r, r'r)``.
    r : numpy.ndarray
        ``(n,)`` weighted residuals at ``theta``.
    theta : numpy.ndarray
    H : numpy.ndarray
        ``(P, P)`` penalty (positive semi-definite).
    sigma, lam : float
    rank : int, optional
        Of ``H`` (default computed).
    H_fixed : numpy.ndarray, optional
        A further prior precision, weight included (its determinant is left out).
    blocks : list of numpy.ndarray, optional
        ``null_blocks(H, H_fixed)``, for a caller that evaluates many weights.

    Returns
    -------
    logml : float
        ``-inf`` where the posterior precision is numerically singular.
    step : numpy.ndarray
        ``d``, to the posterior mode.
    A : numpy.ndarray
        The posterior precision ``J'J / sigma^2 + lam H``.

    Examples
    --------
    >>> import numpy as np
    >>> J = np.eye(3); H = np.diag([0.0, 1.0, 1.0]); r = np.array([0.0, -3.0, 3.0])
    >>> a = log_evidence(J, r, np.zeros(3), H, 1.0, 0.5)[0]
    >>> b = log_evidence(J, r, np.zeros(3), H, 1.0, 50.0)[0]
    >>> bool(a > b)
    True
    """
    return _log_evidence(J, r, theta, H, sigma, lam, rank, H_fixed, blocks)[:3]


def _log_evidence(J, r, theta, H, sigma, lam, rank=None, H_fixed=None, blocks=None):
    """Return :func:`log_evidence`'s three values and the factor of ``A`` it used.

    The factor is :func:`scipy.linalg.cho_factor`'s of ``A`` scaled to a unit diagonal
    (None where it failed): a caller that also inverts ``A`` (:func:`_scaled_inverse`)
    factors it once.
    """
    if rank is None:
        rank = _penalty_rank(H)
    if isinstance(J, tuple):  # (J'J, J'r) precomputed
        JtJ, Jtr = J[0] / sigma**2, J[1] / sigma**2
    else:
        JtJ, Jtr = J.T @ J / sigma**2, J.T @ r / sigma**2
    Q = lam * H if H_fixed is None else lam * H + H_fixed
    A = JtJ + Q
    theta = null_shifted(theta, Q, blocks)
    d = np.diag(A).copy()
    d[d <= 0] = 1.0
    s = 1.0 / np.sqrt(d)  # unit diagonal: log|A| = log|S A S| + sum(log d)
    try:
        c = cho_factor(A * s[:, None] * s[None, :])
    except np.linalg.LinAlgError:
        return -np.inf, np.zeros_like(theta), A, None
    step = s * cho_solve(c, -s * (Jtr + Q @ theta))
    th = theta + step
    if isinstance(J, tuple):  # ||r + J d||^2 = r'r + 2 d'J'r + d'J'J d
        rr2 = J[2] + 2 * step @ J[1] + step @ J[0] @ step
    else:
        rr = r + J @ step
        rr2 = rr @ rr
    logml = (-0.5 * (rr2 / sigma**2 + th @ Q @ th) + 0.5 * rank * np.log(lam)
             - np.sum(np.log(np.diag(c[0]))) - 0.5 * np.sum(np.log(d)))
    return float(logml), step, A, c


def _blocks(nz):
    """Index arrays of the connected components of a symmetric nonzero pattern ``nz``.

    Rows without a nonzero belong to no block. A fit asks for the blocks of the same few
    patterns (the speed's penalty, the gradients') at every weight it tries: the last
    patterns' blocks are kept (:func:`_pattern_blocks`), read-only.
    """
    nz = np.asarray(nz, bool)
    return _pattern_blocks(nz.shape, np.packbits(nz).tobytes())


@functools.lru_cache(maxsize=16)
def _pattern_blocks(shape, packed):
    """:func:`_blocks` of the pattern ``np.packbits(nz)`` of ``shape``."""
    from scipy.sparse.csgraph import connected_components

    size = int(np.prod(shape))
    nz = np.unpackbits(np.frombuffer(packed, np.uint8), count=size).astype(bool).reshape(shape)
    idx = np.flatnonzero(nz.any(axis=1))
    if not idx.size:
        return ()
    label = connected_components(csr_matrix(nz[np.ix_(idx, idx)]), directed=False)[1]
    out = tuple(idx[label == j] for j in range(label.max() + 1))
    for block in out:
        block.setflags(write=False)
    return out


def null_blocks(*Qs):
    """Return the blocks on which :func:`null_shifted` may shift: index arrays.

    A block is a connected component of the nonzero pattern of the symmetric matrices ``Qs``
    together (the speed's coefficients, each gradient component's); it is kept where every
    one of them annihilates the constant on it, so that it does so for any positive weights
    of them (``lam H + H_fixed``).

    Parameters
    ----------
    *Qs : numpy.ndarray or None
        ``(P, P)`` symmetric penalties (None: left out).

    Returns
    -------
    list of numpy.ndarray

    Examples
    --------
    >>> D = np.array([[1.0, -1.0], [-1.0, 1.0]])
    >>> Q = np.zeros((5, 5)); Q[1:3, 1:3] = D; Q[3:, 3:] = np.eye(2)
    >>> [b.tolist() for b in null_blocks(Q)]
    [[1, 2]]
    """
    Qs = [Q for Q in Qs if Q is not None]
    nz = np.zeros(Qs[0].shape, bool)
    for Q in Qs:
        nz |= Q != 0.0
    blocks = []
    for block in _blocks(nz):  # a component: Q is zero between it and the other rows
        subs = [Q[np.ix_(block, block)] for Q in Qs]
        if all(np.abs(S.sum(axis=1)).max() <= 1e-9 * np.abs(S).max() * np.sqrt(block.size)
               for S in subs if np.any(S)):
            blocks.append(block)
    return blocks


def null_shifted(theta, Q, blocks=None):
    """Return ``theta`` less, on each block of ``Q``, the mean of that block's entries.

    Where ``Q`` annihilates the constant on a block (:func:`null_blocks`), ``Q theta`` and
    ``theta' Q theta`` are unchanged in exact arithmetic; evaluated directly they cancel to
    round-off, of hundreds of nats with speed coefficients near 1 and a weight near 1e13
    (docs/gnssa.md, "Choosing lambda"). One mean over all the blocks would shift coefficients
    near 0 by the others' mean, where a weight of 1e15 turns the same round-off into an error
    of order 1 in ``Q theta``.

    Parameters
    ----------
    theta : array_like
        ``(P,)`` parameters.
    Q : numpy.ndarray
        ``(P, P)`` symmetric penalty.
    blocks : list of numpy.ndarray, optional
        ``null_blocks(Q)`` (or of matrices whose weighted sum ``Q`` is), computed once by a
        caller that evaluates many ``theta`` or weights.

    Returns
    -------
    numpy.ndarray
        Float; a block on which ``Q`` does not annihilate a constant is left as it is.

    Examples
    --------
    >>> Q = np.array([[0.0, 0.0, 0.0], [0.0, 1.0, -1.0], [0.0, -1.0, 1.0]])
    >>> null_shifted(np.array([5.0, 1.0, 3.0]), Q).tolist()
    [5.0, -1.0, 1.0]
    >>> Q2 = np.kron(np.eye(2), Q[1:, 1:])
    >>> null_shifted(np.array([1.0, 3.0, 0.0, 0.0]), Q2).tolist()
    [-1.0, 1.0, 0.0, 0.0]
    """
    if blocks is None:
        blocks = null_blocks(Q)
    out = np.array(theta, float)
    for block in blocks:
        out[block] -= out[block].mean()
    return out


def evidence_curve(pre, theta, H, sigma, rank, H_fixed=None, blocks=None):
    """Return ``f(lam)``, :func:`log_evidence`'s ``logml`` at the smoothing weight ``lam``.

    The weights of one search share ``J'J``, ``H`` and ``H_fixed``: where they form an
    arrowhead (:mod:`.arrowhead`: a band of spline coefficients bordered by the positions)
    each evaluation factors the band, not the dense matrix; elsewhere it is
    :func:`log_evidence` itself. The two agree to round-off (``tests/survey_in/test_arrowhead.py``).

    Parameters
    ----------
    pre : tuple
        ``(J'J, J'r, r'r)`` of the weighted residuals.
    theta, H, sigma, rank, H_fixed, blocks
        As for :func:`log_evidence` (``rank`` and ``blocks`` required here).

    Returns
    -------
    callable
    """
    structure = arrowhead([pre[0], H, H_fixed])
    if structure is None:
        return lambda lam: log_evidence(pre, None, theta, H, sigma, lam, rank, H_fixed,
                                        blocks)[0]
    th0 = null_shifted(theta, H if H_fixed is None else H + H_fixed, blocks)
    g_data = pre[1] / sigma**2 + (0.0 if H_fixed is None else structure.matvec(2, th0))
    g_pen = structure.matvec(1, th0)

    def f(lam):
        out = structure.solve([1.0 / sigma**2, lam, 1.0], -(g_data + lam * g_pen))
        if out is None:
            return -np.inf
        logdet, step = out
        th = th0 + step
        rr2 = pre[2] + 2 * step @ pre[1] + structure.quad(0, step)
        pen = lam * structure.quad(1, th) + (0.0 if H_fixed is None else structure.quad(2, th))
        return float(-0.5 * (rr2 / sigma**2 + pen) + 0.5 * rank * np.log(lam) - 0.5 * logdet)

    return f


def choose_smoothing(J, r, theta, H, sigma, lam=None, H_fixed=None, *, with_evidence=False):
    """Return the smoothing weight of largest :func:`log_evidence` (a 1-D search).

    A grid of half-decades about ``lam`` (or, without one, of decades over the whole
    range), re-centred while the best is at an edge, then a parabola through the best
    three points. The weight stays within ``10^-10`` and ``10^7`` times the ratio of the
    data's information on the coefficients to the penalty's (a bound is returned
    where the evidence keeps rising towards it: the data want no more, or no less,
    smoothing).

    Parameters
    ----------
    J, r, theta, H, sigma
        As for :func:`log_evidence` (``J`` may be :func:`normal_equations`' tuple).
    lam : float, optional
        The previous weight.
    H_fixed : numpy.ndarray, optional
        A further prior precision held fixed (:func:`log_evidence`).
    with_evidence : bool, default False
        Also return the log evidence at the weight returned.

    Returns
    -------
    float, or (float, float) with ``with_evidence``
    """
    lam, curve = _choose_weight(J, r, theta, H, sigma, lam, H_fixed)
    return (lam, curve(lam)) if with_evidence else lam


def _weight_scale(JtJ, H, sigma):
    """Return the data's information on the penalised coefficients over the penalty's (traces).

    The search's bounds are :data:`WEIGHT_BOUNDS` decades about it.
    """
    pen = np.diag(H) > 0
    return float(np.diag(JtJ)[pen].sum() / sigma**2 / np.trace(H))


def normal_equations(J, r):
    """Return ``(J'J, J'r, r'r)``: what :func:`log_evidence` and :func:`choose_smoothing` take.

    Computed once where several weights are chosen on one Jacobian.

    Parameters
    ----------
    J : numpy.ndarray
        ``(n, P)`` Jacobian of the weighted residuals.
    r : numpy.ndarray
        ``(n,)`` weighted residuals.

    Returns
    -------
    tuple
    """
    G = gram(J)
    G.flags.writeable = False  # searches over weights reuse its arrowhead parts (by identity)
    return G, J.T @ r, float(r @ r)


def _choose_weight(J, r, theta, H, sigma, lam, H_fixed):
    """:func:`choose_smoothing`'s search: the weight and the search's :func:`evidence_curve`."""
    rank = _penalty_rank(H)
    pre = J if isinstance(J, tuple) else normal_equations(J, r)
    blocks = null_blocks(H, H_fixed)
    curve = evidence_curve(pre, theta, H, sigma, rank, H_fixed, blocks)

    def f(x):
        return curve(10.0 ** x)

    lo, hi = np.log10(_weight_scale(pre[0], H, sigma)) + np.array(WEIGHT_BOUNDS)
    x = (np.linspace(lo, hi, 18) if lam is None else  # decades; else half-decades about lam
         np.clip(np.log10(lam), lo + 2.0, hi - 2.0) + np.arange(-2.0, 2.01, 0.5))
    y = None  # every point of the grid: the evidence over a weight can have two peaks
    for _ in range(40):
        if y is None:
            y = np.array([f(v) for v in x])
        i = int(np.argmax(y))
        if 0 < i < x.size - 1 or x[i] <= lo + 1e-9 or x[i] >= hi - 1e-9:
            break
        step = x[1] - x[0]  # re-centred on the best, the grid kept within the bounds
        x = np.clip(x[i], lo + 4 * step, hi - 4 * step) + step * np.arange(-4, 5)
        y = None
    if x[i] <= lo + 1e-9 or x[i] >= hi - 1e-9:  # the evidence is flat or monotone: a bound
        return float(10.0 ** x[i]), curve
    i = int(np.clip(i, 1, x.size - 2))
    step = x[1] - x[0]
    if step > 0.3:  # refine; the best point and its two neighbours are known
        known = {0: y[i - 1], 4: y[i], 8: y[i + 1]}
        x = x[i] + np.arange(-1.0, 1.01, 0.25) * step
        y = np.array([known[j] if j in known else f(v) for j, v in enumerate(x)])
        i = int(np.clip(np.argmax(y), 1, x.size - 2))
    y0, y1, y2 = y[i - 1], y[i], y[i + 1]
    h = x[1] - x[0]
    den = y0 - 2 * y1 + y2
    ok = np.isfinite([y0, y1, y2]).all() and den < 0
    best = x[i] + (0.5 * h * (y0 - y2) / den if ok else 0.0)
    return float(10.0 ** np.clip(best, x[i] - h, x[i] + h)), curve


def _plus(*Ms):
    """Sum of the matrices given (None left out); None where every one is None."""
    Ms = [M for M in Ms if M is not None]
    if not Ms:
        return None
    out = Ms[0]
    for M in Ms[1:]:
        out = out + M
    return out


class _PriorTravelTimeEM(TravelTimeEM):
    """:class:`TravelTimeEM` with a Gaussian prior on the free positions (``speed_intervals``).

    The M-step holds ``sigma`` at its current value and minimises ``||r||^2 / sigma^2 +
    phi' P phi`` (``P`` the prior precision of the first ``phi``): the prior enters
    ``least_squares`` as rows ``sigma R phi`` (``P = R'R``), and ``sigma`` is then the
    true replies' scatter alone.
    """

    def __init__(self, t, resid, jac, x_scale, windows, index, outliers, prior):
        super().__init__(t, resid, jac, x_scale, windows, index, outliers)
        vals, vecs = np.linalg.eigh(prior)
        self.root = (vecs * np.sqrt(np.clip(vals, 0.0, None))).T  # R'R = P

    def solve(self, fit, p):
        """Return the parameters of least ``||r||^2 / sigma^2 + phi' P phi`` from ``fit``'s."""
        R, nf = fit.sigma * self.root, self.root.shape[0]

        def resid(th):
            return np.concatenate([self.resid(th, p), R @ th[:nf]])

        def jac(th):
            J = self.jac(th, p)
            return np.vstack([J, np.hstack([R, np.zeros((nf, J.shape[1] - nf))])])

        return least_squares(resid, fit.theta, jac=jac, x_scale=self.x_scale).x


class _SmoothArrayEM(TravelTimeEM):
    """:class:`TravelTimeEM` with a roughness penalty on the speed (docs/gnssa.md)."""

    def __init__(self, t, resid, jac, x_scale, windows, index, outliers, H, coef0, Hg=None,
                 prior=None):
        super().__init__(t, resid, jac, x_scale, windows, index, outliers)
        self.H, self.Hg, self.prior = H, Hg, prior
        self.n_steps = 0
        self.gn = {}  # the last M-step's Gauss-Newton: converged

    def run(self, theta, *, sigma_min, **kw):
        """Return the EM's run from ``theta`` (as :meth:`TravelTimeEM.run`)."""
        from ..mixture.em import run_em

        r = self.resid(theta)
        sigma = max(1.4826 * float(np.median(np.abs(r - np.median(r)))), sigma_min)
        return run_em(self, _SmoothFit(theta, r, sigma, np.full(len(self.windows), 0.9), None),
                      **kw)

    def m_step(self, fit, p):
        """Return the new parameters given the probabilities ``p`` of true shots."""
        J, r0 = self.jac(fit.theta, p), self.resid(fit.theta, p)
        pre = normal_equations(J, r0)  # the weights are chosen on it; the first step uses it
        lam_g = fit.lam_g
        self.n_steps += 1
        if self.Hg is not None and self.n_steps > FREEZE_AFTER:  # two weights: held, so
            lam = fit.lam  # that choosing them in turn cannot alternate for ever
        elif self.Hg is None:
            lam = choose_smoothing(pre, r0, fit.theta, self.H, fit.sigma, fit.lam, self.prior)
        else:
            if lam_g is None:  # start the gradients stiff: they enter as they are supported
                lam = fit.lam
                if lam is None:  # the speed's first weight with the gradients held stiff (free,
                    # they make the normal matrix singular to round-off on long tracks)
                    scale = _weight_scale(pre[0], self.Hg, fit.sigma)
                    if not 0.0 < scale < np.inf:  # no data on the gradients: the speed's
                        scale = _weight_scale(pre[0], self.H, fit.sigma)
                    stiff = 10.0 ** WEIGHT_BOUNDS[1] * scale
                    lam = choose_smoothing(pre, r0, fit.theta, self.H, fit.sigma, None,
                                           _plus(stiff * self.Hg, self.prior))
                lam_g = 1e6 * lam
            lam = choose_smoothing(pre, r0, fit.theta, self.H, fit.sigma, fit.lam,
                                   _plus(lam_g * self.Hg, self.prior))
            lam_g = choose_smoothing(pre, r0, fit.theta, self.Hg, fit.sigma, lam_g,
                                     _plus(lam * self.H, self.prior))
        Q = _plus(lam * self.H if self.Hg is None else lam * self.H + lam_g * self.Hg,
                  self.prior)
        theta = penalised_gauss_newton(lambda th: self.resid(th, p),
                                       lambda th: self.jac(th, p), fit.theta,
                                       fit.sigma**2 * Q, start=(r0, J, pre), report=self.gn)
        r = self.resid(theta)
        sigma = float(np.sqrt(np.sum(p * r * r) / p.sum()))
        k = len(self.rows)
        if self.index is None:
            shares = np.array([np.clip(p.mean(), 1e-6, 1 - 1e-6)])
        else:
            shares = np.clip(np.bincount(self.index, p, k) / np.bincount(self.index, minlength=k),
                             1e-6, 1 - 1e-6)
        return _SmoothFit(theta, r, sigma, shares, lam, lam_g)

    def change(self, old, new, gain):
        """Return the change of ``sigma`` (s); infinite while a weight still moves."""
        if old.lam is None or abs(np.log(new.lam / old.lam)) > 0.01:
            return np.inf
        if new.lam_g is not None and (old.lam_g is None
                                      or abs(np.log(new.lam_g / old.lam_g)) > 0.01):
            return np.inf
        return abs(new.sigma - old.sigma)


#: Gauss-Newton steps before the geodesic acceleration is added (a well-posed M-step is done
#: in one or two; a curved valley takes hundreds without it)
ACCELERATE_AFTER = 4
#: the damping falls tenfold after each success down to this (relative to the scaled unit
#: diagonal), then to 0; a failure raises it to at least 1e-6
MU_FLOOR = 1e-12


def penalised_gauss_newton(resid, jac, theta, Q, *, max_steps=50, rtol=1e-12, start=None,
                           normal=None, report=None):
    """Minimise ``||resid(theta)||^2 + theta' Q theta`` by damped Gauss-Newton steps.

    Each step solves ``(J'J + Q + mu D) d = -(J'r + Q theta)`` (``D`` the diagonal of
    ``J'J + Q``) by Cholesky, ``mu`` raised tenfold until the objective decreases and
    lowered after a success: the normal equations of a few hundred parameters, not a
    factorisation of the tall Jacobian. ``mu`` falls tenfold after each success down to
    :data:`MU_FLOOR`, then to 0, so that it settles between the steps too long and too short
    for a valley whose scaled normal matrix has a condition number near 1e14 (snapped to 0
    from 1e-6, it alternated between a rejected 72 m step and an accepted 5 mm one on a
    ship holding station for 18 minutes). After :data:`ACCELERATE_AFTER` steps, each step
    adds the **geodesic acceleration** (Transtrum & Sethna 2012): the residuals' second
    directional derivative along ``d`` from one more evaluation, ``a`` solving the same
    system with ``J' r_dd``, the step ``d + a / 2`` where ``2 |a| <= 0.75 |d|`` (norms
    scaled by ``D``). Positions barely determined by a short track lie on a curved valley
    (ranges from a nearly straight track leave a rotation about it): there plain damped
    steps crept along it (a 0.3-h, three-transponder campaign took 16 s, 50 steps in each
    of 33 M-steps).

    Parameters
    ----------
    resid, jac : callable
        Residuals ``(n,)`` and their Jacobian ``(n, P)`` at ``theta``.
    theta : numpy.ndarray
        Start.
    Q : numpy.ndarray
        ``(P, P)`` penalty (positive semi-definite).
    max_steps : int, default 50
    rtol : float, default 1e-12
        Stop when a step lowers the objective by less than this fraction.
    start : tuple, optional
        ``(r, J, (J'J, J'r, r'r))`` at ``theta`` (:func:`normal_equations`), where the
        caller has them already: the first step then neither evaluates nor multiplies them.
    normal : callable, optional
        ``normal(J, r)``, default :func:`normal_equations` (a caller's may keep the last).
    report : dict, optional
        Its ``converged`` set: False where ``max_steps`` ran out while steps still lowered
        the objective by more than ``rtol``.

    Returns
    -------
    numpy.ndarray

    References
    ----------
    Transtrum, M. K. & Sethna, J. P. (2012). Improvements to the Levenberg-Marquardt
    algorithm for nonlinear least-squares minimization. arXiv:1201.5885.

    Examples
    --------
    >>> import numpy as np
    >>> th = penalised_gauss_newton(lambda t: t - 1.0, lambda t: np.eye(2), np.zeros(2),
    ...                             np.diag([0.0, 1.0]))
    >>> np.round(th, 6).tolist()
    [1.0, 0.5]
    """
    blocks = null_blocks(Q)

    def penalty(t):  # without the round-off of coefficients near 1 (null_shifted)
        tc = null_shifted(t, Q, blocks)
        return tc @ Q @ tc

    th = np.asarray(theta, float).copy()
    Q = np.array(Q, float)  # owned and read-only: each step's arrowhead reuses its parts
    Q.flags.writeable = False
    r, J, pre = (resid(th), None, None) if start is None else start
    f = r @ r + penalty(th)
    mu = 0.0
    report = {} if report is None else report
    report["converged"] = True
    for n_step in range(max_steps):
        if pre is None:
            J = jac(th)
            pre = (normal or normal_equations)(J, r)
        head = arrowhead([pre[0], Q])  # None: a dense factor
        A = pre[0] + Q if head is None else None  # the arrowhead reads its parts itself
        g = pre[1] + Q @ null_shifted(th, Q, blocks)
        d = np.diag(pre[0]) + np.diag(Q)
        pre = None
        d[d <= 0] = 1.0
        s = 1.0 / np.sqrt(d)
        for _ in range(12):
            solve = _damped_solver(A, d, s, mu, head)
            if solve is None:
                mu = max(10.0 * mu, 1e-8)
                continue
            step = -solve(g)
            if -(g @ step) <= rtol * f:  # the expected decrease is round-off: converged
                return th
            if n_step >= ACCELERATE_AFTER:  # None: the acceleration too large to trust
                step = _accelerated(step, th, r, J, resid, solve, s)
            if step is not None:
                new = th + step
                r_new = resid(new)
                f_new = r_new @ r_new + penalty(new)
                if f_new <= f:
                    break
            mu = max(10.0 * mu, 1e-6)
        else:
            return th
        gain = f - f_new
        th, r, f, mu = new, r_new, f_new, mu / 10.0 if mu > MU_FLOOR else 0.0
        if gain <= rtol * f:
            break
    else:
        report["converged"] = False
    return th


def _damped_solver(A, d, s, mu, head=None):
    """Return ``g -> (A + mu D)^-1 g`` (``D = diag(d)``, ``s = d^-1/2``), or None if not positive.

    Factored scaled to a unit diagonal: by the arrowhead ``head`` of ``A``'s parts where
    there is one (:meth:`.arrowhead.Arrowhead.factor`; ``A`` is then not needed, None),
    densely otherwise.
    """
    if head is not None:
        factor = head.factor([1.0, 1.0], damping=mu)
        return None if factor is None else factor.solve
    try:
        c = cho_factor((A + mu * np.diag(d)) * s[:, None] * s[None, :])
    except np.linalg.LinAlgError:
        return None
    return lambda g: s * cho_solve(c, s * g)


def _accelerated(v, th, r, J, resid, solve, s, h=0.1, alpha=0.75):
    """Return the step ``v + a / 2`` with the geodesic acceleration ``a``, or None.

    ``r_vv`` by a finite difference along ``v`` (one more evaluation of the residuals);
    ``a`` solves the damped normal equations (``solve``, :func:`_damped_solver`) with
    ``J' r_vv`` (the penalty is quadratic: no second derivative). None where
    ``2 |a| / |v| > alpha`` in the scaled coordinates (``s``), the acceleration too large for
    the step to be trusted (Transtrum & Sethna 2012, section 4).
    """
    r_h = resid(th + h * v)
    rvv = (2.0 / h) * ((r_h - r) / h - J @ v)
    if not np.all(np.isfinite(rvv)):
        return None
    a = -solve(J.T @ rvv)
    if 2.0 * np.linalg.norm(a / s) > alpha * np.linalg.norm(v / s):
        return None
    return v + 0.5 * a


#: The refit under correlated noise of an unpenalised speed with a prior on the positions
#: repeats its solve until ``sigma``, at which the prior is weighed, moves by less than this
#: fraction (:func:`_correlated_refit`).
SIGMA_SETTLED = 1e-3


def _correlated_refit(correlation, resid, jac, phi, p, sub, index, H, Hg, lam, lam_g, sigma,
                      prior=None):
    """Refit the EM's true replies under GARPOS's correlated noise (:mod:`.noise`).

    Returns ``(refit, record)``: ``refit`` None for independent noise, else ``(phi, sigma,
    lam, lam_g, J, r)`` with ``J`` and ``r`` whitened (``L^-1``, ``E = L L'``) and the
    weights chosen again on them; ``record`` for ``model["noise"]`` (None where not asked),
    with ``refit_rounds``, ``refit_converged`` and ``refit_gauss_newton_converged``. The
    rounds (weights chosen, then one penalised Gauss-Newton solve) go on until neither weight
    moves by more than 1 %, at most :data:`REFIT_ROUNDS` (unpenalised, until ``sigma`` settles
    to :data:`SIGMA_SETTLED` where there is a ``prior``); a :class:`LocateWarning` where they
    stop short, and where the last round's Gauss-Newton ran out of steps. ``prior``: the
    positions' prior precision among all the parameters (None: none).
    """
    spec = correlation_spec(correlation)
    if spec is None:
        return None, None
    keep = np.flatnonzero(p > 0.5)
    time = sub["time"].to_numpy(float)[keep]
    r0 = resid(phi)[keep]
    table = None
    if spec == "auto":
        if not np.all(np.isfinite(r0)):  # not expected: invalid rays get the chord's time
            return None, _noise_record(0.0, None, None, None, keep.size)
        (tau, share, white), table = choose_correlation(
            time, index[keep], r0,
            evidence=_noise_evidence(jac(phi)[keep], r0, phi, H, Hg, lam, lam_g, prior))
    else:
        tau, share, white = spec
    if tau <= 0.0:
        return None, _noise_record(0.0, None, None, table, keep.size)
    try:
        w = Whitener(time, index[keep], tau, share, white)
    except np.linalg.LinAlgError:
        raise InputError(f"correlation ({tau:g} s, {share:g}, white {white:g}): the replies' "
                         "covariance is singular (two replies at one time fully correlated: "
                         "one transponder heard twice, or a share of 1); give a white share "
                         "above 0") from None
    except ValueError as exc:
        raise InputError(f"correlation ({tau:g} s, {share:g}, white {white:g}): {exc}; give "
                         "a shorter time") from None

    def rw(th):
        return w.whiten(resid(th)[keep])

    last = {}

    def jw(th):  # the last point's: Gauss-Newton ends where the next round starts
        key = np.asarray(th, float).tobytes()
        if last.get("key") != key:
            last.update(key=key, J=w.whiten(jac(th)[keep]))
        return last["J"]

    def normal(J, r):  # the last: the next round starts where Gauss-Newton ended
        if not (last.get("J_n") is J and np.array_equal(last.get("r_n"), r)):
            last.update(J_n=J, r_n=r, pre=normal_equations(J, r))
        return last["pre"]

    r = rw(phi)
    # unpenalised and flat, one solve; a prior weighs in at sigma^2, so again until it settles
    rounds, settled, gn = 0, H is None and prior is None, {}
    while rounds == 0 or (not settled and rounds < REFIT_ROUNDS):
        rounds += 1
        J = jw(phi)
        pre = normal(J, r)  # the weights are chosen on it; the first step uses it
        if H is not None:
            before = (lam, lam_g)
            lam = choose_smoothing(pre, r, phi, H, sigma, lam,
                                   _plus(None if Hg is None else lam_g * Hg, prior))
            Q = lam * H
            if Hg is not None:
                lam_g = choose_smoothing(pre, r, phi, Hg, sigma, lam_g, _plus(Q, prior))
                Q = Q + lam_g * Hg
            Q = _plus(Q, prior)
            settled = rounds > 1 and all(  # the EM's weights come from independent replies
                a is None or abs(np.log(b / a)) <= 0.01 for a, b in zip(before, (lam, lam_g),
                                                                       strict=True))
        else:
            Q = np.zeros((phi.size, phi.size)) if prior is None else prior
        phi = penalised_gauss_newton(rw, jw, phi, sigma**2 * Q, start=(r, J, pre),
                                     normal=normal, report=gn)
        r = rw(phi)
        sigma, before = float(np.sqrt(r @ r / r.size)), sigma
        if H is None and prior is not None:
            settled = abs(np.log(sigma / before)) <= SIGMA_SETTLED
    record = _noise_record(tau, share, white, table, keep.size)
    record.update(refit_rounds=rounds, refit_converged=bool(settled),
                  refit_gauss_newton_converged=bool(gn["converged"]))
    if not settled:
        what = ("the smoothing weights of the refit under correlated noise still moved by "
                "more than 1 %" if H is not None else "the refit under correlated noise's "
                f"sigma (the positions' prior's weight) still moved by more than {SIGMA_SETTLED:g}")
        warnings.warn(f"array: {what} after {rounds} round{'s' * (rounds != 1)}", LocateWarning,
                      stacklevel=5)  # past locate_array's two decorators
    if not gn["converged"]:
        warnings.warn("array: the last Gauss-Newton solve of the refit under correlated noise "
                      "ran out of steps still lowering the misfit: the positions may not be at "
                      "the optimum", LocateWarning, stacklevel=5)
    return (phi, sigma, lam, lam_g, jw(phi), r), record


#: The shortest correlation time (s) taken (0 is independent replies): 5e-324 s gave NumPy's
#: "array must not contain infs or NaNs" from the whitener.
MIN_CORRELATION_S = 1.0


def correlation_spec(correlation):
    """Return ``correlation`` checked: None (independent), ``"auto"`` or ``(tau, share, white)``.

    Parameters
    ----------
    correlation : None, str or sequence of float
        None or ``"off"``; ``"auto"``; ``(mu_t[, mu_mt[, white]])`` with ``mu_t >= 0`` (s),
        ``mu_mt`` in [0, 1] (default 0.5) and ``white`` in [0, 1) (default 0).

    Returns
    -------
    None, str or tuple of float

    Raises
    ------
    InputError
        For anything else, naming what was expected.

    Examples
    --------
    >>> correlation_spec((60,)), correlation_spec("off")
    ((60.0, 0.5, 0.0), None)
    """
    if correlation is None or (isinstance(correlation, str) and correlation in ("off", "auto")):
        return None if correlation in (None, "off") else "auto"
    what = ("correlation: expected 'auto', 'off', None or (mu_t[, mu_mt[, white]]) with mu_t "
            f"0 or at least {MIN_CORRELATION_S:g} s, mu_mt in [0, 1] and white in [0, 1), got "
            f"{correlation!r}")
    try:
        vals = [float(v) for v in correlation] if not isinstance(correlation, str) else []
    except (TypeError, ValueError):
        raise InputError(what) from None
    if not 1 <= len(vals) <= 3:
        raise InputError(what)
    tau, share, white = (vals + [0.5, 0.0][len(vals) - 1:])[:3]
    if not (np.isfinite(tau) and (tau == 0 or tau >= MIN_CORRELATION_S) and 0 <= share <= 1
            and 0 <= white < 1):
        raise InputError(what)
    return tau, share, white


def _noise_evidence(J0, r0, phi, H, Hg, lam, lam_g, prior=None):
    """Return ``evidence(whitener)``: the linearised log marginal likelihood under ``E``.

    The fit's Jacobian ``J0`` and residuals ``r0`` (the true replies) whitened, ``sigma``
    at its estimate, the speed's weight chosen again (the gradients' held): GARPOS's
    -ABIC / 2 with ``-n log sigma - log|E| / 2`` kept, as they differ between ``E``. The
    positions' ``prior`` (None: flat) enters as a fixed precision.
    """
    fixed = _plus(None if Hg is None else lam_g * Hg, prior)

    def evidence(w):
        J, r = w.whiten(J0), w.whiten(r0)
        sigma = float(np.sqrt(r @ r / r.size))
        if H is None:  # unpenalised: a flat prior, the same constant for every E
            ll = log_evidence(J, r, phi, np.zeros((phi.size, phi.size)), sigma, 1.0, 0,
                              prior)[0]
        else:
            ll = choose_smoothing(J, r, phi, H, sigma, lam, fixed, with_evidence=True)[1]
        return ll - r.size * np.log(sigma) - 0.5 * w.logdet

    return evidence


def _noise_record(tau, share, white, table, n):
    """``model["noise"]``: the correlation used and, where chosen, the likelihood table."""
    return {"model": "independent" if tau <= 0 else
            "white + (1 - white) GARPOS's exp(-|dt| / mu_t) (mu_mt + (1 - mu_mt) [same "
            "transponder]), tapered",
            "correlation_s": float(tau), "share": share, "white": white, "n_replies": int(n),
            "criterion": None if table is None else
            "for each correlation time the share and white share of largest residual "
            "likelihood; between times the largest marginal likelihood of the linearised "
            "model (GARPOS's ABIC)",
            "at_grid_edge": bool(table is not None and tau > 0 and (
                tau >= max(x["correlation_s"] for x in table if x["stage"] == "scan")
                or white >= WHITES[-1])),
            "grid": table}


#: Decades about the gradients' best weight over which the intervals average (step 0.5).
GRADIENT_WEIGHT_GRID = np.arange(-2.0, 2.0001, 0.5)
#: Most total share of the intervals' average that the grid weights left out may hold: the
#: smallest shares are left out (their covariances not computed) while their sum stays below.
GRID_SHARE = 1e-4


def _penalty_rank(H):
    """Rank of a roughness penalty: numpy's numerical rank of each of its blocks.

    A fixed threshold of 1e-10 of the largest eigenvalue miscounted from about 600 knots (a
    second-derivative penalty's smallest nonzero eigenvalue falls as the fourth power of the
    knot count), and one threshold for the whole matrix miscounts blocks weighted apart
    (speed and gradients); each block's singular values above ``N eps`` of its largest count
    ``k - 2`` per block to at least 2,000 knots (``tests/survey_in/test_gnssa_smooth.py``).
    """
    H = np.asarray(H, float)
    return sum(_block_rank(np.ascontiguousarray(H[np.ix_(block, block)]).tobytes(), block.size)
               for block in _blocks(H != 0))


@functools.lru_cache(maxsize=8)
def _block_rank(values, size):
    """Return numpy's numerical rank of the symmetric ``(size, size)`` block of ``values``.

    Cached: a fit asks for the same few penalties' blocks at every weight it tries.
    """
    block = np.frombuffer(values, float).reshape(size, size)
    return int(np.linalg.matrix_rank(block, hermitian=True))


def _scaled_inverse(A, factor=None):
    """Inverse of a symmetric positive (semi-)definite ``A`` after scaling it to a unit diagonal.

    Positions (m), speed coefficients (known to 1e-9) and gradient terms put the condition
    number of ``A`` itself near 1e17, where ``numpy.linalg.inv`` returned an asymmetric
    matrix with negative variances; scaled, Cholesky (else eigenvalues floored at 1e-12 of
    the largest) is accurate. ``factor``: :func:`scipy.linalg.cho_factor`'s of the scaled
    ``A``, where the caller has it (:func:`_log_evidence`).
    """
    d = np.diag(A).copy()
    d[d <= 0] = 1.0
    s = 1.0 / np.sqrt(d)
    try:
        if factor is None:
            factor = cho_factor(A * s[:, None] * s[None, :])
        c, lower = factor
        inv, info = dpotri(c, lower=lower)  # from the factor: a third of cho_solve's work
        if info:
            raise np.linalg.LinAlgError(f"dpotri: info {info}")
        inv = np.tril(inv) + np.tril(inv, -1).T if lower else np.triu(inv) + np.triu(inv, 1).T
    except np.linalg.LinAlgError:
        B = A * s[:, None] * s[None, :]
        vals, vecs = np.linalg.eigh(0.5 * (B + B.T))
        vals = np.maximum(vals, 1e-12 * vals.max())
        inv = (vecs / vals) @ vecs.T
    inv = inv * s[:, None] * s[None, :]
    return 0.5 * (inv + inv.T)


def _grid_average(J, r, theta, H, sigma, lam, H_fixed, meat, n_clusters, grid, mid_row=None,
                  free=None):
    """Posterior modes and covariances over weights ``lam 10^x``, and their average.

    ``J`` is the Jacobian of the weighted residuals ``r``, or :func:`normal_equations`'
    ``(J'J, J'r, r'r)`` of them, formed once by a caller that averages over two grids.
    ``mid_row``: the row at ``x = 0`` where the caller has it (the other grid's middle:
    the same weights, ``lam H + H_fixed`` summed in the other order, the same numbers).

    The evidence is evaluated at every weight of the grid; the modes and covariances only
    at the weights of the average (:func:`_grid_used`: the smallest shares, together below
    :data:`GRID_SHARE`, are left out) and at the grid's middle (``x`` nearest 0), whose row
    the caller reads: a sharp evidence leaves most of the grid with shares of 1e-6 and
    less, whose dense inverses changed the intervals by less than the shares.

    A row whose covariance of the unpenalised parameters (the positions) is not positive
    semi-definite to :data:`GRID_ACCURACY` of its largest eigenvalue, or that has a
    variance not above 0, is left out of the average (its share set to 0) and listed in
    ``dropped``: at weights far stiffer than the data ask for, the penalty's null space is
    near-singular after scaling and the row's numbers are round-off (on a 30-minute
    campaign of a ship holding station, where the evidence was flat, the stiffest row gave
    the array centre a negative variance). Where every row is so, all are kept (the
    gradients on a 2-hour circle, where the deep gradient trades with the positions: the
    intervals are then wide, and finite). ``free``: the mask of the positions, where the
    caller has it (default: the parameters neither penalty touches; a prior on the positions
    is in ``H_fixed``).

    Returns
    -------
    w, mean_cov, spread, rows, ll, dropped
        ``rows[k]`` is ``(x, None, step, C, Ainv, edf)``, or None where not computed;
        ``mean_cov`` and ``spread`` are NaN where no weight has a finite evidence;
        ``dropped`` the indices of the rows left out as inaccurate.
    """
    rank = _penalty_rank(H)
    blocks = null_blocks(H, H_fixed)
    pre = J if isinstance(J, tuple) else normal_equations(J, r)
    JtJ = pre[0]
    curve = evidence_curve(pre, theta, H, sigma, rank, H_fixed, blocks)
    ll = np.array([curve(lam * 10.0 ** x) for x in grid])
    ll[np.isnan(ll)] = -np.inf  # a failed evaluation counts as no support, not as all unknown
    finite = np.isfinite(ll)
    w = np.exp(ll - ll[finite].max()) if finite.any() else np.full(ll.size, np.nan)
    w /= w.sum()
    mid = int(np.argmin(np.abs(grid)))
    used = _grid_used(w)
    if free is None:
        free = (np.diag(H) == 0 if H_fixed is None else
                (np.diag(H) == 0) & (np.diag(H_fixed) == 0))

    def row(x):
        lg = lam * 10.0 ** x
        _, step, A, factor = _log_evidence(pre, r, theta, H, sigma, lg, rank, H_fixed, blocks)
        Ainv = _scaled_inverse(A, factor)
        prior = lg * H if H_fixed is None else lg * H + H_fixed
        C, edf = _sandwich(Ainv, JtJ, meat, n_clusters, sigma, prior)
        return (x, None, step, C, Ainv, edf)

    rows = [None] * len(grid)
    if mid_row is not None and grid[mid] == 0.0 == mid_row[0]:
        rows[mid] = (grid[mid], *mid_row[1:])
    todo = [k for k in range(len(grid)) if (used[k] or k == mid) and rows[k] is None]
    for k, out in zip(todo, thread_map(row, [grid[k] for k in todo]), strict=True):
        rows[k] = out  # each a dense factor, inverse and products: the rows on the cores
    dropped = [k for k in range(len(grid)) if used[k] and not _accurate(rows[k][3], free)]
    if dropped and len(dropped) < used.sum():  # every row inaccurate: all kept, as before
        used[dropped] = False
        w[dropped] = 0.0
        w /= w.sum()
    else:
        dropped = []
    used = np.flatnonzero(used)
    if not used.size:
        nan = np.full((theta.size, theta.size), np.nan)
        return w, nan, nan.copy(), rows, ll, dropped
    wu = w[used] / w[used].sum()
    steps = np.array([rows[k][2] for k in used])
    dev = steps - wu @ steps
    mean_cov = sum(wi * rows[k][3] for wi, k in zip(wu, used, strict=True))
    return w, mean_cov, (dev.T * wu) @ dev, rows, ll, dropped


#: Relative accuracy a grid row's covariance of the positions must have (its most negative
#: eigenvalue against its largest) to enter the intervals' average (:func:`_grid_average`).
GRID_ACCURACY = 1e-6


def _accurate(C, free):
    """Whether a covariance is usable: finite variances above 0, the ``free`` block PSD.

    The ``free`` block (the unpenalised parameters) to :data:`GRID_ACCURACY` of its largest
    eigenvalue; the penalised coefficients are checked by their variances only (an
    eigendecomposition of the whole matrix would cost as much as the row itself).
    """
    d = np.diag(C)
    if not (np.all(np.isfinite(d)) and np.all(d > 0)):
        return False
    if not free.any():
        return True
    block = C[np.ix_(free, free)]
    if not np.all(np.isfinite(block)):
        return False
    vals = np.linalg.eigvalsh(block)
    return bool(vals[0] >= -GRID_ACCURACY * vals[-1])


def _grid_used(w):
    """Return which grid weights the intervals' average uses.

    Not the smallest shares ``w`` whose sum stays below :data:`GRID_SHARE`, nor a NaN one.

    Parameters
    ----------
    w : numpy.ndarray
        The weights' shares of the average (summing to 1, or all NaN).

    Returns
    -------
    numpy.ndarray of bool
    """
    ok = np.isfinite(w)
    order = np.argsort(np.where(ok, w, np.inf), kind="stable")
    below = np.cumsum(np.where(ok, w, 0.0)[order]) < GRID_SHARE
    used = ok.copy()
    used[order[below]] = False
    return used


def _smooth_covariance(J, r, theta, H, sigma, lam, clusters, Hg=None, lam_g=None, prior=None,
                       n_pos=None):
    """Covariance of a smooth-speed fit, averaged over the smoothing weights (docs/gnssa.md).

    Returns ``cov``, the model-based ``cov_model`` at ``lam`` and the ``smoothing`` record.
    ``prior``: the positions' prior precision (the first ``n_pos`` parameters), a fixed
    part of every row's prior.
    """
    S = _cluster_sums(clusters, J * r[:, None])
    n_clusters = S.shape[0]
    meat = S.T @ S / sigma**4
    H_fixed = _plus(None if Hg is None else lam_g * Hg, prior)
    free = None if prior is None else np.arange(theta.size) < n_pos
    pre = normal_equations(J, r)  # both grids' (and the positions') normal equations
    w, cov, spread, rows, ll, dropped = _grid_average(pre, r, theta, H, sigma, lam, H_fixed,
                                                      meat, n_clusters, WEIGHT_GRID, free=free)
    mid = int(np.argmin(np.abs(WEIGHT_GRID)))
    cov = cov + spread
    grad_grid = None
    if Hg is not None:
        v, cov_g, spread_g, rows_g, ll_g, dropped_g = _grid_average(
            pre, r, theta, Hg, sigma, lam_g, _plus(lam * H, prior), meat, n_clusters,
            GRADIENT_WEIGHT_GRID, rows[mid], free)
        cov = cov + cov_g - rows[mid][3] + spread_g
        grad_grid = {"log10_weight": [float(np.log10(lam_g) + x) for x in GRADIENT_WEIGHT_GRID],
                     "log_evidence": _relative(ll_g),
                     "posterior_weight": [float(x) for x in v],
                     "edge": _grid_edge(ll_g),
                     "inaccurate": [float(np.log10(lam_g) + GRADIENT_WEIGHT_GRID[k])
                                    for k in dropped_g]}
    record = {
        "penalty": "integral over time (hours) of the squared second derivative of the speed "
                   "coefficient (profile scale, or m/s for straight rays)",
        "weight": float(lam), "log10_weight": float(np.log10(lam)),
        "criterion": "maximum marginal likelihood (linearised at the solution, at the EM's "
                     "class probabilities; equivalently minimum ABIC = -2 log evidence)",
        "effective_dof": rows[mid][5], "penalty_rank": _penalty_rank(H),
        "intervals": "averaged over the smoothing weights of the grid, each weighted by its "
                     "marginal likelihood (flat prior on log weight), with the spread of the "
                     "solutions between weights added"
                     + ("; the same over the gradients' weight (gradient_grid), the two "
                        "weights' effects taken as additive" if Hg is not None else ""),
        "grid": {"log10_weight": [float(np.log10(lam) + x) for x in WEIGHT_GRID],
                 "log_evidence": _relative(ll),
                 "posterior_weight": [float(v) for v in w],
                 "edge": _grid_edge(ll),
                 "inaccurate": [float(np.log10(lam) + WEIGHT_GRID[k]) for k in dropped]}}
    if grad_grid is not None:
        record["gradient_grid"] = grad_grid
    return cov, rows[mid][4], record


def _relative(ll):
    """Log evidences relative to their largest; all None where none is finite."""
    top = np.max(ll) if len(ll) else -np.inf
    return [float(v - top) for v in ll] if np.isfinite(top) else [None] * len(ll)


def _grid_edge(ll, tol=0.1, flat=1.0):
    """Where a weight's evidence grid is largest: ``"stiff"``, ``"rough"``, ``"flat"`` or None.

    ``"flat"``: the finite values span less than ``flat`` nats (the data do not determine
    the weight over the grid; the intervals average over it). ``"stiff"``: the value at the
    grid's top (two decades above the weight) is within ``tol`` nats of the largest, so the
    data ask for no more roughness and the weight is at or near the search's upper limit
    (:func:`choose_smoothing`); ``"rough"``: the same at the bottom. None: a peak inside.
    """
    ll = np.asarray(ll, float)
    ok = np.isfinite(ll)
    if not ok.any():
        return None
    top = ll[ok].max()
    if top - ll[ok].min() < flat:
        return "flat"
    if ok[-1] and ll[-1] >= top - tol:
        return "stiff"
    if ok[0] and ll[0] >= top - tol:
        return "rough"
    return None


def _cluster_sums(clusters, X):
    """Rows of ``X`` summed within each cluster, clusters in sorted order of their labels.

    The rows of a cluster are added one after the other in their order, as ``np.add.at``
    adds them (the same numbers), a pass per row of the largest cluster over all clusters at
    once: ``np.add.at`` took 0.12 s for SeaGap's whitened Jacobian (3,347 x 902, one cluster
    a row), where this is a copy. (``np.add.reduceat`` sums in another order: round-off.)

    Parameters
    ----------
    clusters : array_like
        ``(n,)`` labels.
    X : numpy.ndarray
        ``(n, P)``.

    Returns
    -------
    numpy.ndarray
        ``(G, P)``, ``G`` the number of distinct labels.

    Examples
    --------
    >>> _cluster_sums([3, 1, 3], np.array([[1.0], [2.0], [4.0]])).ravel().tolist()
    [2.0, 5.0]
    """
    codes = np.unique(np.asarray(clusters), return_inverse=True)[1].ravel()
    order = np.argsort(codes, kind="stable")
    sorted_codes = codes[order]
    starts = np.flatnonzero(np.r_[True, sorted_codes[1:] != sorted_codes[:-1]])
    counts = np.diff(np.r_[starts, codes.size])
    rows = np.asarray(X, float)[order]
    out = rows[starts]  # a copy: each cluster's first row
    for j in range(1, int(counts.max())):
        more = counts > j
        out[more] += rows[starts[more] + j]
    return out


def _prior_covariance(J, r, clusters, sigma, prior):
    """Covariances of an unpenalised fit whose positions have a prior (``speed_intervals``).

    Returns ``(cov, cov_model)``: with ``A = J'J / sigma^2 + P`` (``P`` the prior precision),
    the cluster-robust ``A^-1 (B G / (G - edf) + P) A^-1`` (``B`` the clusters' scores'
    outer products over ``sigma^4``, ``edf = tr(A^-1 J'J) / sigma^2``), as each row of
    :func:`_grid_average`, and the model-based ``A^-1``. Without a prior the first is
    :func:`robust_covariance`.
    """
    S = _cluster_sums(clusters, J * r[:, None])
    JtJ = J.T @ J
    Ainv = _scaled_inverse(JtJ / sigma**2 + prior)
    return _sandwich(Ainv, JtJ, S.T @ S / sigma**4, S.shape[0], sigma, prior)[0], Ainv


def _sandwich(Ainv, JtJ, meat, n_clusters, sigma, prior):
    """Return ``(C, edf)``: the cluster-robust covariance of a penalised fit, and its dof.

    ``C = A^-1 (meat G / (G - edf) + prior) A^-1`` (``A^-1`` the inverse posterior precision,
    ``meat`` the clusters' scores' outer products over ``sigma^4``, ``G`` the clusters), made
    exactly symmetric; ``edf = tr(A^-1 J'J) / sigma^2``. A row of :func:`_grid_average`, and
    :func:`_prior_covariance`.
    """
    edf = float(np.sum(Ainv * JtJ) / sigma**2)  # trace(Ainv JtJ), both symmetric
    C = Ainv @ (meat * n_clusters / max(n_clusters - edf, 1.0) + prior) @ Ainv
    return 0.5 * (C + C.T), edf


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
    S = _cluster_sums(clusters, J * r[:, None])
    G, P = S.shape
    Ainv = np.linalg.pinv(J.T @ J)
    return Ainv @ (S.T @ S) @ Ainv * (G / max(G - P, 1))


def _warn(n_bad, n_legs, converged, it, gn_ok=True):
    """Emit the :class:`LocateWarning` of an array fit (invalid rays, no convergence)."""
    if n_bad:
        warnings.warn(f"array: {n_bad} of {n_legs} legs have no direct eigenray through the "
                      "profile; their travel times are the straight chord at the profile's "
                      "mean speed", LocateWarning, stacklevel=5)  # past two decorators
    if not converged:
        warnings.warn(f"array: location EM did not converge in {it} iterations", LocateWarning,
                      stacklevel=5)
    elif not gn_ok:
        warnings.warn("array: the EM's last Gauss-Newton step ran out of steps still lowering "
                      "the misfit: the positions may not be at the optimum", LocateWarning,
                      stacklevel=5)
