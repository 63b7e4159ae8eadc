"""Transponder location by EM: simulated truth, OBSrange's CC03 solution, spurious pings."""

import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from bayes_mpem.exceptions import InputError, LocateWarning
from bayes_mpem.io.formats import read_survey
from bayes_mpem.io.geodesy import enu_to_geodetic, geodetic_to_enu
from bayes_mpem.survey_in.heldout import heldout_logpdf
from bayes_mpem.survey_in.location import locate

DATA = Path(__file__).resolve().parents[2] / "data" / "obsrange"
FILES = [("SIO_CC03.txt", "obsrange-sio"), ("SIO_EC03.txt", "obsrange-sio"),
         ("SIO_WC03.txt", "obsrange-sio"), ("WHOI_S05.txt", "obsrange-whoi")]


def _simulated(seed, n=150, depth=4000.0, c=1505.0, tat=0.013, sigma=1e-3, p_bad=0.06):
    rng = np.random.default_rng(seed)
    ang = np.linspace(0, 2 * np.pi, n)
    x, y = 3000 * np.cos(ang) + rng.normal(0, 20, n), 3000 * np.sin(ang) + rng.normal(0, 20, n)
    truth = np.array([35.0, -60.0, depth])
    t = 2 * np.sqrt((x - truth[0]) ** 2 + (y - truth[1]) ** 2 + depth**2) / c + tat
    t += rng.normal(0, sigma, n)
    bad = rng.random(n) < p_bad
    t[bad] = rng.uniform(0.5, 8.0, bad.sum())
    pings = pd.DataFrame({"beacon": "T", "twtt": t, "x": x, "y": y, "depth": 0.0})
    beacons = pd.DataFrame({"beacon": ["T"], "x": [0.0], "y": [0.0], "depth": [depth + 100]})
    return pings, beacons, truth, bad


@pytest.mark.parametrize("seed", range(4))
def test_recovers_a_simulated_transponder(seed):
    pings, beacons, truth, bad = _simulated(seed)
    r = locate(pings, beacons)
    for k, v in zip(("east", "north", "depth"), truth, strict=True):
        assert abs(getattr(r, k) - v) < 4 * r.sd[k], (k, getattr(r, k), v, r.sd[k])
    assert abs(r.sound_speed - 1505.0) < 4 * r.sd["sound_speed"]
    np.testing.assert_array_equal(r.p_true < 0.5, bad)
    assert r.sigma == pytest.approx(1e-3, rel=0.2)


def test_cc03_agrees_with_obsrange_within_its_2_sigma():
    """OBSrange's published CC03 bootstrap solution (data/obsrange/CC03_obsrange_solution.txt)."""
    raw = read_survey(DATA / "SIO_CC03.txt", "obsrange-sio")
    r = locate(*raw.to_pings())
    e, n, _ = geodetic_to_enu(-4.88160, -132.68895, 0.0, raw.header["lat"], raw.header["lon"])
    assert abs(r.east - 13.36722) < 1.07463 and abs(r.north - 89.27011) < 1.50812
    assert abs(r.depth - 4739.12772) < 3.54529
    assert abs(r.sound_speed - 1506.86306) < 1.01580
    lat, lon, _ = enu_to_geodetic(r.east, r.north, 0.0, raw.header["lat"], raw.header["lon"])
    assert abs(lat - -4.88160) < 1e-5 + 5e-6 and abs(lon - -132.68895) < 1e-5 + 5e-6
    assert r.n_spurious == 3  # OBSrange: "Bad Pings Removed: 3"
    assert 1e3 * r.sigma == pytest.approx(1.54414, abs=0.33)  # OBSrange RMS 1.54 +- 0.33 ms


@pytest.mark.parametrize(("name", "fmt"), FILES)
def test_spurious_pings_match_a_robust_residual_check(name, fmt):
    raw = read_survey(DATA / name, fmt)
    r = locate(*raw.to_pings())
    t = raw.pings["twtt"].to_numpy()
    # independent check: residuals of a median-based straight-ray fit (the test's own)
    x, y = geodetic_to_enu(raw.pings["lat"], raw.pings["lon"], 0, raw.header["lat"],
                           raw.header["lon"])[:2]
    pred = 2 * np.sqrt((x - r.east) ** 2 + (y - r.north) ** 2 + r.depth**2) / r.sound_speed + r.tat
    res = t - pred
    mad = 1.4826 * np.median(np.abs(res - np.median(res)))
    outlying = np.abs(res - np.median(res)) > 8 * mad
    clean = np.abs(res - np.median(res)) < 3 * mad
    assert np.all(r.p_true[outlying] < 0.5)  # every gross outlier is found
    assert np.all(r.p_true[clean] > 0.5)  # no true ping is lost
    assert r.n_spurious >= 2


