import json
import os
import subprocess
import sys

import pandas as pd
import pytest

import bayes_mpem as bm
from bayes_mpem.cli import main


@pytest.fixture(scope="module")
def survey_files(tmp_path_factory):
    out = tmp_path_factory.mktemp("survey")
    assert main(["simulate", "--preset", "abe58", "--seed", "3", "--out", str(out)]) == 0
    return out


def test_simulate_writes_files(survey_files):
    truth = json.loads((survey_files / "truth.json").read_text())
    assert set(truth["beacons"]) == {"1", "2", "3", "4"}
    assert (survey_files / "pings.csv").exists() and (survey_files / "beacons.csv").exists()


@pytest.mark.parametrize("method", ["mixture", "paper"])
def test_fit_command(survey_files, tmp_path, method, capsys):
    args = ["fit", str(survey_files / "pings.csv"), "--beacons",
            str(survey_files / "beacons.csv"), "--out", str(tmp_path), "--method", method,
            "--sigma-dp", "3.97", "--path", "triangle"]
    args += ["--pol", "0.1", "--alpha", "0.5"] if method == "paper" else ["--weights", "learned"]
    assert main(args) == 0
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["method"] == method
    assert abs(summary["beacons"]["4"]["d0"] - 2472.0) < 5
    assert summary["beacons"]["4"]["sigma_dp"] == 3.97
    out = pd.read_csv(tmp_path / "classified.csv")
    assert len(out) == len(pd.read_csv(survey_files / "pings.csv"))
    assert "d0 (m)" in capsys.readouterr().out


def test_fit_command_with_figures(survey_files, tmp_path):
    from bayes_mpem.plots.style import PALETTES, class_color

    assert main(["fit", str(survey_files / "pings.csv"), "--beacons",
                 str(survey_files / "beacons.csv"), "--out", str(tmp_path), "--figures",
                 "--palette", "paper"]) == 0
    assert (tmp_path / "fig13_classification.png").stat().st_size > 10_000
    assert class_color("ol") == PALETTES["okabe-ito"]["ol"]  # the command restored it


def test_fit_command_bad_input_exits_2_with_message(survey_files, tmp_path, capsys):
    pings = pd.read_csv(survey_files / "pings.csv", dtype=str, keep_default_na=False)
    pings.loc[4, "range"] = "-3.2"
    bad = tmp_path / "bad.csv"
    pings.to_csv(bad, index=False)
    code = main(["fit", str(bad), "--beacons", str(survey_files / "beacons.csv"),
                 "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert code == 2
    assert "bad.csv" in err and "line 6" in err and "'range'" in err and "-3.2" in err
    assert not (tmp_path / "o" / "summary.json").exists()


def test_fit_command_missing_file(tmp_path, capsys):
    code = main(["fit", str(tmp_path / "nope.csv"), "--beacons", str(tmp_path / "b.csv"),
                 "--out", str(tmp_path)])
    assert code == 2
    assert "nope.csv" in capsys.readouterr().err


def test_demo_without_bayes(tmp_path, capsys):
    assert main(["demo", "--out", str(tmp_path), "--no-bayes"]) == 0
    text = capsys.readouterr().out
    assert "d0 (m)" in text and "The paper's EM" in text
    for name in ("summary.json", "classified.csv", "history.json", "summary.md",
                 "survey/pings.csv", "survey/truth.json", "paper/summary.json",
                 "fig01_ranges.png", "fig05_track.png", "fig07_first_iteration_4.png",
                 "fig08_colormap.png", "fig09_last_iteration_4.png",
                 "fig10_11_convergence_4.png", "fig12_pol_sensitivity_4.png",
                 "fig13_classification.png", "table2.png", "paper/fig13_classification.png"):
        assert (tmp_path / name).exists(), name
    summary = json.loads((tmp_path / "summary.json").read_text())
    truth = json.loads((tmp_path / "survey" / "truth.json").read_text())["beacons"]
    for bid, b in summary["beacons"].items():
        assert abs(b["d0"] - truth[bid]["d0"]) < 3
    md = (tmp_path / "summary.md").read_text()
    assert "Table II" in md and "(fig13_classification.png)" in md


@pytest.mark.slow
def test_demo_full(tmp_path, capsys):
    """The README's main job, end to end, including the Bayesian part."""
    assert main(["demo", "--out", str(tmp_path)]) == 0
    text = capsys.readouterr().out
    assert "min ESS" in text and "verdict" in text
    for name in ("bayes/posterior_4.nc", "bayes/intervals.png", "bayes/trace_4.png",
                 "compare/compare.json", "compare/compare.png"):
        assert (tmp_path / name).exists(), name


def test_version(capsys):
    with pytest.raises(SystemExit):
        main(["--version"])
    assert bm.__version__ in capsys.readouterr().out


@pytest.mark.parametrize(("extra", "msg"), [
    (["--pol", "0.2"], "--pol and --alpha apply to --method paper only"),
    (["--method", "paper", "--weights", "equal"], "--weights applies to --method mixture"),
])
def test_fit_refuses_options_of_the_other_method(survey_files, tmp_path, capsys, extra, msg):
    code = main(["fit", str(survey_files / "pings.csv"), "--beacons",
                 str(survey_files / "beacons.csv"), "--out", str(tmp_path), *extra])
    assert code == 2 and msg in capsys.readouterr().err


def test_fit_bad_pol_is_refused_even_for_the_mixture(survey_files):
    with pytest.raises(ValueError, match="pol: expected a number in"):
        bm.fit(survey_files / "pings.csv", survey_files / "beacons.csv", pol=2.0)


def test_plot_with_nothing_fitted(survey_files, tmp_path, capsys):
    with pytest.warns(bm.SkippedBeaconWarning):
        res = bm.fit(survey_files / "pings.csv", survey_files / "beacons.csv", min_pings=10**6)
    res.write(tmp_path)
    assert main(["plot", str(tmp_path)]) == 2
    assert "nothing to draw" in capsys.readouterr().err


@pytest.mark.parametrize("given", [None, "module://my_backend"])
def test_the_command_line_draws_on_agg_and_gives_the_backend_back(tmp_path, given):
    """Figures are written with Agg; the caller's MPLBACKEND (or its absence) comes back.

    In a fresh interpreter: matplotlib is not imported until a command draws.
    """
    (tmp_path / "none.csv").write_text("")  # the input files are checked before the command
    code = (
        "import os, sys\n"
        "import bayes_mpem.cli.survey_in as m\n"
        "from bayes_mpem.cli import main\n"
        "seen = []\n"
        "m.cmd_locate = lambda args: seen.append(os.environ.get('MPLBACKEND')) or 0\n"
        f"assert main(['locate', {str(tmp_path / 'none.csv')!r}, '--out', "
        f"{str(tmp_path / 'o')!r}]) == 0\n"
        "assert 'matplotlib' not in sys.modules and seen == ['Agg'], (seen, sys.modules.keys())\n"
        "print(os.environ.get('MPLBACKEND'))\n")
    env = {k: v for k, v in os.environ.items() if k != "MPLBACKEND"}
    if given is not None:
        env["MPLBACKEND"] = given
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                         check=False)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == str(given)
