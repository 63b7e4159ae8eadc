"""The shared mixture densities (bayes_mpem.mixture.densities)."""

import numpy as np
import pytest
from scipy import integrate, stats

from bayes_mpem.mixture.densities import (
    EPS_LATE,
    first_arrival_logpdf,
    gaussian_logpdf,
    log_mix,
    responsibilities,
    uniform_logpdf,
)


def test_gaussian_matches_scipy():
    """The Gaussian log-density is scipy's."""
    r = np.linspace(-5.0, 5.0, 11)
    np.testing.assert_allclose(gaussian_logpdf(r, 2.0), stats.norm.logpdf(r, scale=2.0),
                               rtol=1e-14)


def test_uniform_and_first_arrival_integrate_to_one():
    """Both outlier densities are normalised over the window."""
    lo, hi, arrival = 10.0, 30.0, 17.0
    assert np.exp(uniform_logpdf(lo, hi)) * (hi - lo) == pytest.approx(1.0)

    def dens(x):
        return float(np.exp(first_arrival_logpdf(x, arrival, lo, hi, min_early=1e-6)))

    total = (integrate.quad(dens, lo, arrival)[0] + integrate.quad(dens, arrival, hi)[0])
    assert total == pytest.approx(1.0, rel=1e-10)
    after = integrate.quad(dens, arrival, hi)[0]
    assert after == pytest.approx(EPS_LATE * (hi - arrival) / (hi - lo), rel=1e-10)


def test_floors_keep_degenerate_windows_finite():
    """A window of one value and an arrival at the window start stay finite."""
    assert np.isfinite(uniform_logpdf(5.0, 5.0))
    assert np.all(np.isfinite(first_arrival_logpdf([5.0, 6.0], 5.0, 5.0, 5.0, min_early=1.0)))


def test_responsibilities_agree_with_log_mix():
    """The general log-sum-exp matches the three-class one."""
    gen = np.random.default_rng(0)
    ld = gen.normal(size=(3, 50)) * 30.0
    lw = np.log([0.5, 0.3, 0.2])
    joint, lse = log_mix(ld[0], ld[1], ld[2], lw)
    resp, log_norm = responsibilities(np.stack(joint, axis=1))
    np.testing.assert_allclose(log_norm, lse, rtol=1e-13)
    np.testing.assert_allclose(resp.sum(axis=1), 1.0, rtol=1e-13)
    np.testing.assert_allclose(resp, np.exp(np.stack(joint, axis=1) - lse[:, None]),
                               rtol=1e-10, atol=1e-300)