def test_turn_around_time_is_not_identifiable_on_cc03():
    raw = read_survey(DATA / "SIO_CC03.txt", "obsrange-sio")
    with pytest.warns(LocateWarning, match="turn-around time trades off"):
        r = locate(*raw.to_pings(), fit_tat=True)
    assert r.sd["depth"] > 50


def test_enu_geodetic_round_trip():
    e, n, u = geodetic_to_enu(-4.9, -132.7, -4700.0, -4.88, -132.69)
    lat, lon, h = enu_to_geodetic(float(e), float(n), float(u), -4.88, -132.69)
    assert lat == pytest.approx(-4.9, abs=1e-9) and lon == pytest.approx(-132.7, abs=1e-9)
    assert h == pytest.approx(-4700.0, abs=1e-3)


def test_bad_input():
    pings, beacons, *_ = _simulated(0)
    with pytest.raises(InputError, match=r"missing column\(s\) \['twtt'\]"):
        locate(pings.drop(columns="twtt"), beacons)
    with pytest.raises(InputError, match="transponder 'X' not in the beacons table"):
        locate(pings, beacons, "X")
    with pytest.raises(InputError, match="3 pings, need at least 6"):
        locate(pings.iloc[:3], beacons)


def test_locate_command_writes_the_contract(tmp_path):
    import json

    from bayes_mpem.cli import main

    assert main(["locate", str(DATA / "SIO_CC03.txt"), "--format", "obsrange",
                 "--out", str(tmp_path)]) == 0
    s = json.loads((tmp_path / "summary.json").read_text())
    t = s["transponders"]["CC03"]
    assert abs(t["lat"] - -4.88160) < 2e-5 and abs(t["lon"] - -132.68895) < 2e-5
    lo, hi = t["depth"]["interval"]
    assert lo < 4739.13 < hi and t["n_spurious"] == 3
    assert set(t["sound_speed"]) >= {"mean", "sd", "interval"}
    cls = pd.read_csv(tmp_path / "classified.csv", keep_default_na=False)
    # one row per ping line and per skipped line of the file: nothing lost
    assert len(cls) == 88 + 33 and (cls["label"] == "skipped").sum() == 33
    assert (cls["label"] == "spurious").sum() == 3
    assert cls["line"].is_monotonic_increasing


def test_locate_command_with_the_model_options(tmp_path):
    """--ssp, --speed-intervals and --fit-lag reach the fit and are recorded in summary.json."""
    import json

    from bayes_mpem.cli import main

    assert main(["locate", str(DATA / "WHOI_S05.txt"), "--format", "obsrange", "--ssp", "woa09",
                 "--fit-lag", "--out", str(tmp_path)]) == 0
    s = json.loads((tmp_path / "summary.json").read_text())
    t = s["transponders"]["S05"]
    assert s["fit_lag"] and s["ssp"].startswith("WOA09") and "refracted" in s["method"]
    assert 4.5 < t["lag"]["mean"] < 6.5 and t["sigma_ms"] < 2.0
    assert main(["locate", str(DATA / "WHOI_S05.txt"), "--format", "obsrange", "--fit-lag",
                 "--sample", "--out", str(tmp_path)]) == 2  # a clear error, not a wrong posterior


def _cv_gain(name, fmt):
    from bayes_mpem.survey_in.heldout import heldout_logpdf

    raw = read_survey(DATA / name, fmt)
    pings, beacons = raw.to_pings()
    tat = raw.header.get("tat", 0.013)
    uni = heldout_logpdf(pings, beacons, tat=tat, outliers="uniform", rng=0)
    first = heldout_logpdf(pings, beacons, tat=tat, outliers="first_arrival", rng=0)
    d = first - uni
    fits = [locate(pings, beacons, tat=tat, outliers=o) for o in ("uniform", "first_arrival")]
    return float(d.sum()), float(np.sqrt(d.size * d.var())), fits


