"""Travel times (moved from ``locate``)."""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..exceptions import InputError


class TravelTimes:
    """Two-way travel times of true arrivals, and their derivatives, for one transponder.

    ``theta = [east, north, depth, *speed, (tat)]``. The speed is one value, or the
    coefficients of a cubic B-spline in time (:func:`speed_basis`; a partition of
    unity, so equal coefficients are a constant speed). Without a profile the
    speed is the straight-ray sound speed (m/s); with one it is the factor the
    profile's speeds are scaled by, which leaves the rays where they are and divides
    their times by it.

    Geometry: ``earth_radius=None`` takes ``x, y, depth`` as Cartesian (a local
    tangent plane); with a radius, ``x, y`` are distances along the sphere and
    ``depth`` is below it (SeaGap's convention), and the straight-line distance is
    the chord between the two radii. The refracted ray runs between the profile
    depths ``depth - surface_depth`` over the horizontal distance that makes a
    constant profile give that same chord.
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

    def _speed(self, theta):
        return self.basis @ theta[3:3 + self.k]

    def _tat(self, theta):
        return theta[-1] if self.fit_tat else self.tat

    def _lag(self, theta):
        return theta[3 + self.k] if self.fit_lag else self.lag

    def _ship(self, lag):
        if self.vel is None or lag == 0.0:
            return self.x, self.y
        return self.x + lag * self.vel[0], self.y + lag * self.vel[1]

    def _chord(self, e, n, d, lag=0.0):
        """Straight-line distance ``L`` and ``dL/de, dL/dn, dL/dd``."""
        sx, sy = self._ship(lag)
        dx, dy = sx - e, sy - n
        h = np.sqrt(dx * dx + dy * dy)
        with np.errstate(invalid="ignore", divide="ignore"):
            ux, uy = np.where(h > 0, dx / h, 0.0), np.where(h > 0, dy / h, 0.0)
        if self.R is None:
            dz = self.z - d
            L = np.maximum(np.sqrt(h * h + dz * dz), 1e-9)
            return L, -dx / L, -dy / L, -dz / L
        R = self.R
        rb, rc = R - self.z, R - d
        phi = h / R
        L = np.maximum(np.sqrt((rb - rc) ** 2 + 4 * rb * rc * np.sin(phi / 2) ** 2), 1e-9)
        dLdh = rb * rc * np.sin(phi) / (R * L)
        return L, -dLdh * ux, -dLdh * uy, -((rc - rb) + 2 * rb * np.sin(phi / 2) ** 2) / L

    def _rays(self, theta):
        """One-way times ``T`` (unscaled) and ``dT/de, dT/dn, dT/dd`` at ``theta``'s position."""
        key = tuple(float(v) for v in theta[:3]) + (float(self._lag(theta)),)
        if key == self._key:
            return self._cache
        e, n, d, lag = key
        L, Le, Ln, Ld = self._chord(e, n, d, lag)
        if self.profile is None:
            out = (L, Le, Ln, Ld, 0)
        else:
            from ..acoustics.eigenray import direct_ray

            za, zb = self.z - self.surface_depth, np.full_like(L, d - self.surface_depth)
            dz = zb - za
            h = np.sqrt(np.maximum(L * L - dz * dz, 0.0))
            ray = direct_ray(self.profile, za, zb, h)
            T, p, bad = ray.time, ray.p, ~ray.valid
            if bad.any():  # no eigenray without a turning point: the chord at the mean speed
                hm = self.profile.harmonic_mean(za[bad], zb[bad])
                T, p = T.copy(), p.copy()
                T[bad] = L[bad] / hm
                p[bad] = h[bad] / L[bad] / hm
            cb = self.profile.speed(zb)
            eta = np.sqrt(np.maximum(1.0 / cb**2 - p * p, 0.0)) * np.sign(dz)
            with np.errstate(invalid="ignore", divide="ignore"):
                q = np.where(h > 1e-9, p / h, 0.0)  # dT/dh / h
            # dT/dd = dT/dzb + dT/dh * dh/dd, with h^2 = L^2 - dz^2 (dh/dd = 0 on a plane)
            Td = eta + q * (L * Ld - dz)
            out = (T, q * L * Le, q * L * Ln, Td, int(bad.sum()))
        self._key, self._cache = key, out
        return out

    def n_invalid(self, theta):
        return self._rays(theta)[4]

    def predict(self, theta):
        return 2.0 * self._rays(theta)[0] / self._speed(theta) + self._tat(theta)

    def jac(self, theta):
        """d(prediction)/d(theta), one row per ping."""
        T, Te, Tn, Td, _ = self._rays(theta)
        s = self._speed(theta)
        cols = [2 * Te / s, 2 * Tn / s, 2 * Td / s]
        extra = []
        if self.fit_lag:  # moving the ship by lag * v is moving the transponder back
            extra.append(-(cols[0] * self.vel[0] + cols[1] * self.vel[1])[:, None])
        if self.fit_tat:
            extra.append(np.ones_like(T)[:, None])
        return np.column_stack(cols + [(-2 * T / s**2)[:, None] * self.basis] + extra)


def ship_velocity(pings: pd.DataFrame) -> tuple:
    """The ship's velocity (m/s) at each ping, from the track: ``(vx, vy)``.

    Columns ``vx``, ``vy`` if the table has them, else central differences of
    ``x``, ``y`` in ``time`` over the pings in time order (pings at the same time
    share a velocity).

    Parameters
    ----------
    pings : pandas.DataFrame
        ``time``, ``x``, ``y`` (or ``vx``, ``vy``).

    Returns
    -------
    tuple of numpy.ndarray
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


def speed_basis(pings, n_intervals, time_range):
    """Design matrix of the sound speed in time: ones, or a cubic B-spline basis.

    ``n_intervals`` equal intervals over ``time_range`` (default: the pings' own
    span); times outside it take the value at the nearer end.
    """
    n = len(pings)
    if not n_intervals:
        return np.ones((n, 1))
    from scipy.interpolate import BSpline

    if "time" not in pings.columns:
        raise InputError("pings: a time-varying sound speed needs a 'time' column (s)")
    t = pings["time"].to_numpy(float)
    lo, hi = (float(t.min()), float(t.max())) if time_range is None else time_range
    if not hi > lo:
        raise InputError(f"time_range: expected start < end, got ({lo}, {hi})")
    k = 3
    knots = np.concatenate([[lo] * k, np.linspace(lo, hi, int(n_intervals) + 1), [hi] * k])
    tc = np.clip(t, lo, hi)
    return BSpline.design_matrix(tc, knots, k).toarray()
