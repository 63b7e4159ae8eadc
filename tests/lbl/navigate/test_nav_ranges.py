"""Travel times through a sound-speed profile as navigate's ranges (lbl/navigate/ranges.py)."""

import warnings

import numpy as np
import pandas as pd
import pytest

from bayes_mpem.acoustics.profile import SoundSpeedProfile
from bayes_mpem.acoustics.turning import direct_times
from bayes_mpem.exceptions import InputError, NavigationWarning
from bayes_mpem.lbl.navigate import navigate
from bayes_mpem.lbl.navigate.checks import model_checks
from bayes_mpem.lbl.navigate.ranges import (
    RangeModel,
    equivalent_ranges,
    prepare,
    travel_time_pings,
)
from bayes_mpem.lbl.navigate.simulate import simulate_ship

#: A surface duct over a thermocline and a deep gradient: rays bend by metres over km.
PROFILE = SoundSpeedProfile([0.0, 60.0, 900.0, 3000.0], [1538.0, 1541.0, 1488.0, 1510.0],
                            source="test profile")
CHI2_95 = 5.991


def test_a_constant_speed_gives_speed_times_time():
    t = np.array([0.5, 1.7, 3.2])
    r, ok = equivalent_ranges(t, 8.0, 2500.0, SoundSpeedProfile.constant(1500.0))
    np.testing.assert_allclose(r, 1500.0 * t, rtol=0, atol=1e-6)
    assert ok.all()


def test_the_equivalent_range_is_the_straight_range_of_the_rays_horizontal_distance():
    gen = np.random.default_rng(0)
    h = gen.uniform(0.0, 6000.0, 400)
    za, zb = gen.uniform(2.0, 40.0, 400), gen.uniform(1500.0, 2900.0, 400)
    t = direct_times(PROFILE, za, zb, h).time
    r, ok = equivalent_ranges(t, za, zb, PROFILE)
    assert ok.all()
    np.testing.assert_allclose(r, np.hypot(h, zb - za), rtol=0, atol=1e-5)
    # and the harmonic-mean conversion it replaces is metres off at long range
    hm = PROFILE.harmonic_mean(za, zb) * t - np.hypot(h, zb - za)
    assert np.abs(hm[h > 4000]).max() > 1.0


def test_a_time_shorter_than_the_vertical_one_is_a_shorter_vertical_range():
    t0 = float(PROFILE.vertical_time(10.0, 2000.0))
    r, ok = equivalent_ranges([0.9 * t0, t0], 10.0, 2000.0, PROFILE)
    np.testing.assert_allclose(r, [0.9 * 1990.0, 1990.0], rtol=1e-12)
    assert ok.all()


def _tables(times, depth=8.0):
    p = pd.DataFrame({"time": np.arange(len(times), dtype=float), "beacon": "1",
                      "range": times, "x": 0.0, "y": 0.0, "depth": depth})
    b = pd.DataFrame({"beacon": ["1"], "x": [100.0], "y": [0.0], "depth": [2008.0]})
    return p, b


def test_two_way_times_with_turnaround_and_transducer_offset():
    m = RangeModel("two-way", 1500.0, turnaround=0.05, transducer_offset=2.0)
    p, b = _tables([2 * 2000.0 / 1500.0 + 0.05, np.nan], depth=6.0)
    out, _ = travel_time_pings(p, b, m)
    assert out["range"][0] == pytest.approx(2000.0, abs=1e-6)
    assert np.isnan(out["range"][1])  # no reply stays no reply
    assert out["depth"][0] == 8.0 and out["depth_input"][0] == 6.0
    assert out["range_input"][0] == p["range"][0]


def test_bad_cells_are_named_with_file_line_and_column(tmp_path):
    p, b = _tables([2.7, 0.01, 2.6])
    p.to_csv(tmp_path / "pings.csv", index=False)
    b.to_csv(tmp_path / "beacons.csv", index=False)
    with pytest.raises(InputError, match=r"pings.csv line 3, column 'range'.*turn-around"):
        prepare(str(tmp_path / "pings.csv"), str(tmp_path / "beacons.csv"),
                travel_times="two-way", profile=PROFILE, turnaround=0.013)
    p["depth"] = [8.0, -30.0, 8.0]
    p.to_csv(tmp_path / "pings.csv", index=False)
    with pytest.raises(InputError, match=r"pings.csv line 3, column 'depth'.*surface_depth"):
        prepare(str(tmp_path / "pings.csv"), str(tmp_path / "beacons.csv"),
                travel_times="two-way", profile=PROFILE)
    # the same transducer with the sea surface 40 m down the tables' frame is fine
    out, _, info = prepare(str(tmp_path / "pings.csv"), str(tmp_path / "beacons.csv"),
                           travel_times="two-way", profile=PROFILE, surface_depth=-40.0)
    assert info["surface_depth"] == -40.0 and np.isfinite(out["range"]).all()


def test_a_profile_that_ends_above_the_beacons_is_refused():
    p, b = _tables([2.7])
    with pytest.raises(InputError, match="profile ends at 1000 m"):
        prepare(p, b, travel_times="one-way",
                profile=SoundSpeedProfile([0.0, 1000.0], [1500.0, 1490.0]))


