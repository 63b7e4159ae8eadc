"""Refracted rays in the simulator and in the mixture EM (``bayes_mpem.refraction``).

References: the closed-form circular-arc eigenray of a constant-gradient ocean
(turning and not), the straight-ray simulator and fit (homogeneous medium), and
direct ray tracing with :mod:`bayes_mpem.acoustics` (the tabulated bounce times).
The sizes of the straight-ray biases asserted here were measured with
``benchmarks/ridge_refraction.py`` (``docs/refraction.md``).
"""

import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import bayes_mpem as bm
from bayes_mpem.acoustics.eigenray import surface_bounce_ray
from bayes_mpem.acoustics.profile import SoundSpeedProfile
from bayes_mpem.acoustics.profile_checks import nominal_sound_speed
from bayes_mpem.acoustics.turning import direct_times
from bayes_mpem.exceptions import FitQualityWarning
from bayes_mpem.lbl.em.em_mixture import fit_mixture_em
from bayes_mpem.lbl.model import geometry
from bayes_mpem.lbl.model.likelihood import total_loglik
from bayes_mpem.lbl.model.refracted import RefractedBeaconGeometry, lbl_ranges
from bayes_mpem.lbl.simulation.presets import ABE58
from bayes_mpem.lbl.simulation.simulate import simulate_lbl

WOA09 = Path(__file__).resolve().parents[3] / "data" / "woa09"
ENDEAVOUR = (47.95, -129.10)
KAIREI = (-25.32, 70.04)
CONST = SoundSpeedProfile.constant(1500.0)


@pytest.fixture(scope="module")
def endeavour():
    return SoundSpeedProfile.from_woa09(*ENDEAVOUR, directory=WOA09)


@pytest.fixture(scope="module")
def kairei():
    return SoundSpeedProfile.from_woa09(*KAIREI, directory=WOA09)



# --------------------------------------------------------------------------- rays

def _circle_ray(c0, g, za, zb, h):
    """Eigenray of ``c = c0 + g z``: the arc of the circle centred where ``c = 0``."""
    zc = -c0 / g
    xc = (h ** 2 + (zb - zc) ** 2 - (za - zc) ** 2) / (2 * h)
    r = np.hypot(xc, za - zc)
    ta, tb = np.arcsin(-xc / r), np.arcsin((h - xc) / r)
    time = np.abs(np.arctanh(np.sin(tb)) - np.arctanh(np.sin(ta))) / abs(g)
    turning = (xc > 0) & (xc < h)
    return time, turning, zc + np.sign(g) * r


@pytest.mark.parametrize("c0, g, zmax, zlo, zhi", [
    (1450.0, 0.016, 5000.0, 2000.0, 2600.0),   # speed growing with depth: rays dip and turn
    (1560.0, -0.05, 1200.0, 200.0, 800.0),     # falling with depth: rays rise and turn
])
def test_direct_rays_match_circular_arcs_turning_or_not(c0, g, zmax, zlo, zhi):
    prof = SoundSpeedProfile([0.0, zmax], [c0, c0 + g * zmax])
    rng = np.random.default_rng(1)
    n = 3000
    za, zb = rng.uniform(zlo, zhi, n), rng.uniform(zlo, zhi, n)
    zb[:400] = za[:400]                     # equal depths always need a turning point
    h = rng.uniform(10.0, 4000.0, n)
    rays = direct_times(prof, za, zb, h)
    time, turning, zt = _circle_ray(c0, g, za, zb, h)
    assert rays.valid.all()
    np.testing.assert_array_equal(rays.turning, turning)
    assert 0.2 < turning.mean() < 0.9
    assert np.abs(rays.time - time).max() * 1500.0 < 1e-5        # m
    assert np.abs(rays.turning_depth - zt)[turning].max() < 1e-6  # m
    assert np.isnan(rays.turning_depth[~turning]).all()


def test_no_direct_ray_across_a_speed_maximum():
    # a speed maximum at 1000 m between the ends: beyond the grazing distance there is
    # no direct eigenray at all (a shadow), which is reported, not approximated
    prof = SoundSpeedProfile([0.0, 1000.0, 2000.0], [1500.0, 1550.0, 1500.0])
    rays = direct_times(prof, 500.0, 1500.0, [500.0, 20000.0])
    assert rays.valid.tolist() == [True, False]
    assert np.isnan(rays.time[1])


