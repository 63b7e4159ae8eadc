"""Two-way travel times of a transponder's true replies, and their derivatives."""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..acoustics.turning import direct_times
from ..exceptions import InputError


def chord(x, y, z, e, n, d, R=None, *, derivatives=False):
    """Straight-line distance between ship points and a transponder, flat or spherical.

    Parameters
    ----------
    x, y, z : array_like
        Ship (transducer) positions: horizontal coordinates and depth (m).
    e, n, d : array_like
        Transponder east, north and depth (m); broadcast with ``x, y, z`` (e.g.
        ``(W, 1)`` columns against ``(n,)`` pings give ``(W, n)``).
    R : float, optional
        ``None``: Cartesian (a local tangent plane). A radius (m): ``x, y`` are
        distances along the sphere and depths are below it (SeaGap's frame);
        the distance is the chord between the two radii.
    derivatives : bool, default False
        Also return ``dL/de, dL/dn, dL/dd``.

    Returns
    -------
    L : numpy.ndarray
        Distance (m), at least 1e-9.
    dL_de, dL_dn, dL_dd : numpy.ndarray
        Only with ``derivatives=True``.

    Examples
    --------
    >>> float(chord(3.0, 4.0, 0.0, 0.0, 0.0, 12.0))
    13.0
    >>> L, de, dn, dd = chord(3.0, 4.0, 0.0, 0.0, 0.0, 12.0, derivatives=True)
    >>> float(L), round(float(dd), 6)
    (13.0, 0.923077)
    """
    dx, dy = x - e, y - n
    if not derivatives:
        h2 = dx * dx + dy * dy
        if R is None:
            dz = z - d
            return np.maximum(np.sqrt(h2 + dz * dz), 1e-9)
        rb, rc = R - z, R - d
        s = np.sin(np.sqrt(h2) / (2.0 * R))
        return np.maximum(np.sqrt((rb - rc) ** 2 + 4.0 * rb * rc * s * s), 1e-9)
    h = np.sqrt(dx * dx + dy * dy)
    if R is None:
        dz = z - d
        L = np.maximum(np.sqrt(h * h + dz * dz), 1e-9)
        return L, -dx / L, -dy / L, -dz / L
    with np.errstate(invalid="ignore", divide="ignore"):
        ux, uy = np.where(h > 0, dx / h, 0.0), np.where(h > 0, dy / h, 0.0)
    rb, rc = R - z, R - d
    phi = h / R
    L = np.maximum(np.sqrt((rb - rc) ** 2 + 4 * rb * rc * np.sin(phi / 2) ** 2), 1e-9)
    dLdh = rb * rc * np.sin(phi) / (R * L)
    return L, -dLdh * ux, -dLdh * uy, -((rc - rb) + 2 * rb * np.sin(phi / 2) ** 2) / L


