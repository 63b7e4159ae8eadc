"""The sampler choice of one beacon (bayes_mpem.lbl.bayes.beacon_chains): emcee with an
independence MHMove from a Laplace proposal, differential evolution where that fits poorly.

Here: the free coordinates, the agreement of the two moves on the same beacon, the
fallback and its reasons, the per-range pass, and the options.
"""

import warnings

import numpy as np
import pytest

import bayes_mpem as bm
import bayes_mpem.lbl.bayes.beacon_chains as bc
from bayes_mpem.lbl.bayes.beacon_chains import FreeCoordinates, beacon_chains
from bayes_mpem.lbl.bayes.beacon_sampling import sample_beacon
from bayes_mpem.lbl.bayes.posterior import BeaconPosterior
from bayes_mpem.lbl.em.em_mixture import fit_mixture_em

FAST = {"progress": False, "n_draws": 1000}


@pytest.fixture(scope="module")
def beacon4():
    return bm.simulate_survey("abe58", rng=0, n_cycles=700).survey.for_beacon("4")


@pytest.fixture(scope="module")
def post4(beacon4):
    post = BeaconPosterior(beacon4)
    post.em = fit_mixture_em(beacon4, rng=0)
    return post


@pytest.mark.parametrize("priors, sigma_dp", [("learned", None), ("equal", None),
                                              ("learned", 4.0)])
def test_free_coordinates_round_trip_and_jacobian(beacon4, priors, sigma_dp):
    post = BeaconPosterior(beacon4, priors=priors, sigma_dp=sigma_dp, precision="float64")
    free = FreeCoordinates(post)
    gen = np.random.default_rng(0)
    theta = post.draw_prior(50, gen)
    u = free.to_free(theta)
    back, log_jac = free.from_free(u)
    np.testing.assert_allclose(back, theta, rtol=1e-12, atol=1e-12)
    if priors == "learned":  # |d(w_dp, w_mp) / d(a_dp, a_mp)| by central differences
        h = 1e-6
        for i in range(3):
            jac = np.empty((2, 2))
            for j in range(2):
                du = np.zeros(post.ndim)
                du[-2 + j] = h
                jac[:, j] = (free.from_free(u[i] + du)[0][0, -2:]
                             - free.from_free(u[i] - du)[0][0, -2:]) / (2 * h)
            np.testing.assert_allclose(log_jac[i], np.log(abs(np.linalg.det(jac))), rtol=1e-6)
    else:
        assert np.all(log_jac == 0)
    # the density in free coordinates is the posterior plus the log-Jacobian, in chunks
    free._chunk = 7
    np.testing.assert_allclose(free(u), post(theta) + log_jac, rtol=1e-12)


def test_independence_and_ensemble_agree(beacon4):
    imh = sample_beacon(beacon4, rng=1, **FAST)
    ens = sample_beacon(beacon4, rng=1, sampler="ensemble", **FAST)
    assert imh.diagnostics["sampler"] == "independence" and imh.diagnostics["fallback"] is None
    assert "MHMove" in imh.diagnostics["moves"] and "DEMove" in ens.diagnostics["moves"]
    assert imh.diagnostics["burn"] == 0 and ens.diagnostics["burn"] > 0
    assert imh.diagnostics["acceptance"] > 0.6 and set(imh.rhat) == set(imh.ess)
    assert all(v < 1.01 for v in imh.rhat.values())
    for k in ("d0", "sigma_mp", "sigma_dp"):
        a, b = imh.summary[k], ens.summary[k]
        # both ESS >= 1000: the means differ by well under 0.2 sd, the sds by under 10 %
        assert abs(a["mean"] - b["mean"]) < 0.2 * b["sd"], (k, a, b)
        assert abs(a["sd"] / b["sd"] - 1) < 0.1, (k, a, b)
    np.testing.assert_allclose(imh.class_probs, ens.class_probs, atol=0.02)
    assert imh.idata.attrs["sampler"].startswith("emcee")


def test_reaches_min_ess_and_keeps_every_draw(beacon4):
    import arviz_stats as azs

    r = sample_beacon(beacon4, rng=2, progress=False, n_draws=2000)
    d = r.diagnostics
    assert d["converged"] and d["thin"] == 1 and d["n_chains"] == 16
    assert d["n_draws"] == 16 * d["n_steps"] >= 2000  # every draw kept
    assert min(r.ess.values()) >= 1000 and max(r.rhat.values()) < 1.01
    post = r.idata.posterior
    assert post.sizes["chain"] == 16 and post.sizes["draw"] == d["n_steps"]
    for k, v in r.ess.items():  # ArviZ's ESS of the draws in the ArviZ data
        assert float(azs.ess(r.idata, var_names=[k])[k]) == pytest.approx(v, rel=1e-10)


