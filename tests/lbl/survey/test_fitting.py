import json

import numpy as np
import pandas as pd
import pytest

import bayes_mpem as bm
from bayes_mpem.exceptions import SkippedBeaconWarning


@pytest.fixture(scope="module")
def sim():
    return bm.simulate_survey("abe58", rng=21)


def test_one_output_row_per_input_row(sim):
    res = bm.fit(sim.survey, rng=0)
    out = res.classified()
    assert len(out) == len(sim.survey)
    pd.testing.assert_frame_equal(out[sim.survey.table.columns], sim.survey.table)
    assert set(out["label"]) == {"dp", "mp", "ol", "no_reply"}
    nr = out["label"] == "no_reply"
    assert nr.sum() == sim.survey.no_reply.sum()
    assert out.loc[nr, ["p_dp", "p_mp", "p_ol"]].isna().all().all()
    assert (out.loc[nr, "reason"] == "empty range: the ping got no reply").all()
    probs = out.loc[~nr, ["p_dp", "p_mp", "p_ol"]].to_numpy()
    np.testing.assert_allclose(probs.sum(axis=1), 1.0)


def test_too_few_pings_warns_and_leaves_beacon_unfitted(sim):
    table = sim.survey.table
    keep = (table["beacon"] != "3") | (np.arange(len(table)) < 80)  # beacon 3: ~20 pings
    pings = table[keep].reset_index(drop=True)
    beacons = sim.survey.beacons.reset_index()
    with pytest.warns(SkippedBeaconWarning, match=r"beacon 3 has \d+ replies .*min_pings=30"):
        res = bm.fit(pings, beacons, rng=0)
    assert "3" not in res.results and "3" in res.skipped
    out = res.classified()
    assert len(out) == len(pings)
    b3 = (out["beacon"] == "3") & (out["label"] != "no_reply")
    assert (out.loc[b3, "label"] == "skipped").all()
    assert out.loc[b3, "reason"].str.contains("fewer than min_pings=30").all()
    assert res.summary()["skipped"]["3"].startswith("beacon 3 has")


def test_beacon_without_any_ping_is_skipped(sim):
    beacons = sim.survey.beacons.reset_index()
    beacons = pd.concat([beacons, pd.DataFrame([{"beacon": "9", "x": 0.0, "y": 0.0,
                                                 "depth": 2000.0}])], ignore_index=True)
    with pytest.warns(SkippedBeaconWarning, match="beacon 9 has 0 replies"):
        res = bm.fit(sim.survey.table, beacons, rng=0)
    assert res.skipped["9"]


def test_summary_contract(sim, tmp_path):
    res = bm.fit(sim.survey, rng=0)
    paths = res.write(tmp_path)
    summary = json.loads(paths["summary"].read_text())
    for bid in "1234":
        b = summary["beacons"][bid]
        for key in ("d0", "sigma_mp", "sigma_dp", "n", "iterations", "converged"):
            assert key in b
        assert set(b["weights"]) == {"dp", "mp", "ol"}
        assert b["n"] == sim.survey.for_beacon(bid).n
        assert b["plane_depth"] == pytest.approx(b["beacon_depth"] - b["d0"])
    assert summary["n_rows"] == len(sim.survey)
    out = pd.read_csv(paths["classified"], keep_default_na=False)
    assert len(out) == len(sim.survey)


def test_paper_method_through_fit(sim, tmp_path):
    with pytest.warns(bm.FitQualityWarning) as record:
        res = bm.fit(sim.survey, method="paper", sigma_dp=3.97, pol=0.1, alpha=0.5)
    assert any("beacon 1 (the paper's EM)" in str(w.message) for w in record)
    assert res.method == "paper"
    assert res.results["4"].settings["pol"] == 0.1
    assert abs(res.results["4"].d0 - 2472.0) < 5 and not res.results["4"].flags
    summary = json.loads(res.write(tmp_path)["summary"].read_text())
    assert summary["beacons"]["1"]["flags"] and summary["beacons"]["4"]["flags"] == []


def test_fit_from_files_equals_fit_from_frames(sim, tmp_path):
    paths = sim.write(tmp_path)
    a = bm.fit(paths["pings"], paths["beacons"], rng=0)
    b = bm.fit(pd.read_csv(paths["pings"]), pd.read_csv(paths["beacons"]), rng=0)
    for bid in "1234":
        assert a.results[bid].d0 == pytest.approx(b.results[bid].d0, abs=1e-9)


def test_bad_method(sim):
    with pytest.raises(ValueError, match="method: expected one of"):
        bm.fit(sim.survey, method="magic")


def test_table_like_table_ii(sim):
    res = bm.fit(sim.survey, rng=0)
    t = res.table()
    assert list(t["beacon"]) == ["1", "2", "3", "4"]
    np.testing.assert_allclose(t["d0_m"], t["beacon_depth_m"], atol=3.0)
    text = res.format_table()
    assert "d0 (m)" in text and "2392.0" in text


def test_one_survey_loop_skips_with_reason_and_warns_at_the_caller(sim):
    """over_beacons: too few replies first ("left unfitted"), then skip_on ("left unsampled")."""
    from bayes_mpem.exceptions import UnusableStartError
    from bayes_mpem.lbl.survey.survey import over_beacons

    def analyse(data):
        if data.beacon == "2":
            raise UnusableStartError("beacon 2: EM start outside the prior")
        return data.n

    with pytest.warns(SkippedBeaconWarning) as record:
        results, skipped = over_beacons(sim.survey, 30, analyse, skip_on=(UnusableStartError,))
    assert list(results) == ["1", "3", "4"] and list(skipped) == ["2"]
    assert skipped["2"] == "beacon 2: EM start outside the prior"
    assert str(record[0].message).endswith("; left unsampled")
    with pytest.raises(UnusableStartError):
        over_beacons(sim.survey, 30, analyse)
    with pytest.warns(SkippedBeaconWarning, match="left unfitted") as record:
        bm.fit(sim.survey, min_pings=10**6)
    assert {r.filename for r in record} == {__file__}  # points at the caller of fit


def test_results_write_the_same_bytes_through_the_one_writer(sim, tmp_path):
    import json as json_

    res = bm.fit(sim.survey, rng=0)
    paths = res.write(tmp_path)
    files = ["classified.csv", "history.json", "summary.json"]  # the completion marker's list
    assert paths["summary"].read_text() == json_.dumps({**res.summary(), "files": files},
                                                       indent=2) + "\n"
    assert paths["history"].read_text() == json_.dumps(res.history(), indent=None) + "\n"
    assert res.to_dict() == res.summary()