def test_first_arrival_outliers_win_on_held_out_whoi_pings():
    """The WHOI EdgeTech log's spurious pings all arrive early (obs/pred 0.07-0.99): the
    first-arrival outlier model predicts held-out pings better (measured +1.47 +- 0.46 nats),
    with the same spurious pings and the same position."""
    gain, se, (uni, first) = _cv_gain("WHOI_S05.txt", "obsrange-whoi")
    assert gain > 0.5 and gain > 2 * se, (gain, se)
    np.testing.assert_array_equal(uni.p_true < 0.5, first.p_true < 0.5)
    assert abs(first.depth - uni.depth) < 0.2 and abs(first.east - uni.east) < 0.2


def test_first_arrival_outliers_lose_where_a_spurious_ping_is_late():
    """SIO_EC03's two spurious pings arrive after the true one (obs/pred 1.10, 1.22): there
    the first-arrival assumption is wrong and cross-validation says so (measured -13.5)."""
    gain, se, _ = _cv_gain("SIO_EC03.txt", "obsrange-sio")
    assert gain < -2.0, (gain, se)


def test_outlier_model_is_checked():
    pings, beacons, _, _ = _simulated(0)
    with pytest.raises(ValueError, match="outliers"):
        locate(pings, beacons, outliers="late")


# ------------------------------------------------------------------ travel-time models

@pytest.mark.parametrize("refracted", [False, True])
@pytest.mark.parametrize("radius", [None, 6.371e6])
def test_travel_time_jacobian_matches_finite_differences(refracted, radius):
    from bayes_mpem.acoustics.profile import SoundSpeedProfile
    from bayes_mpem.survey_in.travel_times import TravelTimes, speed_basis

    rng = np.random.default_rng(3)
    n = 40
    x, y = rng.uniform(-2500, 2500, n), rng.uniform(-2500, 2500, n)
    z = rng.uniform(-16, -14, n)
    prof = SoundSpeedProfile.from_file(DATA.parent / "seagap" / "ss_prof.inp") if refracted \
        else None
    basis = speed_basis(pd.DataFrame({"time": np.linspace(0, 1e3, n)}), 3, None)
    tt = TravelTimes(x, y, z, 0.0, basis=basis, fit_tat=True, profile=prof,
                      surface_depth=-18.0, earth_radius=radius)
    speed = 1.0 if refracted else 1489.0
    theta = np.r_[120.0, -40.0, 2700.0, speed * (1 + rng.normal(0, 1e-3, 6)), 0.01]
    steps = np.r_[1e-3, 1e-3, 1e-3, np.full(6, 1e-6 * speed), 1e-6]
    J = tt.jac(theta)
    for i, h in enumerate(steps):
        up, dn = theta.copy(), theta.copy()
        up[i] += h
        dn[i] -= h
        num = (tt.predict(up) - tt.predict(dn)) / (2 * h)
        np.testing.assert_allclose(J[:, i], num, rtol=1e-5, atol=1e-9 * np.abs(J).max())


def test_a_constant_profile_gives_the_straight_ray_fit():
    from bayes_mpem.acoustics.profile import SoundSpeedProfile

    pings, beacons, truth, _ = _simulated(0)
    a = locate(pings, beacons)
    b = locate(pings, beacons, ssp=SoundSpeedProfile.constant(1500.0))
    for k in ("east", "north", "depth", "sound_speed", "sigma"):
        assert getattr(b, k) == pytest.approx(getattr(a, k), rel=1e-7, abs=1e-6), k
    assert b.refracted and not a.refracted
    np.testing.assert_allclose(b.logpdf(pings), a.logpdf(pings), atol=1e-4)


def test_refracted_fit_recovers_a_transponder_simulated_through_a_profile():
    from bayes_mpem.acoustics.eigenray import direct_ray
    from bayes_mpem.acoustics.profile import SoundSpeedProfile

    prof = SoundSpeedProfile([0, 200, 1000, 5000], [1535.0, 1520.0, 1482.0, 1510.0])
    pings, beacons, truth, bad = _simulated(1, sigma=2e-4)
    h = np.hypot(pings["x"] - truth[0], pings["y"] - truth[1])
    t = 2 * direct_ray(prof, 0.0, truth[2], h).time + 0.013
    t += np.random.default_rng(9).normal(0, 2e-4, t.size)
    t[bad] = pings["twtt"].to_numpy()[bad]
    pings = pings.assign(twtt=t)
    straight, refr = locate(pings, beacons), locate(pings, beacons, ssp=prof)
    err = lambda r: np.abs([r.east - truth[0], r.north - truth[1], r.depth - truth[2]])  # noqa: E731
    assert np.all(err(refr) < 4 * np.array([refr.sd[k] for k in ("east", "north", "depth")]))
    assert refr.model["ssp"] is prof and refr.sigma < straight.sigma
    assert err(refr)[2] < err(straight)[2]


