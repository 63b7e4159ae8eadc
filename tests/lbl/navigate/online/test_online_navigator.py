"""The online navigator: exact restarts, what each kind of line does, and recovery."""

import json
import math
import warnings

import numpy as np
import pandas as pd
import pytest

from bayes_mpem.exceptions import InputError
from bayes_mpem.io.lines import Ping
from bayes_mpem.lbl.navigate import navigate, simulate_dive
from bayes_mpem.lbl.navigate.online import Navigator

COLS = ["time", "beacon", "range", "x", "y", "depth"]


@pytest.fixture(scope="module")
def dive():
    return simulate_dive("abe58", rng=5, n_cycles=160)


def _beacons(sim):
    return sim.survey.beacons.reset_index()


def test_restart_continues_exactly(dive, tmp_path):
    table = dive.survey.table
    whole = Navigator(_beacons(dive), warmup=120, rng=7).run(table)
    parts, nav = [], Navigator(_beacons(dive), warmup=120, rng=7)
    for a, b in ((0, 50), (50, 121), (121, 400), (400, len(table))):  # in and after the warm-up
        parts.append(nav.run(table.iloc[a:b]))
        nav.save(tmp_path / "state.json")
        nav = Navigator.load(tmp_path / "state.json")
    pd.testing.assert_frame_equal(pd.concat(parts, ignore_index=True), whole)
    assert set(whole["phase"]) == {"warmup", "online"}


def test_lines_without_range_advance_the_filter(dive):
    nav = Navigator(_beacons(dive), warmup=120, rng=0)
    out = nav.run(dive.survey.table.iloc[:300])
    last = dive.survey.table.iloc[299]
    f = nav.filter
    before = (f.x, f.y, f.p[0])
    t = float(last["time"]) + 100.0
    r = nav.update(Ping(t, None, None, float(last["x"]) + 10.0, float(last["y"]), None))
    assert r.label is None and r.reason.startswith("dead-reckoning")
    # moved by the corrected dead-reckoned step; the random walk's variance added
    step = 10.0 * nav.filter.scale * math.cos(nav.filter.beta)
    assert r.x - before[0] == pytest.approx(step, rel=1e-9)
    assert r.sd_x ** 2 > before[2] + 0.9 * 0.01 * 100.0
    r = nav.update(Ping(t + 5.0, "1", None, float(last["x"]) + 10.0, float(last["y"]), 2400.0))
    assert r.label == "no_reply" and r.p_dp is None and r.sd_x > 0
    assert out["label"].notna().all()


def test_bad_lines_leave_the_state_alone(dive):
    nav = Navigator(_beacons(dive), warmup=120, rng=0)
    nav.run(dive.survey.table.iloc[:200])
    before = json.dumps(nav.to_dict())
    t = float(dive.survey.table["time"].iloc[199])
    with pytest.raises(InputError, match="time order"):
        nav.update(Ping(t - 1.0, "1", 1000.0, 0.0, 0.0, 2400.0))
    with pytest.raises(InputError, match="not in the beacons table"):
        nav.update({"time": t, "beacon": "99", "range": 1000.0, "x": 0, "y": 0, "depth": 1})
    with pytest.raises(InputError, match="column 'range'"):
        nav.update({"time": t, "beacon": "1", "range": -5, "x": 0, "y": 0, "depth": 1})
    assert json.dumps(nav.to_dict()) == before
    with pytest.raises(InputError, match="navigator state"):
        Navigator.from_dict({"format": "something else"})


def test_memory_is_bounded(dive):
    nav = Navigator(_beacons(dive), warmup=120, rng=0)
    table = dive.survey.table
    nav.run(table.iloc[:200])
    size = len(json.dumps(nav.to_dict()))
    nav.run(table.iloc[200:])
    assert abs(len(json.dumps(nav.to_dict())) - size) < 200  # digits, not history


def test_a_beacon_first_heard_online_starts_from_the_prior(dive):
    table = dive.survey.table
    late = (table["beacon"] == "4") & (table["time"] < 1200)
    nav = Navigator(_beacons(dive), warmup=120, rng=0)
    out = nav.run(table[~late])
    m = nav.reflectors()["4"]
    assert m["n"] > 20 and abs(m["d0"] - 2472.0) < 10.0  # learned from the sea surface prior
    assert (out["phase"] == "online").sum() > 300


def _moment_of(table, n):
    """Row count when every beacon has ``n`` replies (whole epochs)."""
    reply = table["range"].notna()
    counts = reply.groupby(table["beacon"]).cumsum()
    done = counts.groupby(table["beacon"]).transform(lambda c: c >= n)
    first = max(int(np.flatnonzero((table["beacon"] == b).to_numpy() & done.to_numpy())[0])
                for b in table["beacon"].unique())
    t = table["time"].iloc[first]
    return int(np.searchsorted(table["time"].to_numpy(), t, side="right"))


@pytest.mark.slow
@pytest.mark.parametrize(("preset", "seed"), [("abe58", 1), ("random", 2)])
def test_online_matches_batch(preset, seed):
    """Small version of benchmarks/stream_accuracy.py (the issue's acceptance)."""
    sim = simulate_dive(preset, rng=seed)
    table = sim.survey.table
    cut = _moment_of(table, 500)
    nav = Navigator(_beacons(sim), rng=0)
    head = nav.run(table.iloc[:cut])
    online_d0 = {b: v["d0"] for b, v in nav.reflectors().items()}
    out = pd.concat([head, nav.run(table.iloc[cut:])], ignore_index=True)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        prefix = navigate(table.iloc[:cut], _beacons(sim), rng=0)
        whole = navigate(sim.survey, rng=0)
    for j, b in enumerate(prefix.dive.beacon_ids):
        assert abs(online_d0[b] - prefix.state.d0[j]) < 3.0, b
    after = (out["phase"] == "online").to_numpy() & table["range"].notna().to_numpy()
    batch_labels = whole.classified()["label"].to_numpy()
    assert np.mean(out["label"].to_numpy()[after] == batch_labels[after]) >= 0.98
    last = np.r_[out["time"].to_numpy()[1:] != out["time"].to_numpy()[:-1], True]
    sel = last & (out["phase"] == "online").to_numpy()
    truth = sim.true_track.set_index("time").loc[out["time"][sel], ["x", "y"]].to_numpy()
    k = np.searchsorted(whole.dive.times, out["time"][sel])
    rmse_online = np.sqrt(np.mean(np.sum((out.loc[sel, ["x", "y"]].to_numpy() - truth) ** 2, 1)))
    rmse_batch = np.sqrt(np.mean(np.sum((whole.track[k] - truth) ** 2, 1)))
    assert rmse_online < 1.5 * rmse_batch


@pytest.mark.parametrize("seed", [0, 1])
def test_staggered_ship_online_scale_does_not_collapse(seed):
    """One range per epoch (issue 25): the online sigma_DP stays at the truth (0.2 m).

    Before the warm-up handed the filter the batch's expected squares (the track's
    uncertainty included), the plain squares restarted it at about 0.14 m.
    """
    from bayes_mpem.lbl.navigate.simulate import simulate_ship

    sim = simulate_ship(rng=seed, n_cycles=500)
    nav = Navigator(_beacons(sim), rng=0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out = nav.run(sim.survey.table)
    assert (out["phase"] == "online").sum() > 250
    assert 0.17 <= nav.dp.sigma <= 0.23
