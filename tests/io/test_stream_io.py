"""The stream's sources and sinks: pipes, UDP datagrams, replayed files."""

import os
import threading
import time

import pytest

from bayes_mpem.exceptions import InputError
from bayes_mpem.io.stream import (
    FdLines,
    LineSink,
    ReplayLines,
    UdpLines,
    parse_address,
    resolve_udp,
)


def test_addresses():
    assert parse_address("udp://localhost:0") == ("udp", ("localhost", 0))
    assert parse_address("out.jsonl") == ("file", "out.jsonl")
    for bad in ("udp://host", "udp://:9", "udp://h:99999", "udp://h:x"):
        with pytest.raises(InputError, match="--in: expected udp://HOST:PORT"):
            parse_address(bad)
    assert parse_address("udp://h:0") == ("udp", ("h", 0))  # listen on any free port
    with pytest.raises(InputError, match=r"--out: expected udp://HOST:PORT \(port 1-65535\)"):
        parse_address("udp://h:0", option="--out")  # but not send there
    assert resolve_udp("127.0.0.1", 5) == ("127.0.0.1", 5)
    with pytest.raises(InputError, match="--out udp://nohost.invalid:5: expected a host that "
                                         "resolves"):
        resolve_udp("nohost.invalid", 5, option="--out")
    with pytest.raises(InputError, match="--out udp://"):
        resolve_udp("a" * 300, 5, option="--out")  # a label over 63 characters


def test_pipe_lines_split_across_reads_and_stop():
    r, w = os.pipe()
    stop = threading.Event()
    src = FdLines(stop, r, poll=0.05)
    os.write(w, b"a,b\nc")
    os.write(w, b"d\r\ne")
    got = []

    def later():
        time.sleep(0.3)
        stop.set()

    threading.Thread(target=later).start()
    got = list(src)
    assert got == [(1, "a,b"), (2, "cd")] and src.partial == b"e"
    os.write(w, b"\n")
    os.close(w)
    src = FdLines(threading.Event(), r, poll=0.05)
    assert list(src) == [(1, "")]  # the end of input ends the source
    os.close(r)


def test_udp_datagrams_and_sink(tmp_path):
    stop = threading.Event()
    src = UdpLines(stop, "127.0.0.1", 0, poll=0.05)
    sink = LineSink(f"udp://127.0.0.1:{src.address[1]}")
    sink.write("one")
    sink.write("two\nthree")
    sink.close()
    got = []
    for item in src:
        got.append(item)
        if len(got) == 3:
            stop.set()
    assert got == [(1, "one"), (2, "two"), (3, "three")]
    f = LineSink(str(tmp_path / "out.jsonl"))
    f.write('{"a": 1}')
    f.close()
    assert (tmp_path / "out.jsonl").read_text() == '{"a": 1}\n'


def test_replay_keeps_the_time_stamps(tmp_path):
    path = tmp_path / "pings.csv"
    path.write_text("time,beacon,range,x,y,depth\n0,1,10,0,0,1\nbad\n0.5,1,10,0,0,1\n"
                    '{"time": 1.0}\n1.0,1,10,0,0,1')
    t0 = time.monotonic()
    lines = list(ReplayLines(threading.Event(), path, speed=2.0))
    took = time.monotonic() - t0
    assert [n for n, _ in lines] == [1, 2, 3, 4, 5, 6] and lines[-1][1] == "1.0,1,10,0,0,1"
    assert 0.45 < took < 5.0  # 1 s of data at twice real time
    t0 = time.monotonic()
    assert len(list(ReplayLines(threading.Event(), path, speed=None))) == 6
    assert time.monotonic() - t0 < 0.4


def test_an_overlong_line_is_answered_once_and_the_next_keeps_its_number():
    from bayes_mpem.io.lines import LineParser
    from bayes_mpem.io.stream import MAX_PARTIAL, _Splitter

    s = _Splitter()
    got = list(s.feed(b"a,b\n" + b"9" * (MAX_PARTIAL + 10)))
    assert [n for n, _ in got] == [1, 2] and s.partial == b""
    got += list(s.feed(b"9" * 100 + b"\nnext\n"))
    assert [(n, t) for n, t in got[2:]] == [(3, "next")]
    parser = LineParser()
    parser.parse("time,beacon,range,x,y,depth", 1)
    with pytest.raises(InputError, match="line 2: expected a line of at most"):
        parser.parse(got[1][1], 2)