def test_lbl_ranges_in_a_homogeneous_medium_are_the_straight_ranges():
    rng = np.random.default_rng(2)
    h, zv = rng.uniform(0.0, 5000.0, 200), rng.uniform(2000.0, 2500.0, 200)
    for path in ("triangle", "double"):
        r = lbl_ranges(CONST, 1500.0, h, zv, 2472.0, 0.0, path)
        assert r.direct_valid.all() and r.multipath_valid.all()
        np.testing.assert_allclose(r.direct, np.hypot(h, 2472.0 - zv), rtol=0, atol=1e-8)
        np.testing.assert_allclose(r.multipath, geometry.multipath_range(h, 2472.0 - zv, 2472.0,
                                                                         path), rtol=0, atol=1e-8)


# --------------------------------------------------------------------------- the simulator

def _same_simulation(a, b, exact=True):
    if exact:
        pd.testing.assert_frame_equal(a.survey.table, b.survey.table, check_exact=True)
        assert a.truth == b.truth and a.config == b.config
    else:
        np.testing.assert_allclose(a.survey.range, b.survey.range, rtol=0, atol=1e-8,
                                   equal_nan=True)
        for col in ("time", "x", "y", "depth"):
            np.testing.assert_array_equal(a.survey.table[col], b.survey.table[col])
    np.testing.assert_array_equal(a.labels, b.labels)


CASES = [("abe58", 0, {}), ("random", 3, {}), ("random", 11, {}),
         ("abe58", 2, {"path": "double", "effects": {"second_reflector": 300.0,
                                                     "plane_drift": 4.0,
                                                     "early_outliers": 0.2}})]


@pytest.mark.parametrize("preset, seed, kw", CASES)
def test_without_a_profile_the_simulator_is_unchanged(preset, seed, kw):
    # ssp=None is the old code path, draw for draw (checked against the code before the
    # option existed when it was added: identical tables, truth, config and labels)
    _same_simulation(bm.simulate_survey(preset, rng=seed, **kw),
                     bm.simulate_survey(preset, rng=seed, ssp=None, sound_speed=None, **kw))


@pytest.mark.parametrize("preset, seed, kw", CASES)
def test_a_homogeneous_profile_reproduces_the_straight_ray_simulator(preset, seed, kw):
    straight = bm.simulate_survey(preset, rng=seed, **kw)
    refr = bm.simulate_survey(preset, rng=seed, ssp=CONST, sound_speed=1500.0, **kw)
    _same_simulation(straight, refr, exact=False)
    for t in refr.truth.values():
        assert t["sound_speed"] == 1500.0 and set(t["no_ray"].values()) == {0}
        assert t["turning_direct"] == 0


def test_refracted_simulation_records_its_profile_and_nominal_speed(kairei):
    sim = bm.simulate_survey("abe58", rng=0, ssp=kairei)
    c_default = nominal_sound_speed(kairei, np.mean([2392, 2491, 2395, 2472]))
    assert sim.config["sound_speed"] == c_default
    assert sim.config["ssp"]["depth"] == kairei.depths.tolist()
    for bid, t in sim.truth.items():
        assert t["sound_speed"] == c_default and "WOA09" in t["ssp"]
        # near the floor the speed grows with depth: many direct rays turn below the ends
        assert t["turning_direct"] > 50
        assert t["no_ray"] == {"dp": 0, "mp": 0}
    # the direct returns are the refracted ones, not the straight lines
    data = sim.survey.for_beacon("4")
    lab = sim.survey.table["true_class"].to_numpy()[data.rows]
    geom = RefractedBeaconGeometry.from_data(data, kairei, c_default)
    r = (data.range - geom.direct)[lab == "dp"]
    assert abs(np.mean(r)) < 0.5 and np.std(r) == pytest.approx(3.97, rel=0.1)


# --------------------------------------------------------------------------- the model

def test_tabulated_bounce_times_match_direct_tracing(kairei):
    sim = bm.simulate_survey("abe58", rng=1, ssp=kairei, n_cycles=400)
    data = sim.survey.for_beacon("4")
    c = sim.truth["4"]["sound_speed"]
    geom = RefractedBeaconGeometry.from_data(data, kairei, c)
    zb = float(data.position[2])
    d0s = np.array([2301.3, 2466.66, 2472.0, 2490.2])
    tab = geom.multipath(d0s[:, None])                 # the walkers' shape (W, 1)
    for i, d0 in enumerate(d0s):
        ray = surface_bounce_ray(kairei, data.depth, zb, geom.h, zb - d0)
        exact = c * 0.5 * (geom.direct_time + ray.time)
        assert np.abs(tab[i] - exact).max() < 1e-4
        assert np.abs(geom.multipath(d0) - exact).max() < 1e-4
        # the derivative is the analytic one, and it is that of the interpolant
        e = 1e-3
        fd = (geom.multipath(d0 + e) - geom.multipath(d0 - e)) / (2 * e)
        assert np.abs(fd - geom.multipath_derivative(d0)).max() < 1e-5
    # noise-free multipath ranges invert to the true plane, range by range
    exact_geom = RefractedBeaconGeometry(**{**geom.__dict__, "z": geom.multipath(2472.0)})
    d0k = exact_geom.invert_plane_height()
    assert np.isfinite(d0k).mean() > 0.99
    assert np.nanmax(np.abs(d0k - 2472.0)) < 1e-2


