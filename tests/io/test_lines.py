"""One line at a time: CSV with a header or JSON, validated with the line and column named."""

import pytest

from bayes_mpem.exceptions import InputError
from bayes_mpem.io.lines import LineParser, Ping, make_ping


def test_csv_json_no_reply_and_dead_reckoning():
    p = LineParser({"1", "2"})
    assert p.parse("", 1) == ("blank", None)
    assert p.parse("# a comment", 2) == ("comment", None)
    assert p.parse("depth,time,beacon,range,x,y,extra", 3) == ("header", None)
    assert p.parse("2440,12,1,2875.5,10,20,foo", 4)[1] == Ping(12.0, "1", 2875.5, 10.0, 20.0,
                                                               2440.0)
    assert p.parse("2440,13,2,,10,20,", 5)[1].kind == "no_reply"
    assert p.parse(",14,,,11,20,", 6)[1] == Ping(14.0, None, None, 11.0, 20.0, None)
    ping = p.parse('{"time": 15, "beacon": 2, "range": "100.5", "x": 1, "y": 2, "depth": 3}',
                   7)[1]
    assert ping == Ping(15.0, "2", 100.5, 1.0, 2.0, 3.0) and ping.kind == "reply"
    assert p.parse('{"time": 16, "beacon": "1", "range": null, "x": 1, "y": 2, "depth": 3}',
                   8)[1].kind == "no_reply"


@pytest.mark.parametrize(("line", "match"), [
    ("1,1,-3,0,0,5", r"line 9, column 'range': expected a positive number \(m\) or an empty"),
    ("1,1,nan,0,0,5", "column 'range'"),
    ("1,1,1_000,0,0,5", "column 'range'"),
    ("x,1,10,0,0,5", "column 'time': expected a finite number"),
    ("1,7,10,0,0,5", "'7' is not in the beacons table"),
    ("1,1,10,0,0", "expected 6 comma-separated fields"),
    ("1,,10,0,0,5", "expected a beacon id for a line with a range"),
    ("1,1,10,0,0,", "column 'depth': expected a number, got an empty cell"),
    ('{"time": 1, "beacon": "1", "range": 10, "x": 0, "y": 0', "invalid JSON"),
    ('{"time": true, "beacon": "1", "range": 10, "x": 0, "y": 0, "depth": 1}', "column 'time'"),
    ('{"time": 1, "beacon": "1", "range": NaN, "x": 0, "y": 0, "depth": 1}', "NaN is not a JSON"),
])
def test_malformed_lines_say_where_and_what(line, match):
    p = LineParser({"1"})
    p.parse("time,beacon,range,x,y,depth", 1)
    with pytest.raises(InputError, match=match):
        p.parse(line, 9)
    assert p.header == ["time", "beacon", "range", "x", "y", "depth"]


def test_a_header_without_the_columns_is_refused():
    p = LineParser()
    with pytest.raises(InputError, match="missing range"):
        p.parse("time,beacon,x,y,depth", 1)
    assert p.header is None
    with pytest.raises(InputError, match="line 2, column 'x'"):
        make_ping({"time": 1, "x": "?", "y": 0}, "line 2")
    # a float NaN (pandas' missing value) is an empty cell: no reply
    assert make_ping({"time": 1, "beacon": "1", "range": float("nan"), "x": 0, "y": 0,
                      "depth": 1}, "row 1").kind == "no_reply"


def test_a_byte_order_mark_opening_the_stream_is_not_data():
    """A byte-order mark opening the stream is skipped, as in every file reader."""
    p = LineParser(["1"])
    assert p.parse("\ufefftime,beacon,range,x,y,depth", 1) == ("header", None)
    kind, ping = p.parse("10,1,500,0,0,5", 2)
    assert kind == "ping" and ping.range == 500.0
    j = LineParser(["1"])
    kind, ping = j.parse('\ufeff{"time": 10, "beacon": "1", "range": 500, "x": 0, "y": 0, '
                         '"depth": 5}', 1)
    assert kind == "ping"
    with pytest.raises(InputError, match="line 3"):  # not the first line: not a BOM to drop
        p.parse("\ufeff10,1,500,0,0,5", 3)


def test_a_json_key_given_twice_is_refused():
    """Not the last value kept silently."""
    p = LineParser(["1"])
    with pytest.raises(InputError, match=r"^line 4: expected each key once, got 'range' twice$"):
        p.parse('{"time": 10, "beacon": "1", "range": 500, "range": 600, "x": 0, "y": 0, '
                '"depth": 5}', 4)