def test_speed_varying_in_time_is_recovered():
    pings, beacons, truth, bad = _simulated(2, n=400, sigma=2e-4)
    # visited in random order: time must not be a function of the position on the circle
    time = np.random.default_rng(5).permutation(np.linspace(0, 7200.0, len(pings)))
    c = 1505.0 + 2.0 * np.sin(2 * np.pi * time / 7200.0)
    L = np.sqrt((pings["x"] - truth[0]) ** 2 + (pings["y"] - truth[1]) ** 2 + truth[2] ** 2)
    t = 2 * L / c + 0.013 + np.random.default_rng(4).normal(0, 2e-4, len(pings))
    t[bad] = pings["twtt"].to_numpy()[bad]
    pings = pings.assign(twtt=t, time=time)
    with pytest.warns(LocateWarning, match="depth poorly constrained"):
        one = locate(pings, beacons)  # one speed: ms residuals, depth and speed trade off
    timed = locate(pings, beacons, speed_intervals=6)
    assert timed.sigma == pytest.approx(2e-4, rel=0.2) and one.sigma > 2 * timed.sigma
    assert abs(timed.sound_speed - c.mean()) < 4 * timed.sd["sound_speed"]
    assert abs(timed.depth - truth[2]) < 4 * timed.sd["depth"]
    with pytest.warns(LocateWarning):
        base = heldout_logpdf(pings, beacons)
    assert (heldout_logpdf(pings, beacons, speed_intervals=6) - base).sum() > 50


def test_bad_model_options_are_refused():
    pings, beacons, _, _ = _simulated(0)
    with pytest.raises(ValueError, match="speed_intervals"):
        locate(pings, beacons, speed_intervals=-1)
    with pytest.raises(InputError, match="'time' column"):
        locate(pings, beacons, speed_intervals=2)
    with pytest.raises(ValueError, match="folds"):
        heldout_logpdf(pings, beacons, folds="sideways")


# ------------------------------------------------------- travel times: chord and turning rays

def test_chord_forms_agree():
    from bayes_mpem.survey_in.travel_times import chord

    rng = np.random.default_rng(4)
    x, y, z = rng.uniform(-3000, 3000, 50), rng.uniform(-3000, 3000, 50), rng.uniform(0, 10, 50)
    for R in (None, 6.37e6):
        L = chord(x, y, z, 12.0, -30.0, 4000.0, R)
        L2, *d = chord(x, y, z, 12.0, -30.0, 4000.0, R, derivatives=True)
        np.testing.assert_allclose(L, L2, rtol=1e-14)
        eps = 1e-3
        for i, grad in enumerate(d):
            hi, lo = [12.0, -30.0, 4000.0], [12.0, -30.0, 4000.0]
            hi[i] += eps
            lo[i] -= eps
            num = (chord(x, y, z, *hi, R) - chord(x, y, z, *lo, R)) / (2 * eps)
            np.testing.assert_allclose(grad, num, atol=1e-7)
    # vectorised over walkers: (W, 1) columns give (W, n)
    W = chord(x, y, z, np.zeros((3, 1)), np.zeros((3, 1)), np.full((3, 1), 4000.0))
    assert W.shape == (3, 50)


