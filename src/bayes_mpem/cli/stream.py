"""``bayes-mpem stream``: each line is answered by one JSON line, in order (``docs/stream.md``)."""

from __future__ import annotations

import json
import os
import signal
import stat
import sys
import threading
import time
import traceback

from ..exceptions import InputError
from ..lbl.model.paths import PATH_CHOICES
from ..lbl.navigate.options import MULTIPATH
from . import options as opt
from .errors import OptionError

# the library (numpy, pandas) is imported when the command runs, not when the parser is
# built: ``bayes-mpem --help`` loads no heavy module (tests/test_layout.py)

#: The counts printed on exit, in order.
COUNTS = ("read", "answered", "malformed", "header", "blank", "comment", "internal_errors",
          "unsent")


def add_stream(sub) -> None:
    """Add ``stream``'s sub-parser."""
    p = sub.add_parser("stream", help="classify ranges as they arrive and filter the vehicle's "
                                      "position (stdin, UDP or a replayed file; JSON lines out)")
    p.add_argument("--beacons", required=True, metavar="BEACONS",
                   help="beacons CSV (beacon, x, y, depth)")
    p.add_argument("--in", dest="source", default="-", metavar="-|udp://HOST:PORT",
                   help="where pings come from: standard input (default) or a UDP socket")
    p.add_argument("--out", default="-", metavar="-|FILE|udp://HOST:PORT",
                   help="where answers go (default standard output); a FILE is replaced, "
                        "or appended to with --append")
    p.add_argument("--append", action="store_true",
                   help="--out FILE: add the answers at the end of the file instead of "
                        "replacing it (to go on after a --state resume)")
    p.add_argument("--max-gap", type=opt.max_gap, default=None, metavar="S",
                   help="refuse a line timed more than S seconds after the previous one "
                        "(a clock jump or unit slip), instead of adopting its time "
                        "(default 3600; a resumed state keeps its own unless given)")
    p.add_argument("--state", default=None, metavar="FILE",
                   help="resume from this saved state if it exists; save to it on exit")
    p.add_argument("--save-every", type=opt.at_least(0), default=0, metavar="N",
                   help="also save the state every N lines (default 0: on exit only)")
    p.add_argument("--replay", default=None, metavar="PINGS",
                   help="feed a recorded file (CSV or JSON lines) at its own time stamps")
    p.add_argument("--speed", default="realtime", metavar="realtime|max|FACTOR",
                   help="--replay: real time (default), as fast as possible, or FACTOR times "
                        "faster (FACTOR in [0.001, 1e6])")
    p.add_argument("--warmup", type=opt.at_least(3), default=200, metavar="N",
                   help="replies fitted in batch before the online estimator starts "
                        "(default 200)")
    p.add_argument("--alpha", default=1.0, metavar="A",
                   type=opt.number("a step-size exponent in (0.5, 1]", 0.5, 1.0,
                                   include_low=False),
                   help="online-EM step size n^-A, 1/2 < A <= 1 (default 1)")
    p.add_argument("--multipath", choices=MULTIPATH, default="signal",
                   help="multipath replies update the position (default) or are outliers")
    p.add_argument("--path", choices=PATH_CHOICES, default="auto",
                   help="multipath geometry: chosen by the warm-up and revised online "
                        "(default auto), or forced")
    p.add_argument("--dr-noise", type=opt.dr_noise, default=0.1, metavar="Q",
                   help="random-walk level of the dead reckoning, m/sqrt(s) (default 0.1)")
    p.add_argument("--sigma-dp", type=opt.sigma_dp_nav, default=None, metavar="S",
                   help="fix sigma_DP, m (default learned)")
    p.add_argument("--seed", type=opt.seed, default=0, help="seed of the warm-up fit (default 0)")


#: The ``--speed`` factors accepted: slower than a thousandth of real time, one 12-s cycle
#: would take hours; faster than a million times, ``max`` is meant.
SPEED_RANGE = (1e-3, 1e6)


def _speed(text: str):
    if text == "realtime":
        return 1.0
    if text == "max":
        return None
    try:
        v = float(text)
    except ValueError:
        v = float("nan")
    low, high = SPEED_RANGE
    if not low <= v <= high:
        raise OptionError(f"--speed: expected realtime, max or a factor in [{low:g}, {high:g}] "
                          f"(times faster than real time), got {text!r}")
    return v


