"""Tests for bayes_mpem.data: reading and validating ping and beacon tables."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from bayes_mpem.exceptions import InputError
from bayes_mpem.io.dead_reckoning import read_dead_reckoning
from bayes_mpem.io.survey import BeaconData, Survey, load_survey
from bayes_mpem.io.tables import BEACON_COLUMNS, PING_COLUMNS, read_beacons, read_pings

HEADER = "time,beacon,range,x,y,depth"
BEACONS = "beacon,x,y,depth\n1,0,0,50\n2,100,0,50\n3,0,100,50\n"


def write(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def pings_csv(tmp_path: Path, *rows: str, header: str = HEADER) -> Path:
    return write(tmp_path, "pings.csv", header + "\n" + "".join(r + "\n" for r in rows))


@pytest.fixture
def beacons_csv(tmp_path: Path) -> Path:
    return write(tmp_path, "beacons.csv", BEACONS)


def ping_frame(**overrides) -> pd.DataFrame:
    cols = {"time": [0.0, 1.0, 2.0], "beacon": [1, 2, 3], "range": [50.0, 60.0, 70.0],
            "x": [0.0, 1.0, 2.0], "y": [0.0, 0.0, 0.0], "depth": [10.0, 10.0, 10.0]}
    cols.update(overrides)
    return pd.DataFrame(cols, index=[10, 15, 20])


# --------------------------------------------------------------------------- valid input


def test_column_constants():
    assert PING_COLUMNS == ("time", "beacon", "range", "x", "y", "depth")
    assert BEACON_COLUMNS == ("beacon", "x", "y", "depth")
    assert issubclass(InputError, ValueError)


def test_valid_round_trip_keeps_extra_columns_as_text(tmp_path, beacons_csv):
    path = pings_csv(tmp_path, "0.5,1,51.25,1,2,10,hello,001", "1.5,2,60,3,4,11,x y,1e3",
                     header=HEADER + ",note,code")
    s = load_survey(path, beacons_csv)
    assert isinstance(s, Survey) and len(s) == 2
    assert list(s.table.columns) == [*PING_COLUMNS, "note", "code"]
    assert s.table["code"].tolist() == ["001", "1e3"]
    assert s.table["note"].tolist() == ["hello", "x y"]
    assert s.table["range"].tolist() == ["51.25", "60"]
    assert s.table.index.equals(pd.RangeIndex(2))
    np.testing.assert_array_equal(s.range, [51.25, 60.0])
    np.testing.assert_array_equal(s.time, [0.5, 1.5])
    np.testing.assert_array_equal(s.depth, [10.0, 11.0])
    assert s.beacon.tolist() == ["1", "2"] and s.beacon.dtype == object
    assert s.beacon_ids == ["1", "2", "3"]
    assert s.beacons.loc["2"].tolist() == [100.0, 0.0, 50.0]
    assert s.pings_source == str(path) and s.beacons_source == str(beacons_csv)
    assert not s.no_reply.any()
    b = s.for_beacon("2")
    assert b.n == 1 and b.beacon == "2" and b.rows.tolist() == [1] and b.rows.dtype == np.int64
    np.testing.assert_array_equal(b.position, [100.0, 0.0, 50.0])
    assert s.for_beacon("3").n == 0
    assert load_survey(s) is s


def test_headers_with_spaces_and_column_order(tmp_path, beacons_csv):
    path = pings_csv(tmp_path, "5, 1 ,0,0,3,40", header=" depth , beacon,x ,y,time, range")
    s = load_survey(path, write(tmp_path, "b.csv", " beacon , x,y , depth \n1,0,0,50\n"))
    assert s.range.tolist() == [40.0] and s.depth.tolist() == [5.0] and s.time.tolist() == [3.0]
    assert s.beacon.tolist() == ["1"]


def test_blank_lines_keep_file_line_numbers(tmp_path, beacons_csv):
    path = pings_csv(tmp_path, "0,1,50,0,0,5", "", "1,1,-1,0,0,5")
    with pytest.raises(InputError, match=r"line 4, column 'range'"):
        load_survey(path, beacons_csv)


def test_quoted_multiline_field_keeps_file_line_numbers(tmp_path, beacons_csv):
    path = pings_csv(tmp_path, '0,1,50,0,0,5,"two\nlines"', "1,1,1_000,0,0,5,ok",
                     header=HEADER + ",note")
    with pytest.raises(InputError, match=r"line 4, column 'range': .*'1_000'"):
        load_survey(path, beacons_csv)


def test_dataframe_int_ids_match_csv_string_ids(tmp_path, beacons_csv):
    df = ping_frame(beacon=[1, 2.0, np.int64(3)])
    before = df.copy()
    s = load_survey(df, beacons_csv)
    assert s.beacon.tolist() == ["1", "2", "3"]
    assert s.pings_source == "pings DataFrame"
    pd.testing.assert_frame_equal(df, before)  # caller's frame untouched
    assert s.table is not df and s.table.index.equals(pd.RangeIndex(3))
    beacons = pd.DataFrame({"beacon": [" 1", "2", "3"], "x": [0, 1, 2], "y": [0, 0, 0],
                            "depth": [9, 9, 9], "extra": ["a", "b", "c"]})
    s2 = load_survey(pings_csv(tmp_path, "0,1,50,0,0,5"), beacons)
    assert list(s2.beacons.columns) == ["x", "y", "depth"]
    assert s2.for_beacon(1).position.tolist() == [0.0, 0.0, 9.0]


def test_empty_range_is_no_reply(tmp_path, beacons_csv):
    path = pings_csv(tmp_path, "0,1,50,0,0,5", "1,1,,1,0,5", "2,1,  ,2,0,5", "3,2,70,3,0,5")
    s = load_survey(path, beacons_csv)
    assert len(s) == 4
    assert s.no_reply.tolist() == [False, True, True, False]
    assert np.isnan(s.range[1:3]).all()
    b = s.for_beacon(1)
    assert b.n == 1 and b.n_no_reply == 2 and b.rows.tolist() == [0]
    assert np.isfinite(b.range).all()
    assert s.for_beacon("2").n_no_reply == 0


@pytest.mark.parametrize("missing", [np.nan, None, pd.NA])
def test_dataframe_missing_range_is_no_reply(beacons_csv, missing):
    df = ping_frame(range=pd.Series([50.0, missing, 70.0], index=[10, 15, 20], dtype=object))
    s = load_survey(df, beacons_csv)
    assert s.no_reply.tolist() == [False, True, False]


def test_read_pings_and_read_beacons_standalone(tmp_path):
    table, arrays = read_pings(pings_csv(tmp_path, "0,9,50,0,0,5"))
    assert set(arrays) == set(PING_COLUMNS) and arrays["beacon"].tolist() == ["9"]
    assert table["beacon"].tolist() == ["9"]
    b = read_beacons(write(tmp_path, "b.csv", BEACONS))
    assert b.index.tolist() == ["1", "2", "3"] and b.index.name == "beacon"
    assert (b.dtypes == np.float64).all()


def test_survey_arrays_are_read_only(beacons_csv):
    s = load_survey(ping_frame(), beacons_csv)
    with pytest.raises(ValueError, match="read-only"):
        s.range[0] = 1.0


# --------------------------------------------------------------------------- errors


def test_missing_columns(tmp_path, beacons_csv):
    path = pings_csv(tmp_path, "0,1,50", header="time,beacon,rng")
    with pytest.raises(InputError, match="pings.csv") as info:
        load_survey(path, beacons_csv)
    msg = str(info.value)
    assert "missing required column(s) 'range', 'x', 'y', 'depth'" in msg
    assert "found 'time', 'beacon', 'rng'" in msg


def test_missing_beacon_columns(beacons_csv):
    with pytest.raises(InputError, match=r"beacons DataFrame: missing .*'depth'"):
        load_survey(ping_frame(), pd.DataFrame({"beacon": [1], "x": [0], "y": [0]}))


def test_non_number_in_x(tmp_path, beacons_csv):
    path = pings_csv(tmp_path, "0,1,50,0,0,5", "1,1,50,abc,0,5")
    with pytest.raises(InputError, match=r"pings\.csv line 3, column 'x': .*number.*'abc'"):
        load_survey(path, beacons_csv)


@pytest.mark.parametrize("text", ["nan", "NaN", "inf"])
def test_nan_text_in_range_is_error_not_no_reply(tmp_path, beacons_csv, text):
    path = pings_csv(tmp_path, f"0,1,{text},0,0,5")
    with pytest.raises(InputError, match=rf"line 2, column 'range': .*got '{text}'"):
        load_survey(path, beacons_csv)


def test_inf_in_depth(tmp_path, beacons_csv):
    path = pings_csv(tmp_path, "0,1,50,0,0,inf")
    with pytest.raises(InputError, match=r"line 2, column 'depth': expected a finite .*'inf'"):
        load_survey(path, beacons_csv)


@pytest.mark.parametrize("value", ["-3.2", "0", "0.0"])
def test_negative_and_zero_range(tmp_path, beacons_csv, value):
    path = pings_csv(tmp_path, "0,1,50,0,0,5", f"1,1,{value},0,0,5")
    with pytest.raises(InputError, match=rf"pings\.csv line 3, column 'range': "
                                         rf"expected a positive number \(m\), got '{value}'"):
        load_survey(path, beacons_csv)


@pytest.mark.parametrize("column", ["time", "x", "y", "depth"])
def test_empty_cell_in_required_numeric_column(tmp_path, beacons_csv, column):
    row = dict(zip(PING_COLUMNS, ["0", "1", "50", "0", "0", "5"], strict=True))
    row[column] = ""
    path = pings_csv(tmp_path, ",".join(row.values()))
    with pytest.raises(InputError, match=rf"line 2, column '{column}': .*empty cell"):
        load_survey(path, beacons_csv)


def test_nan_in_dataframe_x_names_row_label(beacons_csv):
    df = ping_frame(x=[0.0, np.nan, 1.0])
    with pytest.raises(InputError, match=r"pings DataFrame row 15, column 'x': .*missing value"):
        load_survey(df, beacons_csv)


def test_inf_and_negative_in_dataframe_range(beacons_csv):
    df = ping_frame(range=[np.inf, -3.2, 5.0])
    with pytest.raises(InputError, match="2 problems") as info:
        load_survey(df, beacons_csv)
    assert "row 10, column 'range': expected a positive number (m), got inf" in str(info.value)
    assert "row 15, column 'range': expected a positive number (m), got -3.2" in str(info.value)


@pytest.mark.parametrize(("column", "values", "shown"), [
    ("x", ["1.5", "nan", "2"], "'nan'"),
    ("y", [0.0, "abc", 1.0], "'abc'"),
    ("depth", [True, False, True], "False"),
])
def test_dataframe_text_and_bool_cells(beacons_csv, column, values, shown):
    df = ping_frame(**{column: values})
    with pytest.raises(InputError, match=rf"row 15, column '{column}': .*got {shown}"):
        load_survey(df, beacons_csv)


def test_dataframe_text_columns_are_parsed(beacons_csv):
    s = load_survey(ping_frame(x=["1.5", " 2", 3], range=["50", "", None]), beacons_csv)
    assert s.x.tolist() == [1.5, 2.0, 3.0] and s.no_reply.tolist() == [False, True, True]


def test_load_survey_argument_errors(beacons_csv):
    s = load_survey(ping_frame(), beacons_csv)
    with pytest.raises(InputError, match="beacons=None"):
        load_survey(s, beacons_csv)
    with pytest.raises(InputError, match="beacons table"):
        load_survey(ping_frame())


def test_empty_beacon_id(tmp_path, beacons_csv):
    path = pings_csv(tmp_path, "0, ,50,0,0,5")
    with pytest.raises(InputError, match=r"line 2, column 'beacon': expected a beacon id"):
        load_survey(path, beacons_csv)


def test_unknown_beacon_lists_known_ids(tmp_path, beacons_csv):
    path = pings_csv(tmp_path, "0,1,50,0,0,5", "1,7,50,0,0,5")
    with pytest.raises(InputError, match=r"line 3, column 'beacon': beacon '7' is not in") as e:
        load_survey(path, beacons_csv)
    assert "known beacon ids: '1', '2', '3'" in str(e.value)
    assert str(beacons_csv) in str(e.value)


def test_for_beacon_unknown_id(beacons_csv):
    s = load_survey(ping_frame(), beacons_csv)
    with pytest.raises(InputError, match=r"unknown beacon '9'.*'1', '2', '3'"):
        s.for_beacon(9)


def test_duplicated_beacon_id_names_both_lines(tmp_path):
    path = write(tmp_path, "beacons.csv", "beacon,x,y,depth\n1,0,0,50\n2,1,1,50\n 1,5,5,5\n")
    with pytest.raises(InputError, match=r"beacons\.csv.*'1' is duplicated \(line 2, line 4\)"):
        read_beacons(path)


def test_a_beacon_id_repeated_many_times_lists_a_few_lines():
    """A pings table given as the beacons listed every line of every id (57 kB)."""
    frame = pd.DataFrame({"beacon": ["1", "2"] * 1000, "x": 0.0, "y": 0.0, "depth": 50.0})
    with pytest.raises(InputError) as err:
        read_beacons(frame)
    assert "beacon id '1' is duplicated (row 0, row 2, row 4, row 6, row 8 and 995 more)" in str(
        err.value)
    assert len(str(err.value)) < 400


@pytest.mark.parametrize("text", ["beacon,x,y,depth\n1,0,abc,50\n", "beacon,x,y,depth\n1,0,,50\n"])
def test_bad_beacon_coordinate(tmp_path, text):
    with pytest.raises(InputError, match=r"beacons\.csv line 2, column 'y'"):
        read_beacons(write(tmp_path, "beacons.csv", text))


def test_empty_tables(tmp_path, beacons_csv):
    with pytest.raises(InputError, match=r"pings\.csv: the pings table is empty"):
        load_survey(pings_csv(tmp_path), beacons_csv)
    with pytest.raises(InputError, match="beacons DataFrame: the beacons table is empty"):
        read_beacons(pd.DataFrame(columns=list(BEACON_COLUMNS)))
    with pytest.raises(InputError, match="file is empty"):
        read_pings(write(tmp_path, "blank.csv", ""))


def test_many_bad_rows_summarised(tmp_path, beacons_csv):
    rows = [f"{i},1,-1,0,0,5" for i in range(47)]
    with pytest.raises(InputError, match=r"47 problems in .*pings\.csv") as info:
        load_survey(pings_csv(tmp_path, *rows), beacons_csv)
    msg = str(info.value)
    assert "... and 37 more problems" in msg
    assert len(re.findall(r"column 'range'", msg)) == 10
    assert "line 2," in msg and "line 11," in msg and "line 12," not in msg


def test_wrong_field_count(tmp_path, beacons_csv):
    with pytest.raises(InputError, match=r"line 3: expected 6 fields .*got 4"):
        load_survey(pings_csv(tmp_path, "0,1,50,0,0,5", "1,1,50,0"), beacons_csv)


def test_missing_file(tmp_path, beacons_csv):
    missing = tmp_path / "nope.csv"
    with pytest.raises(FileNotFoundError, match="nope.csv"):
        load_survey(missing, beacons_csv)
    with pytest.raises(FileNotFoundError, match="nope.csv"):
        read_beacons(str(missing))


def test_bad_source_type():
    with pytest.raises(TypeError, match="CSV path or a pandas DataFrame"):
        read_pings(42)


# --------------------------------------------------------------------------- BeaconData


def test_from_arrays_defaults():
    b = BeaconData.from_arrays([10, 11, 12], [0, 1, 2], [0, 0, 0], [5, 5, 5], (1, 2, 30),
                               beacon=4)
    assert b.n == 3 and b.beacon == "4" and b.n_no_reply == 0
    assert b.time.tolist() == [0.0, 1.0, 2.0] and b.rows.tolist() == [0, 1, 2]
    assert b.range.dtype == np.float64 and b.position.shape == (3,)


def test_from_arrays_length_mismatch():
    with pytest.raises(InputError, match=r"x: length 2 differs from range length 3"):
        BeaconData.from_arrays([1, 2, 3], [0, 1], [0, 0, 0], [5, 5, 5], (0, 0, 0))


def test_from_arrays_negative_range_first_index():
    with pytest.raises(InputError, match=r"range\[1\]: expected a positive number"):
        BeaconData.from_arrays([1, -2, -3], [0, 1, 2], [0, 0, 0], [5, 5, 5], (0, 0, 0))


@pytest.mark.parametrize(("kwargs", "pattern"), [
    ({"depth": [5, np.nan, 5]}, r"depth\[1\]: expected a finite number"),
    ({"position": (0, 0)}, "position: expected 3 finite numbers"),
    ({"time": [0, 1]}, "time: length 2 differs"),
    ({"x": [[0, 1, 2]]}, "x: expected a 1-D array"),
])
def test_from_arrays_other_errors(kwargs, pattern):
    args = {"range": [1, 2, 3], "x": [0, 1, 2], "y": [0, 0, 0], "depth": [5, 5, 5],
            "position": (0, 0, 0)}
    args.update(kwargs)
    with pytest.raises(InputError, match=pattern):
        BeaconData.from_arrays(**args)


def test_duplicated_header_in_a_plain_csv(tmp_path, beacons_csv):
    """The fast CSV path must not let pandas rename a duplicated column (x -> x.1)."""
    p = tmp_path / "dup.csv"
    p.write_text("time,beacon,range,x,y,depth,x\n0,1,100,0,0,10,5\n")
    with pytest.raises(InputError, match=r"duplicated column name\(s\) 'x' \(columns 4, 7\)"):
        load_survey(p, beacons_csv)
    p.write_text("time,beacon,range,x,y,depth,,\n0,1,100,0,0,10,,\n")  # a header ending in ",,"
    with pytest.raises(InputError, match=r"duplicated column name\(s\) '' \(columns 7, 8\)"):
        load_survey(p, beacons_csv)


def test_fast_and_exact_csv_readers_agree(tmp_path, beacons_csv):
    """Blank lines and a quoted cell (exact reader) give the same line numbers as the fast one."""
    body = "time,beacon,range,x,y,depth\n0,1,100,0,0,10\n\n1,1,-4,0,0,10\n"
    plain, quoted = tmp_path / "plain.csv", tmp_path / "quoted.csv"
    plain.write_text(body)
    quoted.write_text(body.replace("0,1,100", '0,"1",100'))
    for path in (plain, quoted):
        with pytest.raises(InputError, match=r"line 4, column 'range'.*got '-4'"):
            load_survey(path, beacons_csv)


def test_reserved_output_column_names_are_refused(tmp_path, beacons_csv):
    p = tmp_path / "p.csv"
    p.write_text("time,beacon,range,x,y,depth,label\n0,1,100,0,0,10,mine\n")
    with pytest.raises(InputError, match=r"'label' would be overwritten by the results"):
        load_survey(p, beacons_csv)


# ------------------------------------------------------------------ dead-reckoning tables


def test_dead_reckoning_positions_and_velocities(tmp_path):
    t, form = read_dead_reckoning(write(tmp_path, "dr.csv", "time,x,y,depth\n0,1,2,5\n10,3,4,5\n"))
    assert form == "position" and t.columns.tolist() == ["time", "x", "y", "depth"]
    t, form = read_dead_reckoning(write(tmp_path, "v.csv",
                                        "time, ve ,vn,extra\n0,1,0,a\n5,1,0,b\n"))
    assert form == "velocity" and t["ve"].tolist() == [1.0, 1.0]


@pytest.mark.parametrize(("text", "match"), [
    ("time,x,y,ve,vn\n0,0,0,1,1\n1,0,0,1,1\n", "found both"),
    ("time,east,north\n0,0,0\n1,0,0\n", "found neither"),
    ("time,x,y\n0,0,0\n", "at least two rows"),
    ("time,x,y\n0,0,0\n10,0,0\n10,1,0\n", r"line 4, column 'time': expected a time after"),
    ("time,x,y\n0,0,0\n10,abc,0\n", r"line 3, column 'x': expected a finite number"),
])
def test_dead_reckoning_errors_name_the_line_and_column(tmp_path, text, match):
    with pytest.raises(InputError, match=match):
        read_dead_reckoning(write(tmp_path, "dr.csv", text))
