"""Simulation-based calibration of the beacon posterior: a small sentinel, able to fail.

``benchmarks/sbc.py`` is the study (docs/bayes-calibration.md). Here: 15 simulations of a
103-ping design with a short stopping rule, checked with the study's tests at a loose level
(a broken sampler or likelihood fails them); and the dispersion check, on synthetic draws,
catches posteriors 20 % too narrow. The seed is fixed.
"""

import numpy as np
import pytest

import bayes_mpem as bm
from bayes_mpem.lbl.bayes.posterior import BeaconPosterior
from bayes_mpem.lbl.bayes.sbc import run_sbc, sbc_design, sbc_posterior, simulate_ranges
from bayes_mpem.mcmc.sbc import (
    rank_dispersion,
    rank_histogram,
    rank_statistic,
    rank_uniformity,
)

FAST = {"min_ess": 50.0, "n_draws": 49}


@pytest.fixture(scope="module")
def design():
    return sbc_design(bm.simulate_survey("abe58", rng=0, n_cycles=110).survey.for_beacon("4"))


def test_rank_tools():
    assert rank_statistic([3.0, 1.0, 2.0], 2.5) == 2
    assert rank_histogram(np.arange(100), 99).tolist() == [10] * 10
    with pytest.raises(ValueError, match="divisor"):
        rank_histogram([0], 99, n_bins=7)
    out = rank_uniformity(np.r_[np.zeros(50, int), np.full(50, 99)], 99)
    assert out["tails"] == 1.0 and out["p_value"] < 1e-10


def test_prior_is_proper_and_ignores_the_ranges(design):
    post = sbc_posterior(design)
    theta = post.draw_prior(2000, np.random.default_rng(0))
    assert np.all(np.isfinite(post.log_prior(theta)))
    d0 = theta[:, 0]
    depth = float(design.position[2])
    assert d0.min() >= depth - 30 and d0.max() <= depth + 30
    # the same prior whatever the ranges: only the design's geometry enters
    other = BeaconPosterior(design, d0_bounds=post.d0_bounds, window=(post.geom.lo, post.geom.hi))
    assert other.d0_bounds == post.d0_bounds
    z = simulate_ranges(post, theta[0], np.random.default_rng(1))
    assert z.shape == (design.n,) and np.all((z >= post.geom.lo) & (z <= post.geom.hi))


def test_d0_bounds_and_window_are_checked(design):
    with pytest.raises(ValueError, match="d0_bounds"):
        BeaconPosterior(design, d0_bounds=(10.0, 5.0))
    with pytest.raises(ValueError, match="must hold every range"):
        BeaconPosterior(design, window=(1.0, 2.0))


def test_sbc_sentinel(design):
    ok = run_sbc(design, 15, rng=11, **FAST)
    assert "independence" in ok.diagnostics["sampler"]
    for name, t in ok.tests(n_bins=5).items():
        assert t["p_value"] > 0.001 and t["tails_p_value"] > 0.001, (name, t)
    assert abs(rank_dispersion(ok.ranks, ok.n_draws)["z"]) < 3.5


def test_dispersion_catches_posteriors_too_narrow():
    gen = np.random.default_rng(0)
    ranks = np.array([[rank_statistic(0.8 * gen.normal(size=49), gen.normal())
                       for _ in range(3)] for _ in range(150)])
    disp = rank_dispersion(ranks, 49)
    assert disp["z"] > 3.0 and disp["ratio"] > 1.1, disp