@pytest.mark.parametrize(("text", "message"), [
    ('{"a":' + "[" * 30000 + "]" * 30000 + "}", "nested too deeply"),
    ('{"time": 1, "x": 0, "y": 0, "depth": 5, "beacon": [1], "range": 5}', "a beacon id"),
    ('{"t": 1, "x": 0, "y": 0}', "did you mean 't' for 'time'"),
    ("1,2,3", "expected 6 comma-separated fields"),
])
def test_malformed_json_and_csv_lines_are_input_errors(text, message):
    from bayes_mpem.io.lines import LineParser

    parser = LineParser()
    parser.parse("time,beacon,range,x,y,depth", 1)
    with pytest.raises(InputError, match=message):
        parser.parse(text, 2)


def test_replay_schedules_no_deeply_nested_line(tmp_path):
    path = tmp_path / "r.jsonl"
    path.write_text('{"a":' + "[" * 30000 + "]" * 30000 + '}\n{"time": 0, "x": 0, "y": 0}\n')
    lines = list(ReplayLines(threading.Event(), path, 10.0))
    assert [n for n, _ in lines] == [1, 2]


def test_a_line_that_is_not_utf8_is_refused_with_its_column():
    from bayes_mpem.io.lines import LineParser
    from bayes_mpem.io.stream import _Splitter

    lines = list(_Splitter().feed(b"time,beacon,range,x,y,depth\n1,caf\xe9,3,4,5,6\nok\n"))
    assert [n for n, _ in lines] == [1, 2, 3]
    parser = LineParser()
    parser.parse(lines[0][1], 1)
    with pytest.raises(InputError, match=r"line 2, column 6: expected UTF-8 text, got the byte "
                                         r"0xe9"):
        parser.parse(lines[1][1], 2)


def test_a_slow_replay_waits_any_length_and_still_stops(tmp_path):
    """A wait of 1.2e11 s (a 12-s step at 1e-10 of real time) raised OverflowError in
    ``Event.wait``; it is now made of slices, and a stop still ends it."""
    path = tmp_path / "pings.csv"
    path.write_text("time,beacon,range,x,y,depth\n0,1,10,0,0,1\n12,1,10,0,0,1\n")
    stop = threading.Event()
    timer = threading.Timer(0.3, stop.set)
    timer.start()
    t0 = time.monotonic()
    lines = list(ReplayLines(stop, path, speed=1e-10))
    timer.cancel()
    assert [n for n, _ in lines] == [1, 2]  # the line at 12 s is 1.2e11 s away: not released
    assert time.monotonic() - t0 < 5.0


def test_a_line_cut_for_its_length_is_refused_with_what_is_known():
    """A line of 3 or 10 MB was refused with 'got 1111758 characters': how much had been read
    when it was cut, which varied with the reads' sizes; its length is not known."""
    from bayes_mpem.io.lines import LineParser
    from bayes_mpem.io.stream import _Splitter

    messages = set()
    for size in (3_000_000, 10_000_000):
        data = b"time,beacon,range,x,y,depth\n0,1," + b"1" * size + b",0,0,2400\n0,1,9,0,0,1\n"
        for chunk in (65536, 100_000, 1 << 20):
            s = _Splitter()
            got = [item for i in range(0, len(data), chunk) for item in s.feed(data[i:i + chunk])]
            assert [n for n, _ in got] == [1, 2, 3] and got[2][1] == "0,1,9,0,0,1"
            parser = LineParser()
            parser.parse(got[0][1], 1)
            with pytest.raises(InputError) as err:
                parser.parse(got[1][1], 2)
            messages.add(str(err.value))
    assert messages == {"line 2: expected a line of at most 65536 characters, got one longer "
                        "than 1,048,576 bytes (read that far; the rest of it is skipped)"}
