"""The direct-path / multipath / outlier mixture likelihood, in one place.

A reported range ``z`` of one beacon has density

``p(z) = w_dp N(z; L_direct, s_dp) + w_mp N(z; f_MP(d0), s_mp) + w_ol U(z; lo, hi)``

with ``f_MP`` from :mod:`bayes_mpem.lbl.geometry` and the outlier density uniform
over the observed window ``[lo, hi]`` of that beacon's ranges (the
component densities and their log-sum-exp are those of
:mod:`bayes_mpem.mixture.densities`). The EM
(:mod:`bayes_mpem.lbl.em_mixture`) and the samplers call these functions; every
parameter broadcasts, so a column of walkers ``d0[:, None]`` evaluates all
walkers at once.
"""

from __future__ import annotations

import numpy as np

from ..mixture.densities import LOG_SQRT_2PI, LOG_TINY, gaussian_logpdf, log_mix, safe_log
from . import geometry
from .beacon_geometry import BeaconGeometry


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


#: beyond this many standard deviations exp(-x^2 / 2) is exactly 0 in float64 (38.6)
_ZERO_SIGMAS = 40.0


def total_loglik(geom: BeaconGeometry, d0, sigma_dp, sigma_mp, weights, path="triangle"):
    """Sum the log-likelihood for many parameter sets at once (the sampler's kernel).

    The same density as :func:`loglik_per_range`, evaluated in linear space:
    two exponentials and one logarithm per range instead of log-sum-exp. The
    uniform outlier term keeps the sum positive wherever ``w_ol > 0``; where a
    Gaussian term underflows it is below 1e-300 of the outlier term, so the
    result agrees with the log-space form to rounding (tested).

    Ranges whose direct-path (or multipath) term is exactly 0 in float64 for
    every parameter set of the call, more than 40 of the largest sigma away
    from the prediction, skip that term; ranges with both terms 0 are counted,
    not evaluated. The multipath residual is bounded over the call's ``d0``
    values through ``|d z_MP / d d0| <= 1`` (triangle) or ``2`` (double). The
    sum is unchanged up to rounding (tested), and about twice as fast.

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
    if not geom.straight:
        raise NotImplementedError("total_loglik: straight-ray geometry only (its multipath bound "
                                  "is the image method's); use loglik_per_range for a "
                                  "refracted geometry")
    d0 = np.asarray(d0, float)
    sigma_dp = np.asarray(sigma_dp, float)
    sigma_mp = np.asarray(sigma_mp, float)
    r_dp = geom.z - geom.direct
    near_dp = np.abs(r_dp) < _ZERO_SIGMAS * float(sigma_dp.max())
    d_ref = float(np.median(d0))
    slope = 1.0 if path == "triangle" else 2.0
    reach = slope * float(np.max(np.abs(d0 - d_ref)))
    near_mp = (np.abs(geom.z - geom.multipath(d_ref, path)) - reach
               < _ZERO_SIGMAS * float(sigma_mp.max()))
    # columns ordered [direct only | both | multipath only]; the rest have the outlier term only
    only_dp = np.flatnonzero(near_dp & ~near_mp)
    both = np.flatnonzero(near_dp & near_mp)
    only_mp = np.flatnonzero(~near_dp & near_mp)
    cols = np.concatenate([only_dp, both, only_mp])
    n_dp = only_dp.size + both.size
    ol = weights[2] * np.exp(geom.log_ol_density + LOG_SQRT_2PI)
    dens = np.repeat(np.reshape(ol, (-1, 1)), cols.size, axis=1)
    rd = r_dp[cols[:n_dp]]
    dens[:, :n_dp] += (weights[0] / sigma_dp) * np.exp(-0.5 * (rd * rd) / (sigma_dp * sigma_dp))
    m = cols[only_dp.size:]
    pred = geometry.multipath_range(geom.h[m], geom.dz[m], d0, path, direct=geom.direct[m])
    rm = geom.z[m] - pred
    dens[:, only_dp.size:] += (weights[1] / sigma_mp) * np.exp(
        -0.5 * (rm * rm) / (sigma_mp * sigma_mp))
    n_rest = geom.n - cols.size
    with np.errstate(divide="ignore"):
        out = np.log(dens).sum(axis=-1)
        if n_rest:  # (0 * log(0) would be NaN when w_ol = 0 and nothing is left)
            out = out + n_rest * np.log(ol).ravel()
    return out - geom.n * LOG_SQRT_2PI
