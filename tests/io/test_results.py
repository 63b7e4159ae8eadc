"""The one writer (issue 15): all-or-nothing runs, the completion marker, valid JSON, timings."""

from __future__ import annotations

import json
import os

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import pandas as hpd

from bayes_mpem.exceptions import InputError
from bayes_mpem.io.results import (
    check_output_folder,
    read_marker,
    split_timings,
    write_csv,
    write_file,
    write_json,
    writing,
)
from bayes_mpem.io.table_files import read_table_file, table_to_csv_bytes


def _strict(path):
    return json.loads(path.read_text(), parse_constant=lambda t: pytest.fail(f"token {t}"))


def test_json_is_always_valid_null_with_the_reason(tmp_path):
    """NaN and Infinity tokens made summary.json invalid JSON."""
    doc = {"sigma": float("nan"), "ci": [float("-inf"), 1.0], "n": 3, "x": np.float64("inf")}
    p = write_json(tmp_path / "a.json", doc, numpy=True)
    got = _strict(p)
    assert got["sigma"] is None and got["ci"] == [None, 1.0] and got["x"] is None
    assert got["non_finite"] == {"sigma": "nan", "ci[0]": "-inf", "x": "inf"}


def test_a_run_commits_all_files_and_the_marker_last(tmp_path):
    out = tmp_path / "run"
    with writing(out) as d:
        write_csv(d / "t.csv", pd.DataFrame({"a": [1]}))
        write_json(d / "summary.json", {"n": 1, "beacons": {"1": {"seconds": 2.5}}})
        write_json(d / "sub" / "summary.json", {"m": 2})
        assert not (d / "t.csv").exists() and not (d / "summary.json").exists()
    doc = read_marker(out)
    assert doc["files"] == ["sub/summary.json", "summary.json", "t.csv", "timings.json"]
    assert doc["beacons"] == {"1": {}} and _strict(out / "timings.json") == {
        "beacons": {"1": {"seconds": 2.5}}}
    assert _strict(out / "sub" / "summary.json") == {"m": 2, "files": ["summary.json"]}
    assert not [p for p in out.rglob(".*")]  # no temporary file left


def test_a_failed_run_leaves_the_previous_results(tmp_path):
    out = tmp_path / "run"
    with writing(out) as d:
        write_csv(d / "t.csv", pd.DataFrame({"a": [1]}))
        write_json(d / "summary.json", {"run": 1})
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    with pytest.raises(RuntimeError), writing(out) as d:
        write_csv(d / "t.csv", pd.DataFrame({"a": [2]}))
        write_json(d / "summary.json", {"run": 2})
        raise RuntimeError("killed half-way")
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before


def test_a_ctrl_c_among_the_renames_waits_for_the_last(tmp_path, monkeypatch):
    """A Ctrl-C (a real SIGINT) at the first rename of a commit left the new files beside no
    summary.json, the earlier run gone; it is held until every file is in place, then raised
    (session 48)."""
    import signal

    from bayes_mpem.io import results

    out = tmp_path / "run"
    with writing(out) as d:
        write_csv(d / "t.csv", pd.DataFrame({"a": [1]}))
        write_json(d / "summary.json", {"run": 1})
    real, calls = os.replace, []

    def replace(src, dst):
        calls.append(dst)
        if len(calls) == 1:
            signal.raise_signal(signal.SIGINT)  # Ctrl-C now
        real(src, dst)

    monkeypatch.setattr(results.os, "replace", replace)
    with pytest.raises(KeyboardInterrupt), writing(out) as d:
        write_csv(d / "t.csv", pd.DataFrame({"a": [2]}))
        write_json(d / "summary.json", {"run": 2})
    assert len(calls) == 2
    assert read_marker(out)["run"] == 2 and pd.read_csv(out / "t.csv")["a"].tolist() == [2]
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_on_commit_is_called_once_every_file_is_in_place(tmp_path):
    out, seen = tmp_path / "run", []

    def hook(name):
        return lambda: seen.append((name, (out / "summary.json").exists()))

    with writing(out, on_commit=hook("outer")) as d, writing(d, on_commit=hook("nested")):
        write_json(d / "summary.json", {"run": 1})
        assert seen == []
    assert seen == [("outer", True), ("nested", True)]
    with pytest.raises(RuntimeError), writing(out, on_commit=hook("failed")):
        raise RuntimeError("no commit")
    assert seen[-1][0] == "nested"


