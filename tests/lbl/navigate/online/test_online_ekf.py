"""The plain-float filter is the extended Kalman filter written with matrices."""

import numpy as np
import pytest

from bayes_mpem.lbl.navigate.online.ekf import COV_NAMES, PositionFilter
from bayes_mpem.lbl.navigate.online.kernel import dr_step


def _matrix(p):
    iu = np.triu_indices(4)
    m = np.zeros((4, 4))
    m[iu] = p
    return m + np.triu(m, 1).T


def _random_filter(gen):
    a = gen.normal(0, 1, (4, 4)) * [3.0, 3.0, 0.01, 0.005]
    cov = a @ a.T + np.diag([1.0, 1.0, 1e-5, 1e-6])
    f = PositionFilter(*gen.normal(0, 100, 2), gen.normal(0, 0.03), 1 + gen.normal(0, 0.01),
                       cov[np.triu_indices(4)], 1e-5, 1e-6)
    return f, cov


def test_predict_is_f_p_ft_plus_q():
    gen = np.random.default_rng(0)
    for _ in range(50):
        f, cov = _random_filter(gen)
        state = np.array([f.x, f.y, f.beta, f.scale])
        dx, dy, dt, q2 = *gen.normal(0, 30, 2), gen.uniform(0, 20), 0.01
        sx, sy, ax, ay, bx, by = dr_step(dx, dy, f.beta, f.scale)
        jac = np.eye(4)
        jac[:2, 2], jac[:2, 3] = (ax, ay), (bx, by)
        want = jac @ cov @ jac.T + np.diag([q2 * dt, q2 * dt, 1e-10 * dt, 1e-12 * dt])
        f.predict(dx, dy, dt, q2)
        np.testing.assert_allclose(_matrix(f.p), want, rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose([f.x, f.y], state[:2] + [sx, sy], rtol=1e-12)


def test_update_is_the_kalman_update():
    gen = np.random.default_rng(1)
    for _ in range(50):
        f, cov = _random_filter(gen)
        state = np.array([f.x, f.y, f.beta, f.scale])
        h = np.array([*gen.normal(0, 1, 2), 0.0, 0.0])
        r, var = gen.normal(0, 5), gen.uniform(1, 30)
        s = h @ cov @ h + var
        k = cov @ h / s
        assert f.range_variance(h[0], h[1]) == np.float64(h @ cov @ h).round(12) or np.isclose(
            f.range_variance(h[0], h[1]), h @ cov @ h, rtol=1e-12)
        f.update(r, h[0], h[1], var)
        np.testing.assert_allclose([f.x, f.y, f.beta, f.scale], state + k * r, rtol=1e-12,
                                   atol=1e-12)
        np.testing.assert_allclose(_matrix(f.p), cov - np.outer(k, k) * s, rtol=1e-9,
                                   atol=1e-12)


def test_round_trip():
    f, _ = _random_filter(np.random.default_rng(2))
    g = PositionFilter.from_dict(f.to_dict())
    assert g.to_dict() == f.to_dict() and len(COV_NAMES) == 10


def test_start_from_a_joint_covariance_or_a_position_one():
    gen = np.random.default_rng(3)
    a = gen.normal(0, 1, (4, 4))
    cov = a @ a.T
    f = PositionFilter.start(1.0, 2.0, 0.01, 1.001, cov)
    np.testing.assert_allclose(_matrix(f.p), cov, rtol=1e-12)
    g = PositionFilter.start(1.0, 2.0, 0.01, 1.001, cov[:2, :2], 1e-4, 1e-6)
    want = np.zeros((4, 4))
    want[:2, :2], want[2, 2], want[3, 3] = cov[:2, :2], 1e-4, 1e-6
    np.testing.assert_allclose(_matrix(g.p), want, rtol=1e-12)
    with pytest.raises(ValueError, match="expected a"):
        PositionFilter.start(1.0, 2.0, 0.0, 1.0, cov[:2, :2])
    with pytest.raises(ValueError, match="expected a"):
        PositionFilter.start(1.0, 2.0, 0.0, 1.0, cov[:3, :3])


def test_the_filter_starts_with_the_smoothers_correlations():
    """The warm-up's filter gets Cov(p_K, beta, s) of the batch fit, not only its diagonal."""
    from bayes_mpem.lbl.navigate import navigate, simulate_dive
    from bayes_mpem.lbl.navigate.online.warmup import endpoint_covariance

    nav = navigate(simulate_dive("abe58", rng=0, n_cycles=80).survey, rng=0, path="triangle")
    c = endpoint_covariance(nav)
    np.testing.assert_allclose(c, c.T)
    assert np.all(np.linalg.eigvalsh(c) > 0)
    np.testing.assert_allclose(c[:2, :2], nav.cov[-1])
    np.testing.assert_allclose(np.sqrt(c[[2, 3], [2, 3]]),
                               [nav.global_sd["beta"], nav.global_sd["scale"]])
    corr = c / np.sqrt(np.outer(np.diag(c), np.diag(c)))
    assert np.abs(corr[:2, 2:]).max() > 0.1  # the correlations the old start dropped
