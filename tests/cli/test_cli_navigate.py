import json
import shutil
import warnings

import pandas as pd
import pytest

from bayes_mpem.cli import main
from bayes_mpem.exceptions import NavigationWarning


@pytest.fixture(scope="module")
def dive_files(tmp_path_factory):
    out = tmp_path_factory.mktemp("dive")
    assert main(["simulate", "--preset", "abe58", "--seed", "2", "--n-cycles", "400",
                 "--navigation", "--heading-bias", "1.5", "--shadow-window", "1000:2000",
                 "--out", str(out)]) == 0
    return out


def test_simulate_navigation_writes_a_dive(dive_files):
    assert {p.name for p in dive_files.iterdir()} >= {"pings.csv", "beacons.csv", "truth.json",
                                                       "true_track.csv"}
    nav = json.loads((dive_files / "truth.json").read_text())["config"]["navigation"]
    assert nav["heading_bias_deg"] == 1.5 and nav["shadow_windows"] == [[1000.0, 2000.0]]


def test_navigate_command(dive_files, tmp_path, capsys):
    assert main(["navigate", str(dive_files / "pings.csv"), "--beacons",
                 str(dive_files / "beacons.csv"), "--out", str(tmp_path), "--figures"]) == 0
    out = capsys.readouterr().out
    assert "heading bias" in out and "converged" in out
    names = {p.name for p in tmp_path.iterdir()}
    assert names >= {"track.csv", "classified.csv", "summary.json", "timings.json",
                     "nav_track.png", "nav_ranges.png", "nav_correction.png"}
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert abs(summary["dead_reckoning"]["heading_bias_deg"]["estimate"] - 1.5) < 0.3
    assert len(pd.read_csv(tmp_path / "classified.csv")) == len(
        pd.read_csv(dive_files / "pings.csv"))


def test_navigate_multipath_as_outliers_and_a_baseline(dive_files, tmp_path):
    for extra in (["--multipath", "outlier"], ["--model", "gate"]):
        assert main(["navigate", str(dive_files / "pings.csv"), "--beacons",
                     str(dive_files / "beacons.csv"), "--out", str(tmp_path), *extra]) == 0
        summary = json.loads((tmp_path / "summary.json").read_text())
        assert summary["beacons"]["1"]["d0"] is None


