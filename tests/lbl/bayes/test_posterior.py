"""Bayesian variant: posterior, sampler, calibration, prior comparison, outputs."""

import json
import re

import numpy as np
import pytest
from scipy import stats

import bayes_mpem as bm
from bayes_mpem.exceptions import SamplingWarning
from bayes_mpem.lbl.bayes.beacon_sampling import sample_beacon
from bayes_mpem.lbl.bayes.loo import compare_beacon, psis_loo
from bayes_mpem.lbl.bayes.posterior import BeaconPosterior
from bayes_mpem.lbl.model.likelihood import loglik_per_range

FAST = {"progress": False, "n_draws": 1000}


@pytest.fixture(scope="module")
def beacon4():
    return bm.simulate_survey("abe58", rng=0, n_cycles=700).survey.for_beacon("4")


# --- the posterior ----------------------------------------------------------


@pytest.mark.parametrize("precision", ["float64", "auto"])
def test_log_posterior_is_prior_plus_shared_likelihood(beacon4, precision):
    from bayes_mpem.lbl.model.loglik_kernel import FLOAT32_MAX_ERROR, FLOAT32_MAX_RANGES

    post = BeaconPosterior(beacon4, concentration=2.5, precision=precision)
    # float64 agrees to rounding; float32 (chosen by "auto" here) within its error bound
    tol = ({"rel": 1e-10} if post.kernel.dtype == np.float64
           else {"abs": FLOAT32_MAX_ERROR * beacon4.n / FLOAT32_MAX_RANGES})
    theta = np.array([[2472.0, np.log(7.0), np.log(4.0), 0.5, 0.35],
                      [2470.0, np.log(9.0), np.log(3.5), 0.4, 0.4]])
    lp = post(theta)
    for row, value in zip(theta, lp, strict=True):
        w = np.array([row[3], row[4], 1 - row[3] - row[4]])
        ll = loglik_per_range(post.geom, row[0], np.exp(row[2]), np.exp(row[1]), w).sum()
        prior = (stats.dirichlet.logpdf(w, [2.5] * 3) - np.log(np.diff(post.d0_bounds)[0])
                 - 2 * np.log(np.diff(post.log_sigma_bounds)[0]))
        assert value == pytest.approx(ll + prior, **tol)


def test_prior_support(beacon4):
    post = BeaconPosterior(beacon4)
    bad = np.array([[2472.0, np.log(7.0), np.log(4.0), 0.7, 0.35],    # w_ol < 0
                    [2472.0, np.log(1e4), np.log(4.0), 0.5, 0.35],    # sigma_mp > 500
                    [-5.0, np.log(7.0), np.log(4.0), 0.5, 0.35]])     # plane below vehicle
    assert np.all(post(bad) == -np.inf)


def test_equal_priors_and_fixed_sigma_dp_drop_parameters(beacon4):
    post = BeaconPosterior(beacon4, priors="equal", sigma_dp=3.97)
    assert post.names == ("d0", "log_sigma_mp")
    p = post.unpack(np.array([[2472.0, np.log(7.0)]]))
    assert p["sigma_dp"][0, 0] == 3.97 and p["w_ol"][0, 0] == pytest.approx(1 / 3)


@pytest.mark.parametrize(("kw", "msg"), [({"priors": "flat"}, "priors: expected one of"),
                                         ({"concentration": 0}, "concentration: expected")])
def test_bad_posterior_options(beacon4, kw, msg):
    with pytest.raises(ValueError, match=msg):
        BeaconPosterior(beacon4, **kw)


# --- the sampler -------------------------------------------------------------


def test_same_seed_same_chain(beacon4):
    a = sample_beacon(beacon4, rng=42, **FAST)
    b = sample_beacon(beacon4, rng=42, **FAST)
    c = sample_beacon(beacon4, rng=43, **FAST)
    np.testing.assert_array_equal(a.idata.posterior["d0"].values, b.idata.posterior["d0"].values)
    assert not np.array_equal(a.idata.posterior["d0"].values, c.idata.posterior["d0"].values)


