"""navigate: recovery against the truth and an oracle, shadowing, honesty where it cannot
correct, the baselines, the output files, bad input."""

import json
import warnings

import numpy as np
import pandas as pd
import pytest

from bayes_mpem.exceptions import InputError, NavigationWarning
from bayes_mpem.lbl.navigate import navigate, simulate_dive

CHI2_95 = 5.991


def _quiet(*args, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NavigationWarning)
        return navigate(*args, rng=0, **kw)


def _oracle(sim):
    truth = sim.simulation.truth
    return dict(classes=sim.labels, sigma_dp=truth["1"]["sigma_dp"],
                reflectors={b: {"d0": v["d0"], "sigma_mp": v["sigma_mp"], "path": v["path"]}
                            for b, v in truth.items()})


def _errors(nav, sim):
    err = nav.track - sim.true_track[["x", "y"]].to_numpy()
    m2 = np.einsum("ka,ka->k", err, np.linalg.solve(nav.cov, err[..., None])[..., 0])
    return np.sqrt(np.mean(np.sum(err ** 2, axis=1))), m2 < CHI2_95


@pytest.fixture(scope="module")
def dives():
    """Three dives: abe58, a random geometry, abe58 with double bounces."""
    return [simulate_dive("abe58", rng=0, n_cycles=500),
            simulate_dive("random", rng=1, n_cycles=500),
            simulate_dive("abe58", rng=2, n_cycles=500, path="double")]


@pytest.fixture(scope="module")
def navs(dives):
    return [navigate(sim.survey, rng=0) for sim in dives]


def test_recovers_track_classes_and_reflectors_without_the_true_positions(dives, navs):
    inside = []
    for sim, nav in zip(dives, navs, strict=True):
        rmse, ok = _errors(nav, sim)
        oracle, _ = _errors(navigate(sim.survey, rng=0, **_oracle(sim)), sim)
        dr = sim.true_track[["dr_x", "dr_y"]].to_numpy() - sim.true_track[["x", "y"]].to_numpy()
        assert rmse <= 1.25 * oracle
        assert rmse < 0.2 * np.sqrt(np.mean(np.sum(dr ** 2, axis=1)))
        for j, b in enumerate(nav.dive.beacon_ids):
            assert abs(nav.state.d0[j] - sim.simulation.truth[b]["d0"]) < 3.0
            assert bool(nav.state.double[j]) == (sim.simulation.truth[b]["path"] == "double")
        pred = np.array(["dp", "mp", "ol"])[np.argmax(nav.resp, axis=1)]
        assert np.mean(pred == sim.labels[nav.dive.rows]) >= 0.97
        truth = sim.truth["navigation"]
        beta = nav.summary()["dead_reckoning"]["heading_bias_deg"]
        assert abs(beta["estimate"] - truth["heading_bias_deg"]) < 4 * beta["sd"] + 0.02
        assert nav.converged and nav.corrected
        inside.append(ok)
    # 95 % ellipses: pooled over three short dives (errors are correlated in time, so the
    # band is wider than the benchmark's 90-98 % over 20 full dives)
    assert 0.85 <= np.mean(np.concatenate(inside)) <= 0.995


def test_multipath_as_signal_corrects_a_shadowed_stretch():
    """The direct path blocked over the middle half: multipath ranges keep the track."""
    sim = simulate_dive("abe58", rng=0, n_cycles=900, shadow_windows=[(2700.0, 8100.0)])
    blocked = sim.true_track["n_blocked"].to_numpy() == 4
    err = {}
    for mp in ("signal", "outlier"):
        nav = _quiet(sim.survey, multipath=mp)
        e = nav.track - sim.true_track[["x", "y"]].to_numpy()
        err[mp] = np.sqrt(np.mean(np.sum(e[blocked] ** 2, axis=1)))
    assert err["signal"] <= 0.6 * err["outlier"]


def test_log_posterior_never_decreases_once_annealed(navs):
    """The E- and track steps never lower the log posterior at the iteration's scales."""
    for nav in navs:
        lp, tau = np.array(nav.history["log_posterior"]), np.array(nav.history["anneal"])
        lp_track = np.array(nav.history["log_posterior_track"])
        run = np.array(nav.history["run"])  # a new ECM run (path or class changed) restarts
        after = np.flatnonzero((tau[:-1] == 0) & (tau[1:] == 0) & (run[:-1] == run[1:])) + 1
        assert after.size >= 2
        assert np.all(lp_track[after] - lp[after - 1] >= -1e-9 * abs(lp[-1]))


