"""The input boundary (issue 15): lines as grep -n counts them, shapes, physical limits.

Each test names the class of problem it guards against; on the code before the boundary
(f31dfee) each of them failed (a silent wrong answer, a traceback or an unclear message).
"""

from __future__ import annotations

import subprocess

import numpy as np
import pandas as pd
import pytest

from bayes_mpem.exceptions import InputError
from bayes_mpem.io.formats import read_survey, sample_file
from bayes_mpem.io.survey import load_survey

# the tests of the problem classes use only the public readers, so that they also run
# (and fail) on the code before the boundary; the boundary's own tests import it

HEADER = "time,beacon,range,x,y,depth"
BEACONS = "beacon,x,y,depth\n1,0,0,50\n2,100,0,50\n"


def _grep_n(path, pattern):
    out = subprocess.run(["grep", "-n", pattern, str(path)], capture_output=True, text=True,
                         check=False).stdout
    return [int(line.split(":", 1)[0]) for line in out.split("\n") if line]  # not splitlines


@pytest.mark.parametrize("sep", ["\f", "\v", "\x1c", "\x85", "\u2028", "\r"])
def test_line_numbers_are_grep_n_numbers(tmp_path, sep):
    from bayes_mpem.io.boundary import read_text_lines

    p = tmp_path / "f.txt"
    p.write_text(f"a\njunk{sep}more\nb\r\nc\n")
    lines = read_text_lines(p)
    assert len(lines) == 4 and lines[2] == "b" and lines.index("c") + 1 == _grep_n(p, "^c")[0]


def test_split_lines_keeps_a_final_line_without_newline():
    from bayes_mpem.io.boundary import split_lines

    assert split_lines("a\nb") == ["a", "b"] and split_lines("") == []


def test_unreadable_inputs_name_the_file(tmp_path):
    from bayes_mpem.io.boundary import read_text_lines

    with pytest.raises(InputError, match="is a folder; expected a file"):
        read_text_lines(tmp_path)
    with pytest.raises(FileNotFoundError, match="nope.txt"):
        read_text_lines(tmp_path / "nope.txt")
    bad = tmp_path / "latin.txt"
    bad.write_bytes(b"ok\nstill ok\ncaf\xe9\n")
    with pytest.raises(InputError, match=r"latin.txt line 3: not UTF-8"):
        read_text_lines(bad)
    nul = tmp_path / "bin.txt"
    nul.write_bytes(b"a\nb\x00c\n")
    with pytest.raises(InputError, match=r"bin.txt line 2: a NUL byte"):
        read_text_lines(nul)


def test_limits_refuse_the_impossible_and_keep_the_possible():
    from bayes_mpem.io.boundary import LIMITS, limit_problem, out_of_limits

    assert out_of_limits("range", [1e-3, 5000.0, 1e5]).tolist() == [False, False, False]
    assert out_of_limits("range", [0.0, -1.0, 1e5 + 1, 1e300, np.nan, np.inf]).all()
    assert out_of_limits("lat", [-90.0, 90.0]).sum() == 0 and out_of_limits("lat", [95.0]).all()
    assert out_of_limits("lon", [200.0]).all() and out_of_limits("twtt", [0.0]).all()
    assert limit_problem("sound_speed", 716242.0).startswith("sound speed 716242 outside")
    assert all(lim.low < lim.high for lim in LIMITS.values())


def test_a_line_is_classified_by_its_whole_shape_not_by_a_character():
    from bayes_mpem.io.boundary import Shape, classify

    shapes = [Shape("ping", r"\d+ msec\..*"), Shape("header", r"[A-Za-z][^:]*:.*")]
    kinds = [k for _, k, _ in classify(["Site: A", "6306 msec. Time(UTC): 12:00", "x:y:"],
                                        shapes)]
    assert kinds == ["header", "ping", "header"]


# --------------------------------------------------------------------------- tables


def _pings(tmp_path, *rows, header=HEADER, name="p.csv", prefix=""):
    p = tmp_path / name
    p.write_text(prefix + header + "\n" + "".join(r + "\n" for r in rows))
    b = tmp_path / "b.csv"
    b.write_text(BEACONS)
    return p, b