def test_result_contents(beacon4):
    r = sample_beacon(beacon4, rng=1, **FAST)
    assert r.diagnostics["converged"]
    assert min(r.ess.values()) >= 1000 and max(r.rhat.values()) < 1.01
    assert sorted(r.idata.children) == ["observed_data", "posterior", "sample_stats"]
    obs = r.idata.observed_data
    np.testing.assert_array_equal(obs["range"], beacon4.rows)  # the input rows
    np.testing.assert_array_equal(obs["time"], beacon4.time)
    assert obs["z"].attrs["units"] == "m" and obs["time"].attrs["units"] == "s"
    assert r.idata.posterior["d0"].attrs["units"] == "m"
    full = sample_beacon(beacon4, rng=1, log_likelihood=True, predictive=True, **FAST)
    assert full.idata.log_likelihood["z"].shape[-1] == beacon4.n
    np.testing.assert_array_equal(full.idata.posterior["d0"], r.idata.posterior["d0"])
    pp = full.idata.posterior_predictive["z"].values
    assert pp.shape == full.idata.log_likelihood["z"].shape
    # the predictive ranges look like the data: the share near the direct path agrees
    geom = BeaconPosterior(beacon4).geom
    near = lambda z: np.mean(np.abs(z - geom.direct) < 3 * full.sigma_dp)  # noqa: E731
    assert near(pp) == pytest.approx(near(beacon4.range), abs=0.03)
    for key in ("d0", "sigma_mp", "sigma_dp"):
        lo, hi = r.summary[key]["interval"]
        assert lo < r.summary[key]["mean"] < hi
    np.testing.assert_allclose(r.class_probs.sum(axis=1), 1.0)
    assert np.all(r.class_probs_sd >= 0) and np.all(r.class_probs_sd <= 0.5)
    # class probabilities agree with the EM's where the EM is sure
    sure = r.em.resp.max(axis=1) > 0.999
    assert np.mean(r.labels[sure] == r.em.labels[sure]) > 0.99


@pytest.mark.parametrize("sampler", ["independence", "ensemble"])
def test_step_cap_warns(beacon4, sampler):
    with pytest.warns(SamplingWarning, match="reached max_steps=40"):
        r = sample_beacon(beacon4, rng=0, max_steps=40, sampler=sampler, **FAST)
    assert not r.diagnostics["converged"] and r.diagnostics["sampler"] == sampler


def test_several_ensembles_give_rhat(beacon4):
    r = sample_beacon(beacon4, rng=3, n_ensembles=2, **FAST)
    assert set(r.rhat) == {"d0", "sigma_mp", "sigma_dp", "w_dp", "w_mp", "w_ol"}
    assert all(v < 1.02 for v in r.rhat.values()) and r.diagnostics["n_ensembles"] == 2


def test_hdi_interval_probability(beacon4):
    r90 = sample_beacon(beacon4, rng=5, ci=0.5, **FAST)
    d = r90.idata.posterior["d0"].values.ravel()
    lo, hi = r90.summary["d0"]["interval"]
    assert np.mean((d >= lo) & (d <= hi)) == pytest.approx(0.5, abs=0.01)


# --- calibration (acceptance) ------------------------------------------------


@pytest.mark.slow
def test_interval_calibration_over_20_surveys():
    """95 % intervals of d0 and sigma_MP contain the truth in 85-100 % of 24 surveys."""
    hits = {"d0": 0, "sigma_mp": 0}
    w_err = []
    n = 24
    for seed in range(n):
        sim = bm.simulate_survey("random", rng=500 + seed, n_cycles=700)
        data = sim.survey.for_beacon("1")
        r = sample_beacon(data, rng=seed, **FAST)
        t = sim.truth["1"]
        for k in hits:
            lo, hi = r.summary[k]["interval"]
            hits[k] += lo <= t[k] <= hi
        w_err += [abs(r.summary["weights"][c]["mean"] - t["weights"][c]) for c in ("dp", "mp")]
    for k, h in hits.items():
        assert 0.85 <= h / n <= 1.0, (k, h)
    assert max(w_err) < 0.06  # learned weights recover the simulated ones


# --- equal against learned priors (acceptance) ------------------------------


@pytest.mark.parametrize("seed", range(3))
def test_loo_prefers_learned_weights_far_from_equal(seed):
    sim = bm.simulate_survey("abe58", rng=seed, n_cycles=700,
                             weights={b: (0.75, 0.15, 0.10) for b in "1234"})
    c = compare_beacon(sim.survey.for_beacon("2"), rng=seed, **FAST)
    assert c.elpd_diff > 2 * c.elpd_diff_se and c.elpd_diff > 4
    assert c.verdict == "learned"


@pytest.mark.parametrize("seed", range(4))
def test_loo_claims_nothing_on_equal_weights(seed):
    sim = bm.simulate_survey("abe58", rng=seed, n_cycles=700,
                             weights={b: (1 / 3, 1 / 3, 1 / 3) for b in "1234"})
    c = compare_beacon(sim.survey.for_beacon("2"), rng=seed, **FAST)
    assert c.verdict == "no clear difference", (c.elpd_diff, c.elpd_diff_se)
    assert abs(c.shifts["d0"]["mean_shift"]) < c.equal.summary["d0"]["sd"]


