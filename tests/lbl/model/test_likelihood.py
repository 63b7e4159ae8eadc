import numpy as np
import pytest
from scipy import stats

from bayes_mpem.io.survey import BeaconData
from bayes_mpem.lbl.model.beacon_geometry import BeaconGeometry
from bayes_mpem.lbl.model.likelihood import e_step, loglik_per_range


@pytest.fixture
def geom():
    rng = np.random.default_rng(3)
    n = 400
    x, y = rng.uniform(-2000, 2000, n), rng.uniform(-2000, 2000, n)
    depth = rng.uniform(2300, 2400, n)
    z = rng.uniform(100, 6000, n)
    return BeaconGeometry.from_data(BeaconData.from_arrays(z, x, y, depth, [0.0, 0.0, 2450.0]))


def test_loglik_matches_scipy(geom):
    d0, sdp, smp, w = 2450.0, 4.0, 9.0, np.array([0.5, 0.3, 0.2])
    ll, resp = e_step(geom, d0, sdp, smp, w)
    dens = np.stack([
        stats.norm.pdf(geom.z, geom.direct, sdp),
        stats.norm.pdf(geom.z, geom.multipath(d0), smp),
        np.full(geom.n, 1.0 / (geom.z.max() - geom.z.min())),
    ], axis=1) * w
    assert ll == pytest.approx(np.log(dens.sum(axis=1)).sum(), rel=1e-12)
    np.testing.assert_allclose(resp, dens / dens.sum(axis=1, keepdims=True), atol=1e-12)


def test_responsibilities_are_finite_far_from_everything(geom):
    # tiny scales: densities underflow, the log-space computation must not
    ll, resp = e_step(geom, 2450.0, 1e-3, 1e-3, [1 / 3] * 3)
    assert np.isfinite(ll)
    np.testing.assert_allclose(resp.sum(axis=1), 1.0)
    assert np.all(np.isfinite(resp))


def test_zero_weight_is_allowed(geom):
    ll, resp = e_step(geom, 2450.0, 4.0, 9.0, [0.7, 0.3, 0.0])
    assert np.isfinite(ll)
    assert np.all(resp[:, 2] == 0.0)


def test_pointwise_loglik_vectorised_over_walkers(geom):
    d0 = np.array([[2440.0], [2450.0], [2460.0]])
    w = [np.full((3, 1), 0.5), np.full((3, 1), 0.3), np.full((3, 1), 0.2)]
    out = loglik_per_range(geom, d0, 4.0, 9.0, w)
    assert out.shape == (3, geom.n)
    ll, _ = e_step(geom, 2450.0, 4.0, 9.0, [0.5, 0.3, 0.2])
    assert out[1].sum() == pytest.approx(ll, rel=1e-12)


def test_total_loglik_matches_log_space(geom):
    from bayes_mpem.lbl.model.likelihood import total_loglik

    rng = np.random.default_rng(0)
    d0 = rng.uniform(2400, 2500, (5, 1))
    sdp, smp = rng.uniform(1, 10, (5, 1)), rng.uniform(1, 30, (5, 1))
    w = rng.dirichlet([1, 1, 1], 5)
    ws = [w[:, [j]] for j in range(3)]
    fast = total_loglik(geom, d0, sdp, smp, ws)
    slow = loglik_per_range(geom, d0, sdp, smp, [np.log(x) * 0 + x for x in ws]).sum(axis=1)
    np.testing.assert_allclose(fast, slow, rtol=1e-12)
    # a zero outlier weight with ranges far from both predictions: zero density, -inf
    ws0 = [np.full((1, 1), 0.5), np.full((1, 1), 0.5), np.zeros((1, 1))]
    out = total_loglik(geom, d0[:1], sdp[:1], smp[:1], ws0)
    assert out[0] == -np.inf


@pytest.mark.parametrize("path", ["triangle", "double"])
@pytest.mark.parametrize("spread", [0.3, 30.0])
def test_total_loglik_screening_is_exact_on_survey_data(path, spread):
    """The per-call screening of zero Gaussian terms leaves the sum unchanged."""
    import bayes_mpem as bm
    from bayes_mpem.lbl.model.likelihood import total_loglik

    sim = bm.simulate_survey("abe58", rng=1, path=path, n_cycles=800)
    g = BeaconGeometry.from_data(sim.survey.for_beacon("4"))
    rng = np.random.default_rng(1)
    w_ = 12
    d0 = 2472.0 + rng.normal(0, spread, (w_, 1))
    sdp, smp = rng.uniform(3, 5, (w_, 1)), rng.uniform(5, 9, (w_, 1))
    w = rng.dirichlet([5, 3, 2], w_)
    ws = [w[:, [j]] for j in range(3)]
    slow = loglik_per_range(g, d0, sdp, smp, ws, path).sum(axis=1)
    np.testing.assert_allclose(total_loglik(g, d0, sdp, smp, ws, path), slow, rtol=1e-12)


def test_total_loglik_zero_outlier_weight_is_finite_when_every_range_is_near():
    """No range left for the outlier-only term: 0 * log(0) must not make a NaN."""
    from bayes_mpem.lbl.model.likelihood import total_loglik

    rng = np.random.default_rng(0)
    h, dz = rng.uniform(100, 2000, 50), np.full(50, 30.0)
    z = np.hypot(h, dz) + rng.normal(0, 3, 50)  # all direct path
    g = BeaconGeometry.from_data(BeaconData.from_arrays(z, h, np.zeros(50), np.full(50, 2370.0),
                                                        [0.0, 0.0, 2400.0]))
    w = [np.full((1, 1), 0.5), np.full((1, 1), 0.5), np.zeros((1, 1))]
    out = total_loglik(g, np.full((1, 1), 2400.0), np.full((1, 1), 500.0),
                       np.full((1, 1), 500.0), w)
    ref = loglik_per_range(g, 2400.0, 500.0, 500.0, [0.5, 0.5, 0.0]).sum()
    assert np.isfinite(out[0]) and out[0] == pytest.approx(ref, rel=1e-12)
