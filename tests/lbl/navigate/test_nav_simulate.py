"""The dive simulator: the dead reckoning the model assumes, shadowing, files, seeds."""

import json

import numpy as np
import pandas as pd
import pytest

from bayes_mpem.lbl.navigate.model import rotation
from bayes_mpem.lbl.navigate.simulate import degrade, degrade_pings, simulate_dive


def test_dead_reckoning_follows_the_motion_model():
    sim = simulate_dive("abe58", rng=4, n_cycles=800, heading_bias=1.5, speed_scale=1.01,
                        dr_noise=0.2)
    tt = sim.true_track
    p, dr = tt[["x", "y"]].to_numpy(), tt[["dr_x", "dr_y"]].to_numpy()
    R, _ = rotation(np.deg2rad(1.5))
    w = np.diff(p, axis=0) - 1.01 * np.diff(dr, axis=0) @ R.T
    dt = np.diff(tt["time"].to_numpy())
    z = w / (0.2 * np.sqrt(dt))[:, None]  # standardised random-walk steps
    assert abs(z.mean()) < 4 / np.sqrt(z.size)
    assert z.std() == pytest.approx(1.0, abs=0.05)
    # the pings report the dead reckoning, one position per cycle, and the true depth
    t = sim.survey.table
    cyc = np.searchsorted(tt["time"].to_numpy(), t["time"].to_numpy())
    np.testing.assert_allclose(t["x"].to_numpy(float), dr[cyc, 0])
    np.testing.assert_allclose(t["depth"].to_numpy(float), tt["depth"].to_numpy()[cyc])


def test_same_seed_same_dive_and_defaults_drawn_in_range():
    a = simulate_dive("random", rng=7, n_cycles=100)
    b = simulate_dive("random", rng=7, n_cycles=100)
    pd.testing.assert_frame_equal(a.survey.table, b.survey.table)
    nav = a.truth["navigation"]
    assert -2 <= nav["heading_bias_deg"] <= 2 and 0.98 <= nav["speed_scale"] <= 1.02


def test_shadowing_turns_blocked_direct_paths_into_surface_bounces():
    plain = simulate_dive("abe58", rng=2, n_cycles=600)
    sim = simulate_dive("abe58", rng=2, n_cycles=600, shadow_windows=[(1000.0, 3000.0)],
                        shadow_range=1900.0)
    lab, t = sim.labels, sim.survey.time
    assert not np.any(sim.blocked & (lab == "dp"))
    assert np.all(sim.blocked[(t >= 1000) & (t <= 3000)])
    turned = sim.blocked & (plain.labels == "dp")
    assert turned.sum() > 100 and np.all(lab[turned] == "mp")
    assert sim.truth["navigation"]["blocked_replies"] == int(
        np.sum(sim.blocked & (lab != "no_reply")))
    # a blocked reply is the surface bounce: longer than the direct path by the bounce's lag
    assert np.all(sim.survey.range[turned] > plain.survey.range[turned] + 50.0)
    full = sim.true_track["n_blocked"].to_numpy() == 4
    tt = sim.true_track["time"].to_numpy()
    assert np.all(full[(tt >= 1000) & (tt <= 3000)])


def test_write_gives_the_files_of_a_dive(tmp_path):
    sim = simulate_dive("abe58", rng=0, n_cycles=30)
    paths = sim.write(tmp_path)
    assert sorted(paths) == ["beacons", "pings", "true_track", "truth"]
    truth = json.loads(paths["truth"].read_text())
    assert truth["config"]["navigation"]["dr_noise"] == 0.1
    assert len(pd.read_csv(paths["true_track"])) == 30


@pytest.mark.parametrize(("kw", "match"), [({"dr_noise": 0}, "dr_noise"),
                                          ({"shadow_windows": [(5, 1)]}, "start <= end"),
                                          ({"shadow_windows": [5]}, "pair of times"),
                                          ({"shadow_range": -1}, "shadow_range")])
def test_bad_options(kw, match):
    with pytest.raises(ValueError, match=match):
        simulate_dive("abe58", rng=0, n_cycles=10, **kw)


def test_degrade_pings_keeps_every_row_and_returns_the_truth():
    p = pd.DataFrame({"time": [0.0, 0.0, 30.0, 60.0], "beacon": ["1", "2", "1", "2"],
                      "x": [0.0, 0.0, 30.0, 60.0], "y": [5.0] * 4, "extra": list("abcd")})
    out, truth = degrade_pings(p, heading_bias=90.0, dr_noise=1e-9, start_error=0.0, rng=0)
    assert out["extra"].tolist() == list("abcd") and len(truth) == 3
    np.testing.assert_allclose(out[["x", "y"]].to_numpy()[[0, 2, 3]],
                               degrade([0, 30, 60], [0, 30, 60], [5, 5, 5], heading_bias=90.0,
                                       speed_scale=1.0, dr_noise=1e-9, start_error=0.0, rng=0),
                               atol=1e-6)