def test_a_homogeneous_profile_reproduces_the_straight_ray_fit():
    sim = bm.simulate_survey("abe58", rng=1)
    for bid in ("1", "4"):
        data = sim.survey.for_beacon(bid)
        a = fit_mixture_em(data, rng=0)
        b = fit_mixture_em(data, rng=0, ssp=CONST, sound_speed=1500.0)
        assert b.d0 == pytest.approx(a.d0, abs=1e-6)
        assert b.sigma_mp == pytest.approx(a.sigma_mp, abs=1e-6)
        assert b.d0_se == pytest.approx(a.d0_se, rel=1e-6)
        assert b.loglik == pytest.approx(a.loglik, abs=1e-5)
        np.testing.assert_allclose(b.resp, a.resp, atol=1e-8)
        assert b.settings["refraction"]["no_ray"] == 0
        assert b.settings["sound_speed"] == 1500.0 and "constant" in b.settings["ssp"]
        # the subsample of the starts goes through the same geometry
        c = fit_mixture_em(data, rng=0, subsample=300)
        d = fit_mixture_em(data, rng=0, subsample=300, ssp=CONST, sound_speed=1500.0)
        assert d.d0 == pytest.approx(c.d0, abs=1e-6)


@pytest.mark.parametrize("site, nominal, sign, size", [
    # measured (docs/refraction.md, 5 seeds): straight-ray offsets -5.3 to -16.8 m at
    # Endeavour with the harmonic-mean speed, +7.1 to +10.3 m at Kairei with 1500 m/s
    ("endeavour", None, -1.0, 3.0),
    ("kairei", 1500.0, 1.0, 4.0),
])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_refracted_fit_finds_the_sea_surface_and_the_straight_fit_does_not(
        request, site, nominal, sign, size, seed):
    prof = request.getfixturevalue(site)
    sim = bm.simulate_survey("abe58", rng=seed, ssp=prof, sound_speed=nominal)
    for bid, t in sim.truth.items():
        data = sim.survey.for_beacon(bid)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", FitQualityWarning)  # the straight fit's sigma_DP
            straight = fit_mixture_em(data, rng=0)
        refr = fit_mixture_em(data, rng=0, ssp=prof, sound_speed=t["sound_speed"])
        assert abs(refr.d0 - t["d0"]) < max(4.0 * refr.d0_se, 1.5), bid
        assert refr.sigma_dp == pytest.approx(3.97, rel=0.1)
        assert sign * (straight.d0 - t["d0"]) > size, bid
        assert refr.settings["refraction"]["no_ray"] == 0
        assert refr.settings["refraction"]["turning_direct"] > 50


def _far_track(n, x_max):
    x = np.linspace(500.0, x_max, n)
    return {"time": np.arange(n) * 10.0, "x": x, "y": np.zeros(n), "depth": np.full(n, 700.0)}


