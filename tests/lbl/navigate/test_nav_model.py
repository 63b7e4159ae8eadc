"""The per-ping pieces: predictions and derivatives, class probabilities, the motion model."""

import numpy as np
import pytest

from bayes_mpem.lbl.navigate.model import (
    class_log_joint,
    dr_noise_var,
    dr_step,
    predict_ranges,
    rotation,
)
from bayes_mpem.mixture.densities import gaussian_logpdf, responsibilities


@pytest.mark.parametrize("path", ["triangle", "double"])
def test_prediction_derivatives_match_finite_differences(path):
    rng = np.random.default_rng(1)
    x, y = rng.uniform(-2000, 2000, 30), rng.uniform(-2000, 2000, 30)
    depth = rng.uniform(5, 2300, 30)
    beacon, d0 = (150.0, -80.0, 2400.0), 2395.0
    p = predict_ranges(x, y, depth, beacon, d0, path)
    eps = 1e-4
    for ax in range(2):
        dx = (eps, 0.0) if ax == 0 else (0.0, eps)
        hi = predict_ranges(x + dx[0], y + dx[1], depth, beacon, d0, path)
        lo = predict_ranges(x - dx[0], y - dx[1], depth, beacon, d0, path)
        np.testing.assert_allclose(p.grad_direct[:, ax], (hi.direct - lo.direct) / (2 * eps),
                                   atol=1e-7)
        np.testing.assert_allclose(p.grad_multipath[:, ax],
                                   (hi.multipath - lo.multipath) / (2 * eps), atol=1e-7)
    hi = predict_ranges(x, y, depth, beacon, d0 + eps, path)
    lo = predict_ranges(x, y, depth, beacon, d0 - eps, path)
    np.testing.assert_allclose(p.d_multipath_d0, (hi.multipath - lo.multipath) / (2 * eps),
                               atol=1e-7)


def test_gradient_is_finite_right_above_the_beacon():
    p = predict_ranges(10.0, 20.0, 100.0, (10.0, 20.0, 500.0), 480.0)
    assert np.all(p.grad_direct == 0) and np.all(np.isfinite(p.grad_multipath))


def test_class_probabilities_are_the_shared_responsibilities():
    rng = np.random.default_rng(2)
    z = rng.uniform(0, 5000, 50)
    direct, mp = rng.uniform(0, 5000, 50), rng.uniform(0, 5000, 50)
    lw = np.log([0.5, 0.3, 0.2])
    resp, lse = class_log_joint(z, direct, mp, 40.0, 300.0, -np.log(5000), lw)
    joint = np.column_stack([gaussian_logpdf(z - direct, 40.0) + lw[0],
                             gaussian_logpdf(z - mp, 300.0) + lw[1],
                             np.full(50, -np.log(5000) + lw[2])])
    ref, ref_lse = responsibilities(joint)
    np.testing.assert_allclose(resp, ref, atol=1e-12)
    np.testing.assert_allclose(lse, ref_lse, rtol=1e-12)
    np.testing.assert_allclose(resp.sum(axis=1), 1.0)


def test_a_weight_of_zero_switches_a_class_off():
    resp, _ = class_log_joint(300.0, 100.0, 300.0, 2.0, 5.0, np.log(1e-3),
                              np.array([np.log(0.8), -np.inf, np.log(0.2)]))
    assert resp[1] == 0.0 and resp[2] == pytest.approx(1.0)


def test_dr_step_and_its_derivatives():
    rng = np.random.default_rng(3)
    p0, delta = rng.normal(0, 100, (5, 2)), rng.normal(0, 10, (5, 2))
    beta, scale, eps = 0.03, 1.02, 1e-7
    p, d_beta, d_scale = dr_step(p0, delta, beta, scale)
    R, _ = rotation(beta)
    np.testing.assert_allclose(p, p0 + scale * delta @ R.T)
    np.testing.assert_allclose(d_beta, (dr_step(p0, delta, beta + eps, scale)[0]
                                        - dr_step(p0, delta, beta - eps, scale)[0]) / (2 * eps),
                               atol=1e-6)
    np.testing.assert_allclose(d_scale, (dr_step(p0, delta, beta, scale + eps)[0]
                                         - dr_step(p0, delta, beta, scale - eps)[0]) / (2 * eps),
                               atol=1e-6)
    assert dr_noise_var(4.0, 0.5) == pytest.approx(1.0)
