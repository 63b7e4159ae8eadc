"""Nothing lost, nothing silently wrong (issue 15), at the command line.

Every option is checked before any work and named; ``--out`` is checked first; a run is
written all or nothing; degenerate fits are named; the same seed gives the same bytes.
Each test guards a class of problem the issue lists (on f31dfee each failed).
"""

from __future__ import annotations

import argparse
import json
import math
import re

import numpy as np
import pandas as pd
import pytest

import bayes_mpem as bm
from bayes_mpem.cli import main
from bayes_mpem.io.formats import sample_file

SIO = sample_file("obsrange/SIO_CC03.txt")


@pytest.fixture(scope="module")
def small(tmp_path_factory):
    out = tmp_path_factory.mktemp("small")
    assert main(["simulate", "--preset", "abe58", "--seed", "5", "--n-cycles", "60",
                 "--out", str(out)]) == 0
    return out


def _fit(small, out, *extra):
    return main(["fit", str(small / "pings.csv"), "--beacons", str(small / "beacons.csv"),
                 "--out", str(out), *extra])


@pytest.mark.parametrize(("argv", "option"), [
    (["locate", str(SIO), "--format", "obsrange", "--ci", "1.5"], "--ci"),
    (["locate", str(SIO), "--format", "obsrange", "--ci", "1"], "--ci"),
    (["locate", str(SIO), "--format", "obsrange", "--tat", "nan"], "--tat"),
    (["diagnose", "P", "--beacons", "B", "--min-gain", "nan"], "--min-gain"),
    (["fit", "P", "--beacons", "B", "--seed", "-1"], "--seed"),
    (["fit", "P", "--beacons", "B", "--min-pings", "2"], "--min-pings"),
    (["fit", "P", "--beacons", "B", "--sigma-dp", "inf"], "--sigma-dp"),
    (["sample", "P", "--beacons", "B", "--ci", "nan"], "--ci"),
    (["sample", "P", "--beacons", "B", "--ci", "0.01"], "--ci"),  # zero-width intervals
    (["sample", "P", "--beacons", "B", "--concentration", "0"], "--concentration"),
])
def test_every_option_is_checked_before_any_work_and_named(small, tmp_path, capsys, argv,
                                                           option):
    """--ci 1.5 wrote NaN intervals; --min-gain nan was accepted; --seed -1 was not named."""
    argv = [str(small / "pings.csv") if a == "P" else str(small / "beacons.csv") if a == "B"
            else a for a in argv]
    with pytest.raises(SystemExit) as exc:  # the parser refuses it, status 2
        main([*argv, "--out", str(tmp_path / "o")])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert f"argument {option}:" in err and not (tmp_path / "o").exists()


def test_min_pings_is_refused_before_the_other_beacons_are_fitted(small, tmp_path, monkeypatch,
                                                                  capsys):
    pings = pd.read_csv(small / "pings.csv")
    few = pings[(pings.beacon != 4) | (pings.index < 40)]
    few.to_csv(tmp_path / "p.csv", index=False)
    with pytest.raises(ValueError, match="min_pings: expected an integer >= 3"):
        bm.sample(tmp_path / "p.csv", small / "beacons.csv", min_pings=2)


def test_output_problems_are_found_before_the_work(small, tmp_path, monkeypatch, capsys):
    """An --out that is a file, under a file or unwritable raised after all the work."""
    def no_work(*args, **kwargs):
        raise AssertionError("the work started")
    monkeypatch.setattr("bayes_mpem.lbl.survey.sampling.sample", no_work)
    f = tmp_path / "file"
    f.write_text("x")
    for out, words in ((f, "is a file"), (f / "sub", "lies under the file"),
                       ("/sys/bayes_mpem_out", "cannot be written")):
        assert main(["sample", str(small / "pings.csv"), "--beacons",
                     str(small / "beacons.csv"), "--out", str(out)]) == 2
        assert f"--out {str(out)!r}: {words}" in capsys.readouterr().err


def test_a_folder_given_for_a_file_is_an_error_not_a_traceback(small, tmp_path, capsys):
    assert main(["fit", str(tmp_path), "--beacons", str(small / "beacons.csv"),
                 "--out", str(tmp_path / "o")]) == 2
    assert "is a folder; expected a file" in capsys.readouterr().err
    assert main(["locate", str(tmp_path), "--format", "obsrange", "--out",
                 str(tmp_path / "o")]) == 2
    assert "is a folder; expected a file" in capsys.readouterr().err