class TravelTimes:
    """Two-way travel times of true arrivals, and their derivatives, for one transponder.

    ``theta = [east, north, depth, *speed, (lag), (tat)]``; the speed is one value or cubic
    B-spline coefficients in time (:func:`speed_basis`), and with a profile it is the factor
    that scales the profile's speeds. A ping no eigenray reaches takes the chord at the
    profile's harmonic-mean speed and is counted by :meth:`n_invalid`.

    Parameters
    ----------
    x, y, z : numpy.ndarray
        Ship (transducer) positions of the pings (m).
    tat : float
        Turn-around time (s), when not fitted.
    basis : numpy.ndarray, optional
        ``(n, k)`` design matrix of the speed in time; default one column of ones.
    fit_tat : bool, default False
        ``theta`` ends with the turn-around time.
    profile : SoundSpeedProfile, optional
        Refracted rays through it; ``None`` for straight rays.
    surface_depth : float, default 0
        Depth, in the pings' frame, of the profile's 0 m.
    earth_radius : float, optional
        Spherical frame of that radius (m; ``x, y`` along the sphere); ``None`` for a flat one.
    velocity : tuple of numpy.ndarray, optional
        The ship's velocity (m/s) at each ping (:func:`ship_velocity`).
    lag : float, default 0
        Time lag (s) of the acoustic position behind the logged one.
    fit_lag : bool, default False
        ``theta`` holds the lag after the speed coefficients.
    """

    def __init__(self, x, y, z, tat, *, basis=None, fit_tat=False, profile=None,
                 surface_depth=0.0, earth_radius=None, velocity=None, lag=0.0,
                 fit_lag=False):
        self.x, self.y, self.z, self.tat = x, y, z, tat
        # the ship's velocity (m/s) and a time lag (s) of the acoustic position behind the
        # logged one: the ship is at (x, y) + lag * velocity (fitted when fit_lag)
        self.vel, self.lag, self.fit_lag = velocity, float(lag), bool(fit_lag)
        self.basis = np.ones((x.size, 1)) if basis is None else basis
        self.k = self.basis.shape[1]
        self.fit_tat = fit_tat
        self.profile, self.surface_depth, self.R = profile, float(surface_depth), earth_radius
        self._key = None

    def speed(self, theta):
        """Speed (or profile scale) at each ping from ``theta``'s coefficients.

        Parameters
        ----------
        theta : numpy.ndarray
            The parameter vector (position, speed coefficients, then the optional ones).

        Returns
        -------
        numpy.ndarray
        """
        return self.basis @ theta[3:3 + self.k]

    def _tat(self, theta):
        return theta[-1] if self.fit_tat else self.tat

    def _lag(self, theta):
        return theta[3 + self.k] if self.fit_lag else self.lag

    def ship(self, lag=None):
        """Ship positions ``(x, y)`` shifted by ``lag`` times its velocity.

        Parameters
        ----------
        lag : float, optional
            Seconds; default the fixed ``lag`` this model was built with.

        Returns
        -------
        x, y : numpy.ndarray
        """
        lag = self.lag if lag is None else lag
        if self.vel is None or lag == 0.0:
            return self.x, self.y
        return self.x + lag * self.vel[0], self.y + lag * self.vel[1]

    def rays(self, theta):
        """One-way times ``T`` (unscaled) and their position derivatives at ``theta``.

        Parameters
        ----------
        theta : numpy.ndarray
            The model's parameters (only position and lag are used).

        Returns
        -------
        tuple
            ``(T, dT/de, dT/dn, dT/dd, n_invalid)``: arrays over the pings (s and
            s/m; for straight rays the distance, m) and the number of pings no
            eigenray reaches.
        """
        key = tuple(float(v) for v in theta[:3]) + (float(self._lag(theta)),)
        if key == self._key:
            return self._cache
        e, n, d, lag = key
        sx, sy = self.ship(lag)
        L, Le, Ln, Ld = chord(sx, sy, self.z, e, n, d, self.R, derivatives=True)
        if self.profile is None:
            out = (L, Le, Ln, Ld, 0)
        else:
            out = self._refracted(L, Le, Ln, Ld, d)
        self._key, self._cache = key, out
        return out

    def _refracted(self, L, Le, Ln, Ld, d):
        """:meth:`rays` through the profile, from the chord and its derivatives."""
        za, zb = self.z - self.surface_depth, np.full_like(L, d - self.surface_depth)
        dz = zb - za
        h = np.sqrt(np.maximum(L * L - dz * dz, 0.0))
        ray = direct_times(self.profile, za, zb, h)
        T, p, bad = ray.time, ray.p, ~ray.valid
        if bad.any():  # no eigenray at all, even turning: flagged (n_invalid)
            hm = self.profile.harmonic_mean(za[bad], zb[bad])
            T, p = T.copy(), p.copy()
            T[bad] = L[bad] / hm
            p[bad] = h[bad] / L[bad] / hm
        cb = self.profile.speed(zb)
        # the vertical slowness at the transponder, signed by the direction the ray
        # arrives in: from the ship's side, or from the turning point
        side = np.where(ray.turning, zb - ray.turning_depth, dz)
        eta = np.sqrt(np.maximum(1.0 / cb**2 - p * p, 0.0)) * np.sign(side)
        with np.errstate(invalid="ignore", divide="ignore"):
            q = np.where(h > 1e-9, p / h, 0.0)  # dT/dh / h
        # dT/dd = dT/dzb + dT/dh * dh/dd, with h^2 = L^2 - dz^2 (dh/dd = 0 on a plane)
        Td = eta + q * (L * Ld - dz)
        if bad.any():  # the chord at the harmonic mean speed: its own derivative, not a ray's
            # d(hm)/dzb = hm / dz (1 - hm / c(zb)): the mean's end moves with the transponder
            dzb, cbb = dz[bad], cb[bad]
            with np.errstate(invalid="ignore", divide="ignore"):
                dhm = np.where(np.abs(dzb) > 1e-9, hm / dzb * (1.0 - hm / cbb), 0.0)
            Td[bad] = Ld[bad] / hm - L[bad] / hm**2 * dhm
        return T, q * L * Le, q * L * Ln, Td, int(bad.sum())

    def n_invalid(self, theta):
        """Count the pings that no eigenray reaches at ``theta`` (0 for straight rays).

        Parameters
        ----------
        theta : numpy.ndarray
            The parameter vector (position, speed coefficients, then the optional ones).

        Returns
        -------
        int
        """
        return self.rays(theta)[4]

    def predict(self, theta):
        """Two-way travel times (s) of true arrivals at ``theta``, one per ping.

        Parameters
        ----------
        theta : numpy.ndarray
            The parameter vector (position, speed coefficients, then the optional ones).

        Returns
        -------
        numpy.ndarray
        """
        return 2.0 * self.rays(theta)[0] / self.speed(theta) + self._tat(theta)

    def jac(self, theta):
        """d(prediction)/d(theta), one row per ping.

        Parameters
        ----------
        theta : numpy.ndarray
            The parameter vector (position, speed coefficients, then the optional ones).

        Returns
        -------
        numpy.ndarray
            ``(n, ndim)``.
        """
        T, Te, Tn, Td, _ = self.rays(theta)
        s = self.speed(theta)
        cols = [2 * Te / s, 2 * Tn / s, 2 * Td / s]
        extra = []
        if self.fit_lag:  # moving the ship by lag * v is moving the transponder back
            extra.append(-(cols[0] * self.vel[0] + cols[1] * self.vel[1])[:, None])
        if self.fit_tat:
            extra.append(np.ones_like(T)[:, None])
        return np.column_stack(cols + [(-2 * T / s**2)[:, None] * self.basis] + extra)


