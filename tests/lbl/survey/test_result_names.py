"""One vocabulary: a fit's and a sample's results answer to the same names (docs/model.md)."""

import numpy as np
import pytest

import bayes_mpem as bm

PER_BEACON = ("beacon", "path", "d0", "sigma_mp", "sigma_dp", "weights", "class_probs",
              "labels", "class_fractions", "n", "rows", "converged")
TABLE = ["beacon", "d0_m", "sigma_mp_m", "beacon_depth_m", "plane_depth_m", "sigma_dp_m",
         "dp", "mp", "ol", "n", "converged", "path"]


@pytest.fixture(scope="module")
def fit_and_sample():
    sim = bm.simulate_survey("abe58", rng=5, n_cycles=250)
    return (bm.fit(sim.survey, rng=0),
            bm.sample(sim.survey, rng=0, progress=False, min_ess=300))


def test_per_beacon_results_read_alike(fit_and_sample):
    fit, post = fit_and_sample
    for bid in fit.results:
        em, pr = fit.results[bid], post.results[bid]
        for name in PER_BEACON:
            assert hasattr(em, name) and hasattr(pr, name), name
        assert pr.d0 == pr.summary["d0"]["mean"] and set(pr.weights) == {"dp", "mp", "ol"}
        assert pr.d0 == pytest.approx(em.d0, abs=5 * pr.summary["d0"]["sd"])
        assert em.class_probs is em.resp and pr.class_probs.shape == em.class_probs.shape
        np.testing.assert_array_equal(pr.rows, em.rows)
        assert pr.n == em.n and sum(pr.class_fractions.values()) == pytest.approx(1.0)


def test_survey_tables_share_their_columns(fit_and_sample):
    fit, post = fit_and_sample
    t_fit, t_post = fit.table(), post.table()
    assert list(t_fit.columns[:len(TABLE) - 3]) == TABLE[:-3]
    assert set(TABLE) <= set(t_fit.columns) and set(TABLE) <= set(t_post.columns)
    assert "hrp_m" not in t_fit.columns  # d0 is named d0 everywhere
    assert np.all(t_post["d0_lo_m"] < t_post["d0_m"]) and np.all(
        t_post["d0_m"] < t_post["d0_hi_m"])
    np.testing.assert_allclose(t_post["plane_depth_m"],
                               t_post["beacon_depth_m"] - t_post["d0_m"])
