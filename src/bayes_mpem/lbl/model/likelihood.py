"""The direct-path / multipath / outlier mixture likelihood, in one place.

A reported range ``z`` of one beacon has density

``p(z) = w_dp N(z; L_direct, s_dp) + w_mp N(z; f_MP(d0), s_mp) + w_ol U(z; lo, hi)``

with ``f_MP`` from :mod:`bayes_mpem.lbl.model.geometry` and the outlier density uniform
over the observed window ``[lo, hi]`` of that beacon's ranges (the
component densities and their log-sum-exp are those of
:mod:`bayes_mpem.mixture.densities`). The EM
(:mod:`bayes_mpem.lbl.em.em_mixture`) and the samplers call these functions; every
parameter broadcasts, so a column of walkers ``d0[:, None]`` evaluates all
walkers at once.
"""

from __future__ import annotations

import numpy as np

from ...mixture.densities import LOG_SQRT_2PI, LOG_TINY, gaussian_logpdf, log_mix, safe_log
from .beacon_geometry import BeaconGeometry
from .loglik_kernel import LoglikKernel


def component_logpdf(geom: BeaconGeometry, d0, sigma_dp, sigma_mp, path: str = "triangle"):
    """Log densities of every range under each class.

    Parameters
    ----------
    geom : BeaconGeometry
    d0, sigma_dp, sigma_mp : float or array_like
        Plane height and the two Gaussian scales (m); arrays broadcast
        against the ranges (use shape ``(W, 1)`` for ``W`` walkers).
    path : {"triangle", "double"}

    Returns
    -------
    tuple of numpy.ndarray
        ``(log p(z|dp), log p(z|mp), log p(z|ol))``; the last is a scalar.
    """
    ldp = gaussian_logpdf(geom.z - geom.direct, sigma_dp)
    lmp = gaussian_logpdf(geom.z - geom.multipath(d0, path), sigma_mp)
    return ldp, lmp, geom.log_ol_density


def e_step(geom: BeaconGeometry, d0, sigma_dp, sigma_mp, weights, path: str = "triangle"):
    """Responsibilities and log-likelihood at the given parameters.

    Parameters
    ----------
    geom : BeaconGeometry
    d0, sigma_dp, sigma_mp : float
    weights : sequence of 3 floats
        Mixing weights of dp, mp, ol.
    path : {"triangle", "double"}

    Returns
    -------
    loglik : float
        Total log-likelihood ``sum_k log p(z_k)``.
    resp : numpy.ndarray
        ``(n, 3)`` class probabilities (columns dp, mp, ol).
    """
    ldp, lmp, lol = component_logpdf(geom, d0, sigma_dp, sigma_mp, path)
    joint, lse = log_mix(ldp, lmp, lol, safe_log(weights))
    resp = np.zeros((geom.n, 3))
    for j in range(3):
        x = joint[j] - lse
        # below exp(-700) the result would be subnormal (or 0): flush to 0, as subnormals
        # slow every later product by ~100x and carry no information
        np.exp(x, out=resp[:, j], where=x > LOG_TINY)
    return float(lse.sum()), resp


def loglik_per_range(geom: BeaconGeometry, d0, sigma_dp, sigma_mp, weights, path="triangle"):
    """Pointwise log-likelihood ``log p(z_k)`` (for LOO and diagnostics).

    Parameters
    ----------
    geom : BeaconGeometry
    d0, sigma_dp, sigma_mp : float or array_like
    weights : sequence of 3 floats or arrays
    path : {"triangle", "double"}

    Returns
    -------
    numpy.ndarray
    """
    ldp, lmp, lol = component_logpdf(geom, d0, sigma_dp, sigma_mp, path)
    return log_mix(ldp, lmp, lol, [safe_log(w) for w in weights])[1]


def weighted_densities(geom: BeaconGeometry, d0, sigma_dp, sigma_mp, weights, path="triangle"):
    """``w_j p(z_k | j)`` of every range for each class, in linear space (broadcasts).

    Exact wherever ``w_ol > 0`` (then the outlier term keeps the sum positive,
    and a Gaussian term that underflows is below 1e-300 of it); the posterior's
    support guarantees it. Class probabilities are each term over their sum,
    and the log of the sum is :func:`loglik_per_range`.

    Parameters
    ----------
    geom : BeaconGeometry
    d0, sigma_dp, sigma_mp : float or numpy.ndarray
        Shape ``(W, 1)`` for ``W`` parameter sets.
    weights : sequence of 3 float or numpy.ndarray
    path : {"triangle", "double"}

    Returns
    -------
    tuple of numpy.ndarray
        ``(dp, mp, ol)`` terms, each broadcast to ``(W, n)``.
    """
    sigma_dp = np.asarray(sigma_dp, float)
    sigma_mp = np.asarray(sigma_mp, float)
    r_dp = geom.z - geom.direct
    r_mp = geom.z - geom.multipath(d0, path)
    c = np.exp(-LOG_SQRT_2PI)
    dp = (c * weights[0] / sigma_dp) * np.exp(-0.5 * (r_dp * r_dp) / (sigma_dp * sigma_dp))
    mp = (c * weights[1] / sigma_mp) * np.exp(-0.5 * (r_mp * r_mp) / (sigma_mp * sigma_mp))
    ol = np.broadcast_to(np.asarray(weights[2], float) * np.exp(geom.log_ol_density), mp.shape)
    return np.broadcast_to(dp, mp.shape), mp, ol


def total_loglik(geom: BeaconGeometry, d0, sigma_dp, sigma_mp, weights, path="triangle"):
    """Sum the log-likelihood for many parameter sets at once, in float64.

    The same density as :func:`loglik_per_range`, evaluated in linear space by
    :class:`~bayes_mpem.lbl.model.loglik_kernel.LoglikKernel` (two exponentials and one
    logarithm per range instead of log-sum-exp; terms that are exactly 0 for
    every parameter set are skipped). The uniform outlier term keeps the sum
    positive wherever ``w_ol > 0``; the result agrees with the log-space form to
    rounding (tested). The sampler keeps one kernel per beacon instead, so that
    the screen of ranges is made once.

    Parameters
    ----------
    geom : BeaconGeometry
        Straight-ray only.
    d0, sigma_dp, sigma_mp : numpy.ndarray
        Shape ``(W, 1)`` for ``W`` parameter sets.
    weights : sequence of 3 numpy.ndarray
        ``w_dp, w_mp, w_ol``, each of shape ``(W, 1)``.
    path : {"triangle", "double"}

    Returns
    -------
    numpy.ndarray
        ``(W,)`` log-likelihoods; ``-inf`` where a range has zero density.

    Raises
    ------
    NotImplementedError
        For a refracted geometry (``geom.straight`` False).
    """
    d0, sigma_dp, sigma_mp, *weights = np.broadcast_arrays(
        *(np.asarray(v, float) for v in (d0, sigma_dp, sigma_mp, *weights)))
    kernel = LoglikKernel(geom, path, precision="float64")
    return kernel(d0, sigma_dp, sigma_mp, *weights)
