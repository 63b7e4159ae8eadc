"""The direct-path / multipath / outlier mixture likelihood, in one place."""

from __future__ import annotations

import numpy as np

from ...mixture.densities import LOG_TINY, gaussian_logpdf, log_mix, safe_log
from .beacon_geometry import BeaconGeometry
from .loglik_kernel import LoglikKernel


def _component_logpdf(geom: BeaconGeometry, d0, sigma_dp, sigma_mp, path: str = "triangle"):
    """Log densities of every range under each class."""
    ldp = gaussian_logpdf(geom.z - geom.direct, sigma_dp)
    lmp = gaussian_logpdf(geom.z - geom.multipath(d0, path), sigma_mp)
    return ldp, lmp, geom.log_ol_density


def e_step(geom: BeaconGeometry, d0, sigma_dp, sigma_mp, weights, path: str = "triangle"):
    """Return the log-likelihood and the ``(n, 3)`` class probabilities (dp, mp, ol).

    Returns
    -------
    loglik : float
    resp : numpy.ndarray
    """
    ldp, lmp, lol = _component_logpdf(geom, d0, sigma_dp, sigma_mp, path)
    joint, lse = log_mix(ldp, lmp, lol, safe_log(weights))
    resp = np.zeros((geom.n, 3))
    for j in range(3):
        x = joint[j] - lse
        # below exp(-700) the result would be subnormal (or 0): flush to 0, as subnormals
        # slow every later product by ~100x and carry no information
        np.exp(x, out=resp[:, j], where=x > LOG_TINY)
    return float(lse.sum()), resp


def loglik_per_range(geom: BeaconGeometry, d0, sigma_dp, sigma_mp, weights, path="triangle"):
    """Pointwise log-likelihood ``log p(z_k)`` (for LOO and diagnostics)."""
    ldp, lmp, lol = _component_logpdf(geom, d0, sigma_dp, sigma_mp, path)
    return log_mix(ldp, lmp, lol, [safe_log(w) for w in weights])[1]


def total_loglik(geom: BeaconGeometry, d0, sigma_dp, sigma_mp, weights, path="triangle"):
    """Sum the log-likelihood for many parameter sets at once (straight rays), in float64.

    Parameters
    ----------
    d0, sigma_dp, sigma_mp : numpy.ndarray
        Shape ``(W, 1)`` for ``W`` parameter sets.

    Returns
    -------
    numpy.ndarray
        ``(W,)``; ``-inf`` where a range has zero density.

    Raises
    ------
    NotImplementedError
        For a refracted geometry.
    """
    d0, sigma_dp, sigma_mp, *weights = np.broadcast_arrays(
        *(np.asarray(v, float) for v in (d0, sigma_dp, sigma_mp, *weights)))
    kernel = LoglikKernel(geom, path, precision="float64")
    return kernel(d0, sigma_dp, sigma_mp, *weights)
