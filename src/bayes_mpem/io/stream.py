"""Where a live stream's lines come from and where the answers go."""

from __future__ import annotations

import csv
import json
import math
import os
import select
import socket
import sys
import time

from ..exceptions import InputError
from .boundary import out_of_limits
from .lines import MAX_LINE, CutLine

#: The longest unfinished line kept (bytes); a longer one is passed on, cut, to be refused
#: on its line, and the rest of it up to the next newline dropped.
MAX_PARTIAL = 1 << 20

#: Largest datagram read (bytes).
MAX_DATAGRAM = 65535

#: The longest single wait of a replay (s); a longer one is made of several.
MAX_WAIT = 3600.0


def parse_address(spec: str, *, option: str = "--in"):
    """Split ``-``, ``udp://HOST:PORT`` or a file path into ``(kind, where)``.

    Parameters
    ----------
    spec : str
    option : str
        The option's name, for messages.

    Returns
    -------
    kind : {"stdio", "udp", "file"}
    where : None, (str, int) or str

    Raises
    ------
    InputError
    """
    if spec == "-":
        return "stdio", None
    if spec.startswith("udp://"):
        host, sep, port = spec[len("udp://"):].rpartition(":")
        low = 1 if option == "--out" else 0  # answers cannot be sent to port 0
        if not sep or not host or not port.isdigit() or not low <= int(port) <= 65535:
            raise InputError(f"{option}: expected udp://HOST:PORT (port {low}-65535), got "
                             f"{spec!r}")
        return "udp", (host, int(port))
    return "file", spec


def resolve_udp(host: str, port: int, *, option: str = "--in"):
    """Return the IPv4 socket address of ``host:port``, resolved before any line is read.

    Parameters
    ----------
    host : str
    port : int
    option : str
        The option's name, for messages.

    Returns
    -------
    tuple of (str, int)

    Raises
    ------
    InputError
        The host does not resolve (an IPv4 address or a name that does).
    """
    try:
        infos = socket.getaddrinfo(host, port, socket.AF_INET, socket.SOCK_DGRAM)
    except (OSError, UnicodeError) as err:
        why = getattr(err, "strerror", None) or str(err)
        raise InputError(f"{option} udp://{host}:{port}: expected a host that resolves to an "
                         f"IPv4 address, got {host!r} ({why})") from None
    return infos[0][4]


class _Splitter:
    """Turns chunks of bytes into numbered lines; keeps the unfinished end."""

    def __init__(self):
        self.n, self.partial, self._skip = 0, b"", False

    def feed(self, data: bytes, *, final: bool = False):
        data = self.partial + data
        *lines, self.partial = data.split(b"\n")
        if self._skip and lines:  # the rest of an overlong line already answered
            lines.pop(0)
            self._skip = False
        cut = None
        if len(self.partial) > MAX_PARTIAL and not self._skip:
            cut = self.partial[:MAX_LINE + 1]  # answered (refused for its length) at once
            self.partial, self._skip = b"", True
        elif self._skip:
            self.partial = b""
        if final and self.partial:
            lines.append(self.partial)
            self.partial = b""
        for raw in lines:
            self.n += 1
            # bytes that are not UTF-8 stay visible (as surrogates) for the parser to refuse
            text = raw.decode("utf-8", errors="surrogateescape")
            yield self.n, text[:-1] if text.endswith("\r") else text
        if cut is not None:
            self.n += 1
            yield self.n, CutLine(cut.decode("utf-8", errors="surrogateescape"), MAX_PARTIAL)


class FdLines:
    """Lines read from a file descriptor (standard input by default).

    Parameters
    ----------
    stop : threading.Event
    fd : int, optional
        Default ``sys.stdin``'s.
    poll : float, default 0.2
        Seconds between looks at ``stop`` while nothing arrives.
    """

    def __init__(self, stop, fd=None, poll=0.2):
        self.stop, self.poll = stop, poll
        self.fd = sys.stdin.fileno() if fd is None else fd
        self._split = _Splitter()

    @property
    def partial(self) -> bytes:
        """The unfinished end of a line when the source stopped."""
        return self._split.partial

    def __iter__(self):
        """Yield ``(line_number, text)`` until the end of the input or a stop."""
        while not self.stop.is_set():
            ready, _, _ = select.select([self.fd], [], [], self.poll)
            if not ready:
                continue
            data = os.read(self.fd, 65536)
            if not data:
                yield from self._split.feed(b"", final=True)
                return
            yield from self._split.feed(data)


