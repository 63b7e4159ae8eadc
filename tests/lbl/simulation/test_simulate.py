import numpy as np
import pytest

import bayes_mpem as bm
from bayes_mpem.lbl.model import geometry


def test_abe58_preset_matches_the_paper():
    sim = bm.simulate_survey("abe58", rng=0)
    depths = sim.survey.beacons["depth"].to_dict()
    assert depths == {"1": 2392.0, "2": 2491.0, "3": 2395.0, "4": 2472.0}
    n_replies = int((~sim.survey.no_reply).sum())
    assert 4800 <= n_replies <= 5200
    assert {b: t["sigma_mp"] for b, t in sim.truth.items()} == {"1": 4.2, "2": 10.5,
                                                                "3": 14.0, "4": 6.9}
    assert all(t["sigma_dp"] == 3.97 and t["d0"] == depths[b] for b, t in sim.truth.items())


def test_same_seed_same_survey_and_different_seed_differs():
    a, b, c = (bm.simulate_survey("random", rng=s) for s in (4, 4, 5))
    np.testing.assert_array_equal(a.survey.range, b.survey.range)
    assert a.truth == b.truth
    assert len(a.survey) != len(c.survey) or not np.allclose(
        np.nan_to_num(a.survey.range), np.nan_to_num(c.survey.range))


def test_generated_classes_follow_the_model():
    sim = bm.simulate_survey("abe58", rng=3, n_cycles=20000)
    for bid, t in sim.truth.items():
        data = sim.survey.for_beacon(bid)
        lab = sim.survey.table["true_class"].to_numpy()[data.rows]
        for c in ("dp", "mp", "ol"):
            assert np.mean(lab == c) == pytest.approx(t["weights"][c], abs=0.015)
        h = geometry.horizontal_distance(data.x, data.y, *data.position[:2])
        dz = data.position[2] - data.depth
        r_dp = data.range[lab == "dp"] - geometry.direct_path(h, dz)[lab == "dp"]
        r_mp = (data.range - geometry.multipath_range(h, dz, t["d0"]))[lab == "mp"]
        assert np.std(r_dp) == pytest.approx(3.97, rel=0.05)
        assert np.std(r_mp) == pytest.approx(t["sigma_mp"], rel=0.05)
    assert np.mean(sim.survey.no_reply) == pytest.approx(0.05, abs=0.01)
    np.testing.assert_array_equal(sim.labels == "no_reply", sim.survey.no_reply)


def test_a_bias_beyond_the_range_labels_its_replies_outliers():
    """range_bias -1000 m: a direct path plus bias below 0 was redrawn as an outlier range
    but kept its 'dp' label (168 rows of the truth file wrong)."""
    sim = bm.simulate_survey("abe58", rng=1, n_cycles=300, effects={"range_bias": -1000.0})
    for bid in sim.truth:
        data = sim.survey.for_beacon(bid)
        lab = sim.survey.table["true_class"].to_numpy()[data.rows]
        h = geometry.horizontal_distance(data.x, data.y, *data.position[:2])
        model = geometry.direct_path(h, data.position[2] - data.depth) - 1000.0
        dp = lab == "dp"
        assert np.all(np.abs(data.range[dp] - model[dp]) < 50.0)
        assert np.all(model[dp] > 0)


def test_write_and_read_back(tmp_path):
    sim = bm.simulate_survey("abe58", rng=1)
    paths = sim.write(tmp_path)
    survey = bm.load_survey(paths["pings"], paths["beacons"])
    assert len(survey) == len(sim.survey)
    np.testing.assert_array_equal(survey.no_reply, sim.survey.no_reply)
    np.testing.assert_allclose(survey.range, sim.survey.range, atol=5e-4, equal_nan=True)
    assert "true_class" in survey.table.columns


@pytest.mark.parametrize("seed", range(10))
def test_random_preset_is_valid(seed):
    sim = bm.simulate_survey("random", rng=seed)
    assert 3 <= len(sim.truth) <= 5
    for t in sim.truth.values():
        assert sum(t["weights"].values()) == pytest.approx(1.0)
        assert t["weights"]["mp"] >= 0.12


def test_bad_options():
    with pytest.raises(ValueError, match="preset: expected one of .* got 'abe59'"):
        bm.simulate_survey("abe59")
    with pytest.raises(ValueError, match="unknown simulation option.*'colour'"):
        bm.simulate_survey("abe58", colour="red")
    with pytest.raises(ValueError, match=r"weights\['1'\]: expected 3 non-negative numbers"):
        bm.simulate_survey("abe58", weights={b: (0.5, 0.5, 0.5) for b in "1234"})


@pytest.mark.parametrize(("effects", "said"), [
    ({"beacon": "9"}, "effects\\['beacon'\\]: shapes beacon_bias or beacon_position"),
    ({"nav_drift_direction": 90.0}, "effects\\['nav_drift_direction'\\]: shapes nav_drift"),
    ({"second_fraction": 0.3}, "effects\\['second_fraction'\\]: shapes second_reflector"),
])
def test_an_option_without_its_effect_is_refused(effects, said):
    """Each was ignored without a word (exit 0)."""
    with pytest.raises(ValueError, match=said):
        bm.simulate_survey("abe58", rng=0, n_cycles=10, effects=effects)


def test_an_effect_given_twice_on_the_command_line_is_refused(tmp_path, capsys):
    from bayes_mpem.cli import main

    argv = ["simulate", "--preset", "abe58", "--out", str(tmp_path / "o"), "--effect",
            "range_bias=6", "--effect", "range_bias=-3"]
    assert main(argv) == 2
    assert "range_bias given twice" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()
