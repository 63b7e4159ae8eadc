"""Batch inputs: manifests named in every error, --workers checked, names kept, no stale folder."""

import json

import pandas as pd
import pytest

from bayes_mpem.batch import BatchTask, read_manifest, run_batch, run_task
from bayes_mpem.cli import main
from bayes_mpem.cli.parser import build_parser
from bayes_mpem.exceptions import InputError


@pytest.fixture(scope="module")
def dive(tmp_path_factory):
    root = tmp_path_factory.mktemp("dive")
    assert main(["simulate", "--seed", "1", "--n-cycles", "120", "--out", str(root / "d")]) == 0
    return root / "d"


@pytest.mark.parametrize(("content", "message"), [
    (b"", "an empty manifest"),
    (b"\n# only a comment\n\n", "an empty manifest"),
    (b"name,pings,beacons\ncaf\xe9,a.csv,b.csv\n", "line 2: not UTF-8 text"),
    (b"name,pings,beacons\n", "lists no survey"),
    (b"name,pings,beacons\nA,a.csv\n", "line 2: expected 3 comma-separated cells"),
    (b"name,pings,beacons\x00\n", "a NUL byte"),
    (b"name,pings,beacons\n\n# note\nA,a.csv,b.csv\nA,c.csv,d.csv\n",
     r"line 5, column 'name': 'A' already on line 4"),
    (b"name,pings,beacons\nDive1,a.csv,b.csv\ndive1,c.csv,d.csv\n",  # one folder on macOS
     r"line 3, column 'name': 'dive1' already on line 2 as 'Dive1' \(names differing only in "
     r"case"),
    (b"name,pings,beacons,sigma_dp,sigma_dp\nd1,a.csv,b.csv,1,20\n",  # 1 was dropped
     r"line 1: column 'sigma_dp' appears twice in the header \(columns 4 and 5\)"),
    (b"# a note\nname, pings,beacons,pings\nd1,a.csv,b.csv,c.csv\n",
     r"line 2: column 'pings' appears twice in the header \(columns 2 and 4\)"),
    # Excel's CSV where the list separator is ';' (a byte-order mark, CRLF): was "missing:
    # name, pings, beacons"
    (b"\xef\xbb\xbfname;pings;beacons\r\nd1;d1/pings.csv;d1/beacons.csv\r\n",
     r"line 1: the header 'name;pings;beacons' is one column; the manifest looks "
     r"semicolon-separated; expected comma-separated values"),
    (b"# exported\nname;pings;beacons;sigma_dp\n\nd1;p.csv;b.csv;3,5\n",  # decimal commas
     r"line 2: .* looks semicolon-separated, with decimal commas"),
    (b"name\tpings\tbeacons\nd1\tp.csv\tb.csv\n", r"line 1: .* looks tab-separated"),
])
def test_manifest_errors_name_the_manifest(tmp_path, content, message):
    path = tmp_path / "manifest.csv"
    path.write_bytes(content)
    with pytest.raises(InputError, match=message) as err:
        read_manifest(path)
    assert str(path) in str(err.value)


def test_a_manifest_that_is_a_folder(tmp_path):
    with pytest.raises(InputError, match="is a folder"):
        read_manifest(tmp_path)


@pytest.mark.parametrize("value", ["-1", "0", "x", "1.5", "100000"])
def test_workers_checked_by_the_parser(value, capsys):
    with pytest.raises(SystemExit) as stop:
        build_parser().parse_args(["batch", "m.csv", "--out", "o", "--workers", value])
    assert stop.value.code == 2
    assert "argument --workers: expected an integer" in capsys.readouterr().err


def test_workers_checked_by_the_library(tmp_path):
    with pytest.raises(InputError, match="n_workers"):
        run_batch([], tmp_path / "out", n_workers=0)


def test_numeric_names_stay_text_and_a_failed_rerun_leaves_no_old_results(dive, tmp_path):
    out = tmp_path / "out"
    pings = tmp_path / "pings.csv"
    pings.write_text((dive / "pings.csv").read_text())
    tasks = [BatchTask(n, "fit", {"pings": str(pings), "beacons": str(dive / "beacons.csv")},
                       {"rng": 0}) for n in ("001", "010")]
    for t in tasks:
        assert run_task(t, str(out))["status"] == "done"
    classified = pd.read_parquet(out / "classified")
    assert sorted(set(classified["name"])) == ["001", "010"]
    assert classified["name"].map(type).eq(str).all()
    assert (out / "surveys" / "001" / "summary.json").is_file()
    pings.write_text("time,beacon,range,x,y,depth\n0,1,abc,0,0,5\n")  # now it fails
    record = run_task(tasks[0], str(out))
    assert record["status"] == "failed" and "abc" in record["reason"]
    left = sorted(p.name for p in (out / "surveys" / "001").iterdir())
    assert left == ["failed.json"]
    assert json.loads((out / "surveys" / "001" / "failed.json").read_text())["status"] == "failed"
    assert not (out / "classified" / "survey-001.parquet").exists()
    assert set(pd.read_parquet(out / "classified")["name"]) == {"010"}


@pytest.mark.parametrize("column", ["pings", "beacons"])
def test_an_input_cell_that_is_a_folder_names_the_line_and_column(dive, tmp_path, column):
    """Was a raw "IsADirectoryError: [Errno 21] Is a directory", without line or column."""
    cells = {"pings": "d/pings.csv", "beacons": "d/beacons.csv", column: "d"}
    (tmp_path / "d").symlink_to(dive)
    manifest = tmp_path / "m.csv"
    manifest.write_text(f"name,pings,beacons\n\n# a folder\nx,{cells['pings']},"
                        f"{cells['beacons']}\n")
    [task], _ = read_manifest(manifest)
    record = run_task(task, str(tmp_path / "out"))
    assert record["reason"] == (
        f"InputError: {manifest} line 4, column {column!r}: {(tmp_path / 'd').resolve()} is a "
        "folder; expected a file (a relative path is taken from the manifest's folder)")
    python = BatchTask("y", "fit", {**task.inputs})  # made in Python: no manifest line
    assert run_task(python, str(tmp_path / "out"))["reason"] == (
        f"InputError: y: input {column!r}: {(tmp_path / 'd').resolve()} is a folder; "
        "expected a file")
