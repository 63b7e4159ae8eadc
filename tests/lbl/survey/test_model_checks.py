"""Model checks: a hidden effect is flagged in either direction, clean data are not.

``benchmarks/model_checks.py`` measures the same over many seeded surveys (every effect,
both signs, three generators) and the false-alarm rate on clean ones.
"""

import json

import numpy as np
import pytest

import bayes_mpem as bm
from bayes_mpem.exceptions import FitQualityWarning, ModelCheckWarning
from bayes_mpem.lbl.survey.model_checks import (
    Z_LIMIT,
    binned_trend,
    checks_record,
    direct_path_checks,
    flagged,
    outlier_timing_check,
    plane_check,
)


def _names(checks):
    return {c["name"] for c in checks if c["flagged"]}


@pytest.mark.parametrize("seed", [0, 1])
def test_clean_surveys_raise_nothing(seed, tmp_path):
    sim = bm.simulate_survey("abe58", rng=seed, n_cycles=700)
    res = bm.fit(sim.survey, rng=seed)  # warnings are errors here: none may be raised
    assert all(not _names(ch) for ch in res.checks.values())
    doc = json.loads(res.write(tmp_path)["summary"].read_text())
    rec = doc["beacons"]["1"]["model_checks"]
    assert rec["flags"] == [] and {c["name"] for c in rec["checks"]} >= {
        "direct_path_offset", "plane_off_surface", "outliers_before_direct"}


@pytest.mark.parametrize("bias", [4.0, -4.0])
def test_a_range_bias_is_flagged_in_either_direction(bias):
    sim = bm.simulate_survey("abe58", rng=2, n_cycles=700, effects={"range_bias": bias})
    with pytest.warns(ModelCheckWarning, match="bayes-mpem diagnose"):
        res = bm.fit(sim.survey, rng=0)
    for b, ch in res.checks.items():
        off = next(c for c in ch if c["name"] == "direct_path_offset")
        assert off["flagged"] and np.sign(off["value"]) == np.sign(bias), (b, off)
        assert off["value"] == pytest.approx(bias, abs=1.0)
        err = res.results[b].d0 - sim.truth[b]["d0"]
        assert abs(err) > 2 * res.results[b].d0_se  # the interval is wrong: hence the flag


def test_one_beacons_bias_is_flagged_on_that_beacon_only():
    sim = bm.simulate_survey("abe58", rng=3, n_cycles=700,
                             effects={"beacon_bias": 5.0, "beacon": "3"})
    with pytest.warns(ModelCheckWarning, match="beacon 3"):
        res = bm.fit(sim.survey, rng=0)
    assert {b for b, ch in res.checks.items() if _names(ch)} == {"3"}


def test_first_arrival_outliers_are_flagged():
    sim = bm.simulate_survey("abe58", rng=4, n_cycles=700, effects={"early_outliers": 0.15})
    with pytest.warns(ModelCheckWarning, match="before the direct path"):
        res = bm.fit(sim.survey, rng=0)
    assert all("outliers_before_direct" in _names(ch) for ch in res.checks.values())


def test_a_drifting_navigation_leaves_trends():
    sim = bm.simulate_survey("abe58", rng=5, n_cycles=700, effects={"nav_drift": 40.0})
    with pytest.warns(FitQualityWarning) as seen:  # also a plane above the sea surface
        res = bm.fit(sim.survey, rng=0)
    assert any(w.category is ModelCheckWarning for w in seen)
    msgs = [m for ch in res.checks.values() for m in flagged(ch)]
    assert any("direct-path residuals vary with" in m and "time" in m for m in msgs), msgs


def test_sample_checks_the_posterior_and_records_them(tmp_path):
    sim = bm.simulate_survey("abe58", rng=6, n_cycles=300, effects={"range_bias": 6.0})
    with pytest.warns(ModelCheckWarning):
        post = bm.sample(sim.survey, rng=1, progress=False)
    doc = json.loads(post.write(tmp_path)["summary"].read_text())
    for b in post.results:
        rec = doc["beacons"][b]["model_checks"]
        assert any("longer than the straight line" in f for f in rec["flags"])
        assert "diagnose" in rec["flags"][-1]


def test_the_building_blocks():
    gen = np.random.default_rng(0)
    r = gen.normal(0.0, 2.0, 2000)
    (off,) = direct_path_checks(r, np.ones(r.size), 2.0)
    assert not off["flagged"] and abs(off["z"]) < 3
    (off,) = direct_path_checks(r + 0.5, np.ones(r.size), 2.0)
    assert off["flagged"] and off["z"] > Z_LIMIT
    # a fixed sigma_DP half the true scatter is caught; a right one is not
    assert _names(direct_path_checks(r, np.ones(r.size), 1.0, sigma_fixed=True)) == {
        "direct_path_scatter"}
    assert not _names(direct_path_checks(r, np.ones(r.size), 2.0, sigma_fixed=True))
    # a trend: centred, so an offset alone is not a trend
    v = np.arange(2000.0)
    assert binned_trend(r + 3.0, 2.0, v, centred=True)["p_value"] > 1e-3
    assert binned_trend(r + v / 500, 2.0, v, centred=True)["p_value"] < 1e-10
    # outliers spread over the window, or all before the direct path
    direct = gen.uniform(1000, 3000, 400)
    z = gen.uniform(1.0, 6000.0, 400)
    (ok,) = outlier_timing_check(z, direct, np.ones(400), 1.0, 6000.0)
    assert not ok["flagged"]
    (early,) = outlier_timing_check(gen.uniform(1.0, direct), direct, np.ones(400), 1.0, 6000.0)
    assert early["flagged"] and early["value"] == 1.0
    assert plane_check(-3.0)[0]["flagged"] is False
    assert plane_check(12.0)[0]["flagged"] and "below" in plane_check(12.0)[0]["message"]
    assert plane_check(-12.0)[0]["flagged"] and "above" in plane_check(-12.0)[0]["message"]
    assert not plane_check(12.0, interval=(8.0, 14.0))[0]["flagged"]  # interval reaches 10 m
    rec = checks_record(plane_check(25.0))
    assert len(rec["flags"]) == 2 and "diagnose" in rec["flags"][1]
    json.dumps(rec, allow_nan=False)  # valid JSON
