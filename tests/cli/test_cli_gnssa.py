"""``bayes-mpem simulate --gnssa``: a campaign in GARPOS's or GNATSS's files, with its truth."""

import json

import pytest

from bayes_mpem.cli import main
from bayes_mpem.io.formats import read_survey


@pytest.mark.parametrize(("fmt", "survey"), [("garpos", "SIM.0000.sim-initcfg.ini"),
                                             ("gnatss", "config.yaml")])
def test_simulate_gnssa_writes_a_campaign_locate_reads(tmp_path, capsys, fmt, survey):
    out = tmp_path / "sim"
    assert main(["simulate", "--gnssa", "--format", fmt, "--out", str(out), "--seed", "2",
                 "--hours", "0.4", "--no-gradients"]) == 0
    truth = json.loads((out / "truth.json").read_text())
    assert truth["format"] == fmt and truth["gradients"] is None
    assert truth["settings"]["hours"] == 0.4 and truth["sound_speed"]["unit"] == "m/s"
    raw = read_survey(out / survey, fmt)
    assert raw.pings["transponder"].nunique() == 4
    assert f"wrote {out / survey}" in capsys.readouterr().out


def test_gradients_by_default_and_seeded(tmp_path):
    for name in ("a", "b"):
        assert main(["simulate", "--gnssa", "--out", str(tmp_path / name), "--hours", "0.3",
                     "--seed", "5", "--track", "circle"]) == 0
    a, b = (json.loads((tmp_path / n / "truth.json").read_text()) for n in ("a", "b"))
    assert a == b
    assert a["gradients"]["unit"] == "(m/s)/km" and a["settings"]["track"] == "circle"
    assert max(map(abs, a["gradients"]["grad1_east"] + a["gradients"]["grad1_north"])) > 0


@pytest.mark.parametrize(("extra", "message"), [
    (["--gnssa", "--navigation"], "--navigation"),
    (["--gnssa", "--preset", "random"], "--preset"),
    # their defaults given were accepted and ignored
    (["--gnssa", "--path", "triangle"], "--path: not with --gnssa"),
    (["--gnssa", "--preset", "abe58"], "--preset: not with --gnssa"),
    (["--gnssa", "--n-cycles", "5"], "--n-cycles"),
    (["--gnssa", "--effect", "range_bias=2"], "--effect"),
    (["--gnssa", "--heading-bias", "1"], "--heading-bias"),
    (["--hours", "2"], "--hours: only with --gnssa"),
    (["--navigation", "--format", "gnatss"], "--format: only with --gnssa"),
    (["--no-gradients"], "--gradients: only with --gnssa"),
])
def test_options_that_do_not_go_with_gnssa_are_refused(tmp_path, capsys, extra, message):
    assert main(["simulate", "--out", str(tmp_path / "o"), *extra]) == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("fmt", ["garpos", "gnatss"])
def test_an_interrupted_simulate_gnssa_leaves_the_earlier_campaign_whole(tmp_path, monkeypatch,
                                                                        fmt):
    """The campaign files were written in place, outside the run: a failure before truth.json
    left the new obs.csv beside the earlier truth.json and summary.json (a mix that looks
    complete). Now every file is staged with the run and listed in summary.json."""
    import bayes_mpem.io.results as results

    out = tmp_path / "c"
    argv = ["simulate", "--gnssa", "--hours", "0.1", "--format", fmt, "--out", str(out)]
    assert main([*argv, "--seed", "1"]) == 0
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    assert set(json.loads(before["summary.json"])["files"]) == set(before)
    real = results.write_json

    def fail(path, *args, **kwargs):
        if str(path).endswith("truth.json"):
            raise KeyboardInterrupt
        return real(path, *args, **kwargs)

    monkeypatch.setattr(results, "write_json", fail)
    assert main([*argv, "--seed", "2"]) == 130
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
