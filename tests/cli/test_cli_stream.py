"""``bayes-mpem stream`` through real pipes and a real UDP socket on 127.0.0.1.

Every test is bounded in lines and time (timeouts on every wait); malformed
lines are mixed into the input, and every line must be answered once, in order.
"""

import contextlib
import json
import signal
import socket
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

from bayes_mpem.cli import main
from bayes_mpem.lbl.navigate import simulate_dive

CMD = [sys.executable, "-c", "import sys; from bayes_mpem.cli import main; sys.exit(main())",
       "stream"]
BAD = ["1,2,3", '{"time": 1, "beacon": "1"', "9,zz,100,0,0,5", '{"time": "x", "x": 0, "y": 0}']


@pytest.fixture(scope="module")
def dive(tmp_path_factory):
    out = tmp_path_factory.mktemp("dive")
    simulate_dive("abe58", rng=11, n_cycles=90).write(out)
    lines = (out / "pings.csv").read_text().splitlines()
    return out, lines


def _mixed(lines, seed=0):
    """The CSV lines with malformed ones inserted; returns (lines, numbers of the bad ones)."""
    gen = np.random.default_rng(seed)
    out, bad = [lines[0]], []
    for i, line in enumerate(lines[1:]):
        if i % 37 == 5:
            out.append(BAD[gen.integers(len(BAD))])
            bad.append(len(out))
        out.append(line)
    return out, bad


def _check_answers(answers, n_lines, bad):
    numbers = [a["line"] for a in answers]
    assert numbers == list(range(2, n_lines + 1))  # every line but the header, once, in order
    for a in answers:
        assert ("error" in a) == (a["line"] in bad)
        if "error" not in a:
            assert {"time", "beacon", "label", "p_dp", "p_mp", "p_ol", "x", "y", "sd_x", "sd_y",
                    "cov_xy"} <= a.keys()