@pytest.mark.parametrize(("row", "column"), [
    ("0,1,1e300,0,0,5", "range"), ("0,1,50,1e300,0,5", "x"), ("0,1,50,0,0,1e300", "depth"),
    ("0,1,2e5,0,0,5", "range"), ("1e300,1,50,0,0,5", "time"), ("0,1,50,0,-3e7,5", "y"),
])
def test_impossible_values_are_refused_naming_line_and_column(tmp_path, row, column):
    """1e300 ranges or positions gave NaN fits and NaN/Infinity in summary.json (exit 0)."""
    p, b = _pings(tmp_path, "0,1,50,0,0,5", row)
    with pytest.raises(InputError, match=rf"p.csv line 3, column '{column}': expected .* within "):
        load_survey(p, b)


def test_a_dataframe_is_held_to_the_same_limits(tmp_path):
    df = pd.DataFrame({"time": [0, 1], "beacon": [1, 1], "range": [50.0, 1e300], "x": [0, 0],
                       "y": [0, 0], "depth": [5, 5]})
    with pytest.raises(InputError, match=r"row 1, column 'range'"):
        load_survey(df, pd.read_csv(_pings(tmp_path)[1]))


def test_semicolons_and_decimal_commas_are_named(tmp_path):
    """A semicolon file with decimal commas said '5260 problems ... expected 1 fields'."""
    p, b = _pings(tmp_path, "0,5;1;50,25;0;0;5", header=HEADER.replace(",", ";"))
    with pytest.raises(InputError, match="semicolon-separated, with decimal commas") as e:
        load_survey(p, b)
    assert "problems" not in str(e.value)


def test_comment_lines_are_comments_not_a_header(tmp_path):
    """A comment line before the header was taken as the header without a word."""
    p, b = _pings(tmp_path, "0,1,50,0,0,5", "# a pause", "1,1,-3,0,0,5",
                  prefix="# exported by hand\n")
    with pytest.raises(InputError, match=r"line 5, column 'range'"):
        load_survey(p, b)
    p, b = _pings(tmp_path, "0,1,50,0,0,5", "1,2,60,0,0,5", prefix="# exported by hand\n")
    s = load_survey(p, b)
    assert len(s) == 2 and s.comment_lines == 1 and s.lines.tolist() == [3, 4]


def test_a_form_feed_line_shifts_no_line_number(tmp_path):
    p, b = _pings(tmp_path, "0,1,50,0,0,5", "junk\fline", "1,1,-3,0,0,5")
    with pytest.raises(InputError) as e:
        load_survey(p, b)
    assert "line 3: expected 6 fields" in str(e.value)
    assert _grep_n(p, "junk") == [3]


def test_big_table_checks_are_vectorised_but_name_every_listed_cell(tmp_path):
    rows = [f"{i},1,{'-1' if i % 1000 == 7 else '50'},0,0,5" for i in range(20000)]
    p, b = _pings(tmp_path, *rows)
    with pytest.raises(InputError, match=r"20 problems") as e:
        load_survey(p, b)
    assert "line 9, column 'range'" in str(e.value) and "... and 10 more problems" in str(e.value)


def test_parquet_pings_read_like_csv(tmp_path):
    p, b = _pings(tmp_path, "0,1,50,0,0,5", "1,2,,1,0,5", "2,1,70.5,2,0,5")
    pq = tmp_path / "p.parquet"
    pd.read_csv(p).to_parquet(pq)
    s_csv, s_pq = load_survey(p, b), load_survey(pq, b)
    np.testing.assert_array_equal(s_pq.range, s_csv.range)
    assert s_pq.beacon.tolist() == ["1", "2", "1"] and s_pq.no_reply.tolist() == [0, 1, 0]
    bad = pd.read_csv(p)
    bad.loc[2, "range"] = -4.0
    bad.to_parquet(pq)
    with pytest.raises(InputError, match=r"p.parquet row 2, column 'range'"):
        load_survey(pq, b)


# --------------------------------------------------------------------------- survey files


def _sio(tmp_path, transform):
    lines = sample_file("obsrange/SIO_CC03.txt").read_text().splitlines()
    p = tmp_path / "s.txt"
    p.write_text("\n".join(transform(lines)) + "\n")
    return p