class UdpLines:
    """Lines from UDP datagrams on ``host:port`` (a datagram ends its last line).

    Parameters
    ----------
    stop : threading.Event
    host : str
    port : int
        0 picks a free port (:attr:`address` says which).
    poll : float, default 0.2
    """

    partial = b""

    def __init__(self, stop, host, port, poll=0.2):
        self.stop, self.poll = stop, poll
        where = resolve_udp(host, port, option="--in")
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            self.sock.bind(where)
        except OSError as err:
            self.sock.close()
            raise InputError(f"--in udp://{host}:{port}: expected an address of this machine "
                             f"and a free port to listen on ({err.strerror or err})") from None
        self.sock.settimeout(poll)
        self._split = _Splitter()

    def close(self) -> None:
        """Close the socket (when the stream ends before reading from it)."""
        self.sock.close()

    @property
    def address(self):
        """``(host, port)`` the socket is bound to."""
        return self.sock.getsockname()

    def __iter__(self):
        """Yield ``(line_number, text)`` until a stop; then close the socket."""
        try:
            while not self.stop.is_set():
                try:
                    data = self.sock.recv(MAX_DATAGRAM)
                except TimeoutError:
                    continue
                yield from self._split.feed(data, final=True)
        finally:
            self.sock.close()


def _line_time(text: str, header):
    """Return the ``time`` of a line, or None (a header, or a line too malformed to schedule).

    A time outside :data:`~bayes_mpem.io.boundary.LIMITS` is None: the line is
    released at once, to be refused on its line by the parser.
    """
    s = text.strip()
    try:
        if s.startswith("{"):
            t = float(json.loads(s)["time"])
        else:
            cells = next(csv.reader([s], strict=True)) if s else []
            if not cells or s.startswith("#"):
                return None, header
            if header is None:
                names = [c.strip() for c in cells]
                return None, (names.index("time") if "time" in names else None)
            t = float(cells[header])
    except (ValueError, KeyError, IndexError, TypeError, OverflowError, RecursionError,
            csv.Error):
        return None, header
    return (None if out_of_limits("time", t).item() else t), header


class ReplayLines:
    """A recorded file's lines, each released at its time stamp.

    Parameters
    ----------
    stop : threading.Event
    path : str or pathlib.Path
    speed : float or None
        ``1`` real time, ``k`` k times faster, None as fast as possible.
    max_gap : float, default inf
        A line timed more than this after the last one, or before it, is released at once.
    """

    partial = b""

    def __init__(self, stop, path, speed, max_gap=math.inf):
        self.stop, self.path, self.speed, self.max_gap = stop, path, speed, max_gap

    def _wait_until(self, when: float) -> bool:
        """Wait until ``time.monotonic()`` reaches ``when``; True if stopped meanwhile.

        The wait goes by slices of at most :data:`MAX_WAIT` seconds: a slow ``speed``
        times a long gap may exceed what :meth:`threading.Event.wait` takes.
        """
        while (wait := when - time.monotonic()) > 0:
            if self.stop.wait(min(wait, MAX_WAIT)):
                return True
        return False

    def __iter__(self):
        """Yield ``(line_number, text)``, each line at its time, until the end or a stop."""
        header, t0, w0, last = None, None, None, None
        try:
            fh = open(self.path, "rb")  # noqa: SIM115 - closed below
        except IsADirectoryError:
            raise InputError(f"--replay {self.path}: a folder; expected a file") from None
        except FileNotFoundError:
            raise InputError(f"--replay {self.path}: no such file") from None
        with fh:
            split = _Splitter()
            for chunk in iter(lambda: fh.read(1 << 16), b""):
                for n, text in split.feed(chunk):
                    if self.stop.is_set():
                        return
                    t, header = _line_time(text, header)
                    if last is not None and t is not None and not (
                            last <= t <= last + self.max_gap):
                        t = None
                    if self.speed is not None and t is not None:
                        if t0 is None:
                            t0, w0 = t, time.monotonic()
                        if self._wait_until(w0 + (t - t0) / self.speed):
                            return
                    if t is not None:
                        last = t
                    yield n, text
            yield from split.feed(b"", final=True)


class LineSink:
    """Writes one answer per line, flushed at once.

    Parameters
    ----------
    spec : str
        ``-`` (standard output), a file path, or ``udp://HOST:PORT``.
    append : bool, default False

    Raises
    ------
    InputError
    """

    def __init__(self, spec: str, *, append: bool = False):
        kind, where = parse_address(spec, option="--out")
        self.kind, self._sock, self._fh = kind, None, None
        if kind == "udp":
            self._dest = resolve_udp(*where, option="--out")
            self._sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        elif kind == "file":
            try:
                self._fh = open(where, "a" if append else "w",  # noqa: SIM115 - close()
                                encoding="utf-8")
            except OSError as err:
                raise InputError(f"--out {where}: cannot be written "
                                 f"({err.strerror or err})") from None
        else:
            self._fh = sys.stdout

    def write(self, text: str) -> None:
        """Send one line (``text`` without its newline).

        Parameters
        ----------
        text : str
        """
        if self._sock is not None:
            self._sock.sendto(text.encode("utf-8"), self._dest)
            return
        self._fh.write(text + "\n")
        self._fh.flush()

    def close(self) -> None:
        """Close a file or socket (never standard output)."""
        if self._sock is not None:
            self._sock.close()
        elif self.kind == "file":
            self._fh.close()
