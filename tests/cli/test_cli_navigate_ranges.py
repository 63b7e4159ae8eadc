"""``bayes-mpem navigate`` on two-way travel times through a sound-speed profile."""

import json

import numpy as np
import pandas as pd
import pytest

from bayes_mpem.acoustics.profile import SoundSpeedProfile
from bayes_mpem.acoustics.turning import direct_times
from bayes_mpem.cli import main
from bayes_mpem.lbl.navigate.simulate import simulate_ship

TAT = 0.013


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """A ship dive as two-way travel times through a profile (beacon depths in the profile's
    frame shifted by 20 m: the tables' depths are 20 m below the profile's)."""
    out = tmp_path_factory.mktemp("times")
    prof = SoundSpeedProfile([0.0, 60.0, 900.0, 3000.0], [1538.0, 1541.0, 1488.0, 1510.0])
    sim = simulate_ship(rng=3, n_cycles=240, outlier_weight=0.0)
    p = sim.survey.table.copy()
    truth = sim.true_track.set_index("time").loc[p["time"], ["x", "y"]].to_numpy()
    xyz = sim.survey.beacons.loc[p["beacon"], ["x", "y", "depth"]].to_numpy()
    h = np.hypot(*(truth - xyz[:, :2]).T)
    t = direct_times(prof, p["depth"].to_numpy() - 1.5, xyz[:, 2], h).time  # transducer 1.5 m up
    p["range"] = 2 * t + TAT
    p["depth"] += 20.0
    p.drop(columns="true_class").to_csv(out / "pings.csv", index=False)
    b = sim.survey.beacons.reset_index()
    b["depth"] += 20.0
    b.to_csv(out / "beacons.csv", index=False)
    pd.DataFrame({"depth": prof.depths, "speed": prof.speeds}).to_csv(out / "ssp.csv",
                                                                         index=False)
    return out, sim.true_track[["x", "y"]].to_numpy()


def _run(files, out, *extra):
    """Exit status of the command (an option argparse refuses exits with 2)."""
    d = files[0]
    try:
        return _main(d, out, extra)
    except SystemExit as stop:
        return stop.code


def _main(d, out, extra):
    return main(["navigate", str(d / "pings.csv"), "--beacons", str(d / "beacons.csv"),
                 "--out", str(out), "--travel-time", "--ranges", "two-way", *extra])


def test_two_way_times_through_the_profile(files, tmp_path, capsys):
    assert _run(files, tmp_path, "--ssp", str(files[0] / "ssp.csv"), "--turnaround", str(TAT),
                "--surface-depth", "20", "--transducer-offset", "-1.5", "--sigma-dp",
                "0.05") == 0
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["options"]["range_model"] == {
        "travel_times": "two-way", "profile": str(files[0] / "ssp.csv"), "turnaround": TAT,
        "transducer_offset": -1.5, "surface_depth": 20.0}
    track = pd.read_csv(tmp_path / "track.csv")[["x", "y"]].to_numpy()
    assert np.sqrt(np.mean(np.sum((track - files[1]) ** 2, axis=1))) < 1.0
    classified = pd.read_csv(tmp_path / "classified.csv")
    assert {"range_input", "depth_input", "ray_traced"} <= set(classified.columns)
    assert "model check" not in capsys.readouterr().out  # exact times: nothing left over


def test_a_transducer_above_the_profiles_sea_surface_is_refused(files, tmp_path, capsys):
    # the transducer at 26.5 m in the tables' frame, the profile's surface put at 40 m
    assert _run(files, tmp_path, "--ssp", str(files[0] / "ssp.csv"), "--surface-depth",
                "40") == 2
    err = capsys.readouterr().err
    assert "pings.csv line 2, column 'depth'" in err and "--surface-depth" in err


@pytest.mark.parametrize("extra, message", [
    (["--sound-speed", "1500", "--ssp", "SSP"], "give --sound-speed or --ssp, not both"),
    (["--ssp", "SSP", "--turnaround", "20"], "--turnaround"),
    (["--ssp", "SSP", "--transducer-offset", "500"], "--transducer-offset"),
    (["--ssp", "missing.csv"], "missing.csv"),
])
def test_bad_options_exit_2_naming_them(files, tmp_path, capsys, extra, message):
    extra = [str(files[0] / "ssp.csv") if e == "SSP" else e for e in extra]
    assert _run(files, tmp_path, *extra) == 2
    assert message in capsys.readouterr().err


def test_surface_depth_without_travel_times_is_refused(files, tmp_path, capsys):
    d = files[0]
    assert main(["navigate", str(d / "pings.csv"), "--beacons", str(d / "beacons.csv"),
                 "--out", str(tmp_path), "--surface-depth", "3"]) == 2
    assert "applies to travel times only" in capsys.readouterr().err
