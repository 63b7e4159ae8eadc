"""``--config FILE.toml``: options from a file, checked as on the command line, overridden by it."""

import json
import os

import pytest

from bayes_mpem.cli import main
from bayes_mpem.cli.parser import build_parser


@pytest.fixture(scope="module")
def survey(tmp_path_factory):
    root = tmp_path_factory.mktemp("cfg")
    assert main(["simulate", "--seed", "2", "--n-cycles", "60", "--out", str(root / "d")]) == 0
    return root / "d"


def test_config_options_and_command_line_overrides(survey, tmp_path):
    cfg = tmp_path / "run.toml"
    cfg.write_text('method = "paper"\nsigma_dp = 4.0\nmin_pings = 40\nfigures = false\n')
    out = tmp_path / "o"
    assert main(["fit", str(survey / "pings.csv"), "--beacons", str(survey / "beacons.csv"),
                 "--out", str(out), "--config", str(cfg), "--sigma-dp", "3.5"]) == 0
    doc = json.loads((out / "summary.json").read_text())
    assert doc["method"] == "paper"
    assert doc["options"]["sigma_dp"] == 3.5 and doc["options"]["min_pings"] == 40


def test_every_command_takes_a_config():
    subs = build_parser().get_default("subparsers")
    for name, sub in subs.items():
        assert "--config" in {s for a in sub._actions for s in a.option_strings}, name


@pytest.mark.parametrize(("text", "message"), [
    ("sigma_dp = -1", "key 'sigma_dp' (--sigma-dp): expected a positive number"),
    ("sigma_dp = nan", "expected a positive number"),
    ("sigmadp = 4", "key 'sigmadp': not an option of this command; did you mean sigma_dp?"),
    ('pings = "x.csv"', "positional arguments PINGS go on the command line"),
    ('method = "best"', "expected one of mixture, paper"),
    ('figures = "yes"', "expected true or false"),
    ("sigma_dp = [1, 2]", "expected one value, got a list"),
    ("sigma_dp = {a = 1}", "expected a value, got a table"),
    ("x = ", "not valid TOML"),
    ("sigma_dp = 4.0\nsigma-dp = 5.0",  # the first was dropped, silently
     "keys 'sigma_dp' and 'sigma-dp': one option (--sigma-dp) given twice"),
    ('config = "other.toml"', "key 'config': not an option a file can give"),
    ("help = true", "key 'help': not an option a file can give"),  # was 'did you mean help?'
])
def test_config_errors_name_the_file_and_key(survey, tmp_path, capsys, text, message):
    cfg = tmp_path / "bad.toml"
    cfg.write_text(text + "\n")
    with pytest.raises(SystemExit) as stop:
        main(["fit", str(survey / "pings.csv"), "--beacons", str(survey / "beacons.csv"),
              "--out", str(tmp_path / "o"), "--config", str(cfg)])
    err = capsys.readouterr().err
    assert stop.value.code == 2 and f"--config {cfg}" in err and message in err
    assert "usage: bayes-mpem fit" in err


def test_a_config_saved_with_a_byte_order_mark_is_read(survey, tmp_path):
    """Notepad's UTF-8 mark was 'not valid TOML (Invalid statement (at line 1, column 1))'."""
    cfg = tmp_path / "bom.toml"
    cfg.write_bytes(b"\xef\xbb\xbfmin_pings = 40\n")
    out = tmp_path / "o"
    assert main(["fit", str(survey / "pings.csv"), "--beacons", str(survey / "beacons.csv"),
                 "--out", str(out), "--config", str(cfg)]) == 0
    assert json.loads((out / "summary.json").read_text())["options"]["min_pings"] == 40


@pytest.mark.parametrize("bad", ["nope.toml", "."])
def test_a_missing_or_folder_config(tmp_path, capsys, bad):
    with pytest.raises(SystemExit):
        main(["fit", "p.csv", "--beacons", "b.csv", "--out", "o", "--config",
              str(tmp_path / bad)])
    assert "--config" in capsys.readouterr().err


def test_stream_from_a_config_alone(survey, tmp_path):
    cfg = tmp_path / "stream.toml"
    out = tmp_path / "answers.jsonl"
    cfg.write_text(f'beacons = "{survey / "beacons.csv"}"\nreplay = "{survey / "pings.csv"}"\n'
                   f'speed = "max"\nwarmup = 60\nout = "{out}"\nmax_gap = 600.0\n')
    assert main(["stream", "--config", str(cfg)]) == 0
    assert len(out.read_text().splitlines()) == len((survey / "pings.csv").read_text()
                                                    .splitlines()) - 1


