"""Densities (moved from ``mixture``)."""

from __future__ import annotations

import numpy as np

CLASSES: tuple[str, str, str] = ("dp", "mp", "ol")
LOG_SQRT_2PI = 0.5 * np.log(2.0 * np.pi)
LOG_TINY = -700.0  # exp(-700) ~ 1e-304, just above the smallest normal float64


def gaussian_logpdf(resid, sigma):
    """Log of the normal density of ``resid`` with scale ``sigma`` (broadcasts).

    Parameters
    ----------
    resid, sigma : array_like

    Returns
    -------
    numpy.ndarray
    """
    sigma = np.asarray(sigma, float)
    return -0.5 * (resid / sigma) ** 2 - np.log(sigma) - LOG_SQRT_2PI


def log_mix(ldp, lmp, lol, log_weights):
    """Weighted log densities and their log-sum-exp, without overflow.

    Parameters
    ----------
    ldp, lmp, lol : array_like
        Component log densities (broadcastable).
    log_weights : sequence of three array_like
        Log mixing weights of dp, mp, ol (broadcastable).

    Returns
    -------
    joint : tuple of numpy.ndarray
        The three ``log w_j + log p(z|j)``.
    lse : numpy.ndarray
        Per-range log-likelihood ``log sum_j w_j p(z|j)``.
    """
    a = ldp + log_weights[0]
    b = lmp + log_weights[1]
    c = np.broadcast_to(lol + log_weights[2], np.broadcast(a, b).shape)
    m = np.maximum(np.maximum(a, b), c)
    lse = m + np.log(np.exp(a - m) + np.exp(b - m) + np.exp(c - m))
    return (a, b, c), lse


def safe_log(w):
    """``log(w)`` with ``log(0) = -inf`` and no warning."""
    w = np.asarray(w, float)
    with np.errstate(divide="ignore"):
        return np.log(w)