def ship_velocity(pings: pd.DataFrame) -> tuple:
    """Estimate the ship's velocity (m/s) at each ping from the track: ``(vx, vy)``.

    Parameters
    ----------
    pings : pandas.DataFrame
        ``time``, ``x``, ``y`` (or ``vx``, ``vy``).
    """
    if {"vx", "vy"} <= set(pings.columns):
        return pings["vx"].to_numpy(float), pings["vy"].to_numpy(float)
    if "time" not in pings.columns:
        raise InputError("pings: the ship's velocity needs a 'time' column (s)")
    t = pings["time"].to_numpy(float)
    ut, inv = np.unique(t, return_inverse=True)
    if ut.size < 3:
        raise InputError(f"pings: the ship's velocity needs pings at 3 or more times, got "
                         f"{ut.size}")
    out = []
    for c in ("x", "y"):
        v = pings[c].to_numpy(float)
        mean = np.bincount(inv, v) / np.bincount(inv)
        out.append(np.gradient(mean, ut)[inv])
    return tuple(out)


def speed_basis(pings, n_intervals, time_range, breaks=None):
    """Design matrix of the sound speed in time: ones, or a cubic B-spline basis.

    Parameters
    ----------
    pings : pandas.DataFrame
        The pings (their ``time`` column).
    n_intervals : int
        Equal intervals of the B-spline (0: one constant speed).
    time_range : tuple of float or None
        The span the intervals divide (default: the pings' own); times outside it take
        the value at the nearer end.
    breaks : array_like, optional
        The intervals' ends, when they are not equal (:func:`speed_breaks`); they replace
        ``n_intervals`` and ``time_range``.

    Returns
    -------
    numpy.ndarray
        ``(n, k)`` design matrix, ``k = 1`` or ``n_intervals + 3``.

    Raises
    ------
    InputError
        When a varying speed is asked for pings without a ``time`` column, or the span
        is empty.
    """
    n = len(pings)
    if not n_intervals:
        return np.ones((n, 1))
    from scipy.interpolate import BSpline

    if "time" not in pings.columns:
        raise InputError("pings: a time-varying sound speed needs a 'time' column (s)")
    t = pings["time"].to_numpy(float)
    if breaks is None and time_range is None:
        time_range = (float(t.min()), float(t.max()))
    edges, knots = _spline_knots(n_intervals, time_range, breaks)
    lo, hi = float(edges[0]), float(edges[-1])
    if not hi > lo:
        raise InputError(f"time_range: expected start < end, got ({lo}, {hi})")
    return BSpline.design_matrix(np.clip(t, lo, hi), knots, 3).toarray()


def _spline_knots(n_intervals, time_range, breaks):
    """Return the cubic spline's interval ends and its clamped knot vector.

    The ends are ``breaks`` where given, else ``n_intervals`` equal intervals of
    ``time_range``.
    """
    if breaks is None:
        lo, hi = map(float, time_range)
        edges = np.linspace(lo, hi, int(n_intervals) + 1)
    else:
        edges = np.asarray(breaks, float)
    return edges, np.concatenate([[edges[0]] * 3, edges, [edges[-1]] * 3])