def test_one_beacon_on_a_straight_line_says_it_cannot_correct():
    sim = simulate_dive("abe58", rng=0, n_cycles=200, heading_bias=1.0,
                        beacons={"1": {"x": 1500.0, "y": 800.0, "depth": 2400.0}},
                        sigma_mp={"1": 5.0}, weights={"1": (0.7, 0.2, 0.1)}, box=(0, 3000, 0, 0),
                        line_spacing=1000.0)
    with pytest.warns(NavigationWarning, match="replies from beacon 1 only.*heading bias"):
        nav = navigate(sim.survey, rng=0)
    assert not nav.corrected and nav.summary()["navigation_corrected"] is False
    track_flags = [f for f in nav.flags if f["kind"] == "track"]
    assert track_flags[0]["n_epochs"] == nav.dive.n_epochs and track_flags[0]["max_sd"] > 30
    assert np.median(np.sqrt(nav.cov[:, [0, 1], [0, 1]]).max(axis=1)) > 30


def test_a_long_stretch_without_replies_is_flagged():
    sim = simulate_dive("abe58", rng=3, n_cycles=600)
    table = sim.survey.table.drop(columns="true_class")
    gap = (table["time"] > 2000) & (table["time"] < 5000)
    table.loc[gap, "range"] = np.nan
    with pytest.warns(NavigationWarning, match="no direct-path or multipath reply"):
        nav = navigate(table, sim.survey.beacons.reset_index(), dr_noise=0.5, rng=0)
    (flag,) = [f for f in nav.flags if f["kind"] == "track"]
    assert 2000 < flag["start"] < flag["end"] < 5000
    sd = np.sqrt(nav.cov[:, [0, 1], [0, 1]]).max(axis=1)
    mid = np.argmin(np.abs(nav.dive.times - 3500))
    assert sd[mid] > 3 * np.median(sd)


@pytest.mark.parametrize("model", ["gaussian", "huber", "gate"])
def test_baselines_take_every_reply_for_the_direct_path_or_nothing(dives, model):
    nav = _quiet(dives[0].survey, model=model)
    assert np.all(nav.resp[:, 1] == 0)
    s = nav.summary()
    assert all(b["d0"] is None and "model=" in b["reason"] for b in s["beacons"].values())


def test_intervals_use_the_observed_information_of_the_mixture(dives, navs):
    """Louis' correction: only where the classes are estimated, and it only widens."""
    from bayes_mpem.lbl.navigate import driver, ecm

    nav = navs[1]
    assert nav.summary()["information"] == "observed (Louis)"
    settings = ecm.Settings(priors=driver._settings(nav.dive, nav.options, {}, None).priors,
                            mp_beacons=np.array([b["mp"] for b in nav.beacons.values()]),
                            free_d0=tuple(j for j, b in enumerate(nav.beacons.values())
                                          if b["d0_free"]), fixed_resp=nav.resp)
    run = ecm.Run(nav.state, nav.resp, nav.loglik, {}, 0, True)
    cov_gn, sd_gn, *_, info = driver._uncertainty(nav.dive, run, settings)
    assert info == driver.INFORMATION["complete"]
    assert all(nav.global_sd[k] >= sd_gn[k] for k in sd_gn)
    assert max(nav.global_sd[k] / sd_gn[k] for k in sd_gn if k.startswith("d0")) > 1.001
    assert np.all(np.linalg.eigvalsh(nav.cov - cov_gn) > -1e-12)
    oracle = _quiet(dives[1].survey, **_oracle(dives[1]))
    assert oracle.summary()["information"] == driver.INFORMATION["complete"]
    # the joint covariance the online filter starts from
    g = len(nav.global_sd)
    assert nav.global_cov.shape == (g, g) and nav.track_global_cov.shape == (
        nav.dive.n_epochs, 2, g)
    np.testing.assert_allclose(np.sqrt(np.diag(nav.global_cov)), list(nav.global_sd.values()))


def test_multipath_as_outliers_has_no_reflector(dives):
    nav = _quiet(dives[0].survey, multipath="outlier")
    assert np.all(nav.resp[:, 1] == 0)
    assert all("multipath='outlier'" in b["reason"] for b in nav.summary()["beacons"].values())