def test_intervals_from_draws_need_a_probability_of_a_half_or_more(small):
    """A 1 % highest-density interval of 3,008 draws had zero width, half an sd from the
    mean, on a draw the independence sampler repeated; 0.01 % was the smallest draw."""
    from bayes_mpem.lbl.bayes.posterior import check_sample_options
    from bayes_mpem.survey_in.posterior import check_location_options

    for check in (check_sample_options, check_location_options):
        with pytest.raises(ValueError, match=r"ci: expected a probability in \[0.5, 1\) for "
                                             r"intervals from draws, got 0.01"):
            check(ci=0.01)
        check(ci=0.5)


def test_a_log_without_drop_point_depth_is_located(tmp_path, capsys):
    """scipy's 'Residuals are not finite in the initial point' reached the user."""
    p = tmp_path / "s.txt"
    p.write_text("\n".join(ln for ln in SIO.read_text().splitlines() if "Depth" not in ln))
    assert main(["locate", str(p), "--format", "obsrange", "--out", str(tmp_path / "o")]) == 0
    depth = json.loads((tmp_path / "o" / "summary.json").read_text())["transponders"]["CC03"]
    assert abs(depth["depth"]["mean"] - 4739.1) < 1.0


def test_plot_refuses_a_damaged_folder_before_drawing(small, tmp_path, capsys):
    """A truncated summary.json said 'Expecting value: line 80 column 15' without the file;
    a truncated classified.csv gave four figures, then a traceback."""
    assert _fit(small, tmp_path / "fit") == 0
    c = tmp_path / "fit" / "classified.csv"
    c.write_bytes(c.read_bytes()[: len(c.read_bytes()) // 2])
    assert main(["plot", str(tmp_path / "fit"), "--out", str(tmp_path / "figs")]) == 2
    assert "classified.csv" in capsys.readouterr().err and not (tmp_path / "figs").exists()
    s = tmp_path / "fit" / "summary.json"
    s.write_text(s.read_text()[:200])
    assert main(["plot", str(tmp_path / "fit")]) == 2
    assert f"{s}: not valid JSON" in capsys.readouterr().err


@pytest.mark.parametrize(("edit", "said"), [
    (lambda s: s["beacons"][next(iter(s["beacons"]))].update(sigma_mp=None),
     r"summary.json: beacons\.\w+\.sigma_mp: expected a finite number, got null"),
    (lambda s: s["beacons"][next(iter(s["beacons"]))].update(d0="abc"),
     r"summary.json: beacons\.\w+\.d0: expected a finite number, got \"abc\""),
    (lambda s: s.update(beacons=list(s["beacons"])),
     r"summary.json: the output files do not fit together \(AttributeError"),
    (lambda s: s.update(beacons_table=list(s["beacons_table"])),
     r"summary.json: beacons_table: expected an object of beacons"),
    (lambda s: s["beacons_table"].pop(next(iter(s["beacons_table"]))),
     r"classified.csv and .*summary.json's beacons_table do not fit together .*classified.csv "
     r"line \d+, column 'beacon': beacon '\w+' is not in beacons_table"),
    (lambda s: s.update(files="classified.csv"),
     r"summary.json: files: expected a list of file names, got 'classified.csv'"),
])
def test_plot_names_the_key_of_a_hand_edited_summary(small, tmp_path, capsys, edit, said):
    """A null (strict JSON's non-finite) or a list where an object was: an internal error;
    a beacon taken out of beacons_table blamed a 'pings DataFrame' row; a string for files
    listed its letters as missing files."""
    assert _fit(small, tmp_path / "fit") == 0
    path = tmp_path / "fit" / "summary.json"
    doc = json.loads(path.read_text())
    edit(doc)
    path.write_text(json.dumps(doc))
    capsys.readouterr()
    assert main(["plot", str(tmp_path / "fit"), "--out", str(tmp_path / "figs")]) == 2
    err = capsys.readouterr().err
    assert re.search(said, err, re.S), err
    assert "internal error" not in err and "DataFrame" not in err


def test_a_failing_figure_leaves_no_complete_looking_diagnosis(small, tmp_path, monkeypatch,
                                                               capsys):
    """diagnose wrote diagnosis.json, then failed drawing a figure."""
    import bayes_mpem.plots.diagnose as figs

    def broken(*args, **kwargs):
        raise RuntimeError("no ink")
    monkeypatch.setattr(figs, "plot_candidates", broken)
    out = tmp_path / "d"
    assert main(["diagnose", str(small / "pings.csv"), "--beacons", str(small / "beacons.csv"),
                 "--out", str(out), "--effects", "range_bias", "--folds", "2",
                 "--no-progress"]) == 1
    assert "internal error: RuntimeError: no ink" in capsys.readouterr().err
    assert not out.exists() or not any(p.suffix in (".json", ".png") for p in out.iterdir())


def test_degenerate_fits_are_named_with_their_rows(small, monkeypatch):
    """A non-finite fit was written as 'dp' with probabilities (0, 0, 0) and NaN sigmas."""
    import dataclasses

    import bayes_mpem.lbl.survey.fitting as fitting

    real = fitting.choose_path

    def nan_for_4(data, *args, **kwargs):
        choice = real(data, *args, **kwargs)
        if data.beacon == "4":
            bad = dataclasses.replace(choice.fit, sigma_mp=math.nan)
            choice = dataclasses.replace(choice, fits={**choice.fits, choice.path: bad})
        return choice
    monkeypatch.setattr(fitting, "choose_path", nan_for_4)
    survey = bm.load_survey(small / "pings.csv", small / "beacons.csv")
    with pytest.warns(bm.SkippedBeaconWarning, match="beacon 4: the fit failed: sigma_mp"):
        res = fitting.fit(survey, rng=0)
    cls = res.classified()
    assert len(cls) == len(survey) and "4" not in res.results
    mine = cls[survey.beacon == "4"]
    assert set(mine["label"]) <= {"failed", "no_reply"}
    assert mine.loc[mine.label == "failed", "reason"].str.contains("not finite").all()


def test_same_seed_same_bytes_and_timings_apart(small, tmp_path):
    """summary.json is byte-identical for the same seed; wall-clock times go to timings.json."""
    runs = []
    for k in range(2):
        out = tmp_path / f"s{k}"
        assert main(["sample", str(small / "pings.csv"), "--beacons", str(small / "beacons.csv"),
                     "--out", str(out), "--seed", "3", "--no-progress", "--min-pings", "30"]) == 0
        runs.append(out)
    a, b = ((r / "summary.json").read_bytes() for r in runs)
    assert a == b and b'"seconds"' not in a
    t = json.loads((runs[0] / "timings.json").read_text())
    assert all(v["diagnostics"]["seconds"] > 0 for v in t["beacons"].values())
    assert (runs[0] / "classified.csv").read_bytes() == (runs[1] / "classified.csv").read_bytes()


def test_parquet_in_and_out(small, tmp_path):
    pd.read_csv(small / "pings.csv", dtype=str, keep_default_na=False).to_parquet(
        tmp_path / "p.parquet")
    out = tmp_path / "o"
    assert main(["fit", str(tmp_path / "p.parquet"), "--beacons", str(small / "beacons.csv"),
                 "--out", str(out), "--table-format", "parquet"]) == 0
    assert _fit(small, tmp_path / "c") == 0
    a = pd.read_parquet(out / "classified.parquet")
    b = pd.read_csv(tmp_path / "c" / "classified.csv", dtype=str, keep_default_na=False)
    np.testing.assert_allclose(a["p_dp"].to_numpy(float),
                               pd.to_numeric(b["p_dp"]).to_numpy(), rtol=0, atol=0)
    assert main(["plot", str(out), "--out", str(tmp_path / "figs")]) == 0
    assert (tmp_path / "figs" / "fig13_classification.png").exists()


def test_the_parser_repeats_the_library_constants_faithfully():
    from bayes_mpem.cli import options
    from bayes_mpem.io.table_files import TABLE_FORMATS
    from bayes_mpem.lbl.survey.survey import MIN_PINGS

    assert options.MIN_PINGS == MIN_PINGS and options.TABLE_FORMATS == TABLE_FORMATS
    from bayes_mpem.survey_in.travel_times import KNOT_MINUTES_RANGE  # locate_survey's too

    assert options.KNOT_MINUTES_RANGE == KNOT_MINUTES_RANGE
    from bayes_mpem._validate import MIN_SAMPLED_CI  # sample --ci's lower bound, repeated

    assert options.sampled_probability(repr(MIN_SAMPLED_CI)) == MIN_SAMPLED_CI
    with pytest.raises(argparse.ArgumentTypeError):
        options.sampled_probability(repr(np.nextafter(MIN_SAMPLED_CI, 0.0)))

