"""navigate honest on a surface ship's staggered schedule (one range per epoch, no multipath):
scales that do not collapse, no spurious multipath class, intervals that hold, no negative
variance, parameters at a bound with one-sided intervals."""

import dataclasses
import warnings

import numpy as np
import pytest

from bayes_mpem.exceptions import NavigationWarning
from bayes_mpem.lbl.navigate import driver, ecm, navigate
from bayes_mpem.lbl.navigate.result import estimate, quality_lines
from bayes_mpem.lbl.navigate.simulate import simulate_ship

CHI2_95 = 5.991


def _nav(sim, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NavigationWarning)
        return navigate(sim.survey, rng=0, **kw)


def _coverage(nav, sim):
    err = nav.track - sim.true_track[["x", "y"]].to_numpy()
    m2 = np.einsum("ka,ka->k", err, np.linalg.solve(nav.cov, err[..., None])[..., 0])
    return float(np.mean(m2 < CHI2_95))


@pytest.fixture(scope="module")
def ships():
    return [simulate_ship(rng=seed, n_cycles=500) for seed in (0, 1)]


@pytest.fixture(scope="module")
def navs(ships):
    return [_nav(sim) for sim in ships]


def test_one_range_per_epoch_the_scale_does_not_collapse(ships, navs):
    """With the residuals' degrees of freedom restored sigma_DP is the truth (0.2 m),
    not the 0.05 m floor the plain weighted RMS falls to."""
    for sim, nav in zip(ships, navs, strict=True):
        assert sim.survey.table.groupby("time").size().max() == 1
        assert 0.16 <= nav.state.sigma_dp <= 0.24
        assert 0.85 <= _coverage(nav, sim) <= 0.995
        s = nav.summary()
        assert not s["sigma_dp"].get("at_bound")
        # its interval counts the residual degrees of freedom the track leaves (MacKay),
        # wider than sigma / sqrt(2 n) where one range per epoch leaves few
        n = float(nav.resp[:, 0].sum())
        assert s["sigma_dp"]["sd"] > 1.3 * s["sigma_dp"]["estimate"] / np.sqrt(2 * n)


def test_plain_rms_collapses_where_the_track_absorbs_the_noise(navs):
    """The baseline this fixes: the scale at the current track, no leverage."""
    nav = navs[0]
    settings = driver._settings(nav.dive, nav.options, {}, None)
    plain = ecm.scales_and_weights(nav.dive, nav.state, nav.resp, settings, expected=False)
    assert plain.sigma_dp < 0.8 * nav.state.sigma_dp


def test_no_multipath_class_without_multipath_and_it_says_why(navs):
    for nav in navs:
        s = nav.summary()
        assert not any(b["mp"] for b in nav.beacons.values())
        for b in s["beacons"].values():
            assert b["d0"] is None and b["reason"]
        assert any("multipath class switched off" in line for line in quality_lines(s))


def test_given_sigma_dp_no_internal_error_and_reported_as_given(ships):
    nav = _nav(ships[1], sigma_dp=0.2)
    s = nav.summary()
    assert s["sigma_dp"]["fixed"] and s["sigma_dp"]["estimate"] == 0.2
    assert "sigma_DP 0.2 m (given)" in nav.format_table()
    assert 0.85 <= _coverage(nav, ships[1]) <= 0.995


@pytest.mark.parametrize("track", [True, False])
def test_observed_information_not_positive_definite_falls_back(navs, monkeypatch, track):
    """A missing information larger than the complete one (in the track block, or in the
    globals' only, where the banded factorisation succeeds and the Schur complement is
    indefinite): the complete-data information is used, said so, no variance negative."""
    nav = navs[0]
    settings = driver._settings(nav.dive, nav.options, {}, None)
    run = ecm.Run(nav.state, nav.resp, nav.loglik, {}, 0, True)
    real = driver.missing_information

    def huge(*args):
        dg, dB, dC = real(*args)
        ne = driver.normal_equations(nav.dive, nav.state, nav.resp[:, 0] / nav.state.sigma_dp
                                     ** 2, nav.resp[:, 1] / nav.state.sigma_mp[
                                         nav.dive.beacon] ** 2, settings.priors,
                                     settings.free_d0)
        return dg + 3.0 * ne.diag * track, dB, dC + 3.0 * ne.C

    monkeypatch.setattr(driver, "missing_information", huge)
    if not track:  # the banded factorisation succeeds: only the Schur complement is indefinite
        ne = driver.normal_equations(nav.dive, nav.state, nav.resp[:, 0], nav.resp[:, 1],
                                     settings.priors, settings.free_d0)
        dg, dB, dC = driver.missing_information(nav.dive, nav.state, nav.resp, settings.free_d0)
        step = driver.solve(ne._replace(C=ne.C - dC))
        assert np.any(np.linalg.eigvalsh(step.S) < 0)
    cov, gsd, gcov, *_, info = driver._uncertainty(nav.dive, run, settings)
    assert info == driver.INFORMATION["fallback"]
    assert np.all(np.linalg.eigvalsh(cov) > 0)
    assert all(np.isfinite(v) and v >= 0 for v in gsd.values())


def test_a_value_at_its_bound_gets_a_one_sided_interval():
    e = estimate(2483.0, 0.04, 1.959964, lo=2483.0)
    assert e["at_bound"] and e["interval"][0] == 2483.0
    assert e["interval"][1] == pytest.approx(2483.0 + 1.644854 * 0.04, rel=1e-6)
    assert "at_bound" not in estimate(2490.0, 0.04, 1.96, lo=2483.0)
    assert estimate(1.0, float("nan"), 1.96)["interval"] == [None, None]


def test_range_scale_estimated_when_asked(ships, navs):
    """Ranges 0.05 % long (a sound speed 0.75 m/s high): without the scale the track and the
    noise level absorb it; with it the scale is found and the ellipses hold again."""
    from bayes_mpem.io.survey import load_survey

    sim = ships[0]
    t = sim.survey.table.copy()
    t["range"] = t["range"] * 1.0005
    survey = load_survey(t, sim.survey.beacons.reset_index())
    longer = dataclasses.replace(sim, simulation=dataclasses.replace(sim.simulation,
                                                                     survey=survey))
    nav = _nav(longer, range_scale=True)
    s = nav.summary()
    rs = s["range_scale"]
    assert abs(rs["estimate"] - 1.0005) < 4 * rs["sd"] + 1e-6
    assert 0.16 <= nav.state.sigma_dp <= 0.24
    assert 0.85 <= _coverage(nav, sim) <= 0.995
    assert "range scale 1.000" in nav.format_table()
    assert navs[0].summary()["range_scale"] is None  # off by default
