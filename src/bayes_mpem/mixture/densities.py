"""Component log-densities of a mixture and their log-sum-exp (broadcasting, in log space)."""

from __future__ import annotations

import numpy as np

#: The three classes of the LBL mixture: direct path, multipath, outlier.
CLASSES: tuple[str, str, str] = ("dp", "mp", "ol")
#: ``log(sqrt(2 pi))``, the normalising constant of the standard normal.
LOG_SQRT_2PI = 0.5 * np.log(2.0 * np.pi)
#: ``exp(-700) ~ 1e-304``, just above the smallest normal float64.
LOG_TINY = -700.0
#: Share of the first-arrival outlier density spread over the whole window
#: (outliers after the true arrival are rare, not impossible).
EPS_LATE = 1e-3


def gaussian_logpdf(resid, sigma):
    """Log of the normal density of ``resid`` with scale ``sigma`` (broadcasts).

    Parameters
    ----------
    resid, sigma : array_like
        Measurement minus prediction, and its standard deviation.

    Returns
    -------
    numpy.ndarray

    Examples
    --------
    >>> round(float(gaussian_logpdf(2.0, 2.0)), 6)
    -2.112086
    """
    sigma = np.asarray(sigma, float)
    return -0.5 * (resid / sigma) ** 2 - np.log(sigma) - LOG_SQRT_2PI


def uniform_logpdf(lo, hi, *, min_width=1e-9):
    """Log-density of outliers uniform over the window ``[lo, hi]`` (broadcasts).

    Parameters
    ----------
    lo, hi : array_like
        Window bounds.
    min_width : float, default 1e-9
        Floor on the width, so that a window of one value stays finite.

    Returns
    -------
    numpy.ndarray
    """
    return -np.log(np.maximum(np.subtract(hi, lo), min_width))


def first_arrival_logpdf(x, arrival, lo, hi, *, min_early, min_width=1e-9):
    """Log-density of outliers reported by a first-arrival detector (broadcasts).

    A first-arrival detector cannot report a false detection after the true arrival:
    outliers are uniform on ``[lo, arrival]``, a share :data:`EPS_LATE` spread over ``[lo, hi]``.

    Parameters
    ----------
    x, arrival : array_like
        Measured values and the predicted true arrival of each.
    lo, hi : array_like
        Window bounds.
    min_early, min_width : float
        Floors on ``arrival - lo`` and on ``hi - lo`` (default 1e-9).

    Returns
    -------
    numpy.ndarray

    Examples
    --------
    >>> out = first_arrival_logpdf([1.0, 5.0], 2.0, 0.0, 10.0, min_early=1e-6)
    >>> [round(float(v), 4) for v in out]
    [-0.6939, -9.2103]
    """
    width = np.maximum(np.subtract(hi, lo), min_width)
    early = np.maximum(np.subtract(arrival, lo), min_early)
    return np.where(np.less_equal(x, arrival), np.log((1.0 - EPS_LATE) / early + EPS_LATE / width),
                    np.log(EPS_LATE / width))


def log_mix(ldp, lmp, lol, log_weights):
    """Weighted log densities of three classes and their log-sum-exp, without overflow.

    Parameters
    ----------
    ldp, lmp, lol : array_like
        Component log densities (broadcastable).
    log_weights : sequence of three array_like
        Log mixing weights of dp, mp, ol.

    Returns
    -------
    joint : tuple of numpy.ndarray
        The three ``log w_j + log p(z|j)``.
    lse : numpy.ndarray
        Per-range log-likelihood.
    """
    a = ldp + log_weights[0]
    b = lmp + log_weights[1]
    c = np.broadcast_to(lol + log_weights[2], np.broadcast(a, b).shape)
    m = np.maximum(np.maximum(a, b), c)
    lse = m + np.log(np.exp(a - m) + np.exp(b - m) + np.exp(c - m))
    return (a, b, c), lse


def responsibilities(log_joint):
    """Class probabilities and log-sum-exp of weighted log densities (last axis).

    Parameters
    ----------
    log_joint : numpy.ndarray
        ``log w_j + log p(x|j)``, one column per class; every row needs one finite entry.

    Returns
    -------
    resp, log_norm : numpy.ndarray
        Class probabilities (rows summing to 1) and ``log sum_j w_j p(x|j)`` of every row.

    Examples
    --------
    >>> resp, log_norm = responsibilities(np.log([[0.1, 0.3], [0.2, 0.2]]))
    >>> np.round(resp, 6).tolist(), np.round(log_norm, 6).tolist()
    ([[0.25, 0.75], [0.5, 0.5]], [-0.916291, -0.916291])
    """
    m = np.max(log_joint, axis=-1)
    e = np.exp(log_joint - m[..., None])
    s = e.sum(axis=-1)
    return e / s[..., None], m + np.log(s)


def safe_log(w):
    """``log(w)`` with ``log(0) = -inf`` and no warning.

    Parameters
    ----------
    w : array_like
        Non-negative values (mixing weights).

    Returns
    -------
    numpy.ndarray
    """
    w = np.asarray(w, float)
    with np.errstate(divide="ignore"):
        return np.log(w)
