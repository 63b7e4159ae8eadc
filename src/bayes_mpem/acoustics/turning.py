"""The package's direct-ray solver: eigenrays with or without a turning point."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .eigenray import direct_ray, surface_bounce_ray
from .profile import SoundSpeedProfile

#: Range (m) standing for "no eigenray" in the mixture model: its Gaussian density is 0
#: in float64 for any scale below 1e10 m, and its square does not overflow.
NO_RAY = 1e12


# --------------------------------------------------------------------------- rays

@dataclass(frozen=True)
class DirectRays:
    """Direct eigenrays between pairs of points (one entry per pair).

    Attributes
    ----------
    time : numpy.ndarray
        One-way travel time (s); NaN where not ``valid``.
    p : numpy.ndarray
        Ray parameter (s/m).
    valid : numpy.ndarray of bool
    turning_depth : numpy.ndarray
        Depth (m) of the turning point; NaN for rays that do not turn.
    """

    time: np.ndarray = field(repr=False)
    p: np.ndarray = field(repr=False)
    valid: np.ndarray = field(repr=False)
    turning_depth: np.ndarray = field(repr=False)

    @property
    def turning(self) -> np.ndarray:
        """True where the ray has a turning point."""
        return np.isfinite(self.turning_depth)


def _stretch_ends(ssp, z, down):
    """Depth where the speed stops increasing away from ``z`` (down or up); NaN if at once."""
    zk, g = ssp.depths, np.diff(ssp.speeds) / np.diff(ssp.depths) if len(ssp) > 1 else None
    out = np.full(z.shape, np.nan)
    if g is None:
        return out
    nl = g.size
    if down:
        i0 = np.searchsorted(zk, z, side="right") - 1       # layer [zk[i0], zk[i0 + 1]] below z
        ok = (i0 >= 0) & (i0 < nl)
        ok[ok] &= g[i0[ok]] > 0
        # for each layer: the bottom knot of the run of increasing layers starting there
        stop = np.empty(nl)
        end = zk[-1]
        for i in range(nl - 1, -1, -1):
            end = end if g[i] > 0 and (i == nl - 1 or g[i + 1] > 0) else zk[i + 1]
            stop[i] = end
        out[ok] = stop[i0[ok]]
    else:
        i1 = np.searchsorted(zk, z, side="left") - 1        # layer [zk[i1], zk[i1 + 1]] above z
        ok = (i1 >= 0) & (i1 < nl)
        ok[ok] &= g[i1[ok]] < 0
        stop = np.empty(nl)
        end = zk[0]
        for i in range(nl):
            end = end if g[i] < 0 and (i == 0 or g[i - 1] < 0) else zk[i]
            stop[i] = end
        out[ok] = stop[i1[ok]]
    return out


def _artanh_over(x):
    """``artanh(x) / x``, 1 at ``x = 0`` (series below ``|x| = 1e-4``)."""
    small = np.abs(x) < 1e-4
    safe = np.where(small, 0.5, x)
    return np.where(small, 1.0 + x * x / 3.0, np.arctanh(safe) / safe)


def _turning_leg(ssp, z_e, zt):
    """Horizontal run and time of the leg from ``z_e`` to the turning depth ``zt``.

    ``s`` comes from ``(c_t - c)(c_t + c)``, exactly 0 at the turning point (from a rounded
    ``p`` it would be ~1e-8 there, ~2 mm of run on a 3 km ray dipping 10 m).
    """
    top, bot = np.minimum(z_e, zt), np.maximum(z_e, zt)
    zk = ssp.depths
    zk = zk[(zk > top.min()) & (zk < bot.max())] if top.size else zk[:0]
    zc = np.empty((top.size, zk.size + 2))
    zc[:, 0], zc[:, -1] = top, bot
    np.clip(zk, top[:, None], bot[:, None], out=zc[:, 1:-1])
    ct = ssp.speed(zt)[:, None]
    cc = ssp.speed(zc)
    ss = np.sqrt(np.maximum((ct - cc) * (ct + cc), 0.0)) / ct
    c0, c1, s0, s1 = cc[:, :-1], cc[:, 1:], ss[:, :-1], ss[:, 1:]
    hh = np.diff(zc, axis=1)
    thick = hh > 0
    with np.errstate(divide="ignore", invalid="ignore"):
        den = s0 + s1
        x = np.where(thick, hh * (c0 + c1) / den, 0.0).sum(axis=1) / ct[:, 0]
        w = (c0 + c1) * (1.0 + s0 * s1) / (den * (c0 * c0 * s1 * s1 + c1 * c1))
        t = np.where(thick, hh * w * _artanh_over((c1 - c0) * w), 0.0).sum(axis=1)
    return x, t


def _turning_leg_sum(ssp, za, zb, zt):
    """Horizontal run and time of the ray turning at ``zt`` (two legs), and its ``p``."""
    xa, ta = _turning_leg(ssp, za, zt)
    xb, tb = _turning_leg(ssp, zb, zt)
    return xa + xb, ta + tb, 1.0 / ssp.speed(zt)


def _solve_turning(ssp, za, zb, H, end, stop, sign, tol, max_iter=200):
    """Root of ``X(zt) = H`` in ``u = sqrt(|zt - end|)``; NaN where there is none."""
    n = H.size
    t_out, p_out, z_out = np.full(n, np.nan), np.full(n, np.nan), np.full(n, np.nan)
    ok = np.isfinite(stop) & (np.abs(stop - end) > 0)
    if not ok.any():
        return t_out, p_out, z_out
    idx = np.flatnonzero(ok)
    lo = np.zeros(idx.size)
    hi = np.sqrt(np.abs(stop[idx] - end[idx]))
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        x_hi, _, _ = _turning_leg_sum(ssp, za[idx], zb[idx], stop[idx])
        x_lo, _, _ = _turning_leg_sum(ssp, za[idx], zb[idx], end[idx])
    # (X is inf where the fastest speed holds over a layer: that brackets too)
    reach = (x_hi >= H[idx]) & np.isfinite(x_lo) & (x_lo <= H[idx])
    idx, lo, hi = idx[reach], lo[reach], hi[reach]
    h = H[idx]
    f_lo, f_hi = x_lo[reach] - h, x_hi[reach] - h
    side = np.zeros(idx.size)           # which end was replaced last (-1 lo, +1 hi)
    atol = tol * np.maximum(h, 1.0)
    active = np.ones(idx.size, bool)
    for it in range(max_iter):
        a = np.flatnonzero(active)
        if a.size == 0:
            break
        with np.errstate(invalid="ignore", divide="ignore"):
            u = hi[a] - f_hi[a] * (hi[a] - lo[a]) / (f_hi[a] - f_lo[a])
        mid = 0.5 * (lo[a] + hi[a])
        u = np.where(np.isfinite(u) & (u > lo[a]) & (u < hi[a]) & (it % 8 != 7), u, mid)
        zt = np.clip(end[idx[a]] + sign * u * u, *np.sort([end[idx[a]], stop[idx[a]]], axis=0))
        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
            x, t, p = _turning_leg_sum(ssp, za[idx[a]], zb[idx[a]], zt)
        f = x - h[a]
        done = (np.abs(f) <= atol[a]) | (hi[a] - lo[a] <= 4 * np.finfo(float).eps * hi[a])
        fin = done & np.isfinite(t)
        t_out[idx[a[fin]]], p_out[idx[a[fin]]], z_out[idx[a[fin]]] = t[fin], p[fin], zt[fin]
        short = f < 0
        # Illinois: halve the value kept at the end that survived twice in a row
        f_hi[a] = np.where(short & (side[a] < 0), 0.5 * f_hi[a], f_hi[a])
        f_lo[a] = np.where(~short & (side[a] > 0), 0.5 * f_lo[a], f_lo[a])
        lo[a], f_lo[a] = np.where(short, u, lo[a]), np.where(short, f, f_lo[a])
        hi[a], f_hi[a] = np.where(short, hi[a], u), np.where(short, f_hi[a], f)
        side[a] = np.where(short, -1.0, 1.0)
        active[a[done]] = False
    return t_out, p_out, z_out


def direct_times(ssp: SoundSpeedProfile, z_a, z_b, horizontal, *, tol: float = 1e-9
                 ) -> DirectRays:
    """Direct eigenrays, with a turning point where the straight-through ray does not exist.

    A ray turning below the deeper end or above the shallower one is two legs meeting at the
    turning depth; of two such rays the first arrival is kept.

    Parameters
    ----------
    z_a, z_b : array_like
        Depths of the ends (m).
    horizontal : array_like
        Horizontal distance (m, >= 0). All three broadcast.
    tol : float, default 1e-9
        Relative tolerance on the horizontal run.
    """
    ray = direct_ray(ssp, z_a, z_b, horizontal, tol=tol)
    shape = ray.time.shape
    za, zb, H = (np.broadcast_to(np.asarray(v, float), shape).ravel()
                 for v in (z_a, z_b, horizontal))
    time, p = ray.time.ravel().copy(), ray.p.ravel().copy()
    zt = np.full(time.size, np.nan)
    bad = np.flatnonzero(~np.isfinite(time))
    if bad.size and len(ssp) > 1:
        a, b, h = za[bad], zb[bad], H[bad]
        top, bot = np.minimum(a, b), np.maximum(a, b)
        zk, ck = ssp.depths, ssp.speeds
        inside = (zk > top[:, None]) & (zk < bot[:, None])
        c_in = np.where(inside, ck, -np.inf).max(axis=1)
        c_top, c_bot = ssp.speed(top), ssp.speed(bot)
        cmax = np.maximum(np.maximum(c_top, c_bot), c_in)
        best_t = np.full(bad.size, np.inf)
        best_p, best_z = np.full(bad.size, np.nan), np.full(bad.size, np.nan)
        for down, end, c_end in ((True, bot, c_bot), (False, top, c_top)):
            stop = _stretch_ends(ssp, end, down)
            stop = np.where(c_end >= cmax, stop, np.nan)  # the end must be the fastest point
            t, pp, z = _solve_turning(ssp, a, b, h, end, stop, 1.0 if down else -1.0, tol)
            better = np.isfinite(t) & (t < best_t)
            best_t[better], best_p[better], best_z[better] = t[better], pp[better], z[better]
        found = np.isfinite(best_t)
        time[bad[found]], p[bad[found]], zt[bad[found]] = (
            best_t[found], best_p[found], best_z[found])
    valid = np.isfinite(time)
    return DirectRays(time.reshape(shape), p.reshape(shape), valid.reshape(shape),
                      zt.reshape(shape))


def bounce_times(ssp: SoundSpeedProfile, z_a, z_b, horizontal, plane_depth, *,
                 tol: float = 1e-9):
    """One-way time of the ray reflected once by a plane, and its plane derivative.

    Parameters
    ----------
    z_a, z_b, horizontal, plane_depth : array_like
        As :func:`~bayes_mpem.acoustics.surface_bounce_ray`.

    Returns
    -------
    time : numpy.ndarray
        NaN where no eigenray without a turning point exists.
    dtime_dd0 : numpy.ndarray
        Derivative with respect to raising the plane (s/m).
    valid : numpy.ndarray of bool
    """
    ray = surface_bounce_ray(ssp, z_a, z_b, horizontal, plane_depth, tol=tol)
    c = ssp.speed(np.broadcast_to(np.asarray(plane_depth, float), ray.time.shape))
    with np.errstate(invalid="ignore"):
        slope = 2.0 * np.sqrt(np.maximum((1.0 / c - ray.p) * (1.0 / c + ray.p), 0.0))
    return ray.time, np.where(ray.valid, slope, np.nan), ray.valid