def test_pipe_in_pipe_out_with_malformed_lines(dive, tmp_path):
    folder, lines = dive
    mixed, bad = _mixed(lines)
    proc = subprocess.run([*CMD, "--beacons", str(folder / "beacons.csv"), "--warmup", "100",
                           "--state", str(tmp_path / "s.json")],
                          input="\n".join(mixed) + "\n", capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 0, proc.stderr
    answers = [json.loads(s) for s in proc.stdout.splitlines()]
    _check_answers(answers, len(mixed), bad)
    counts = json.loads(proc.stderr.strip().splitlines()[-1])
    assert counts["read"] == len(mixed) and counts["header"] == 1
    assert counts["answered"] + counts["malformed"] == len(mixed) - 1
    assert counts["malformed"] == len(bad) and counts["phase"] == "online"
    assert json.loads((tmp_path / "s.json").read_text())["phase"] == "online"


def test_json_lines_and_a_restart_from_the_state(dive, tmp_path):
    folder, lines = dive
    cols = lines[0].split(",")
    as_json = [json.dumps(dict(zip(cols, row.split(","), strict=True))) for row in lines[1:]]
    args = [*CMD, "--beacons", str(folder / "beacons.csv"), "--warmup", "100"]
    whole = subprocess.run(args, input="\n".join(as_json), capture_output=True, text=True,
                           timeout=120)
    state = str(tmp_path / "state.json")
    half = len(as_json) // 2
    first = subprocess.run([*args, "--state", state], input="\n".join(as_json[:half]),
                           capture_output=True, text=True, timeout=120)
    second = subprocess.run([*args, "--state", state], input="\n".join(as_json[half:]),
                            capture_output=True, text=True, timeout=120)
    strip = [{k: v for k, v in json.loads(s).items() if k != "line"}
             for s in first.stdout.splitlines() + second.stdout.splitlines()]
    assert strip == [{k: v for k, v in json.loads(s).items() if k != "line"}
                     for s in whole.stdout.splitlines()]


def test_sigterm_mid_stream_answers_what_was_read_and_saves(dive, tmp_path):
    folder, lines = dive
    state = tmp_path / "state.json"
    proc = subprocess.Popen([*CMD, "--beacons", str(folder / "beacons.csv"), "--warmup", "100",
                             "--state", str(state)], stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    watchdog = threading.Timer(90, proc.kill)  # bounds the blocking reads below
    watchdog.start()
    sent = lines[:150]
    proc.stdin.write("\n".join(sent) + "\n")
    proc.stdin.flush()
    got = [proc.stdout.readline() for _ in range(len(sent) - 1)]  # blocks until answered
    proc.send_signal(signal.SIGTERM)  # stdin still open
    out, err = proc.communicate(timeout=30)
    watchdog.cancel()
    assert proc.returncode == 0
    assert all(got) and out == ""
    counts = json.loads(err.strip().splitlines()[-1])
    assert counts["stream"] == "stopped by a signal"
    assert counts["read"] == len(sent) and counts["answered"] == len(sent) - 1
    assert json.loads(state.read_text())["phase"] == "online"


def test_a_reader_that_goes_away_ends_the_stream(dive):
    """The answers' reader closes its end: the stream stops there and says why (the locate
    commands' guard against a broken pipe swallowed it once: 361 lines read to nowhere)."""
    folder, lines = dive
    proc = subprocess.Popen([*CMD, "--beacons", str(folder / "beacons.csv"), "--warmup", "100"],
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    watchdog = threading.Timer(90, proc.kill)
    watchdog.start()
    proc.stdout.close()
    try:
        for line in lines:
            proc.stdin.write(line + "\n")
            proc.stdin.flush()
    except BrokenPipeError:
        pass  # the stream stopped reading: what is asked
    with contextlib.suppress(BrokenPipeError):
        proc.stdin.close()
    err = proc.stderr.read()
    proc.stderr.close()
    assert proc.wait(timeout=60) == 0
    watchdog.cancel()
    counts = json.loads(err.strip().splitlines()[-1])
    assert counts["stream"] == "the reader of the answers went away"
    assert counts["read"] < len(lines)


def test_udp_in_udp_out(dive, tmp_path):
    folder, lines = dive
    mixed, bad = _mixed(lines[:200], seed=1)
    rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    rx.bind(("127.0.0.1", 0))
    rx.settimeout(30)
    proc = subprocess.Popen([*CMD, "--beacons", str(folder / "beacons.csv"), "--warmup", "100",
                             "--in", "udp://127.0.0.1:0",
                             "--out", f"udp://127.0.0.1:{rx.getsockname()[1]}",
                             "--state", str(tmp_path / "s.json")],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        port = int(proc.stderr.readline().strip().rsplit(":", 1)[1])
        tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        answers, t_end = [], time.monotonic() + 60
        for line in mixed:  # one datagram a line, each answered before the next is sent
            tx.sendto(line.encode(), ("127.0.0.1", port))
            if line is not mixed[0]:
                answers.append(json.loads(rx.recv(65535)))
            assert time.monotonic() < t_end
        tx.close()
    finally:
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=30)
        rx.close()
    _check_answers(answers, len(mixed), bad)
    counts = json.loads(err.strip().splitlines()[-1])
    assert counts["read"] == len(mixed) and counts["malformed"] == len(bad)
    assert (tmp_path / "s.json").exists()


def test_a_udp_send_that_fails_is_counted_unsent_and_said(dive, tmp_path, monkeypatch,
                                                          capsys):
    """A datagram ``--out udp://`` could not send was counted ``answered`` (and stopped the
    stream, its counts line saying "end of input"); now ``unsent``, said on standard error,
    and the stream goes on."""
    import errno

    folder, lines = dive
    (tmp_path / "short.csv").write_text("\n".join(lines[:31]) + "\n")
    real, calls = socket.socket.sendto, []

    def flaky(self, data, address):
        calls.append(address)
        if len(calls) in (5, 6, 9):  # two failures in a row, then one more later
            raise OSError(errno.ENETUNREACH, "Network is unreachable")
        return real(self, data, address)

    monkeypatch.setattr(socket.socket, "sendto", flaky)
    rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    rx.bind(("127.0.0.1", 0))
    rx.settimeout(2)
    out = f"udp://127.0.0.1:{rx.getsockname()[1]}"
    try:
        assert main(["stream", "--beacons", str(folder / "beacons.csv"), "--replay",
                     str(tmp_path / "short.csv"), "--speed", "max", "--out", out]) == 0
        received = [json.loads(rx.recv(65535)) for _ in range(27)]
    finally:
        rx.close()
    err = capsys.readouterr().err
    counts = json.loads(err.strip().splitlines()[-1])
    assert counts["stream"] == "end of input" and counts["read"] == 31
    assert counts["answered"] == len(received) == 27 and counts["unsent"] == 3
    assert [a["line"] for a in received] == [n for n in range(2, 32) if n not in (6, 7, 10)]
    said = [s for s in err.splitlines() if "answer not sent" in s]
    assert [s.split(":")[1].strip() for s in said] == ["line 6", "line 10"]
    assert all(out in s and "Network is unreachable" in s for s in said)


def test_replay_and_option_errors(dive, tmp_path, capsys):
    folder, lines = dive
    (tmp_path / "short.csv").write_text("\n".join(lines[:41]) + "\n")
    beacons = str(folder / "beacons.csv")
    t0 = time.monotonic()
    proc = subprocess.run([*CMD, "--beacons", beacons, "--replay", str(tmp_path / "short.csv"),
                           "--speed", "120", "--out", str(tmp_path / "out.jsonl")],
                          capture_output=True, text=True, timeout=120)
    took = time.monotonic() - t0
    assert proc.returncode == 0, proc.stderr
    answers = [json.loads(s) for s in (tmp_path / "out.jsonl").read_text().splitlines()]
    assert [a["line"] for a in answers] == list(range(2, 42))
    assert took > 108.0 / 120  # 10 cycles of 12 s, 120 times faster
    for extra, msg in ((["--speed", "max"], "--speed applies to --replay only"),
                       (["--replay", "x.csv", "--in", "udp://127.0.0.1:0"], "give one source"),
                       (["--in", "pings.csv"], "use --replay for a file"),
                       (["--replay", "x.csv", "--speed", "-2"], "expected realtime, max")):
        assert main(["stream", "--beacons", beacons, *extra]) == 2
        assert msg in capsys.readouterr().err


def test_speed_outside_its_range_is_refused_naming_the_option(dive, tmp_path, capsys):
    """``--speed 1e-10`` crashed after a few lines (OverflowError: timestamp out of range)."""
    folder, lines = dive
    (tmp_path / "short.csv").write_text("\n".join(lines[:9]) + "\n")
    for factor in ("1e-10", "0.0001", "1e7", "0", "nan", "inf", "x"):
        assert main(["stream", "--beacons", str(folder / "beacons.csv"), "--replay",
                     str(tmp_path / "short.csv"), "--speed", factor,
                     "--out", str(tmp_path / "o.jsonl")]) == 2, factor
        err = capsys.readouterr().err
        assert (f"--speed: expected realtime, max or a factor in [0.001, 1e+06] (times faster "
                f"than real time), got {factor!r}") in err, err
        assert "Traceback" not in err and not (tmp_path / "o.jsonl").exists()


def test_udp_addresses_are_checked_before_anything_is_read(dive, tmp_path):
    """An --out host that did not resolve failed on the first answer: the line read, the state
    advanced and saved, the answer lost, the message '[Errno -2] Name or service not known'
    naming no option; --in left an unclosed socket (ResourceWarning)."""
    folder, lines = dive
    state = tmp_path / "s.json"
    dev = [sys.executable, "-X", "dev", *CMD[1:], "--beacons", str(folder / "beacons.csv")]
    cases = {("--out", "udp://nohost.invalid:5"): "expected a host that resolves",
             ("--in", "udp://nohost.invalid:5"): "expected a host that resolves",
             ("--in", "udp://192.0.2.1:5"): "expected an address of this machine",
             ("--out", "udp://127.0.0.1:0"): "expected udp://HOST:PORT (port 1-65535)"}
    for (option, spec), expected in cases.items():
        proc = subprocess.run([*dev, option, spec, "--state", str(state)],
                              input="\n".join(lines[:20]) + "\n", capture_output=True,
                              text=True, timeout=60)
        assert proc.returncode == 2, (option, spec, proc.stderr)
        assert f"error: {option}" in proc.stderr and spec in proc.stderr, proc.stderr
        assert expected in proc.stderr, proc.stderr
        assert '"stream":' not in proc.stderr  # no line read, no counts
        assert "ResourceWarning" not in proc.stderr and "Traceback" not in proc.stderr
        assert not state.exists()  # nothing advanced, nothing saved


def test_the_pings_given_as_beacons_are_named_as_such(dive, capsys):
    """The pings file as --beacons printed a 57-kB list of duplicated ids' lines."""
    folder, _ = dive
    pings = str(folder / "pings.csv")
    assert main(["stream", "--beacons", pings, "--replay", pings]) == 2
    err = capsys.readouterr().err
    assert f"--beacons {pings}: looks like a pings table: it has the columns time and range" in err
    assert "expected one row per beacon with the columns beacon, x, y, depth" in err
    assert len(err) < 400 and "duplicated" not in err
