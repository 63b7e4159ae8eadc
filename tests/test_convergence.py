"""The rank-normalised ESS, R-hat and HDI of bayes_mpem.mcmc.convergence against ArviZ.

bayes_mpem computes them itself (importing arviz_stats costs 0.6 s, more than sampling a
beacon); ArviZ stays the reference: the same values to rounding on white-noise,
autocorrelated, tied, shifted and stuck chains.
"""

import arviz_stats as azs
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bayes_mpem.mcmc.convergence import (
    average_ranks,
    ess_bulk,
    ess_mean,
    hdi_nearest,
    rhat_rank,
    split_chains,
    z_scale,
)


def ar1(gen, n_chains, n_draws, phi):
    e = gen.standard_normal((n_chains, n_draws))
    a = np.empty_like(e)
    a[:, 0] = e[:, 0]
    for t in range(1, n_draws):
        a[:, t] = phi * a[:, t - 1] + e[:, t]
    return a


def arviz(a, what):
    if what == "rhat":
        return float(azs.rhat(a, method="rank", chain_axis=0, draw_axis=1))
    return float(azs.ess(a, method=what, chain_axis=0, draw_axis=1))


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n_chains=st.integers(1, 6), n_draws=st.integers(4, 700),
       phi=st.floats(-0.6, 0.995), ties=st.booleans(), shift=st.floats(0.0, 3.0))
def test_same_as_arviz(seed, n_chains, n_draws, phi, ties, shift):
    gen = np.random.default_rng(seed)
    a = ar1(gen, n_chains, n_draws, phi) + shift * gen.standard_normal((n_chains, 1))
    if ties:
        a = np.round(a, 1)
    np.testing.assert_allclose(ess_bulk(a), arviz(a, "bulk"), rtol=1e-10)
    np.testing.assert_allclose(ess_mean(a), arviz(a, "mean"), rtol=1e-10)
    if n_chains > 1:
        np.testing.assert_allclose(rhat_rank(a), arviz(a, "rhat"), rtol=1e-10)
    prob = float(gen.uniform(0.5, 0.99))
    np.testing.assert_allclose(hdi_nearest(a, prob), azs.hdi(a.ravel(), prob=prob), rtol=1e-12)


def test_stuck_and_constant_chains():
    a = np.ones((4, 100))
    assert ess_bulk(a) == arviz(a, "bulk") == 400
    stuck = np.repeat(np.random.default_rng(0).standard_normal((4, 10)), 50, axis=1)
    assert ess_bulk(stuck) < 60 and rhat_rank(stuck) > 1.01
    np.testing.assert_allclose(ess_bulk(stuck), arviz(stuck, "bulk"), rtol=1e-10)


def test_white_noise_has_ess_near_draws_and_rhat_near_one():
    a = np.random.default_rng(1).standard_normal((4, 1000))
    assert 3600 < ess_bulk(a) < 4400 and rhat_rank(a) < 1.005


def test_helpers():
    assert split_chains(np.arange(10.0).reshape(2, 5)).tolist() == [[0, 1], [5, 6], [3, 4],
                                                                      [8, 9]]
    assert average_ranks([[2.0, 2.0], [1.0, 3.0]]).tolist() == [[2.5, 2.5], [1.0, 4.0]]
    z = z_scale(np.arange(1001.0))
    assert abs(z[500]) < 1e-12 and z[0] < -3
    assert np.isnan(ess_bulk(np.ones((2, 3)))) and np.isnan(rhat_rank(np.ones((1, 50))))
    with pytest.raises(ValueError, match="chain, draw"):
        ess_bulk(np.ones((2, 2, 2)))
    with pytest.raises(ValueError, match="too few draws"):
        hdi_nearest([], 0.95)


def test_ndtri_is_scipys():
    from scipy.special import ndtri as scipy_ndtri

    from bayes_mpem.mcmc.convergence import ndtri

    p = np.concatenate([np.linspace(0.0, 1.0, 20001), np.logspace(-300, -1, 500),
                        1.0 - np.logspace(-16, -1, 500)])
    ours, ref = ndtri(p), scipy_ndtri(p)
    finite = np.isfinite(ref)
    np.testing.assert_allclose(ours[finite], ref[finite], rtol=1e-14, atol=1e-300)
    assert np.array_equal(ours[~finite], ref[~finite])  # -inf at 0, inf at 1
    assert np.isnan(ndtri([-0.1, 1.1, np.nan])).all()
