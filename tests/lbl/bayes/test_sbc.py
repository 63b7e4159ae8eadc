"""Simulation-based calibration of the beacon posterior: small, and able to fail.

``benchmarks/sbc.py`` is the study (500 simulations of the shipped sampler, 250 of
each other arm, the shipped stopping rule). Here: 150 simulations of a 103-ping
design with a short stopping rule (no ESS target; the ensemble 10 autocorrelation
times), with the shipped sampler (``sampler="auto"``: independence chains from a
Laplace proposal, on this small design the ensemble for 30-45 % of the prior's
draws) and with an ensemble whose moves are half emcee 3.1.6's released snooker
(DE the other half; on a 5-D standard normal that mix has sd 0.90-0.91). The check
is the dispersion of the ranks (``rank_dispersion``, pooled over the parameters per
simulation): too-narrow chains put the truth in their tails. Measured on seeds
11-14 of this set-up: shipped z = 0.8, 0.3, -0.9, -0.0 (the smallest of the 12
chi-square and tail p-values per seed 0.185, 0.113, 0.109, 0.275; the ensemble alone,
before issue 17: z = 2.0, 1.0, -0.2, -2.1); released mix z = 5.2, 4.7, 3.7, 2.0. So
the check catches the released move on three seeds of four at z > 3: it is a sharp
test of a 10 % narrowing only with the study's 500 simulations. The seed is fixed.
"""

import sys
from pathlib import Path

import emcee
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

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # tests/, for the released move
from released_snooker import ReleasedSnooker  # noqa: E402

FAST = {"tau_factor": 10.0, "min_ess": 0.0, "n_draws": 99}


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


@pytest.mark.slow
def test_sbc_passes_the_shipped_sampler_and_fails_the_released_snooker(design):
    ok = run_sbc(design, 150, rng=11, **FAST)
    assert set(ok.diagnostics["sampler"]) == {"independence", "ensemble"}  # both paths ran
    for name, t in ok.tests().items():
        assert t["p_value"] > 0.01 and t["tails_p_value"] > 0.01, (name, t)
    assert abs(rank_dispersion(ok.ranks, ok.n_draws)["z"]) < 3.0
    bad = run_sbc(design, 150, rng=11,
                  moves=[(emcee.moves.DEMove(), 0.5), (ReleasedSnooker(), 0.5)], **FAST)
    disp = rank_dispersion(bad.ranks, bad.n_draws)
    assert disp["z"] > 3.0 and disp["ratio"] > 1.05, disp  # the truth too often in the tails
