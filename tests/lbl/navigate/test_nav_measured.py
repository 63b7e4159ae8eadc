"""Navigation on measured surveys against their GPS truth (benchmarks/navigate_measured.py
has the full tables): SeaGap, four transponders (straight rays, and travel times through
its profile); OBSrange CC03, one beacon."""

import warnings

import numpy as np
import pytest

from bayes_mpem.acoustics.profile import SoundSpeedProfile
from bayes_mpem.exceptions import NavigationWarning
from bayes_mpem.io.formats import read_survey, sample_file
from bayes_mpem.io.geodesy import geodetic_to_enu
from bayes_mpem.lbl.navigate import navigate
from bayes_mpem.lbl.navigate.checks import model_checks
from bayes_mpem.lbl.navigate.simulate import degrade_pings


def _rmse(track, truth, cols=("x", "y")):
    return float(np.sqrt(np.mean(np.sum((track - truth[list(cols)].to_numpy()) ** 2, axis=1))))


def _navigate(pings, beacons, truth, **kw):
    out = {}
    for name, extra in (("this", {}), ("gaussian", {"model": "gaussian"})):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", NavigationWarning)
            out[name] = navigate(pings, beacons, rng=0, **kw, **extra)
    return out, _rmse(truth[["dr_x", "dr_y"]].to_numpy(), truth)


def test_seagap_ship_navigated_from_four_transponders():
    pings, beacons = read_survey(sample_file("seagap/obsdata.inp"), "seagap").to_pings()
    dr, truth = degrade_pings(pings, heading_bias=2.0, dr_noise=0.1, start_error=10.0, rng=0)
    navs, dr_rmse = _navigate(dr, beacons, truth, dr_noise=0.1)
    this, gauss = (_rmse(navs[k].track, truth) for k in ("this", "gaussian"))
    assert dr_rmse > 15.0
    assert this < 3.0 and this < 0.2 * dr_rmse  # measured: 1.59 m against 26 m
    # the survey has no spurious reply and no separable surface bounce (a surface ship):
    # every reply is direct path, and the Gaussian smoother is as good, not worse
    assert np.all(np.argmax(navs["this"].resp, axis=1) == 0)
    assert this <= 1.02 * gauss
    assert navs["this"].corrected
    assert abs(navs["this"].summary()["dead_reckoning"]["heading_bias_deg"]["estimate"]
               - 2.0) < 0.2


def _coverage(nav, truth):
    err = nav.track - truth[["x", "y"]].to_numpy()
    m2 = np.einsum("ka,ka->k", err, np.linalg.solve(nav.cov, err[..., None])[..., 0])
    return float(np.mean(m2 < 5.991))


def test_seagap_on_ray_traced_travel_times_is_accurate_and_honest():
    raw = read_survey(sample_file("seagap/obsdata.inp"), "seagap")
    pings, beacons = raw.to_pings()
    straight = pings.copy()
    pings["range"] = pings["twtt"]
    prof = raw.header["ss_prof"]
    # the heights are ellipsoidal: the profile's sea surface 3 m above the mean transducer
    ray = {"travel_times": "two-way", "surface_depth": float(pings["depth"].mean()) - 3.0,
           "profile": SoundSpeedProfile(prof["depth"], prof["sound_speed"])}
    dr, truth = degrade_pings(pings, heading_bias=2.0, dr_noise=0.1, start_error=10.0, rng=0)
    dr_straight, _ = degrade_pings(straight, heading_bias=2.0, dr_noise=0.1, start_error=10.0,
                                   rng=0)
    navs = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NavigationWarning)
        for name, p, kw in (("ray", dr, ray), ("straight", dr_straight, {})):
            navs[name] = navigate(p, beacons, dr_noise=0.1, rng=0, range_scale=True, **kw)
        gauss = navigate(dr, beacons, dr_noise=0.1, rng=0, model="gaussian", **ray)
    rmse = {k: _rmse(v.track, truth) for k, v in navs.items()}
    # measured: 0.46 m against 0.77 m on straight rays at one speed (both with the range
    # scale) and 1.53 m for the Gaussian smoother on the same ray-traced ranges (no scale);
    # coverage 91.7 % (84 % on straight rays)
    assert rmse["ray"] < 0.6 and rmse["ray"] < 0.75 * rmse["straight"]
    assert rmse["ray"] < 0.5 * _rmse(gauss.track, truth)
    assert 0.9 <= _coverage(navs["ray"], truth) <= 0.98
    assert _coverage(navs["straight"], truth) < 0.9
    # what the profile leaves (a sound speed changing in the 14.6 h) shows in the checks
    assert any("vary with time" in f for f in model_checks(navs["ray"])["flags"])


@pytest.fixture(scope="module")
def cc03():
    raw = read_survey(sample_file("obsrange/SIO_CC03.txt"), "obsrange-sio")
    pings, beacons = raw.to_pings(sound_speed=1506.86, tat=0.013)
    # the transponder where OBSrange's published bootstrap solution puts it
    e, n, _ = geodetic_to_enu(-4.88160, -132.68895, 0.0, raw.header["lat"], raw.header["lon"])
    beacons.loc[0, ["x", "y", "depth"]] = [float(e), float(n), 4739.13]
    return pings, beacons


def test_one_beacon_cannot_fix_an_unknown_heading_bias_and_says_so(cc03):
    dr, truth = degrade_pings(cc03[0], heading_bias=2.0, dr_noise=0.1, start_error=10.0, rng=0)
    with pytest.warns(NavigationWarning, match="beacon CC03 only.*heading bias"):
        nav = navigate(dr, cc03[1], dr_noise=0.1, rng=0)
    assert not nav.corrected
    this, dr_rmse = _rmse(nav.track, truth), _rmse(truth[["dr_x", "dr_y"]].to_numpy(), truth)
    assert this < dr_rmse  # measured 65.6 m against 69.0 m: the radial part only
    assert np.sqrt(nav.cov[:, [0, 1], [0, 1]]).max() > 50.0  # and it knows it


def test_one_beacon_with_a_known_heading_corrects_a_drift_and_the_spurious_pings(cc03):
    dr, truth = degrade_pings(cc03[0], heading_bias=0.0, dr_noise=0.3, start_error=10.0, rng=0)
    navs, dr_rmse = _navigate(dr, cc03[1], truth, dr_noise=0.3, heading_sd=0.5)
    this, gauss = (_rmse(navs[k].track, truth) for k in ("this", "gaussian"))
    assert this < 0.6 * dr_rmse  # measured: 8.1 m against 25.4 m
    assert this < 0.1 * gauss  # the 3 spurious pings wreck the Gaussian smoother (482 m)
    assert int(np.sum(np.argmax(navs["this"].resp, axis=1) == 2)) == 3