def test_sio_without_separator_keeps_every_ping(tmp_path):
    """Without its ===== line, 37 of 88 pings were taken for header lines (they contain ':')."""
    full = read_survey(sample_file("obsrange/SIO_CC03.txt"), "obsrange-sio")
    raw = read_survey(_sio(tmp_path, lambda ls: [ln for ln in ls if not ln.startswith("=")]),
                      "obsrange-sio")
    assert len(raw.pings) == len(full.pings) == 88
    assert raw.header["depth"] == full.header["depth"]


@pytest.mark.parametrize(("old", "new", "reason"), [
    ("Lat: 4 ", "Lat: 95 ", "latitude"), ("Lon: 132", "Lon: 200", "longitude"),
    (" 52.", " 75.", "arc-minutes"), ("6306 msec", "0 msec", "two-way travel time"),
    ("2018:114", "2018:400", "day of year"),
])
def test_sio_impossible_pings_are_skipped_with_the_reason(tmp_path, old, new, reason):
    """Latitude 95, longitude 200, 75 arc-minutes, 0 msec were used as pings."""
    def edit(ls):
        i = next(k for k, ln in enumerate(ls) if "msec" in ln)
        ls[i] = ls[i].replace(old, new, 1)
        return ls
    raw = read_survey(_sio(tmp_path, edit), "obsrange-sio")
    assert len(raw.pings) == 87
    row = raw.skipped[raw.skipped["reason"].str.contains(reason)]
    assert len(row) == 1 and int(row["line"].iloc[0]) == 11


def test_sio_form_feed_junk_keeps_grep_line_numbers(tmp_path):
    p = _sio(tmp_path, lambda ls: ls[:12] + ["junk\fjunk"] + ls[12:])
    raw = read_survey(p, "obsrange-sio")
    assert _grep_n(p, "junk") == [13]
    assert raw.skipped["line"].tolist()[:1] == [13]
    first = raw.pings.iloc[2]
    assert _grep_n(p, f"^ {round(first['twtt'] * 1000)} msec. Lat: 4 52.9267")[0] == first["line"]


def test_sio_impossible_drop_point_is_an_error_naming_the_line(tmp_path):
    """A drop-point latitude of 123 gave a sound speed of 716,242 m/s with a warning only."""
    p = _sio(tmp_path, lambda ls: [ln.replace("-4.88241", "123") for ln in ls])
    with pytest.raises(InputError, match=r"s.txt line 5: header 'Drop Point \(Latitude\)': "
                                         r"latitude 123 outside"):
        read_survey(p, "obsrange-sio")


def test_whoi_nan_heading_is_skipped_with_the_reason(tmp_path):
    lines = sample_file("obsrange/WHOI_S05.txt").read_text().splitlines()
    lines[18] = lines[18].rsplit(",", 1)[0] + ", nan"
    p = tmp_path / "w.txt"
    p.write_text("\n".join(lines) + "\n")
    raw = read_survey(p, "obsrange-whoi")
    assert raw.skipped["line"].tolist() == [19] and "heading" in raw.skipped["reason"].iloc[0]


def _seagap(tmp_path, edit):
    for name in ("pxp-ini.inp", "tr-ant.inp", "ss_prof.inp"):
        (tmp_path / name).write_text(sample_file(f"seagap/{name}").read_text())
    lines = sample_file("seagap/obsdata.inp").read_text().splitlines()[:200]
    (tmp_path / "obsdata.inp").write_text("\n".join(edit(lines)) + "\n")
    return tmp_path / "obsdata.inp"


@pytest.mark.parametrize(("first_field", "reason"), [
    ("1.7", "transponder '1.7' is not an integer"),
    ("9", "transponder 9 is not in pxp-ini.inp"),
])
def test_seagap_ids_are_exact_and_known(tmp_path, first_field, reason):
    """A transponder '1.7' was truncated to 1; one not in pxp-ini.inp became a NaN ping."""
    def edit(ls):
        ls[4] = first_field + " " + ls[4].split(" ", 1)[1]
        return ls
    raw = read_survey(_seagap(tmp_path, edit), "seagap")
    assert raw.skipped["line"].tolist() == [5] and reason in raw.skipped["reason"].iloc[0]
    assert 5 not in raw.pings["line"].tolist() and len(raw.pings) == 199