def _check_beacons(path) -> None:
    """Read ``--beacons``; a pings table given there is named as such (as ``fit`` does)."""
    from ..io.tables import load_table, read_beacons

    try:
        read_beacons(path)
    except InputError as err:
        try:
            frame = load_table(path, None, "beacons").frame
        except (InputError, OSError, ValueError):
            raise err from None
        if not {"time", "range"} <= set(map(str, frame.columns)):
            raise
        raise InputError(f"--beacons {path}: looks like a pings table: it has the columns time "
                         f"and range, and {len(frame)} rows; expected one row per beacon with "
                         "the columns beacon, x, y, depth (the pings go to standard input, "
                         "--in or --replay)") from None


def _navigator(args):
    from ..io.tables import read_beacons
    from ..lbl.navigate.online import Navigator

    _check_beacons(args.beacons)
    if args.state and os.path.exists(args.state):
        try:
            nav = Navigator.load(args.state)
        except InputError as err:
            raise InputError(f"--state: {err} (move the file away to start a new "
                             "stream)") from None
        mine = read_beacons(args.beacons)
        if not (list(mine.index) == list(nav.beacons.index)
                and (mine.to_numpy() == nav.beacons.to_numpy()).all()):
            raise InputError(f"--state {args.state}: its beacons differ from {args.beacons}")
        if args.max_gap is not None:
            nav.options["max_gap"] = args.max_gap
        print(f"resuming from {args.state} (phase {nav.phase}; the saved state's options are "
              "kept)", file=sys.stderr, flush=True)
        return nav
    gap = {} if args.max_gap is None else {"max_gap": args.max_gap}
    return Navigator(args.beacons, warmup=args.warmup, alpha=args.alpha,
                     multipath=args.multipath, path=args.path, dr_noise=args.dr_noise,
                     sigma_dp=args.sigma_dp, rng=args.seed, **gap)


def _source(args, stop, max_gap):
    from ..io.stream import FdLines, ReplayLines, UdpLines, parse_address

    if args.replay is not None:
        if args.source != "-":
            raise OptionError("--replay and --in: give one source")
        speed = _speed(args.speed)
        if not os.path.isfile(args.replay):
            raise InputError(f"--replay {args.replay}: expected a file, got "
                             f"{'a folder' if os.path.isdir(args.replay) else 'no such file'}")
        return ReplayLines(stop, args.replay, speed, max_gap=max_gap)
    if args.speed != "realtime":
        raise OptionError("--speed applies to --replay only")
    kind, where = parse_address(args.source)
    if kind == "udp":
        src = UdpLines(stop, *where)
        host, port = src.address
        print(f"listening on udp://{host}:{port}", file=sys.stderr, flush=True)
        return src
    if kind == "file":
        raise OptionError(f"--in: expected - or udp://HOST:PORT, got {args.source!r} (use "
                          "--replay for a file)")
    return FdLines(stop)


def _answer(nav, parser, n, text):
    """Return line ``n``'s count (a key of :data:`COUNTS`) and JSON answer (None: it gets none).

    The count of a line answered is the caller's to add, once the answer is sent.
    """
    try:
        kind, ping = parser.parse(text, n)
        if kind != "ping":
            return kind, None
        try:
            out = {"line": n, **nav.update(ping).to_dict()}
        except InputError as err:  # the navigator's own checks: say which line
            raise InputError(f"line {n}: {err}") from None
    except InputError as err:
        return "malformed", {"line": n, "error": str(err)}
    except Exception as err:  # noqa: BLE001 - a bug must not stop the stream
        traceback.print_exc(file=sys.stderr)
        return "internal_errors", {"line": n, "error": f"internal error: {type(err).__name__}: "
                                                       f"{err}"}
    return "answered", out


def _send(sink, answer, n, out, failing) -> str | None:
    """Send line ``n``'s answer; return None, or why a UDP datagram could not be sent.

    A failed send to ``udp://`` is said on standard error (once while it keeps failing the
    same way) and the stream goes on; a file or standard output that fails stops it (its
    ``OSError`` raised, :class:`BrokenPipeError` included).

    Parameters
    ----------
    out : str
        ``--out``, for the message.
    failing : str or None
        Why the previous send failed (None: it did not).
    """
    try:
        sink.write(json.dumps(answer, allow_nan=False, separators=(",", ":")))
    except OSError as err:
        if sink.kind != "udp" or isinstance(err, BrokenPipeError):
            raise
        why = str(err)
        if why != failing:
            print(f"bayes-mpem stream: line {n}: answer not sent to {out}: {why} (counted in "
                  "'unsent'; the stream goes on)", file=sys.stderr, flush=True)
        return why
    return None