def test_travel_times_turning_rays():
    """Rays that must turn are solved (not the chord at the mean speed), with exact slopes."""
    from bayes_mpem.acoustics.profile import SoundSpeedProfile
    from bayes_mpem.acoustics.turning import direct_times
    from bayes_mpem.survey_in.travel_times import TravelTimes

    prof = SoundSpeedProfile([0.0, 5000.0], [1450.0, 1530.0])
    x = np.array([3000.0, 2500.0, 200.0])
    y = np.array([0.0, 400.0, 100.0])
    z = np.array([2390.0, 2395.0, 2000.0])
    tt = TravelTimes(x, y, z, 0.0, profile=prof)
    theta = np.array([10.0, -20.0, 2400.0, 1.0])
    rays = direct_times(prof, z, 2400.0, np.hypot(x - 10.0, y + 20.0))
    assert rays.turning[:2].all() and not rays.turning[2]
    assert tt.n_invalid(theta) == 0
    np.testing.assert_allclose(tt.predict(theta), 2 * rays.time, rtol=1e-12)
    J = tt.jac(theta)
    for i in range(3):
        step = np.zeros(4)
        step[i] = 0.05  # the rays are solved to 1e-9 of their run: keep the step large
        num = (TravelTimes(x, y, z, 0.0, profile=prof).predict(theta + step)
               - TravelTimes(x, y, z, 0.0, profile=prof).predict(theta - step)) / 0.1
        np.testing.assert_allclose(J[:, i], num, rtol=1e-4, atol=2e-8)
    # the depth slope of a turning ray: moving the transponder down, towards the turning
    # point, shortens it (the ray arrives from below)
    assert J[0, 2] < 0


def test_travel_times_no_ray_is_counted():
    """A pair no eigenray joins (a speed maximum between the ends) is counted, not hidden."""
    from bayes_mpem.acoustics.profile import SoundSpeedProfile
    from bayes_mpem.survey_in.travel_times import TravelTimes

    prof = SoundSpeedProfile([0.0, 1000.0, 2000.0], [1480.0, 1540.0, 1480.0])
    tt = TravelTimes(np.array([20000.0, 100.0]), np.zeros(2), np.array([100.0, 100.0]), 0.0,
                     profile=prof)
    theta = np.array([0.0, 0.0, 1900.0, 1.0])
    assert tt.n_invalid(theta) == 1
    assert np.all(np.isfinite(tt.predict(theta)))
    J = tt.jac(theta)  # the flagged ping's chord at the mean speed: its own derivatives
    for i in range(3):
        step = np.zeros(4)
        step[i] = 0.05
        num = (tt.predict(theta + step) - tt.predict(theta - step)) / 0.1
        np.testing.assert_allclose(J[0, i], num[0], rtol=1e-6, atol=1e-10)


@pytest.mark.parametrize(("old", "new", "why"), [
    ("-4.88241", "-4.98241", r"located at depth -4,7\d\d\.\d m, above the transducers"),
    ("-132.68907", "132.68907", r"fitted sound speed [\d,.]+ m/s, outside 1300-1800 m/s"),
])
def test_a_drop_position_kilometres_off_is_refused_not_mirrored(tmp_path, old, new, why):
    """A latitude 0.1 degree off put CC03 4.7 km above the sea (exit 0, a tight interval); a
    longitude's sign slipped gave 742,025 m/s with every ping spurious."""
    from bayes_mpem.survey_in.survey import locate_survey

    path = tmp_path / "cc03.txt"
    path.write_text((DATA / "SIO_CC03.txt").read_text().replace(old, new, 1))
    raw = read_survey(path, "obsrange-sio")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LocateWarning)  # the depth poorly constrained
        with pytest.raises(InputError, match=rf"transponder CC03: {why}.*drop position in "
                                             r".*cc03.txt \(lat "):
            locate_survey(raw)


def test_the_lag_check_is_skipped_with_its_reason_on_a_few_pings(tmp_path):
    """Six pings locate CC03, but the lag check's folds cannot fit: the whole command failed
    ("4 pings, need at least 6", no file named) where only the check should be left out."""
    from bayes_mpem.survey_in.survey import locate_survey

    lines = (DATA / "SIO_CC03.txt").read_text().split("\n")
    end = next(i for i, line in enumerate(lines) if line.startswith("====="))
    pings = [line for line in lines if "msec" in line]
    path = tmp_path / "six.txt"
    path.write_text("\n".join(lines[:end + 1] + pings[::len(pings) // 6][:6]) + "\n")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LocateWarning)
        entry = locate_survey(read_survey(path, "obsrange-sio"), lag_check=True
                              ).summary["transponders"]["CC03"]
    assert set(entry["lag_check"]) == {"skipped"}
    assert "too few pings for a 5-fold held-out check" in entry["lag_check"]["skipped"]
    assert 4700 < entry["depth"]["mean"] < 4800