def test_navigate_bad_input_exits_2_naming_the_line(dive_files, tmp_path, capsys):
    pings = pd.read_csv(dive_files / "pings.csv", dtype=str, keep_default_na=False)
    pings.loc[7, "x"] = "east"
    bad = tmp_path / "bad.csv"
    pings.to_csv(bad, index=False)
    code = main(["navigate", str(bad), "--beacons", str(dive_files / "beacons.csv"),
                 "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert code == 2 and "line 9" in err and "'x'" in err and "east" in err
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize(("args", "msg"), [
    (["--dr-noise", "0"], "argument --dr-noise: expected a positive number"),
    (["--dead-reckoning", "nope.csv"], "dead-reckoning file not found"),
])
def test_navigate_bad_options_exit_2(dive_files, tmp_path, capsys, args, msg):
    try:
        code = main(["navigate", str(dive_files / "pings.csv"), "--beacons",
                     str(dive_files / "beacons.csv"), "--out", str(tmp_path), *args])
    except SystemExit as exc:  # an option value the parser refuses
        code = exc.code
    assert code == 2 and msg in capsys.readouterr().err


@pytest.mark.parametrize(("args", "msg"), [
    (["--shadow-range", "500"], "--shadow-range: only with --navigation"),
    (["--navigation", "--effect", "range_bias=5"], "--effect does not apply"),
    (["--navigation", "--shadow-window", "10-20"], "expected T0:T1"),
])
def test_simulate_refuses_mixed_options(tmp_path, capsys, args, msg):
    assert main(["simulate", "--out", str(tmp_path), *args]) == 2
    assert msg in capsys.readouterr().err


def test_plot_draws_a_navigate_folder_and_refuses_unknown_ones(dive_files, tmp_path, capsys):
    nav = tmp_path / "nav"
    assert main(["navigate", str(dive_files / "pings.csv"), "--beacons",
                 str(dive_files / "beacons.csv"), "--out", str(nav), "--path", "triangle"]) == 0
    assert main(["plot", str(nav), "--out", str(tmp_path / "figs")]) == 0
    assert sorted(p.name for p in (tmp_path / "figs").iterdir()) == [
        "nav_correction.png", "nav_ranges.png", "nav_track.png", "summary.json"]
    capsys.readouterr()
    other = tmp_path / "other"
    other.mkdir()
    (other / "summary.json").write_text('{"written_by": "someone else"}')
    answers = tmp_path / "answers.jsonl"
    answers.write_text('{"line": 1, "label": "dp"}\n')
    empty = tmp_path / "empty"
    empty.mkdir()
    for folder, msg in ((other, "of no known kind"), (answers, "'bayes-mpem stream' writes JSON"),
                        (tmp_path / "figs", "holds no result"),
                        (empty, "summary.json: not found")):
        assert main(["plot", str(folder), "--out", str(tmp_path / "none")]) == 2
        err = capsys.readouterr().err
        assert "error:" in err and msg in err and "navigate" in err and "Traceback" not in err
    assert main(["plot", str(answers)]) == 2  # RESULT_DIR is also where the figures go
    assert "RESULT_DIR" in capsys.readouterr().err
    for name, damage, msg in (
            ("gone", lambda d: (d / "track.csv").unlink(), "track.csv, missing"),
            ("text", lambda d: (d / "track.csv").write_text(
                (d / "track.csv").read_text().replace("\n", "\nabc", 1)),
             "track.csv line 2, column 'time': expected a finite number, got 'abc"),
            ("nan", _first_time_nan,  # blamed the pings ("200 distinct ping times, but ...")
             "track.csv line 2, column 'time': expected a finite number, got 'nan")):
        bad = shutil.copytree(nav, tmp_path / name)
        damage(bad)
        assert main(["plot", str(bad), "--out", str(tmp_path / f"{name}_figs")]) == 2
        err = capsys.readouterr().err
        assert msg in err and "Traceback" not in err
        assert not (tmp_path / f"{name}_figs").exists()


@pytest.fixture(scope="module")
def ship_files(tmp_path_factory):
    from bayes_mpem.lbl.navigate.simulate import simulate_ship

    out = tmp_path_factory.mktemp("ship")
    simulate_ship(rng=3, n_cycles=400).write(out)
    return out


@pytest.mark.parametrize("extra", [[], ["--sigma-dp", "0.2"]])
def test_navigate_staggered_single_range_schedule(ship_files, tmp_path, capsys, extra):
    """One reply per epoch, beacons in turn, a ship at 8 m: no internal error, the scale and
    every quality flag of summary.json printed."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NavigationWarning)
        assert main(["navigate", str(ship_files / "pings.csv"), "--beacons",
                     str(ship_files / "beacons.csv"), "--out", str(tmp_path), *extra]) == 0
    out = capsys.readouterr().out
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert "sigma_DP" in out and "quality flags" in out
    for b in summary["beacons"].values():
        for flag in b["flags"] + [b.get("reason") or ""]:
            assert flag in out
    assert summary["information"] in out
    assert 0.15 < summary["sigma_dp"]["estimate"] < 0.25


def test_navigate_convergence_advice_names_its_options(ship_files, tmp_path, capsys):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NavigationWarning)
        assert main(["navigate", str(ship_files / "pings.csv"), "--beacons",
                     str(ship_files / "beacons.csv"), "--out", str(tmp_path), "--max-iter", "2",
                     "--tol", "1e-6"]) == 0
    cap = capsys.readouterr()
    assert "ConvergenceWarning" in cap.err and "(--max-iter)" in cap.err and "(--tol)" in cap.err
    assert "did NOT converge: raise --max-iter or loosen --tol" in cap.out


def _first_time_nan(folder):
    lines = (folder / "track.csv").read_text().split("\n")
    lines[1] = "nan," + lines[1].split(",", 1)[1]
    (folder / "track.csv").write_text("\n".join(lines))