def test_vehicle_at_the_surface_gets_no_multipath_class(dives):
    t = dives[0].survey.table.drop(columns="true_class").assign(depth=0.0)
    nav = _quiet(t, dives[0].survey.beacons.reset_index())
    for b in nav.summary()["beacons"].values():
        assert b["d0"] is None and "at the surface" in b["reason"]


def test_outputs_every_row_deterministic_and_valid_json(tmp_path, dives, navs):
    sim, nav = dives[0], navs[0]
    a = nav.write(tmp_path / "a")
    b = navigate(sim.survey, rng=0).write(tmp_path / "b")
    assert a["summary"].read_bytes() == b["summary"].read_bytes()
    assert a["track"].read_bytes() == b["track"].read_bytes()
    summary = json.loads(a["summary"].read_text(),
                         parse_constant=lambda c: pytest.fail(f"JSON token {c}"))
    assert set(json.loads(a["timings"].read_text())) >= {"ecm", "total"}
    assert "timings" not in summary and "total" not in json.dumps(summary["options"])
    classified = pd.read_csv(a["classified"])
    assert len(classified) == len(sim.survey)
    assert (classified["label"] == "no_reply").sum() == int(sim.survey.no_reply.sum())
    track = pd.read_csv(a["track"])
    assert list(track.columns[:9]) == ["time", "x", "y", "depth", "sd_x", "sd_y", "cov_xy",
                                       "dr_x", "dr_y"]
    assert len(track) == nav.dive.n_epochs
    d0 = summary["beacons"]["1"]["d0"]
    assert d0["interval"][0] < d0["estimate"] < d0["interval"][1]


def test_a_dead_reckoning_table_replaces_the_pings_positions(dives, navs):
    sim = dives[0]
    tt = sim.true_track
    table = sim.survey.table.drop(columns="true_class").assign(x=0.0, y=0.0)
    dr = pd.DataFrame({"time": tt["time"], "x": tt["dr_x"], "y": tt["dr_y"]})
    nav = navigate(table, sim.survey.beacons.reset_index(), dead_reckoning=dr, rng=0)
    np.testing.assert_allclose(nav.track, navs[0].track, atol=1e-6)


@pytest.mark.parametrize(("kw", "err", "match"), [
    ({"model": "kalman"}, ValueError, "model"),
    ({"multipath": "maybe"}, ValueError, "multipath"),
    ({"dr_noise": 0.0}, ValueError, "dr_noise"),
    ({"path": "single"}, ValueError, "path"),
    ({"classes": ["dp"] * 3}, InputError, "one label per input row"),
    ({"reflectors": {"9": {"d0": 1.0, "sigma_mp": 1.0}}}, InputError, "unknown beacon '9'"),
    ({"reflectors": {"1": {"d0": 1.0}}}, InputError, "'d0' and 'sigma_mp'"),
    ({"reflectors": {"1": {"d0": 1.0, "sigma_mp": 2.0, "path": "auto"}}}, ValueError,
     r"reflectors\['1'\]\['path'\]: expected one of \('triangle', 'double'\)"),
])
def test_bad_options_are_named(dives, kw, err, match):
    with pytest.raises(err, match=match):
        navigate(dives[0].survey, **kw)


def test_bad_classes_name_the_row(dives):
    lab = dives[0].labels.copy()
    row = int(np.flatnonzero(lab != "no_reply")[3])
    lab[row] = "xx"
    with pytest.raises(InputError, match=rf"classes\[{row}\]: expected 'dp', 'mp' or 'ol'"):
        navigate(dives[0].survey, classes=lab)


def test_a_few_replies_and_a_beacon_without_any():
    """Two replies in one epoch: direct paths (not outliers for want of a window); the silent
    beacon is listed as skipped and its row kept; the single epoch is flagged, not failed."""
    beacons = pd.DataFrame({"beacon": ["A", "B", "C"], "x": [0.0, 800.0, 0.0],
                            "y": [0.0, 0.0, 800.0], "depth": [1000.0] * 3})
    pings = pd.DataFrame({"time": [0.0] * 3, "beacon": ["A", "B", "C"],
                          "range": [1000.5, 1290.0, np.nan], "x": [0.0] * 3, "y": [0.0] * 3,
                          "depth": [10.0] * 3})
    with pytest.warns(NavigationWarning, match="not corrected"):
        nav = navigate(pings, beacons)
    assert nav.classified()["label"].tolist() == ["dp", "dp", "no_reply"]
    assert nav.skipped == {"C": "beacon C has no reply"}
    json.dumps(nav.summary(), allow_nan=False)