def speed_breaks(times, time_range, n_intervals) -> np.ndarray:
    """Return the ends of the speed spline's intervals: equal, merged across gaps in the shots.

    A break between two intervals that both hold no shot is dropped, so a gap of several
    intervals becomes one interval, across which the spline (and its roughness penalty) runs
    as one cubic piece: no coefficients that only the penalty determines (as the field's
    reference drops its knots in long gaps). Shots without a gap of two intervals keep the
    equal intervals exactly.

    Parameters
    ----------
    times : array_like
        The shots' times (s).
    time_range : tuple of float
        The span (s).
    n_intervals : int
        Equal intervals before merging (at least 1).

    Returns
    -------
    numpy.ndarray
        Increasing ends, from ``time_range[0]`` to ``time_range[1]``.

    Examples
    --------
    >>> speed_breaks([0.0, 50.0, 960.0, 1000.0], (0.0, 1000.0), 10).tolist()
    [0.0, 100.0, 900.0, 1000.0]
    """
    lo, hi = map(float, time_range)
    n = int(n_intervals)
    edges = np.linspace(lo, hi, n + 1)
    t = np.clip(np.asarray(times, float), lo, hi)
    held = np.bincount(np.clip(np.searchsorted(edges, t, side="right") - 1, 0, n - 1),
                       minlength=n) > 0
    keep = np.ones(n + 1, bool)
    keep[1:-1] = held[:-1] | held[1:]
    return edges[keep]


#: The knot spacings (min) the smooth sound speed takes (``locate --knot-minutes``, repeated in
#: ``cli/options.py``): below 0.1 min (6 s, under a shot cycle) a spacing only costs memory
#: (1e-9 min asked 445 GiB before any check of the fit's size), above a day it is one speed.
KNOT_MINUTES_RANGE = (0.1, 1440.0)


def smooth_intervals(time_range, knot_minutes) -> int:
    """Return the number of equal B-spline intervals with knots at most ``knot_minutes`` apart.

    Parameters
    ----------
    time_range : tuple of float
        Span (s).
    knot_minutes : float
        Largest knot spacing (min).

    Returns
    -------
    int
        At least 1.

    Examples
    --------
    >>> smooth_intervals((0.0, 6 * 3600.0), 5.0)
    72
    """
    span = float(time_range[1]) - float(time_range[0])
    return max(1, int(np.ceil(span / (60.0 * float(knot_minutes)) - 1e-9)))


def speed_penalty(n_intervals, time_range, *, order=2, time_unit=3600.0,
                  breaks=None) -> np.ndarray:
    """Gram matrix of the roughness ``int (d^q s / du^q)^2 du`` of :func:`speed_basis`'s spline.

    ``u = t / time_unit``: the penalty is an integral over time, so its weight means
    the same at any knot spacing. Exact (Gauss-Legendre on each interval).

    Parameters
    ----------
    n_intervals : int
        Intervals of the spline (at least 1).
    time_range : tuple of float
        Its span (s).
    order : int, default 2
        ``q``: the derivative penalised (2: curvature; constant and linear trends are free).
    time_unit : float, default 3600
        Seconds per unit of ``u`` (hours).
    breaks : array_like, optional
        Unequal intervals' ends (:func:`speed_breaks`), in place of ``n_intervals`` and
        ``time_range``.

    Returns
    -------
    numpy.ndarray
        ``(n_intervals + 3, n_intervals + 3)``, symmetric, rank ``n_intervals + 3 - order``.

    Examples
    --------
    >>> H = speed_penalty(4, (0.0, 3600.0))
    >>> H.shape, bool(abs(H @ np.ones(7)).max() < 1e-9)
    ((7, 7), True)
    """
    from scipy.interpolate import BSpline

    edges, knots = _spline_knots(n_intervals, time_range, breaks)
    k, n = 3, edges.size - 1
    m = n + k
    deriv = BSpline(knots, np.eye(m), k).derivative(order)
    x, w = np.polynomial.legendre.leggauss(4)
    a, b = edges[:-1, None], edges[1:, None]
    t = (0.5 * (b - a) * x + 0.5 * (a + b)).ravel()
    wt = (0.5 * (b - a) * w).ravel() / time_unit  # du
    D = deriv(t) * time_unit ** order  # d/du = time_unit d/dt
    return (D * wt[:, None]).T @ D
