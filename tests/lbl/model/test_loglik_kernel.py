"""The sampler's kernel: exact in float64, within its error bound in float32, same chain."""

import numpy as np
import pytest

import bayes_mpem as bm
from bayes_mpem.io.survey import BeaconData
from bayes_mpem.lbl.bayes.beacon_sampling import sample_beacon
from bayes_mpem.lbl.bayes.posterior import BeaconPosterior
from bayes_mpem.lbl.model.beacon_geometry import BeaconGeometry
from bayes_mpem.lbl.model.likelihood import e_step, loglik_per_range
from bayes_mpem.lbl.model.loglik_kernel import FLOAT32_MAX_ERROR, FLOAT32_MAX_RANGES, LoglikKernel
from bayes_mpem.mcmc import default_moves, run_ensembles


def _beacon(n_cycles, seed=1, path="triangle"):
    return bm.simulate_survey("abe58", rng=seed, path=path, n_cycles=n_cycles).survey \
        .for_beacon("4")


def _batch(rng, w, spread, d0=2472.0):
    """Walkers around the abe58 beacon 4 truth, as columns."""
    wts = rng.dirichlet([50, 35, 15], w)
    return (d0 + rng.normal(0, spread, w), rng.uniform(3.5, 4.5, w), rng.uniform(6, 8, w),
            wts[:, 0], wts[:, 1], wts[:, 2])


def _reference(geom, batch, path="triangle"):
    d0, sdp, smp, *w = (np.asarray(v)[:, None] for v in batch)
    return loglik_per_range(geom, d0, sdp, smp, w, path).sum(axis=1)


@pytest.mark.parametrize("path", ["triangle", "double"])
def test_float64_matches_the_log_space_form_across_screens(path):
    geom = BeaconGeometry.from_data(_beacon(800, path=path))
    kern = LoglikKernel(geom, path, precision="float64")
    rng = np.random.default_rng(0)
    for spread in (0.2, 0.2, 0.25, 5.0, 0.2, 60.0):  # inside, then leaving, the envelope
        batch = _batch(rng, 12, spread)
        np.testing.assert_allclose(kern(*batch), _reference(geom, batch, path), rtol=1e-12)
    assert 2 <= kern.n_screens <= 4  # remade only when a batch left the envelope


def test_pointwise_matches_the_e_step():
    geom = BeaconGeometry.from_data(_beacon(500))
    kern = LoglikKernel(geom, precision="auto")  # pointwise is float64 whatever the kernel
    batch = _batch(np.random.default_rng(1), 3, 1.0)
    ll, probs = kern.pointwise(*batch)
    for i in range(3):
        total, resp = e_step(geom, batch[0][i], batch[1][i], batch[2][i],
                             [batch[3][i], batch[4][i], batch[5][i]])
        assert ll[i].sum() == pytest.approx(total, rel=1e-12)
        np.testing.assert_allclose(np.stack([p[i] for p in probs], axis=1), resp, atol=1e-12)


def test_auto_precision_and_the_float64_fallback():
    geom = BeaconGeometry.from_data(_beacon(300))
    assert LoglikKernel(geom).dtype == np.float32
    big = geom.take(np.resize(np.arange(geom.n), FLOAT32_MAX_RANGES + 1))
    assert LoglikKernel(big).dtype == np.float64
    # an outlier weight so small that float32 terms could underflow: done in float64
    kern = LoglikKernel(geom, precision="float32")
    batch = list(_batch(np.random.default_rng(2), 4, 0.5))
    batch[5] = np.full(4, 1e-30)
    np.testing.assert_allclose(kern(*batch), _reference(geom, batch), rtol=1e-12)
    with pytest.raises(ValueError, match="precision: expected one of"):
        LoglikKernel(geom, precision="half")


def test_float32_error_is_within_its_bound_and_moves_the_posterior_by_nothing():
    """At the largest size "auto" runs in float32, over posterior-like and wide batches.

    The posterior sampled in float32 is the float64 one reweighted by exp(e): the
    means of the importance-reweighted draws must move by far less than their
    Monte-Carlo error (0.03 sd at ESS 1,000).
    """
    n = FLOAT32_MAX_RANGES
    data = _beacon(int(n / 0.95) + 200, seed=3)
    idx = np.arange(n)
    data = BeaconData.from_arrays(data.range[idx], data.x[idx], data.y[idx], data.depth[idx],
                                  data.position, beacon="4")
    geom = BeaconGeometry.from_data(data)
    k32, k64 = LoglikKernel(geom, precision="float32"), LoglikKernel(geom, precision="float64")
    rng = np.random.default_rng(4)
    errors, draws = [], []
    for spread in [0.1] * 30 + [3.0] * 10:
        batch = _batch(rng, 12, spread)
        errors.append(k32(*batch) - k64(*batch))
        draws.append(np.column_stack(batch))
    err = np.concatenate(errors)
    assert np.max(np.abs(err)) < FLOAT32_MAX_ERROR
    theta = np.concatenate(draws)[:360]  # the posterior-like batches
    w = np.exp(err[:360] - err[:360].max())
    w /= w.sum()
    shift = np.abs(w @ theta - theta.mean(axis=0)) / theta.std(axis=0)
    assert np.all(shift < 0.003), shift


def test_same_seed_same_chain_as_the_log_space_likelihood():
    """The float64 kernel changes nothing: the chain equals that of the log-space form."""

    class LogSpace(BeaconPosterior):
        def __call__(self, theta):
            lp = self.log_prior(theta)
            ok = np.isfinite(lp)
            p = self.unpack(theta[ok])
            lp[ok] += loglik_per_range(self.geom, p["d0"], p["sigma_dp"], p["sigma_mp"],
                                       [p["w_dp"], p["w_mp"], p["w_ol"]]).sum(axis=1)
            return lp

    data = _beacon(400)
    em = bm.fit_mixture_em(data, rng=0)
    chains = []
    for post in (BeaconPosterior(data, em=em, precision="float64"), LogSpace(data, em=em)):
        start = post.start(24, np.random.default_rng(5))
        run = run_ensembles(post, [start], moves=default_moves(), gen=np.random.default_rng(7),
                            min_ess=np.inf, max_steps=300, progress=False, warn=False)
        chains.append(run.chain)
    assert np.array_equal(chains[0], chains[1])


def test_float32_posterior_agrees_with_float64_within_monte_carlo_error():
    data = _beacon(700)
    runs = [sample_beacon(data, rng=11, progress=False, precision=p)
            for p in ("float32", "float64")]
    for k in ("d0", "sigma_mp", "sigma_dp"):
        (m1, s1), (m2, s2) = [(r.summary[k]["mean"], r.summary[k]["sd"]) for r in runs]
        ess = min(r.ess_bulk[k] for r in runs)
        assert abs(m1 - m2) < 4 * np.hypot(s1, s2) / np.sqrt(ess), k
        assert abs(s1 / s2 - 1) < 4 * np.sqrt(2 / ess), k