def test_ranges_without_an_eigenray_become_outliers_and_are_counted():
    # the surface is much faster than the water below: far away, the ray leaving the
    # vehicle turns before it reaches the surface, so there is no surface bounce
    prof = SoundSpeedProfile([0.0, 150.0, 3000.0], [1600.0, 1490.0, 1500.0])
    beacons = {"1": {"x": 0.0, "y": 0.0, "depth": 1000.0}}
    track = _far_track(600, 14000.0)
    kw = dict(sigma_dp=2.0, sigma_mp={"1": 3.0}, weights={"1": (0.55, 0.4, 0.05)},
              window=(1.0, 30000.0), p_no_reply=0.0, ssp=prof, sound_speed=1500.0)
    sim = simulate_lbl(beacons, track, rng=4, **kw)
    t = sim.truth["1"]
    assert t["no_ray"]["mp"] > 20 and t["no_ray"]["dp"] == 0
    data = sim.survey.for_beacon("1")
    r = lbl_ranges(prof, 1500.0, data.x, data.depth, 1000.0, 0.0)
    assert (~r.multipath_valid).sum() > 100 and r.direct_valid.all()
    # in the fit those ranges cannot be multipath; the count is reported
    res = fit_mixture_em(data, rng=0, ssp=prof, sound_speed=1500.0)
    rays = res.settings["refraction"]
    assert rays["no_multipath_ray"] == int((~r.multipath_valid).sum())
    assert rays["no_direct_ray"] == 0 and rays["no_ray"] == 0
    no_mp = ~r.multipath_valid
    assert res.resp[no_mp, 1].max() == 0.0
    assert abs(res.d0 - 1000.0) < 1.0
    # and a geometry where neither exists: only outliers, flagged
    beacons = {"1": {"x": 0.0, "y": 0.0, "depth": 1500.0}}
    prof2 = SoundSpeedProfile([0.0, 150.0, 1100.0, 3000.0], [1600.0, 1490.0, 1560.0, 1500.0])
    sim = simulate_lbl(beacons, _far_track(600, 25000.0), rng=5, **{**kw, "ssp": prof2})
    t = sim.truth["1"]
    assert t["no_ray"]["dp"] > 20 and t["no_ray"]["mp"] > 20
    data = sim.survey.for_beacon("1")
    lab = sim.survey.table["true_class"].to_numpy()[data.rows]
    assert (lab == "ol").sum() >= t["no_ray"]["dp"] + t["no_ray"]["mp"]
    with pytest.warns(FitQualityWarning, match="no eigenray through the sound-speed profile"):
        res = fit_mixture_em(data, rng=0, ssp=prof2, sound_speed=1500.0)
    rays = res.settings["refraction"]
    assert rays["no_ray"] > 0.01 * data.n
    none = res.resp[:, 2] == 1.0
    assert none.sum() >= rays["no_ray"]


def test_bad_input_gives_clear_errors(kairei):
    shallow = SoundSpeedProfile([0.0, 1000.0], [1520.0, 1490.0])
    with pytest.raises(ValueError, match=r"profile ends at 1000 m .* rays reach 2491 m"):
        bm.simulate_survey("abe58", rng=0, ssp=shallow)
    with pytest.raises(TypeError, match="ssp: expected a SoundSpeedProfile"):
        bm.simulate_survey("abe58", rng=0, ssp=[1500.0])
    with pytest.raises(ValueError, match="sound_speed: only used with a sound-speed profile"):
        bm.simulate_survey("abe58", rng=0, sound_speed=1500.0)
    with pytest.raises(ValueError, match="sound_speed: expected a positive sound speed"):
        bm.simulate_survey("abe58", rng=0, ssp=kairei, sound_speed=-1500.0)
    with pytest.raises(ValueError, match="plane_depth: a refracted multipath needs the "
                                         "reflector above the vehicle"):
        bm.simulate_survey("abe58", rng=0, ssp=kairei, plane_depth=2360.0)
    with pytest.raises(ValueError, match=r"effects\['second_reflector'\]: a refracted"):
        bm.simulate_survey("abe58", rng=0, ssp=kairei, effects={"second_reflector": 2400.0})
    data = bm.simulate_survey("abe58", rng=0, n_cycles=100).survey.for_beacon("2")
    with pytest.raises(ValueError, match=r"profile ends at 1000 m .* rays reach 2491 m"):
        fit_mixture_em(data, ssp=shallow, sound_speed=1500.0)
    with pytest.raises(ValueError, match="sound_speed: with ssp=..., pass the nominal"):
        fit_mixture_em(data, ssp=kairei)
    with pytest.raises(ValueError, match="sound_speed: only used with a sound-speed profile"):
        fit_mixture_em(data, sound_speed=1500.0)
    with pytest.raises(TypeError, match="ssp: expected a SoundSpeedProfile"):
        fit_mixture_em(data, ssp="woa09", sound_speed=1500.0)
    geom = RefractedBeaconGeometry.from_data(data, kairei, 1500.0)
    one = np.ones((1, 1))
    with pytest.raises(NotImplementedError, match="straight-ray geometry only"):
        total_loglik(geom, 2491.0 * one, 4.0 * one, 10.0 * one, [one / 3] * 3)
    # a one-knot profile is homogeneous at every depth: accepted
    assert RefractedBeaconGeometry.from_data(data, CONST, 1500.0).n == data.n


def test_abe58_layout_is_the_simulator_preset():
    # the ridge benchmark relies on the preset's beacon depths (Table II)
    assert [b["depth"] for b in ABE58["beacons"].values()] == [2392.0, 2491.0, 2395.0, 2472.0]