def test_same_seed_same_draws(beacon4):
    a = sample_beacon(beacon4, rng=5, **FAST)
    b = sample_beacon(beacon4, rng=5, **FAST)
    np.testing.assert_array_equal(a.idata.posterior["d0"].values, b.idata.posterior["d0"].values)


def test_falls_back_without_a_mode(post4, monkeypatch):
    monkeypatch.setattr(bc, "laplace_proposal", lambda *a, **k: None)
    for sampler in ("auto", "independence"):  # no proposal at all: DE either way
        r = beacon_chains(post4, np.random.default_rng(0), sampler=sampler, min_ess=200,
                          progress=False)
        assert r.sampler == "ensemble" and "Hessian not negative definite" in r.info["fallback"]


def test_falls_back_when_the_proposal_fits_poorly(post4, monkeypatch, capsys):
    monkeypatch.setattr(bc, "MIN_ESS_PER_DRAW", 1.5)  # no proposal can pass
    with pytest.warns(bm.exceptions.SamplingWarning, match="max_steps=300"):
        r = beacon_chains(post4, np.random.default_rng(0), min_ess=1e6, max_steps=300,
                          progress="log")
    assert r.sampler == "ensemble" and "fits poorly" in r.info["fallback"]
    assert "differential evolution instead" in capsys.readouterr().err
    # forced, the independence move is kept (and warns at its cap)
    with pytest.warns(bm.exceptions.SamplingWarning, match="beacon 4: the chain reached"):
        r = beacon_chains(post4, np.random.default_rng(0), sampler="independence",
                          min_ess=1e6, max_steps=300, progress=False, where="beacon 4")
    assert r.sampler == "independence" and not r.run.converged


def test_hands_over_to_de_when_the_independence_move_overruns(post4, monkeypatch):
    monkeypatch.setattr(bc, "INDEPENDENCE_BUDGET", 20)
    with pytest.warns(bm.exceptions.SamplingWarning, match="max_steps=300"):
        r = beacon_chains(post4, np.random.default_rng(0), min_ess=1e6, max_steps=300,
                          progress=False)
    assert r.sampler == "ensemble" and "did not meet the stopping rule in 20" in \
        r.info["fallback"]


def test_ensembles_mean_differential_evolution(post4):
    r = beacon_chains(post4, np.random.default_rng(0), min_ess=300, n_ensembles=2,
                      progress=False)
    assert r.sampler == "ensemble" and r.info["fallback"] is None and r.run.n_ensembles == 2
    r = beacon_chains(post4, np.random.default_rng(0), min_ess=300, n_walkers=24,
                      progress=False)
    assert r.sampler == "independence" and r.chain.shape[1] == 24


def test_pointwise_moments_equal_the_full_pass(post4):
    """The per-range pass on screened columns gives what every column would."""
    from bayes_mpem.mcmc import draw_moments

    r = beacon_chains(post4, np.random.default_rng(3), min_ess=0, progress=False)
    flat = r.chain.reshape(-1, post4.ndim)[:300]
    ll, m, s = post4.pointwise_moments(flat)
    ll_ref, m_ref, s_ref = draw_moments(flat, post4.loglik_and_classes)
    np.testing.assert_allclose(ll, ll_ref, rtol=1e-12)
    np.testing.assert_allclose(m, m_ref, atol=1e-12)
    np.testing.assert_allclose(s, s_ref, atol=1e-7)


def test_sampler_option_is_checked_before_any_work(beacon4):
    with pytest.raises(ValueError, match="sampler: expected one of"):
        sample_beacon(beacon4, sampler="nuts")
    sim = bm.simulate_survey("abe58", rng=0, n_cycles=100)
    with pytest.raises(ValueError, match="sampler"):
        bm.sample(sim.survey, sampler="gibbs", progress=False)


def test_cli_sampler_option(tmp_path):
    from bayes_mpem.cli import main

    files = bm.simulate_survey("abe58", rng=0, n_cycles=150).write(tmp_path / "s")
    pings, beacons = files["pings"], files["beacons"]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert main(["sample", str(pings), "--beacons", str(beacons), "--out",
                     str(tmp_path / "o"), "--sampler", "ensemble", "--no-progress"]) == 0
    import json

    s = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert {b["diagnostics"]["sampler"] for b in s["beacons"].values()} == {"ensemble"}