def test_the_examples_of_docs_cli_md_parse(tmp_path):
    import re
    from pathlib import Path

    from bayes_mpem.cli.parser import _parse

    docs = Path(__file__).resolve().parents[2] / "docs" / "cli.md"
    if not docs.is_file():
        pytest.skip("not a source checkout")
    blocks = re.findall(r"```toml\n(.*?)```", docs.read_text(), re.S)
    assert len(blocks) >= 8
    positional = {"fit": ["p.csv"], "sample": ["p.csv"], "diagnose": ["p.csv"],
                  "navigate": ["p.csv"], "locate": ["s.txt"], "batch": ["m.csv"]}
    for i, block in enumerate(blocks):
        command = re.match(r"# (\w+)\.toml", block).group(1)
        cfg = tmp_path / f"{i}.toml"
        cfg.write_text(block)
        args = _parse(build_parser(), [command, *positional.get(command, []), "--config",
                                       str(cfg)])
        assert args.command == command


def test_relative_paths_in_a_config_are_read_from_its_folder(tmp_path, monkeypatch):
    """``ssp = "prof.txt"`` beside the config was read from the working folder: "not found",
    or another file of that name used silently. The command line's paths stay as they are."""
    from bayes_mpem.cli.parser import _parse

    (tmp_path / "cfg").mkdir()
    cfg = tmp_path / "cfg" / "run.toml"
    cfg.write_text('beacons = "b.csv"\nout = "res"\nssp = "../prof.txt"\n'
                   'dead_reckoning = "/abs/dr.csv"\n')
    monkeypatch.chdir(tmp_path)
    args = _parse(build_parser(), ["navigate", "p.csv", "--config", "cfg/run.toml"])
    assert (args.beacons, args.out) == (os.path.join("cfg", "b.csv"), os.path.join("cfg", "res"))
    assert args.travel_ssp == os.path.join("cfg", "../prof.txt")
    assert args.dead_reckoning == "/abs/dr.csv" and args.pings == "p.csv"
    args = _parse(build_parser(), ["navigate", "p.csv", "--config", "cfg/run.toml",
                                   "--beacons", "here.csv"])
    assert args.beacons == "here.csv"  # the command line's: from the working folder
    cfg.write_text('ssp = "woa09"\nout = "o"\n')
    assert _parse(build_parser(), ["locate", "s.txt", "--config", str(cfg)]).ssp == "woa09"
    cfg.write_text('out = "-"\nbeacons = "b.csv"\nreplay = "p.csv"\n')
    args = _parse(build_parser(), ["stream", "--config", str(cfg)])
    assert args.out == "-" and args.replay == str(tmp_path / "cfg" / "p.csv")
    cfg.write_text('out = "udp://localhost:5000"\nbeacons = "b.csv"\n')
    assert _parse(build_parser(), ["stream", "--config", str(cfg)]).out == "udp://localhost:5000"


def test_a_profile_beside_a_config_is_used_and_recorded(tmp_path, monkeypatch, capsys):
    camp = tmp_path / "camp"
    assert main(["simulate", "--gnssa", "--format", "garpos", "--hours", "0.5", "--seed", "1",
                 "--out", str(camp)]) == 0
    (tmp_path / "cfg").mkdir()
    svp = (camp / "SIM.0000.sim-svp.csv").read_text().splitlines()[1:]
    (tmp_path / "cfg" / "prof.txt").write_text("\n".join(ln.replace(",", " ") for ln in svp))
    (tmp_path / "cfg" / "run.toml").write_text('ssp = "prof.txt"\nout = "res"\n')
    (tmp_path / "cfg" / "bad.toml").write_text('ssp = "nothere.txt"\nout = "res2"\n')
    monkeypatch.chdir(tmp_path)
    site = "camp/SIM.0000.sim-initcfg.ini"
    capsys.readouterr()
    assert main(["locate", site, "--config", "cfg/bad.toml"]) == 2
    bad = os.path.join("cfg", "nothere.txt")
    assert (f"error: --ssp: sound-speed profile not found: {bad!r} (--ssp from --config "
            "cfg/bad.toml, key 'ssp')") in capsys.readouterr().err
    assert main(["locate", site, "--config", "cfg/run.toml"]) == 0
    doc = json.loads((tmp_path / "cfg" / "res" / "summary.json").read_text())
    prof = os.path.join("cfg", "prof.txt")
    assert doc["ssp"] == prof and doc["input_files"]["ssp"] == prof
    assert "svp" not in doc["input_files"]
    assert doc["input_files"]["not_used"]["svp"].endswith("SIM.0000.sim-svp.csv")
