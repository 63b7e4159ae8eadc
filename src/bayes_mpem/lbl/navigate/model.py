"""The per-ping pieces of the navigation model, shared by batch and streaming.

Metres, depths positive down, heading bias in radians counter-clockwise (``docs/navigate.md``).

Examples
--------
A vehicle 30 m east of a beacon 40 m below it:

>>> import numpy as np
>>> pred = predict_ranges(30.0, 0.0, 0.0, (0.0, 0.0, 40.0), 40.0)
>>> float(pred.direct), pred.grad_direct.tolist()
(50.0, [0.6, 0.0])
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ...mixture.densities import LOG_TINY, gaussian_logpdf, log_mix
from ..model import geometry


class RangePrediction(NamedTuple):
    """Predicted ranges of a vehicle position and their derivatives.

    Attributes
    ----------
    direct, multipath : numpy.ndarray
        Predicted direct-path and multipath ranges (m).
    grad_direct, grad_multipath : numpy.ndarray
        ``(..., 2)`` derivatives with respect to the vehicle's ``(x, y)``.
    d_multipath_d0 : numpy.ndarray
        Derivative of the multipath range with respect to the plane height.
    """

    direct: np.ndarray
    multipath: np.ndarray
    grad_direct: np.ndarray
    grad_multipath: np.ndarray
    d_multipath_d0: np.ndarray


def predict_ranges(x, y, depth, beacon, d0, path="triangle") -> RangePrediction:
    """Direct and multipath ranges of vehicle positions, with their derivatives.

    Parameters
    ----------
    x, y : array_like
        Vehicle horizontal position (m).
    depth : array_like
        Vehicle depth (m, positive down; trusted, not estimated).
    beacon : sequence of 3 array_like
        Beacon ``x``, ``y``, ``depth`` (one beacon, or one per range).
    d0 : float or array_like
        Height of the reflecting plane above the beacon (m).
    path : {"triangle", "double"} or array_like
        Multipath geometry (one, or one per range: names or a boolean mask
        that is True for the double bounce).

    Examples
    --------
    The derivative matches a finite difference:

    >>> p0 = predict_ranges(100.0, 50.0, 20.0, (0.0, 0.0, 500.0), 480.0)
    >>> p1 = predict_ranges(100.001, 50.0, 20.0, (0.0, 0.0, 500.0), 480.0)
    >>> bool(abs((p1.multipath - p0.multipath) / 1e-3 - p0.grad_multipath[0]) < 1e-6)
    True
    """
    bx, by, bz = (np.asarray(v, float) for v in beacon)
    dx = np.asarray(x, float) - bx
    dy = np.asarray(y, float) - by
    h = np.hypot(dx, dy)
    dz = bz - np.asarray(depth, float)
    direct = geometry.direct_path(h, dz)
    mp = geometry.multipath_range(h, dz, d0, path, direct=direct)
    s_dp, s_mp = geometry.horizontal_slopes(h, dz, d0, path, direct=direct)
    grad_dp = np.stack([dx * s_dp, dy * s_dp], axis=-1)
    grad_mp = np.stack([dx * s_mp, dy * s_mp], axis=-1)
    dd0 = geometry.multipath_derivative(h, dz, d0, path)
    return RangePrediction(direct, mp, grad_dp, grad_mp, dd0)


def class_log_joint(z, direct, multipath, sigma_dp, sigma_mp, log_ol, log_weights):
    """``log w_j + log p(z | j)`` of the three classes, their log-sum-exp and probabilities.

    Parameters
    ----------
    z : array_like
        Measured ranges (m).
    direct, multipath : array_like
        Predicted ranges (m).
    sigma_dp, sigma_mp : array_like
        Scales of the direct-path and multipath Gaussians (m).
    log_ol : array_like
        Log-density of an outlier (uniform over the beacon's window, 1/m).
    log_weights : array_like
        ``(..., 3)`` log mixing weights of dp, mp, ol; ``-inf`` switches a
        class off (multipath treated as an outlier).

    Returns
    -------
    resp : numpy.ndarray
        ``(..., 3)`` class probabilities (below ``exp(-700)`` flushed to 0).
    lse : numpy.ndarray
        Log-likelihood of every range, ``log sum_j w_j p(z | j)``.

    Examples
    --------
    A range on the direct path, far from the multipath:

    >>> resp, lse = class_log_joint(100.0, 100.0, 300.0, 2.0, 5.0, np.log(1 / 1000),
    ...                             np.log([0.6, 0.3, 0.1]))
    >>> np.round(resp, 4).tolist()
    [0.9992, 0.0, 0.0008]
    """
    z = np.asarray(z, float)
    ldp = gaussian_logpdf(z - direct, sigma_dp)
    lmp = gaussian_logpdf(z - multipath, sigma_mp)
    lw = np.asarray(log_weights, float)
    joint, lse = log_mix(ldp, lmp, log_ol, [lw[..., 0], lw[..., 1], lw[..., 2]])
    resp = np.zeros(np.shape(lse) + (3,))
    for j in range(3):
        d = joint[j] - lse
        np.exp(d, out=resp[..., j], where=d > LOG_TINY)
    return resp, lse


def rotation(beta):
    """Return the rotation matrix ``R(beta)`` and its derivative.

    Parameters
    ----------
    beta : float
        Angle (rad, counter-clockwise).

    Returns
    -------
    R, dR : numpy.ndarray
        ``(2, 2)`` each.

    Examples
    --------
    >>> R, _ = rotation(np.pi / 2)
    >>> np.round(R @ [1.0, 0.0], 12).tolist()
    [0.0, 1.0]
    """
    c, s = np.cos(beta), np.sin(beta)
    return np.array([[c, -s], [s, c]]), np.array([[-s, -c], [c, -s]])


def dr_step(p_prev, delta, beta, scale):
    """Predict a position by the dead-reckoning motion model, with its derivatives.

    ``p_k = p_{k-1} + scale R(beta) delta`` (plus the random walk of
    :func:`dr_noise_var`).

    Parameters
    ----------
    p_prev : array_like
        ``(..., 2)`` previous positions.
    delta : array_like
        ``(..., 2)`` dead-reckoned displacements over the step (m).
    beta : float
        Heading bias (rad).
    scale : float
        Speed scale.

    Returns
    -------
    p_pred : numpy.ndarray
        ``(..., 2)`` predicted positions.
    d_beta, d_scale : numpy.ndarray
        ``(..., 2)`` derivatives of the prediction with respect to ``beta`` and
        ``scale``.

    Examples
    --------
    >>> p, db, ds = dr_step([0.0, 0.0], [10.0, 0.0], 0.0, 1.1)
    >>> p.tolist(), db.tolist(), ds.tolist()
    ([11.0, 0.0], [0.0, 11.0], [10.0, 0.0])
    """
    R, dR = rotation(beta)
    delta = np.asarray(delta, float)
    rot = delta @ R.T
    return np.asarray(p_prev, float) + scale * rot, scale * (delta @ dR.T), rot


def dr_noise_var(dt, q):
    """Variance (m^2, per axis) of the random walk over ``dt`` seconds: ``q^2 dt``.

    Parameters
    ----------
    dt : array_like
        Time steps (s).
    q : float
        Noise level (m / sqrt(s)).

    Examples
    --------
    >>> round(float(dr_noise_var(100.0, 0.1)), 12)
    1.0
    """
    return q * q * np.asarray(dt, float)