def test_a_full_disk_names_the_file_and_leaves_nothing_that_looks_done(tmp_path,
                                                                       monkeypatch):
    """Found by session 46's hunt: "[Errno 28] No space left on device" named no file, and
    the run's other files stood complete beside a stray partial summary."""
    import errno
    import pathlib

    out = tmp_path / "run"
    real = pathlib.Path.write_text

    def full(self, text, *args, **kwargs):
        if self.name.startswith(".summary.partial-"):
            raise OSError(errno.ENOSPC, "No space left on device")
        return real(self, text, *args, **kwargs)

    monkeypatch.setattr(pathlib.Path, "write_text", full)
    with pytest.raises(OSError, match=r"No space left on device: '.*summary.json'"), \
            writing(out) as d:
        write_csv(d / "t.csv", pd.DataFrame({"a": [1]}))
        write_file(d / "solution.txt", lambda tmp: real(tmp, "the solution"))
        write_json(d / "summary.json", {"run": 1})
    assert sorted(p.name for p in out.iterdir()) == []
    # a full disk on a rerun leaves the earlier run as it was (was: its summary.json deleted,
    # its files replaced by the new ones and then removed)
    monkeypatch.setattr(pathlib.Path, "write_text", real)
    with writing(out) as d:
        write_csv(d / "t.csv", pd.DataFrame({"a": [1]}))
        write_json(d / "summary.json", {"run": 1})
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    monkeypatch.setattr(pathlib.Path, "write_text", full)
    for second in ("t.csv", "figure.png"):  # a rerun, and a run adding a file (as plot does)
        with pytest.raises(OSError, match="No space left"), writing(out) as d:
            write_csv(d / second, pd.DataFrame({"a": [2]}))
            if second == "t.csv":
                write_json(d / "summary.json", {"run": 2})
        assert {p.name: p.read_bytes() for p in out.iterdir()} == before


def test_earlier_files_stay_unlisted_and_dead_partials_are_cleaned(tmp_path):
    """A run into a folder with inputs (fit into simulate's folder) never deletes them."""
    out = tmp_path / "run"
    with writing(out) as d:
        write_csv(d / "pings.csv", pd.DataFrame({"a": [1]}))
        write_json(d / "summary.json", {"run": 1})
    (out / ".x.partial-999999999.csv").write_text("left by a killed run")
    with writing(out) as d:
        write_json(d / "summary.json", {"run": 2})
    assert sorted(p.name for p in out.iterdir()) == ["pings.csv", "summary.json"]
    assert read_marker(out) == {"run": 2, "files": ["summary.json"]}


def test_a_run_without_a_marker_keeps_the_folders(tmp_path):
    out = tmp_path / "run"
    with writing(out) as d:
        write_json(d / "summary.json", {"run": 1})
    with writing(out) as d:
        write_file(d / "fig.png", lambda tmp: tmp.write_bytes(b"png"))
    assert read_marker(out) == {"run": 1, "files": ["fig.png", "summary.json"]}


def test_read_marker_names_the_damage(tmp_path):
    with pytest.raises(FileNotFoundError, match="no complete output"):
        read_marker(tmp_path)
    (tmp_path / "summary.json").write_text('{"files": ["gone.csv"], "a": ')
    with pytest.raises(InputError, match=r"summary.json: not valid JSON"):
        read_marker(tmp_path)
    (tmp_path / "summary.json").write_text('{"files": ["gone.csv"]}')
    with pytest.raises(InputError, match=r"lists gone.csv, which is missing"):
        read_marker(tmp_path)


def test_a_write_method_names_its_argument_not_the_command_line_option(tmp_path):
    """``SurveyFit.write(file)`` said "--out '...': is a file" to a Python caller."""
    import bayes_mpem as bm

    f = tmp_path / "file"
    f.write_text("x")
    res = bm.fit(bm.simulate_survey("abe58", rng=1, n_cycles=60).survey, path="triangle",
                 rng=0)
    for call in (lambda: res.write(f), lambda: writing(f).__enter__()):
        with pytest.raises(InputError, match=rf"^out_dir {str(f)!r}: is a file; expected a "
                                             r"folder$"):
            call()
    with pytest.raises(InputError, match=r"^--out "):
        check_output_folder(f, "--out")  # the command line names its option