@pytest.mark.parametrize("kw, match", [
    ({"profile": 1500.0}, r"profile \(--ssp\) applies to travel times only"),
    ({"turnaround": 0.1}, r"--turnaround\) applies to travel times only"),
    ({"travel_times": "both", "profile": 1500.0}, "expected one of one-way, two-way"),
    ({"travel_times": "two-way"}, "need a sound-speed profile"),
    ({"travel_times": "two-way", "profile": 900.0}, r"\[1300, 1800\] m/s"),
    ({"travel_times": "two-way", "profile": 1500.0, "turnaround": -1}, "turnaround"),
    ({"transducer_offset": "deep"}, r"transducer_offset \(--transducer-offset\)"),
])
def test_bad_options_are_named(kw, match):
    p, b = _tables([2.7])
    with pytest.raises(ValueError, match=match):
        prepare(p, b, **kw)


def _refracted_ship(seed):
    """A staggered ship dive whose direct paths are travel times through PROFILE.

    Range noise 0.05 m, so that the straight-ray error (0.1-0.6 m) is not lost in it.
    """
    sim = simulate_ship(rng=seed, n_cycles=500, sigma_dp=0.05)
    p = sim.survey.table.copy()
    truth = sim.true_track.set_index("time").loc[p["time"], ["x", "y"]].to_numpy()
    xyz = sim.survey.beacons.loc[p["beacon"], ["x", "y", "depth"]].to_numpy()
    h = np.hypot(*(truth - xyz[:, :2]).T)
    straight = np.hypot(h, xyz[:, 2] - p["depth"])
    noise = p["range"].to_numpy() - straight  # the simulator's noise, in metres
    ray = direct_times(PROFILE, p["depth"].to_numpy(), xyz[:, 2], h).time
    dp = (sim.labels == "dp")
    c = 1500.0
    p["range"] = np.where(dp, ray + noise / c, p["range"] / c)
    beacons = sim.survey.beacons.reset_index()
    return p, beacons, sim.true_track[["x", "y"]].to_numpy()


def _scores(nav, truth):
    err = nav.track - truth
    m2 = np.einsum("ka,ka->k", err, np.linalg.solve(nav.cov, err[..., None])[..., 0])
    return float(np.sqrt(np.mean(np.sum(err ** 2, axis=1)))), float(np.mean(m2 < CHI2_95))


def test_ray_traced_ranges_remove_the_refraction_a_harmonic_mean_leaves():
    rmse, cover, checks = {}, {}, {}
    for seed in (0, 1):
        p, b, truth = _refracted_ship(seed)
        hm = p.copy()  # the conversion a field user would make without the ray solver
        xyz = b.set_index("beacon").loc[p["beacon"], ["depth"]].to_numpy()[:, 0]
        hm["range"] = p["range"] * PROFILE.harmonic_mean(p["depth"].to_numpy(), xyz)
        for name, pings, kw in (("ray", p, {"travel_times": "one-way", "profile": PROFILE}),
                                ("harmonic", hm, {})):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", NavigationWarning)
                nav = navigate(pings, b, rng=0, **kw)
            r, c = _scores(nav, truth)
            rmse.setdefault(name, []).append(r)
            cover.setdefault(name, []).append(c)
            checks.setdefault(name, []).append(len(model_checks(nav)["flags"]))
            if name == "ray":
                assert nav.summary()["options"]["range_model"]["profile"] == "test profile"
    # measured: ray 0.31 m and 95-97 %, harmonic 0.42-0.43 m and 91-93 % (the track takes
    # in part of the straight-ray error: one range per epoch, the random walk between)
    assert max(rmse["ray"]) < 0.85 * min(rmse["harmonic"])
    assert 0.9 <= min(cover["ray"]) and max(cover["ray"]) <= 0.98
    # the straight-ray residue shows in the model checks; the ray-traced ranges pass them
    assert min(checks["harmonic"]) > 0 and max(checks["ray"]) == 0


def test_the_range_scale_with_ray_traced_ranges_finds_a_sound_speed_error():
    p, b, truth = _refracted_ship(2)
    slow = p.copy()
    slow["range"] = p["range"] * 1.001  # the profile 0.1 % too slow: times 0.1 % long
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NavigationWarning)
        nav = navigate(slow, b, rng=0, travel_times="one-way", profile=PROFILE,
                       range_scale=True)
    k = nav.summary()["range_scale"]
    # ranges 0.1 % long (times through a profile are not exactly proportional to the range:
    # measured 1.0010032, sd 2.3e-6)
    assert abs(k["estimate"] - 1.001) < 4 * k["sd"] + 1e-5
    r, c = _scores(nav, truth)
    assert r < 0.6 and 0.9 <= c <= 0.99


def test_a_time_no_eigenray_takes_keeps_the_harmonic_mean_conversion_and_says_so():
    p, b = _tables([2.6, 40.0])  # the second: 60 km away, beyond every direct ray
    out, _ = travel_time_pings(p, b, RangeModel("one-way", PROFILE))
    assert out["ray_traced"].tolist() == [True, False]
    hm = float(PROFILE.harmonic_mean(8.0, 2008.0))
    assert out["range"][1] == pytest.approx(40.0 * hm, rel=1e-12)


def test_a_bad_profile_file_is_named_with_its_line(tmp_path):
    (tmp_path / "ssp.txt").write_text("depth speed\n0 1540\n100 fast\n")
    p, b = _tables([2.7])
    with pytest.raises(InputError, match=r"ssp.txt line 3"):
        prepare(p, b, travel_times="one-way", profile=tmp_path / "ssp.txt")
