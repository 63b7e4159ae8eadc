"""Refracted eigenrays without a turning point through a layered ocean.

Depth positive down (m), speed (m/s), times (s). Each ray keeps its ray parameter
``p = sin(theta) / c``; the layer formulas (``acoustics.layers``) are written without
dividing by the gradient, so they stay exact as it goes to 0. A horizontal distance that
needs a turning point is NaN here; :func:`bayes_mpem.acoustics.turning.direct_times`
solves those. Formulas and timings: ``docs/refraction.md``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .._validate import check_int, check_positive
from .layers import Legs
from .profile import SoundSpeedProfile

_CHUNK = 1 << 15  # array elements per block of rays (keeps the temporaries in cache)




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
        Direction of travel at ``z_a`` and at ``z_b``, degrees from the downward
        vertical: 0 straight down, 90 horizontal, 180 straight up.
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


def _trace(profile, legs, H, V, tol, max_iter):
    """Solve every ray in blocks; return ``p``, ``time`` (NaN where impossible)."""
    check_positive("tol", tol)
    check_int("max_iter", max_iter, minimum=1)
    n = H.size
    p = np.full(n, np.nan)
    time = np.full(n, np.nan)
    if n == 0:
        return p, time
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
        Depths of the two ends (m, positive down); either may be the deeper.
    horizontal : array_like
        Horizontal distance between the ends (m, >= 0). All three broadcast.
    tol : float, default 1e-9
        Stop when the ray's horizontal run misses ``horizontal`` by at most
        ``tol * max(horizontal, |z_b - z_a|)``.
    max_iter : int, default 100
        Newton/bisection steps per ray; a ray not converged by then is invalid.

    Returns
    -------
    Eigenray
        ``time`` is symmetric in the ends. Invalid (NaN) where the horizontal
        distance needs a turning point, including ``z_a == z_b`` with
        ``horizontal > 0`` unless the speed is constant around that depth (then
        the ray is the horizontal line, ``time = horizontal / c``).

    Raises
    ------
    ValueError
        Non-finite input, negative horizontal distance, shapes that do not
        broadcast, or a non-positive ``tol``.

    Examples
    --------
    In a homogeneous medium the ray is the straight line:

    >>> ray = direct_ray(SoundSpeedProfile.constant(1500.0), 0.0, 400.0, 300.0)
    >>> round(float(ray.time * 1500.0), 9), round(float(ray.launch_angle), 4)
    (500.0, 36.8699)

    Speed falling with depth bends the ray down; a far, shallow target would need
    a turning point:

    >>> prof = SoundSpeedProfile([0.0, 1000.0], [1540.0, 1490.0])
    >>> ray = direct_ray(prof, 1000.0, [900.0, 900.0], [500.0, 5000.0])
    >>> ray.valid.tolist()
    [True, False]
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
    z_a, z_b : array_like
        Depths of the two ends (m); both at or below ``plane_depth``.
    horizontal : array_like
        Horizontal distance between the ends (m, >= 0).
    plane_depth : array_like, default 0.0
        Depth of the reflector (m); 0 is the sea surface. Broadcasts with the rest.
    tol : float, default 1e-9
        Stop when the horizontal run misses by at most ``tol * max(horizontal,
        vertical path)``.
    max_iter : int, default 100

    Returns
    -------
    Eigenray
        ``launch_angle`` points up (> 90), ``arrival_angle`` down (< 90).

    Raises
    ------
    ValueError
        As :func:`direct_ray`, and an end above the plane (names the index).

    Examples
    --------
    >>> ray = surface_bounce_ray(SoundSpeedProfile.constant(1500.0), 2400.0, 10.0, 3000.0)
    >>> d = float(np.hypot(3000.0, 2400.0 + 10.0))  # to the image of z_b above the surface
    >>> abs(float(ray.time) * 1500.0 - d) < 1e-9
    True
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
    """Horizontal run and travel time of the non-turning ray with ray parameter ``p``.

    Parameters
    ----------
    profile : SoundSpeedProfile
    z_a, z_b : array_like
        Depths of the ends (m).
    p : array_like
        Ray parameter (s/m), ``0 <= p <= 1 / c_max`` with ``c_max`` the fastest
        speed between the ends. All three broadcast.

    Returns
    -------
    horizontal, time : numpy.ndarray
        m and s; NaN where ``p`` is negative or the ray would turn
        (``p c_max > 1``); inf at ``p = 1 / c_max`` when the fastest speed holds
        over a layer of finite thickness (the ray runs along it for ever).

    Raises
    ------
    ValueError
        Non-finite input or shapes that do not broadcast.

    Examples
    --------
    >>> x, t = shoot(SoundSpeedProfile.constant(1500.0), 0.0, 400.0, 0.6 / 1500.0)
    >>> round(float(x), 9), round(float(t) * 1500.0, 9)
    (300.0, 500.0)
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
