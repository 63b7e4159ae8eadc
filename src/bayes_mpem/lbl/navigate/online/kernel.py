"""The navigation model of one ping in plain Python floats (``docs/stream.md``)."""

from __future__ import annotations

import math

from ....mixture.densities import LOG_SQRT_2PI, LOG_TINY

_LOG_SQRT_2PI = float(LOG_SQRT_2PI)  # a Python float: no NumPy scalar in the arithmetic


def ranges(x, y, depth, bx, by, bz, d0, double):
    """Direct and multipath range of one position, with their derivatives.

    Parameters
    ----------
    x, y, depth : float
        Vehicle position (m, depth positive down).
    bx, by, bz : float
        Beacon position (m, depth positive down).
    d0 : float
        Plane height above the beacon (m).
    double : bool
        Double bounce (else the triangle path).

    Returns
    -------
    tuple of float
        ``(direct, multipath, d_direct/dx, d_direct/dy, d_mp/dx, d_mp/dy, d_mp/d_d0)``,
        as :func:`~bayes_mpem.lbl.navigate.model.predict_ranges`.

    Examples
    --------
    >>> d, m, *_ = ranges(0.0, 0.0, 10.0, 0.0, 0.0, 110.0, 110.0, True)
    >>> d, m
    (100.0, 120.0)
    """
    dx = x - bx
    dy = y - by
    h = math.hypot(dx, dy)
    dz = bz - depth
    direct = math.hypot(h, dz)
    lever = 2.0 * d0 - dz
    refl = math.hypot(h, lever)
    inv_d = 1.0 / direct
    inv_r = 1.0 / refl
    if double:
        mp, s_mp, dd0 = refl, inv_r, 2.0 * lever * inv_r
    else:
        mp, s_mp, dd0 = 0.5 * (direct + refl), 0.5 * (inv_d + inv_r), lever * inv_r
    return direct, mp, dx * inv_d, dy * inv_d, dx * s_mp, dy * s_mp, dd0


def gaussian_logpdf(resid, sigma):
    """Return the normal log-density of a residual (as ``mixture.densities.gaussian_logpdf``).

    Examples
    --------
    >>> round(gaussian_logpdf(2.0, 2.0), 6)
    -2.112086
    """
    u = resid / sigma
    return -0.5 * u * u - math.log(sigma) - _LOG_SQRT_2PI


def class_probabilities(z, direct, multipath, sigma_dp, sigma_mp, log_ol, lw_dp, lw_mp, lw_ol):
    """Class probabilities and log-likelihood of one range (as ``class_log_joint``).

    Parameters
    ----------
    z : float
        The range (m).
    direct, multipath : float
        Predicted ranges (m).
    sigma_dp, sigma_mp : float
        Scales (m) of the two Gaussians.
    log_ol : float
        Log-density of an outlier.
    lw_dp, lw_mp, lw_ol : float
        Log mixing weights; ``-inf`` switches a class off.

    Returns
    -------
    p_dp, p_mp, p_ol, lse : float
        Probabilities below ``exp(-700)`` are flushed to 0, as
        :func:`~bayes_mpem.lbl.navigate.model.class_log_joint` does.

    Examples
    --------
    >>> p = class_probabilities(100.0, 100.0, 300.0, 2.0, 5.0, math.log(1 / 1000),
    ...                         math.log(0.6), math.log(0.3), math.log(0.1))
    >>> [round(v, 4) for v in p[:3]]
    [0.9992, 0.0, 0.0008]
    """
    a = gaussian_logpdf(z - direct, sigma_dp) + lw_dp
    b = gaussian_logpdf(z - multipath, sigma_mp) + lw_mp
    c = log_ol + lw_ol
    m = max(a, b, c)
    lse = m + math.log(math.exp(a - m) + math.exp(b - m) + math.exp(c - m))
    a, b, c = a - lse, b - lse, c - lse
    return (math.exp(a) if a > LOG_TINY else 0.0, math.exp(b) if b > LOG_TINY else 0.0,
            math.exp(c) if c > LOG_TINY else 0.0, lse)


def log_weight(w):
    """``log(w)``, ``-inf`` for 0 (as :func:`~bayes_mpem.mixture.densities.safe_log`).

    Examples
    --------
    >>> log_weight(0.0)
    -inf
    """
    return math.log(w) if w > 0.0 else -math.inf


def dr_step(dx, dy, beta, scale):
    """Return the dead-reckoning step ``s R(beta) Delta`` and its derivatives (as ``dr_step``).

    Parameters
    ----------
    dx, dy : float
        Dead-reckoned displacement (m).
    beta : float
        Heading bias (rad, counter-clockwise).
    scale : float
        Speed scale.

    Returns
    -------
    tuple of float
        ``(step_x, step_y, d/dbeta x, d/dbeta y, d/dscale x, d/dscale y)``.

    Examples
    --------
    >>> dr_step(10.0, 0.0, 0.0, 1.1)
    (11.0, 0.0, -0.0, 11.0, 10.0, 0.0)
    """
    c, s = math.cos(beta), math.sin(beta)
    rx, ry = c * dx - s * dy, s * dx + c * dy
    return scale * rx, scale * ry, -scale * ry, scale * rx, rx, ry