def test_psis_loo_matches_arviz_where_arviz_works(beacon4):
    import arviz_stats as azs

    r = sample_beacon(beacon4, rng=2, log_likelihood=True, **FAST)  # learned: no tied tails
    ours = psis_loo(r)
    ref = azs.loo(r.idata, pointwise=True, var_name="z")
    assert ours.n_constant == 0
    assert ours.elpd == pytest.approx(float(ref.elpd), rel=1e-10)
    assert ours.se == pytest.approx(float(ref.se), rel=1e-6)
    with pytest.raises(ValueError, match="log_likelihood=True"):
        psis_loo(sample_beacon(beacon4, rng=2, **FAST))


def test_psis_loo_tied_tail_is_exact_for_constant_ranges(beacon4):
    r = sample_beacon(beacon4, priors="equal", rng=2, log_likelihood=True, **FAST)
    loo = psis_loo(r)
    ll = r.idata.log_likelihood["z"].values.reshape(-1, beacon4.n)
    const = np.ptp(ll, axis=0) == 0
    assert const.any() and loo.n_constant >= const.sum()
    np.testing.assert_allclose(loo.elpd_i[const], ll[0, const], rtol=1e-12)
    assert np.all(np.isnan(loo.pareto_k[const]))


# --- survey level, files, command line ---------------------------------------


@pytest.fixture(scope="module")
def survey_files(tmp_path_factory):
    out = tmp_path_factory.mktemp("s")
    return bm.simulate_survey("abe58", rng=4, n_cycles=500).write(out)


def test_sample_command_writes_the_contract(survey_files, tmp_path):
    import xarray as xr

    from bayes_mpem.cli import main

    assert main(["sample", str(survey_files["pings"]), "--beacons",
                 str(survey_files["beacons"]), "--out", str(tmp_path), "--seed", "1",
                 "--ci", "0.9", "--no-progress", "--figures"]) == 0
    s = json.loads((tmp_path / "summary.json").read_text())
    assert s["ci"] == 0.9
    b = s["beacons"]["3"]
    for key in ("d0", "sigma_mp", "sigma_dp"):
        assert set(b[key]) == {"mean", "sd", "interval"}
    assert set(b["weights"]) == {"dp", "mp", "ol"}
    assert set(b["ess"]) >= {"d0", "sigma_mp"} and set(b["tau"]) >= {"d0", "sigma_mp"}
    lo, hi = b["d0"]["interval"]
    assert lo < 2395.0 < hi
    out = __import__("pandas").read_csv(tmp_path / "classified.csv")
    assert len(out) == len(__import__("pandas").read_csv(survey_files["pings"]))
    assert {"p_dp", "p_mp", "p_ol", "p_mp_sd", "label"} <= set(out.columns)
    tree = xr.open_datatree(tmp_path / "posterior_3.nc", engine="h5netcdf")
    assert "log_likelihood" not in tree.children  # only when asked for
    assert sorted(p.name for p in tmp_path.glob("*.nc")) == [
        f"posterior_{b}.nc" for b in sorted(s["beacons"])]
    for name in ("intervals.png", "trace_3.png", "pair_3.png", "classes_3.png"):
        assert (tmp_path / name).stat().st_size > 10_000


def test_compare_command(survey_files, tmp_path, capsys):
    from bayes_mpem.cli import main

    assert main(["compare", str(survey_files["pings"]), "--beacons",
                 str(survey_files["beacons"]), "--out", str(tmp_path), "--seed", "2"]) == 0
    # standard error is not a terminal here: progress comes as plain lines, per beacon and
    # priors, ending with the draws run, the ESS against its target and the seconds
    err = capsys.readouterr().err
    for bid in ("1", "2", "3", "4"):
        for priors in ("equal", "learned"):
            assert re.search(rf"^\[sampler\] beacon {bid} \({priors} priors\): done, \d+ "
                             r"steps x 16 walkers: ESS [\d,]+, target 1,000; R-hat \d\.\d+, "
                             r"target < 1\.01; \d+\.\d s$", err, re.M), err
    c = json.loads((tmp_path / "compare.json").read_text())
    for b in c["beacons"].values():
        for key in ("elpd_equal", "elpd_learned", "elpd_diff", "elpd_diff_se", "shifts",
                    "n_changed", "pareto_k", "verdict", "model_checks"):
            assert key in b
        assert b["model_checks"]["flags"] == []  # a clean survey
        assert b["elpd_diff"] == pytest.approx(b["elpd_learned"] - b["elpd_equal"], rel=1e-9)
    assert (tmp_path / "compare.png").stat().st_size > 10_000
    # bayes-mpem plot redraws it from compare.json alone
    assert main(["plot", str(tmp_path), "--out", str(tmp_path / "again")]) == 0
    assert (tmp_path / "again" / "compare.png").stat().st_size > 10_000


