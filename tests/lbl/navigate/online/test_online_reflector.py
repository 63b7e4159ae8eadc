"""Online EM of one beacon: with alpha = 1 it is the batch M-step over the replies so far."""

import math

import numpy as np
import pytest

from bayes_mpem.lbl.navigate.online.reflector import BeaconModel, DirectPathScale, step_size


def _model(**kw):
    args = dict(d0=100.0, sigma_mp=5.0, weights=(0.5, 0.3, 0.2), n=1, double=False, mp_on=True,
                xyz=(0.0, 0.0, 100.0), d0_min=0.0, window=(10.0, 200.0))
    args.update(kw)
    return BeaconModel.start(**args)


def test_alpha_one_is_the_weighted_least_squares_of_all_replies():
    gen = np.random.default_rng(0)
    g = gen.dirichlet([2, 2, 1], 300)
    jac = gen.uniform(0.3, 1.0, 300)
    u = jac * 7.0 + gen.normal(0, 3, 300)  # delta = d0 - d0_ref = 7 m
    first = (g[0, 0], g[0, 1], g[0, 2], g[0, 1] * jac[0] ** 2, g[0, 1] * jac[0] * u[0],
             g[0, 1] * u[0] ** 2)
    m = _model(stats=first)
    for i in range(1, 300):
        m.learn(*g[i], jac[i], u[i], u[i] ** 2, 1.0, 0.05)
    w = g[:, 1]
    delta = np.sum(w * jac * u) / np.sum(w * jac ** 2)
    assert m.d0 == pytest.approx(100.0 + delta, rel=1e-12)
    var = np.sum(w * (u - jac * delta) ** 2) / np.sum(w)
    assert m.sigma_mp == pytest.approx(math.sqrt(var), rel=1e-9)
    np.testing.assert_allclose(m.weights, g.mean(axis=0) / g.mean(axis=0).sum(), rtol=1e-12)
    assert m.n == 300 and 1 / m.sumsq == pytest.approx(300, rel=1e-9)
    assert m.d0_variance() == pytest.approx(var / np.sum(w * jac ** 2), rel=1e-9)


def test_smaller_alpha_forgets_and_d0_stays_physical():
    assert step_size(100, 0.6) > step_size(100, 1.0) == 0.01
    m = _model(d0_min=99.0)
    for _ in range(50):
        m.learn(0.0, 1.0, 0.0, 1.0, -10.0, 100.0, 0.6, 0.05)  # pulls d0 down to 90 m
    assert m.d0 == 99.0
    assert 1 / m.sumsq < m.n


def test_switches_geometry_on_evidence_only():
    m = _model()
    m.alt = _model(double=True)
    for _ in range(20):
        m.learn(0.5, 0.3, 0.2, 1.0, 0.0, 25.0, 1.0, 0.05)
        assert m.weigh(0.1, 1.0, 10.0) is m  # 0.1 nat a reply: 2 nats, not enough yet
    for i in range(200):
        m.learn(0.5, 0.3, 0.2, 1.0, 0.0, 25.0, 1.0, 0.05)
        new = m.weigh(0.5, 1.0, 10.0)
        if new is not m:
            break
    assert 10 < 2 + 0.5 * (i + 1) < 12  # the summed evidence crossed 10 nats then
    assert new.double and new.alt is m and m.alt is None and new.evidence < 0


def test_round_trip_and_sigma_dp():
    m = _model()
    m.alt = _model(double=True)
    back = BeaconModel.from_dict(m.to_dict())
    assert back.to_dict() == m.to_dict() and back.alt.double
    dp = DirectPathScale(3.0, 1)
    for r2 in (4.0, 16.0, 9.0):
        dp.learn(1.0, r2, 1.0, 0.05)
    assert dp.sigma == pytest.approx(math.sqrt((9 + 4 + 16 + 9) / 4))
    assert DirectPathScale.from_dict(dp.to_dict()).to_dict() == dp.to_dict()
