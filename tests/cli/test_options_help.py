"""The command line helps: a mistyped option, numeric options checked with their names."""

import pandas as pd
import pytest

from bayes_mpem.cli import main
from bayes_mpem.exceptions import InputError
from bayes_mpem.io.dead_reckoning import read_dead_reckoning


@pytest.mark.parametrize(("argv", "usage", "hint"), [
    (["fit", "p.csv", "--beacons", "b.csv", "--out", "o", "--sigmadp", "4"],
     "usage: bayes-mpem fit", "did you mean --sigma-dp"),
    (["batch", "m.csv", "--out", "o", "--wokers", "2"], "usage: bayes-mpem batch",
     "did you mean --workers"),
    (["stream", "--beacons", "b.csv", "--max_gap", "5"], "usage: bayes-mpem stream",
     "did you mean --max-gap"),
    (["fit", "p.csv", "--beacons", "b.csv", "--out", "o", "--zzzzzz"], "usage: bayes-mpem fit",
     "see 'bayes-mpem fit --help'"),
])
def test_a_mistyped_option_gets_the_subcommand_usage_and_a_suggestion(argv, usage, hint,
                                                                       capsys):
    with pytest.raises(SystemExit) as stop:
        main(argv)
    err = capsys.readouterr().err
    assert stop.value.code == 2 and usage in err and hint in err


@pytest.mark.parametrize("command", [["navigate", "p.csv", "--beacons", "b.csv", "--out", "o"],
                                     ["stream", "--beacons", "b.csv"]])
@pytest.mark.parametrize("value", ["1e300", "1e-8", "1e-300", "1e10", "nan", "-1", "x"])
def test_dr_noise_is_refused_by_the_parser_naming_it(command, value, capsys):
    with pytest.raises(SystemExit) as stop:
        main([*command, "--dr-noise", value])
    err = capsys.readouterr().err
    assert stop.value.code == 2
    assert "argument --dr-noise: expected a positive number in [0.0001, 100]" in err


@pytest.mark.parametrize("value", ["1e300", "-1", "inf"])
def test_simulated_dr_noise_is_checked(value, capsys):
    with pytest.raises(SystemExit):
        main(["simulate", "--navigation", "--dr-noise", value, "--out", "o"])
    assert "argument --dr-noise" in capsys.readouterr().err


def test_dead_reckoning_time_errors_show_plain_numbers():
    with pytest.raises(InputError) as err:
        read_dead_reckoning(pd.DataFrame({"time": [0.0, 132.0, 132.0], "x": [0, 1, 2],
                                          "y": [0, 0, 0]}))
    assert "np.float64" not in str(err.value) and "132 s" in str(err.value)


@pytest.mark.parametrize(("option", "value"), [
    ("--start-sd", "1e300"), ("--start-sd", "1e-300"), ("--scale-sd", "1e300"),
    ("--scale-sd", "1e-300"), ("--sigma-dp", "1e300"), ("--heading-sd", "1e300")])
def test_navigate_priors_are_bounded_by_the_parser(option, value, capsys):
    with pytest.raises(SystemExit):
        main(["navigate", "p.csv", "--beacons", "b.csv", "--out", "o", option, value])
    assert f"argument {option}: expected a positive number in" in capsys.readouterr().err


@pytest.mark.parametrize(("option", "value"), [("--max-gap", "1e-300"), ("--max-gap", "0.5"),
                                               ("--sigma-dp", "1e300"), ("--max-gap", "nan")])
def test_stream_numbers_are_bounded_by_the_parser(option, value, capsys):
    with pytest.raises(SystemExit):
        main(["stream", "--beacons", "b.csv", option, value])
    assert f"argument {option}: expected a positive number in" in capsys.readouterr().err