def test_sample_bad_input(tmp_path, capsys):
    from bayes_mpem.cli import main

    (tmp_path / "p.csv").write_text("time,beacon,range,x,y,depth\n0,1,-5,0,0,10\n")
    (tmp_path / "b.csv").write_text("beacon,x,y,depth\n1,0,0,100\n")
    assert main(["sample", str(tmp_path / "p.csv"), "--beacons", str(tmp_path / "b.csv"),
                 "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "line 2" in err and "'range'" in err and "-5" in err


# --- review fixes: unusable starts, early option checks, no overflow -----------


def _misplaced_beacon_survey():
    sim = bm.simulate_survey("abe58", rng=6, n_cycles=500)
    beacons = sim.survey.beacons.reset_index()
    beacons.loc[beacons["beacon"] == "4", ["x", "y"]] = 0.0  # wrong position for beacon 4
    return sim, beacons


def test_misplaced_beacon_is_skipped_not_a_traceback():
    sim, beacons = _misplaced_beacon_survey()
    with pytest.warns(UserWarning) as record:
        post = bm.sample(sim.survey.table, beacons, rng=0, **FAST)
    messages = [str(w.message) for w in record]
    assert any("beacon 4: the EM solution to start from" in m for m in messages)
    assert "4" in post.skipped and "4" not in post.results
    assert set(post.results) == {"1", "2", "3"}


def test_unusable_start_raises_for_one_beacon():
    from bayes_mpem.exceptions import UnusableStartError

    sim, beacons = _misplaced_beacon_survey()
    survey = bm.load_survey(sim.survey.table, beacons)
    with pytest.warns(bm.FitQualityWarning), pytest.raises(UnusableStartError,
                                                           match="check this beacon|Check"):
        sample_beacon(survey.for_beacon("4"), rng=0, **FAST)


def test_no_multipath_beacon_is_flagged_and_not_sampled():
    sim = bm.simulate_survey("abe58", rng=7, n_cycles=500,
                             weights={b: (0.85, 0.0, 0.15) for b in "1234"})
    with pytest.warns(bm.FitQualityWarning) as record:
        fit = bm.fit(sim.survey, rng=0)
    assert all(r.flags for r in fit.results.values())
    assert any("multipath" in str(w.message) for w in record)
    with pytest.warns(UserWarning):
        post = bm.sample(sim.survey, rng=0, **FAST)
    assert not post.results and set(post.skipped) == {"1", "2", "3", "4"}


@pytest.mark.parametrize(("kw", "msg"), [({"ci": 1.5}, "ci: expected a probability"),
                                         ({"n_ensembles": 0}, "n_ensembles: expected"),
                                         ({"priors": "flat"}, "priors: expected"),
                                         ({"concentration": -1}, "concentration: expected")])
def test_sample_options_checked_before_any_work(kw, msg):
    sim = bm.simulate_survey("abe58", rng=0, n_cycles=20)  # every beacon has < 30 replies
    with pytest.raises(ValueError, match=msg):
        bm.sample(sim.survey, **kw)
    if "ci" not in kw and "priors" not in kw:  # compare() samples both priors, no ci
        with pytest.raises(ValueError, match=msg):
            bm.compare(sim.survey, **kw)


def test_far_proposals_do_not_overflow(beacon4):
    post = BeaconPosterior(beacon4)
    theta = np.array([[2472.0, 1e4, 1e4, 0.5, 0.3], [2472.0, -1e4, np.log(4), 0.5, 0.3]])
    assert np.all(post(theta) == -np.inf)  # warnings are errors here: no overflow warning


def test_step_cap_warning_says_which_test_failed(beacon4):
    with pytest.warns(SamplingWarning, match=r"40 steps x 48 walkers, burn-in \d+, bulk ESS "
                                             r"[\d,]+ \(target 1,000\), R-hat"):
        sample_beacon(beacon4, rng=0, max_steps=40, sampler="ensemble", **FAST)
    with pytest.warns(SamplingWarning, match=r"20 steps x 16 walkers, burn-in 0, bulk ESS"):
        sample_beacon(beacon4, rng=0, max_steps=20, **FAST)