def test_output_folder_is_checked_before_any_work(tmp_path):
    f = tmp_path / "file"
    f.write_text("x")
    with pytest.raises(InputError, match="is a file"):
        check_output_folder(f)
    with pytest.raises(InputError, match="lies under the file"):
        check_output_folder(f / "a" / "b")
    with pytest.raises(InputError, match="cannot be written"):
        check_output_folder("/sys/bayes_mpem_test")  # read-only for root too
    if os.geteuid() != 0:
        ro = tmp_path / "ro"
        ro.mkdir(mode=0o500)
        with pytest.raises(InputError, match="cannot be written"):
            check_output_folder(ro / "x")
    assert check_output_folder(tmp_path / "new" / "deep") == tmp_path / "new" / "deep"
    assert not (tmp_path / "new").exists()


def test_split_timings():
    doc, t = split_timings({"a": 1, "b": {"sampling_seconds": 1.0, "c": {"seconds": 2}}})
    assert doc == {"a": 1, "b": {"c": {}}} and t == {"b": {"sampling_seconds": 1.0,
                                                           "c": {"seconds": 2}}}


# --------------------------------------------------------------------------- tables


_cells = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.none(),
                   st.text(alphabet=st.characters(blacklist_categories=("Cs",),
                                                  blacklist_characters="\x00"), max_size=8))


@settings(max_examples=60, deadline=None)
@given(hpd.data_frames([hpd.column("f", dtype=float), hpd.column("s", dtype=object,
                                                                 elements=_cells),
                        hpd.column("i", dtype=int)], index=hpd.range_indexes(max_size=12)))
def test_fast_csv_writer_writes_what_pandas_writes(frame):
    """The vectorised writer is byte-identical to DataFrame.to_csv (existing outputs unchanged)."""
    assert table_to_csv_bytes(frame) == frame.to_csv(index=False).encode()


@settings(max_examples=40, deadline=None)
@given(st.lists(st.sampled_from(["data", "", "   ", "# note", "\t"]), min_size=1, max_size=15),
       st.booleans())
def test_table_rows_keep_their_file_line_numbers(tmp_path_factory, kinds, crlf):
    path = tmp_path_factory.mktemp("t") / "t.csv"
    lines, expect = ["a,b"], []
    for k, kind in enumerate(kinds):
        lines.append(f"{k},{k * 2}" if kind == "data" else kind)
        if kind == "data":
            expect.append(len(lines))
    path.write_bytes(("\r\n" if crlf else "\n").join(lines).encode() + b"\n")
    if not expect:
        return
    t = read_table_file(path, "t.csv")
    assert t.lines.tolist() == expect and t.frame["b"].tolist() == [
        str(2 * int(a)) for a in t.frame["a"]]


@settings(max_examples=40, deadline=None)
@given(st.lists(st.floats(allow_nan=False, allow_infinity=False, width=64), min_size=3,
                max_size=60), st.sampled_from([1, 3]))
def test_big_arrays_are_dumped_as_json_dumps_would(values, width):
    """history.json's first_resp is formatted vectorised: the same bytes as json.dumps."""
    import bayes_mpem.io.documents as documents

    a = np.asarray(values[: len(values) // width * width]).reshape(-1, width)
    a = a.ravel() if width == 1 else a
    doc = {"b": {"first_resp": a, "n": 1}, "x": [1.5]}
    old, documents.BIG_ARRAY = documents.BIG_ARRAY, 1
    try:
        got = documents.json_text(doc, None, numpy=True)
    finally:
        documents.BIG_ARRAY = old
    assert got == json.dumps({"b": {"first_resp": a.tolist(), "n": 1}, "x": [1.5]}) + "\n"


@pytest.mark.parametrize("zero", [0.0, -0.0])
@pytest.mark.parametrize("width", [1, 3])
def test_rounded_probabilities_are_formatted_once_per_value(zero, width, monkeypatch):
    """Few distinct values (first_resp rounded to 3 decimals) take the lookup path: same bytes."""
    import bayes_mpem.io.documents as documents
    import bayes_mpem.io.table_files as table_files

    if not np.signbit(zero):  # the lookup path needs no general formatter; -0.0 goes there
        monkeypatch.setattr(table_files, "format_floats", lambda a: pytest.fail("not taken"))

    p = np.round(np.random.default_rng(0).dirichlet([1, 1, 1], size=20_000), 3)
    p[:5] = zero
    a = p[:, 0].copy() if width == 1 else p
    assert a.size >= documents.BIG_ARRAY
    got = documents.json_text({"first_resp": a}, None, numpy=True)
    assert got == json.dumps({"first_resp": a.tolist()}) + "\n"
