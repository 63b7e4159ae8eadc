"""The two classes of a survey-in ping, true arrival or spurious: their log-densities.

Examples
--------
>>> import numpy as np
>>> ld, lu = log_classes(np.array([1.0]), np.array([1.0]), 0.001, 0.9, (0.0, 10.0),
...                      "uniform")
>>> round(float(true_probability(ld, lu)[0]), 6)
0.999972
"""

from __future__ import annotations

import numpy as np

from ..mixture.densities import first_arrival_logpdf, uniform_logpdf

#: The spurious arrivals: uniform over the window, or before the true arrival.
OUTLIER_MODELS = ("uniform", "first_arrival")


def log_classes(t, pred, sigma, weight, window, outliers):
    """Weighted log densities (true, spurious) of travel times ``t`` given predictions.

    Parameters
    ----------
    t : numpy.ndarray
        Two-way travel times (s).
    pred : numpy.ndarray
        Predicted travel time of a true arrival for each ping (s).
    sigma : float
        Scatter of the true arrivals (s).
    weight : float
        Fraction of true arrivals.
    window : tuple of float
        The listening window ``(lo, hi)`` (s).
    outliers : {"uniform", "first_arrival"}
        Spurious pings uniform over the window, or reported by a first-arrival
        detector (:func:`~bayes_mpem.mixture.densities.first_arrival_logpdf`).

    Returns
    -------
    ld, lu : numpy.ndarray
        ``log(weight) + log N(t; pred, sigma)`` and ``log(1 - weight) + log
        p_spurious(t)``; ``lu`` is ``-inf`` when ``weight >= 1``.
    """
    lo, hi = window
    # the Gaussian in this operation order (log of sigma sqrt(2 pi) in one piece), not
    # gaussian_logpdf's: it differs in the last bit, and the recorded fits use this one
    ld = np.log(weight) - 0.5 * ((t - pred) / sigma) ** 2 - np.log(sigma * np.sqrt(2 * np.pi))
    if weight >= 1:
        return ld, np.full_like(t, -np.inf)
    if outliers == "uniform":
        lu = np.full_like(t, uniform_logpdf(lo, hi))
    else:  # a detector reporting the first threshold crossing: spurious before the true arrival
        lu = first_arrival_logpdf(t, pred, lo, hi, min_early=1e-6)
    return ld, np.log1p(-weight) + lu


def true_probability(ld, lu):
    """Probability of a true arrival from the two class log-densities (broadcasts).

    Parameters
    ----------
    ld, lu : array_like
        Weighted log-densities of the true and the spurious class
        (:func:`log_classes`).

    Returns
    -------
    numpy.ndarray
        ``1 / (1 + exp(lu - ld))``, with the exponent clipped to +-700.

    Examples
    --------
    >>> float(true_probability(0.0, 0.0))
    0.5
    """
    return 1.0 / (1.0 + np.exp(np.clip(lu - ld, -700.0, 700.0)))
