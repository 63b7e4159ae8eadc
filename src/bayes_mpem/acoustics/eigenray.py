"""Refracted eigenrays without a turning point through a layered ocean.

Details: ``docs/refraction.md``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.polynomial import chebyshev

from .._validate import check_int, check_positive
from .profile import SoundSpeedProfile

_CHUNK = 1 << 15  # array elements per block of rays (keeps the temporaries in cache)
_SHARED_MIN = 64          # rays of one leg worth a shared table (:func:`_trace_shared`)
_SHARED_RATIO = 4         # ... when the shared layers outnumber the ends' this many times
_SHARED_DEGREES = (32, 64)  # Chebyshev degrees tried for the shared layers
_SHARED_TAIL = 1e-14      # the series' last coefficients, relative to its largest
_SHARED_GRAZE = 0.999     # the table stops at p = 0.999 / c_max (rays beyond: block solver)
_SHARED_QUANTILE = 0.9    # where the whole range does not converge: a table for 90 % of rays


# --------------------------------------------------------------------------- layers

def _artanh_ratio(x):
    """``artanh(x) / x``, 1 at ``x = 0`` (series below ``|x| = 0.01``, error < 1e-20)."""
    x2 = x * x
    if x2.size and x2.max() < 1e-8:  # |x| < 1e-4: two terms are exact to 2e-17
        x2 *= 1 / 3
        x2 += 1.0
        return x2
    out = 1.0 + x2 * (1 / 3 + x2 * (1 / 5 + x2 * (1 / 7 + x2 / 9)))
    big = np.abs(x) >= 1e-2
    if big.any():
        out[big] = np.arctanh(x[big]) / x[big]
    return out


class Legs:
    """Vertical legs ``[top, bot]`` of a block of rays, as per-ray knot arrays.

    Parameters
    ----------
    legs : sequence of (ndarray, ndarray)
        Per leg, the top and bottom depth (m) of every ray, each of shape ``(rays,)``.

    Attributes
    ----------
    C, H, A, B, R2 : list of ndarray
        Per leg: speeds at the leg's knots, layer thicknesses, ``A = H (c0 + c1)``,
        ``B = 1 - (c/c_max)**2`` and ``R2 = (c/c_max)**2``, so that
        ``s = sqrt(B + R2 sin(phi)**2)`` has no cancellation at grazing.
    cmax : ndarray
        The fastest speed met by each ray over all its legs.
    """

    def __init__(self, profile, legs):
        self.C, self.H = [], []
        z, c = profile.ray_knots
        for top, bot in legs:
            inside = (z > top.min()) & (z < bot.max())
            zk, ck = z[inside], c[inside]
            n, m = top.size, zk.size
            t, b = top[:, None], bot[:, None]
            zc = np.empty((n, m + 2))
            zc[:, :1], zc[:, -1:] = t, b
            np.clip(zk, t, b, out=zc[:, 1:-1])
            cc = np.empty((n, m + 2))
            cc[:, 0], cc[:, -1] = profile.speed(top), profile.speed(bot)
            mid = cc[:, 1:-1]
            mid[:] = ck
            np.copyto(mid, cc[:, :1], where=zk <= t)
            np.copyto(mid, cc[:, -1:], where=zk >= b)
            self.C.append(cc)
            self.H.append(np.diff(zc, axis=1))
        self.cmax = np.max([cc.max(axis=1) for cc in self.C], axis=0)
        m = self.cmax[:, None]
        self.A, self.B, self.R2 = [], [], []
        for cc, hh in zip(self.C, self.H, strict=True):
            a = cc[:, :-1] + cc[:, 1:]
            a *= hh
            self.A.append(a)
            bb = m - cc
            bb *= m + cc
            bb *= 1.0 / (m * m)
            self.B.append(bb)
            r2 = cc * (1.0 / m)
            r2 *= r2
            self.R2.append(r2)

    def take(self, idx, names=("C", "H", "A", "B", "R2")):
        """Return the same legs for the rays ``idx`` only (with the arrays ``names``)."""
        new = object.__new__(Legs)
        for name in names:
            setattr(new, name, [a[idx] for a in getattr(self, name)])
        new.cmax = self.cmax[idx]
        return new

    def cosines(self, sin2):
        """``s = cos(theta)`` at every knot, per leg, for grazing angles ``sin(phi)**2 = sin2``.

        Parameters
        ----------
        sin2 : ndarray
            ``sin(phi)**2`` of each ray's grazing angle at its fastest knot.
        """
        out = []
        for b, r2 in zip(self.B, self.R2, strict=True):
            s = np.multiply(r2, sin2[:, None])
            s += b
            out.append(np.sqrt(s, out=s))
        return out

    def cosines_from_p(self, p):
        """``s = sqrt(1 - (p c)**2)`` at every knot, per leg (0 where ``p c >= 1``).

        Parameters
        ----------
        p : ndarray
            Ray parameter (s/m) of each ray.
        """
        out = []
        for cc in self.C:
            pc = p[:, None] * cc
            out.append(np.sqrt(np.maximum((1.0 - pc) * (1.0 + pc), 0.0)))
        return out

    def sums(self, S, deriv=True, safe=False):
        """``sum A / (s0 + s1)`` (= X / p) and ``sum A / ((s0 + s1) s0 s1)`` (= dX/dp).

        Parameters
        ----------
        S : list of ndarray
            Per leg, the cosines at the knots (:meth:`cosines`).
        deriv : bool
            Also sum the derivative term (else ``d`` is None).
        safe : bool
            Zero-thickness layers count 0 where both ends graze (0/0); needed at ``p = 1 / c_max``.
        """
        x = np.zeros(S[0].shape[0])
        d = np.zeros_like(x) if deriv else None
        for a, s in zip(self.A, S, strict=True):
            s0, s1 = s[:, :-1], s[:, 1:]
            term = s0 + s1
            np.divide(a, term, out=term)
            if safe:
                term[a == 0] = 0.0
            x += term.sum(axis=1)
            if deriv:
                term /= np.multiply(s0, s1)
                d += term.sum(axis=1)
        return x, d

    def x_grazing(self):
        """``X`` at ``p = 1 / c_max`` (inf if the fastest speed holds over a finite layer)."""
        with np.errstate(divide="ignore", invalid="ignore"):
            x, _ = self.sums(self.cosines(np.zeros(self.cmax.size)), deriv=False, safe=True)
        return x / self.cmax

    def times(self, S):
        """One-way travel time (s) of each ray summed over the layers, for knot cosines ``S``."""
        t = np.zeros(S[0].shape[0])
        with np.errstate(divide="ignore", invalid="ignore"):
            for cc, hh, s in zip(self.C, self.H, S, strict=True):
                c0, c1, s0, s1 = cc[:, :-1], cc[:, 1:], s[:, :-1], s[:, 1:]
                den = c0 * s1
                den *= den
                den += c1 * c1
                den *= s0 + s1
                w = s0 * s1
                w += 1.0
                w *= c0 + c1
                w /= den
                x = c1 - c0
                x *= w
                w *= hh
                w *= _artanh_ratio(x)
                tt = w.sum(axis=1)
                bad = np.isnan(tt)  # 0/0 of zero-thickness layers at grazing incidence
                if bad.any():
                    tt[bad] = np.where(hh[bad] > 0, w[bad], 0.0).sum(axis=1)
                t += tt
        return t


# --------------------------------------------------------------------------- eigenrays

@dataclass(frozen=True)
class Eigenray:
    """Eigenrays between pairs of points, one entry per pair.

    Attributes
    ----------
    time : numpy.ndarray
        One-way travel time (s); NaN where not ``valid``.
    p : numpy.ndarray
        Ray parameter ``sin(theta) / c`` (s/m), ``theta`` from the vertical.
    launch_angle, arrival_angle : numpy.ndarray
        Direction of travel at ``z_a`` and ``z_b``, degrees from the downward vertical.
    valid : numpy.ndarray of bool
        False where no eigenray of this kind exists without a turning point.
    kind : str
        ``"direct"`` or ``"surface_bounce"``.
    """

    time: np.ndarray = field(repr=False)
    p: np.ndarray = field(repr=False)
    launch_angle: np.ndarray = field(repr=False)
    arrival_angle: np.ndarray = field(repr=False)
    valid: np.ndarray = field(repr=False)
    kind: str = "direct"


def _solve_block(legs, H, V, c_mean, tol, max_iter):
    """Grazing angle ``phi`` at the fastest point with ``X(phi) = H``; NaN where impossible."""
    n = H.size
    phi = np.full(n, np.nan)
    vertical = H == 0
    phi[vertical] = np.pi / 2
    todo = np.flatnonzero(~vertical & (V > 0))
    if todo.size:
        todo = todo[H[todo] <= legs.x_grazing()[todo]]
    if todo.size == 0:
        return phi
    sub = legs.take(todo)
    h = H[todo]
    lo = np.zeros(todo.size)             # X(lo) >= h (phi = 0: grazing)
    hi = np.full(todo.size, np.pi / 2)   # X(hi) = 0 < h (vertical)
    # phi0 from the guess c0 = c_mean: cos(phi0) = h c_max / (L c_mean), written without
    # the cancellation of arccos near 1 (exact for a homogeneous medium)
    cm, cx, v = c_mean[todo], sub.cmax, V[todo]
    x = np.arctan2(np.sqrt(np.maximum(v * v * cm * cm + h * h * (cm - cx) * (cm + cx), 0.0)),
                   h * cx)
    x = np.clip(x, 1e-150, np.pi / 2 * (1 - 1e-12))
    atol = tol * np.maximum(h, V[todo])
    idx = np.arange(todo.size)           # rows of `todo` held by `sub`
    active = np.ones(todo.size, bool)
    for _ in range(max_iter):
        sin_x, cos_x = np.sin(x), np.cos(x)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            S = sub.cosines(sin_x * sin_x)
            sx, sd = sub.sums(S)
            f = cos_x / sub.cmax * sx - h[idx]
            step = x + f / (sd * sin_x / sub.cmax)  # dX/dphi = -dX/dp sin(phi) / c_max
        lo_i = np.where(f > 0, x, lo[idx])
        hi_i = np.where(f > 0, hi[idx], x)
        done = active & ((np.abs(f) <= atol[idx])
                         | ((hi_i - lo_i) <= 4 * np.finfo(float).eps * hi_i))
        inside = (step > lo_i) & (step < hi_i)
        # converged: keep the last Newton step too (free, and squares the error)
        phi[todo[idx[done]]] = np.where(inside, step, x)[done]
        active &= ~done
        lo[idx], hi[idx] = lo_i, hi_i
        x = np.where(inside, step, 0.5 * (lo_i + hi_i))
        n_active = np.count_nonzero(active)
        if n_active == 0:
            break
        if n_active <= active.size // 2:
            sub = sub.take(active, ("A", "B", "R2"))
            idx, x, active = idx[active], x[active], np.ones(n_active, bool)
    return phi


def _as_rays(z_a, z_b, horizontal, extra=(),
             names=("z_a", "z_b", "horizontal", "plane_depth")):
    """Broadcast and flatten the inputs; check they are finite, ``horizontal >= 0``."""
    try:
        arrays = [np.asarray(v, float) for v in (z_a, z_b, horizontal, *extra)]
    except (TypeError, ValueError):
        raise ValueError(f"{', '.join(n for n in names if n)}: expected numbers or arrays of "
                         "numbers") from None
    try:
        arrays = np.broadcast_arrays(*arrays)
    except ValueError:
        raise ValueError(f"{', '.join(n for n in names if n)} must broadcast together, got "
                         f"shapes {[a.shape for a in arrays]}") from None
    flat = [a.ravel() for a in arrays]
    for name, a in zip(names, flat, strict=False):
        if not name:
            continue
        bad = np.flatnonzero(~np.isfinite(a))
        if bad.size:
            raise ValueError(f"{name}: expected finite numbers, got {a[bad[0]]} at flat index "
                             f"{bad[0]}")
    bad = np.flatnonzero(flat[2] < 0)
    if bad.size:
        raise ValueError(f"horizontal: expected distances >= 0 m, got {flat[2][bad[0]]} at flat "
                         f"index {bad[0]}")
    return arrays[0].shape, flat


def _shared_table(profile, z1, z2, u_hi):
    """Chebyshev series in ``u = p^2`` on ``[0, u_hi]`` of ``X / p`` and ``T`` over ``[z1, z2]``.

    Returns ``(cg, ct)``, or None where neither degree of :data:`_SHARED_DEGREES` brings the
    last three coefficients below :data:`_SHARED_TAIL` of the largest (``u_hi`` too near
    ``1 / c_max^2``, where the layers' square roots have their branch points).
    """
    for deg in _SHARED_DEGREES:
        x = np.cos(np.pi * (np.arange(deg + 1) + 0.5) / (deg + 1))  # Chebyshev points
        common = Legs(profile, [(np.full(x.size, z1), np.full(x.size, z2))])
        S = common.cosines_from_p(np.sqrt(0.5 * u_hi * (x + 1.0)))
        g, _ = common.sums(S, deriv=False)
        fits = [chebyshev.chebfit(x, y, deg) for y in (g, common.times(S))]
        if all(np.abs(c[-3:]).max() <= _SHARED_TAIL * np.abs(c).max() for c in fits):
            return fits
    return None


def _trace_shared(profile, top, bot, H, V, tol, max_iter, p, time):
    """Solve the rays of one leg through the layers they all cross, tabulated once.

    Every ray crosses ``[z1, z2] = [max(top), min(bot)]``. There the horizontal run is
    ``p g(p^2)`` and the time ``T(p^2)``, both analytic in ``u = p^2`` below ``1/c_max^2``:
    each is interpolated by a Chebyshev series in ``u`` (NumPy's
    :mod:`numpy.polynomial.chebyshev`) on the range of ray parameters the rays can have (or,
    where the rays nearest grazing keep the series from converging, on that of
    :data:`_SHARED_QUANTILE` of them), and only the short per-ray ends ``[top, z1]`` and
    ``[z2, bot]`` are summed ray by ray. Newton's
    method on ``p`` (kept in its bracket) stops on the same tolerance as :func:`_solve_block`
    and keeps its last step. The series must have converged to round-off
    (:data:`_SHARED_TAIL`); otherwise, where the ends hold many layers, or where a ray's
    parameter falls outside the table, the ray is left to the exact block solver.

    Parameters
    ----------
    profile : SoundSpeedProfile
    top, bot, H, V : numpy.ndarray
        Per ray: the leg's top and bottom depth, the horizontal run and ``bot - top`` (m).
    tol, max_iter
        As :func:`direct_ray`.
    p, time : numpy.ndarray
        Filled where solved.

    Returns
    -------
    numpy.ndarray of bool
        The rays solved here.
    """
    n = H.size
    solved = np.zeros(n, bool)
    z1, z2 = top.max(), bot.min()
    zk, ck = profile.ray_knots
    shared = np.count_nonzero((zk > z1) & (zk < z2))
    n_end = np.count_nonzero((zk > top.min()) & (zk < z1)) + np.count_nonzero(
        (zk > z2) & (zk < bot.max()))
    if not z2 > z1 or shared < _SHARED_RATIO * (n_end + 2):  # z2 > z1: every V > 0
        return solved
    inside = (zk > top.min()) & (zk < bot.max())
    c_all = np.concatenate([ck[inside], profile.speed(np.array([top.min(), z1, z2, bot.max()]))])
    cmin, cmax = c_all.min(), c_all.max()
    # the eigenray is parallel to its chord somewhere, so p <= sin(chord) / c_min; where
    # the rays nearest grazing keep the series from converging, a table for the rest
    sin_chord = H / np.hypot(H, V)
    bound = sin_chord * ((1 + 1e-6) / cmin)
    for cap in (bound.max(), np.quantile(bound, _SHARED_QUANTILE)):
        p_hi = min(float(cap), _SHARED_GRAZE / cmax)
        u_hi = p_hi * p_hi
        coef = _shared_table(profile, z1, z2, u_hi) if u_hi > 0.0 else None
        if coef is not None:
            break
    if coef is None:
        return solved
    cg, ct = coef
    cgd = chebyshev.chebder(cg)
    scale = 2.0 / u_hi
    legs = [(top, np.full(n, z1))] + ([(np.full(n, z2), bot)] if bot.max() > z2 else [])
    ends = parts = Legs(profile, legs)
    # rays that reach H within the table (X(p_hi) >= H); the others are the block solver's
    with np.errstate(divide="ignore", invalid="ignore"):
        sx, _ = parts.sums(parts.cosines_from_p(np.full(n, p_hi)), deriv=False)
    idx = np.flatnonzero(p_hi * (chebyshev.chebval(1.0, cg) + sx) >= H)
    if idx.size < n:
        parts = parts.take(idx, ("C", "A"))
    # first guess: the chord in the harmonic-mean speed (as the block solver)
    pp = np.clip(sin_chord * profile.vertical_time(top, bot) / V, 0.0, p_hi)[idx]
    lo, hi = np.zeros(n), np.full(n, p_hi)
    atol = tol * np.maximum(H, V)
    out = np.full(n, np.nan)
    for _ in range(max_iter):
        x = pp * pp * scale - 1.0
        g = chebyshev.chebval(x, cg)
        with np.errstate(divide="ignore", invalid="ignore"):
            sx, sd = parts.sums(parts.cosines_from_p(pp))
            f = pp * (g + sx) - H[idx]
            step = pp - f / (g + 2.0 * pp * pp * scale * chebyshev.chebval(x, cgd) + sd)
        lo_i = np.where(f < 0, pp, lo[idx])
        hi_i = np.where(f < 0, hi[idx], pp)
        done = (np.abs(f) <= atol[idx]) | ((hi_i - lo_i) <= 4 * np.finfo(float).eps * hi_i)
        inside = (step > lo_i) & (step < hi_i)
        out[idx[done]] = np.where(inside, step, pp)[done]
        lo[idx], hi[idx] = lo_i, hi_i
        keep = ~done
        if not keep.any():
            break
        pp = np.where(inside, step, 0.5 * (lo_i + hi_i))[keep]
        idx = idx[keep]
        if not keep.all():  # the ends are a few layers: cheap to cut down
            parts = parts.take(keep, ("C", "A"))
    # a ray whose run at p_hi is still short of H needs a larger p than the table holds
    ok = np.isfinite(out) & (out < p_hi)
    if not ok.any():
        return solved
    rays = ends.take(ok, ("C", "H"))
    S = rays.cosines_from_p(out[ok])
    x = out[ok] ** 2 * scale - 1.0
    time[ok] = chebyshev.chebval(x, ct) + rays.times(S)
    p[ok] = out[ok]
    solved[ok] = True
    return solved


def _trace(profile, legs, H, V, tol, max_iter):
    """Solve every ray; return ``p``, ``time`` (NaN where impossible).

    Rays of one leg that share most of their layers go through :func:`_trace_shared`
    first; the rest (and any it leaves) are solved exactly in blocks.
    """
    check_positive("tol", tol)
    check_int("max_iter", max_iter, minimum=1)
    n = H.size
    if n == 0:
        return np.full(0, np.nan), np.full(0, np.nan)
    if len(legs) != 1 or n < _SHARED_MIN:
        return _trace_blocks(profile, legs, H, V, tol, max_iter)
    p, time = np.full(n, np.nan), np.full(n, np.nan)
    solved = _trace_shared(profile, *legs[0], H, V, tol, max_iter, p, time)
    if not solved.any():
        return _trace_blocks(profile, legs, H, V, tol, max_iter)
    if not solved.all():
        rest = np.flatnonzero(~solved)
        p[rest], time[rest] = _trace_blocks(profile, [(t[rest], b[rest]) for t, b in legs],
                                            H[rest], V[rest], tol, max_iter)
    return p, time


def _trace_blocks(profile, legs, H, V, tol, max_iter):
    """Solve every ray exactly, in blocks of rays; return ``p``, ``time``."""
    n = H.size
    p = np.full(n, np.nan)
    time = np.full(n, np.nan)
    deepest = np.max([b for _, b in legs], axis=0)
    shallowest = np.min([t for t, _ in legs], axis=0)
    order = np.lexsort((deepest, shallowest))
    # first guess: the straight chord in the harmonic-mean (vertical time-averaged) speed
    t_vert = 0.0
    for t, b in legs:
        t_vert = t_vert + profile.vertical_time(t, b)
    with np.errstate(divide="ignore", invalid="ignore"):
        c_mean = np.where(V > 0, V / t_vert, profile.speed(shallowest))
    knots = profile.ray_knots[0]
    span = np.count_nonzero((knots > shallowest.min()) & (knots < deepest.max())) + 2
    rows = max(16, _CHUNK // (span * len(legs)))
    for start in range(0, n, rows):
        sel = order[start:start + rows]
        block = Legs(profile, [(t[sel], b[sel]) for t, b in legs])
        phi = _solve_block(block, H[sel], V[sel], c_mean[sel], tol, max_iter)
        ok = np.isfinite(phi)
        if not ok.any():
            continue
        good = block if ok.all() else block.take(ok)
        sphi = np.sin(phi[ok])
        time[sel[ok]] = good.times(good.cosines(sphi * sphi))
        p[sel[ok]] = np.where(H[sel][ok] == 0, 0.0, np.cos(phi[ok]) / good.cmax)
    return p, time


def _angles(profile, p, z, down):
    theta = np.degrees(np.arcsin(np.minimum(p * profile.speed(z), 1.0)))
    return np.where(down, theta, 180.0 - theta)


def direct_ray(profile: SoundSpeedProfile, z_a, z_b, horizontal, *, tol: float = 1e-9,
               max_iter: int = 100) -> Eigenray:
    """Direct (non-turning) eigenray between depths ``z_a`` and ``z_b``.

    Parameters
    ----------
    profile : SoundSpeedProfile
    z_a, z_b : array_like
        Depths of the two ends (m, positive down).
    horizontal : array_like
        Horizontal distance between the ends (m, >= 0). All three broadcast.
    tol : float, default 1e-9
        Relative tolerance on the horizontal run.
    max_iter : int, default 100
        Newton/bisection steps per ray.

    Returns
    -------
    Eigenray
        Invalid (NaN) where the ray would need a turning point.

    Raises
    ------
    ValueError
        Non-finite input, negative horizontal distance, shapes that do not broadcast, or a
        non-positive ``tol``.
    """
    shape, (za, zb, H) = _as_rays(z_a, z_b, horizontal)
    top, bot = np.minimum(za, zb), np.maximum(za, zb)
    p, time = _trace(profile, [(top, bot)], H, bot - top, tol, max_iter)
    flat = (za == zb) & (H > 0) & profile.flat_at(za)
    c = profile.speed(za[flat])
    p[flat], time[flat] = 1.0 / c, H[flat] / c
    valid = np.isfinite(time)
    down = zb >= za
    launch = np.where(valid, _angles(profile, p, za, down), np.nan)
    arrival = np.where(valid, _angles(profile, p, zb, down), np.nan)
    return Eigenray(time.reshape(shape), p.reshape(shape), launch.reshape(shape),
                    arrival.reshape(shape), valid.reshape(shape), "direct")


def surface_bounce_ray(profile: SoundSpeedProfile, z_a, z_b, horizontal, plane_depth=0.0, *,
                       tol: float = 1e-9, max_iter: int = 100) -> Eigenray:
    """Eigenray reflected once by a horizontal plane above both ends.

    Parameters
    ----------
    profile : SoundSpeedProfile
    z_a, z_b, horizontal : array_like
        As :func:`direct_ray`; both ends at or below ``plane_depth``.
    plane_depth : array_like, default 0.0
        Depth of the reflector (m); 0 is the sea surface.
    tol : float, default 1e-9
    max_iter : int, default 100

    Returns
    -------
    Eigenray

    Raises
    ------
    ValueError
        As :func:`direct_ray`, and an end above the plane.
    """
    shape, (za, zb, H, zp) = _as_rays(z_a, z_b, horizontal, (plane_depth,))
    bad = np.flatnonzero((za < zp) | (zb < zp))
    if bad.size:
        i = bad[0]
        raise ValueError(f"surface_bounce_ray: the reflector must be above both ends; at flat "
                         f"index {i} plane_depth = {zp[i]} m but z_a = {za[i]} m, z_b = {zb[i]} "
                         "m")
    V = (za - zp) + (zb - zp)
    p, time = _trace(profile, [(zp, za), (zp, zb)], H, V, tol, max_iter)
    flat = (V == 0) & (H > 0) & profile.flat_at(zp)
    c = profile.speed(zp[flat])
    p[flat], time[flat] = 1.0 / c, H[flat] / c
    valid = np.isfinite(time)
    launch = np.where(valid, _angles(profile, p, za, np.zeros(za.size, bool)), np.nan)
    arrival = np.where(valid, _angles(profile, p, zb, np.ones(zb.size, bool)), np.nan)
    return Eigenray(time.reshape(shape), p.reshape(shape), launch.reshape(shape),
                    arrival.reshape(shape), valid.reshape(shape), "surface_bounce")


def shoot(profile: SoundSpeedProfile, z_a, z_b, p):
    """Horizontal run (m) and travel time (s) of the non-turning ray with ray parameter ``p``.

    Parameters
    ----------
    profile : SoundSpeedProfile
    z_a, z_b : array_like
    p : array_like
        Ray parameter (s/m), ``0 <= p <= 1 / c_max``. All three broadcast.

    Returns
    -------
    horizontal, time : numpy.ndarray
        NaN where ``p`` is negative or the ray would turn; inf along a layer at ``c_max``.

    Raises
    ------
    ValueError
        Non-finite input or shapes that do not broadcast.
    """
    shape, (za, zb, _, pp) = _as_rays(z_a, z_b, 0.0, (p,), ("z_a", "z_b", "", "p"))
    top, bot = np.minimum(za, zb), np.maximum(za, zb)
    x = np.full(za.size, np.nan)
    t = np.full(za.size, np.nan)
    if za.size:
        legs = Legs(profile, [(top, bot)])
        ok = np.isfinite(pp) & (pp >= 0) & (pp * legs.cmax <= 1.0)
        if ok.any():
            sub = legs.take(ok)
            S = sub.cosines_from_p(pp[ok])
            with np.errstate(divide="ignore", invalid="ignore"):
                sx, _ = sub.sums(S, deriv=False, safe=True)
            x[ok] = np.where(bot[ok] > top[ok], pp[ok] * sx, 0.0)
            t[ok] = np.where(np.isinf(x[ok]), np.inf, sub.times(S))
    return x.reshape(shape), t.reshape(shape)