def _save(nav, path) -> None:
    """Save the state; a state that could not be resumed is not written (the message says so)."""
    try:
        nav.save(path)
    except (InputError, OSError) as err:
        print(f"bayes-mpem stream: error: --state {path}: {err}", file=sys.stderr, flush=True)


def _check_out_is_not_an_input(args) -> None:
    """Refuse an ``--out FILE`` that is one of the inputs: replacing it would empty it first.

    Only a regular file: a terminal or ``/dev/null`` may be both read and written.
    """
    if args.out == "-" or args.out.startswith("udp://"):
        return
    try:
        out = os.stat(args.out)
    except OSError:
        return  # not there yet: nothing to lose
    if not stat.S_ISREG(out.st_mode):
        return  # a terminal, a pipe or /dev/null: writing to it empties nothing
    inputs = [("--beacons", args.beacons), ("--replay", args.replay), ("--state", args.state)]
    for option, path in inputs:
        if path is not None and os.path.exists(path) and os.path.samefile(args.out, path):
            raise OptionError(f"--out {args.out}: the same file as {option} {path}; the answers "
                              "would replace it: give another file")
    if args.replay is None and args.source == "-":
        try:
            stdin = os.fstat(sys.stdin.fileno())
        except (OSError, ValueError):
            return
        if os.path.samestat(stdin, out):
            raise OptionError(f"--out {args.out}: the file standard input reads; the answers "
                              "would replace it: give another file")


def _check_addresses(args) -> None:
    """Resolve ``--in`` and ``--out`` ``udp://HOST:PORT`` before anything is read or loaded."""
    from ..io.stream import parse_address, resolve_udp

    for option, spec in (("--in", args.source), ("--out", args.out)):
        kind, where = parse_address(spec, option=option)
        if kind == "udp":
            resolve_udp(*where, option=option)


def cmd_stream(args) -> int:
    """Run ``bayes-mpem stream`` until the end of the input, SIGTERM or SIGINT (status 0)."""
    if args.save_every < 0:
        raise OptionError(f"--save-every: expected a count >= 0, got {args.save_every}")
    if args.append and (args.out == "-" or args.out.startswith("udp://")):
        raise OptionError(f"--append applies to --out FILE only, got --out {args.out}")
    _check_out_is_not_an_input(args)
    _check_addresses(args)
    from ..io.lines import LineParser
    from ..io.stream import LineSink

    nav = _navigator(args)
    parser = LineParser(nav.beacons.index)
    stop = threading.Event()
    source = _source(args, stop, nav.options["max_gap"])
    try:
        sink = LineSink(args.out, append=args.append)
    except InputError:
        if hasattr(source, "close"):  # a UDP socket already bound
            source.close()
        raise
    counts = dict.fromkeys(COUNTS, 0)
    previous = {s: signal.signal(s, lambda *_: stop.set()) for s in (signal.SIGTERM,
                                                                      signal.SIGINT)}
    t0, why, failing = time.monotonic(), "end of input", None
    try:
        for n, text in source:
            counts["read"] += 1
            kind, answer = _answer(nav, parser, n, text)
            if answer is not None:
                try:
                    failing = _send(sink, answer, n, args.out, failing)
                except OSError:
                    counts["unsent"] += 1  # the line is read, its answer not delivered
                    raise
                kind = kind if failing is None else "unsent"
            counts[kind] += 1
            if args.state and args.save_every and counts["read"] % args.save_every == 0:
                _save(nav, args.state)
        if stop.is_set():
            why = "stopped by a signal"
    except BrokenPipeError:
        why = "the reader of the answers went away"
    except OSError as err:  # --out FILE or standard output: the message is main's
        why = f"the answers could not be written ({err.strerror or err})"
        raise
    finally:
        for s, h in previous.items():
            signal.signal(s, h)
        sink.close()
        if args.state:
            _save(nav, args.state)
        report = {"stream": why, **counts, "incomplete_line": bool(source.partial),
                  "phase": nav.phase, "seconds": round(time.monotonic() - t0, 3),
                  "state": args.state}
        print(json.dumps(report), file=sys.stderr, flush=True)
    return 0
