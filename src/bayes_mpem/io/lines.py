"""Pings one line at a time: the line formats of a live stream, validated.

Details: ``docs/stream.md``.
"""

from __future__ import annotations

import csv
import json
import math
import re
from typing import NamedTuple

from ..exceptions import InputError
from .boundary import LIMITS, limit_problem
from .tables import PING_COLUMNS, as_beacon_id

#: Bytes that were not UTF-8, as :func:`bytes.decode` with ``surrogateescape`` keeps them.
_NOT_UTF8 = re.compile("[\udc80-\udcff]")
#: The longest line a stream takes (characters); a longer one is refused on its line.
MAX_LINE = 65536

#: What :meth:`LineParser.parse` says a line is.
KINDS = ("ping", "header", "blank", "comment")


class CutLine(str):
    """The start of a line its reader cut, longer than it keeps (to be refused on its line).

    Its length is not known: only that it is longer than ``limit`` bytes.

    Parameters
    ----------
    text : str
        The start of the line.
    limit : int
        The reader's limit (bytes).

    Examples
    --------
    >>> cut = CutLine("1,2,3", 1 << 20)
    >>> cut.limit, isinstance(cut, str)
    (1048576, True)
    """

    def __new__(cls, text: str, limit: int):
        """Return the cut ``text``, with its reader's ``limit``."""
        self = super().__new__(cls, text)
        self.limit = limit
        return self


class Ping(NamedTuple):
    """One validated input line.

    Attributes
    ----------
    time : float
    beacon : str or None
        None on a dead-reckoning line.
    range : float or None
        One-way range (m); None for no reply or a dead-reckoning line.
    x, y : float
    depth : float or None
    """

    time: float
    beacon: str | None
    range: float | None
    x: float
    y: float
    depth: float | None

    @property
    def kind(self) -> str:
        """``"reply"``, ``"no_reply"`` or ``"dead_reckoning"``."""
        if self.beacon is None:
            return "dead_reckoning"
        return "no_reply" if self.range is None else "reply"


def _number(value, column, where, *, positive=False, optional=False):
    """Return a finite float within :data:`~bayes_mpem.io.boundary.LIMITS` of its column.

    A JSON value or a CSV cell; an :class:`InputError` naming the line and column otherwise.
    """
    missing = value is None or (isinstance(value, str) and not value.strip()) or (
        isinstance(value, float) and math.isnan(value))  # NaN: pandas' missing value
    if missing:
        if optional:
            return None
        raise InputError(f"{where}, column {column!r}: expected a number, got an empty cell")
    try:
        if isinstance(value, bool) or not isinstance(value, (int, float, str)):
            raise ValueError
        if isinstance(value, str) and "_" in value:
            raise ValueError
        v = float(value)
    except (ValueError, OverflowError):
        v = math.nan
    if not math.isfinite(v) or (positive and v <= 0.0):
        what = "a positive number (m)" if positive else "a finite number"
        hint = " or an empty cell for no reply" if column == "range" else ""
        raise InputError(f"{where}, column {column!r}: expected {what}{hint}, got {value!r}")
    lim = LIMITS.get(column)
    if lim is not None and not ((v >= lim.low if lim.include_low else v > lim.low)
                                and v <= lim.high):  # plain floats: no numpy per cell
        problem = limit_problem(column, v)
        if problem is not None:
            raise InputError(f"{where}, column {column!r}: expected a value within the "
                             f"limits of docs/input.md, got {problem}")
    return v


def _missing_keys(values: dict, where: str, beacon) -> None:
    """Refuse a JSON object without a key its line needs, naming the keys it has."""
    needed = ("time", "x", "y") + (("depth",) if beacon is not None else ())
    absent = [k for k in needed if k not in values]
    if not absent:
        return
    import difflib

    have = [str(k) for k in values]
    hints = []
    for k in absent:
        close = difflib.get_close_matches(k, have, n=1, cutoff=0.3)
        close = close or [h for h in have if h and k.startswith(h.lower()) and h not in needed]
        if close:
            hints.append(f"{close[0]!r} for {k!r}?")
    hint = f"; did you mean {' '.join(hints)}" if hints else ""
    raise InputError(f"{where}: expected the key{'s' if len(absent) > 1 else ''} "
                     f"{', '.join(repr(k) for k in absent)}, got the keys "
                     f"{', '.join(repr(k) for k in have[:12]) or 'none'}{hint}")


def make_ping(values: dict, where: str, beacons=None, *, json_keys: bool = False) -> Ping:
    """Validate one line's values into a :class:`Ping`.

    Parameters
    ----------
    values : dict
        Column name to raw value (str, number or None).
    where : str
        For messages (``"line 17"``).
    beacons : collection of str, optional
        Known beacon ids.
    json_keys : bool, default False
        The values are a JSON object's (a missing key named with the likeliest misspelling).

    Returns
    -------
    Ping

    Raises
    ------
    InputError
        A missing or bad value, an unknown beacon, a range on a dead-reckoning line.
    """
    raw_b = values.get("beacon")
    if isinstance(raw_b, (list, dict, bool)):
        raise InputError(f"{where}, column 'beacon': expected a beacon id (text or a whole "
                         f"number), got {json.dumps(raw_b)[:40]}")
    beacon = None if raw_b is None else (as_beacon_id(raw_b) or None)
    if json_keys:
        _missing_keys(values, where, beacon)
    rng = _number(values.get("range"), "range", where, positive=True, optional=True)
    if beacon is None and rng is not None:
        raise InputError(f"{where}, column 'beacon': expected a beacon id for a line with a "
                         f"range, got {raw_b!r}")
    if beacon is not None and beacons is not None and beacon not in beacons:
        known = ", ".join(sorted(beacons)[:10])
        raise InputError(f"{where}, column 'beacon': {beacon!r} is not in the beacons table "
                         f"(known: {known})")
    t = _number(values.get("time"), "time", where)
    x = _number(values.get("x"), "x", where)
    y = _number(values.get("y"), "y", where)
    depth = _number(values.get("depth"), "depth", where, optional=beacon is None)
    return Ping(t, beacon, rng, x, y, depth)


def _no_constant(name):
    """Refuse ``NaN`` and ``Infinity``, which are not JSON."""
    raise ValueError(f"{name} is not a JSON number")


class _RepeatedKey(ValueError):
    """A JSON object naming one key twice (valid JSON, but which value is meant?)."""


def _unique_keys(pairs):
    """``object_pairs_hook``: a key given twice is an error, not the last one kept."""
    obj = {}
    for k, v in pairs:
        if k in obj:
            raise _RepeatedKey(f"expected each key once, got {k!r} twice")
        obj[k] = v
    return obj


def _csv_cells(text: str, where: str) -> list[str]:
    """Split one CSV line into its cells; a malformed line is an :class:`InputError`."""
    for bad, name in (("\r", "a carriage return (\\r)"), ("\x00", "a NUL character")):
        at = text.find(bad)
        if at >= 0:
            raise InputError(f"{where}, column {at + 1}: expected one line of comma-separated "
                             f"fields, got {name} inside it")
    try:
        return next(csv.reader([text], strict=True))
    except csv.Error as err:
        raise InputError(f"{where}: expected comma-separated fields, got a malformed CSV line "
                         f"({err})") from None


class LineParser:
    """Turns lines into pings; remembers the CSV header.

    Parameters
    ----------
    beacons : collection of str, optional
        Known beacon ids (a ping of another beacon is an error).

    Attributes
    ----------
    header : list of str or None
        The CSV columns, once a header line has been read.
    """

    def __init__(self, beacons=None):
        self.beacons = None if beacons is None else frozenset(beacons)
        self.header = None

    def parse(self, text: str, line_no: int):
        """Classify and parse one line (``line_no`` from 1, for messages).

        Parameters
        ----------
        text : str
        line_no : int

        Returns
        -------
        kind : str
            One of :data:`KINDS`.
        ping : Ping or None

        Raises
        ------
        InputError
            A malformed line (the parser's state is unchanged).
        """
        where = f"line {line_no}"
        if isinstance(text, CutLine):  # its length is not known, only that it is too long
            raise InputError(f"{where}: expected a line of at most {MAX_LINE} characters, got "
                             f"one longer than {text.limit:,} bytes (read that far; the rest "
                             "of it is skipped)")
        if line_no == 1:  # a byte-order mark opens some files saved on Windows: not data
            text = text.removeprefix("\ufeff")
        s = text.strip()
        if len(s) > MAX_LINE:
            raise InputError(f"{where}: expected a line of at most {MAX_LINE} characters, got "
                             f"{len(s)}")
        bad = _NOT_UTF8.search(s)
        if bad is not None:
            byte = ord(bad.group()) - 0xDC00
            raise InputError(f"{where}, column {len(text) - len(text.lstrip()) + bad.start() + 1}:"
                             f" expected UTF-8 text, got the byte 0x{byte:02x}")
        if not s:
            return "blank", None
        if s.startswith("#"):
            return "comment", None
        if s.startswith("{"):
            try:
                obj = json.loads(s, parse_constant=_no_constant, object_pairs_hook=_unique_keys)
            except _RepeatedKey as err:
                raise InputError(f"{where}: {err}") from None
            except ValueError as err:
                at = f" at column {err.colno}" if hasattr(err, "colno") else ""
                raise InputError(f"{where}: expected a JSON object, got invalid JSON "
                                 f"({getattr(err, 'msg', err)}{at})") from None
            except RecursionError:
                raise InputError(f"{where}: expected a flat JSON object, got one nested too "
                                 "deeply") from None
            if not isinstance(obj, dict):  # pragma: no cover - "{" starts an object
                raise InputError(f"{where}: expected a JSON object")
            return "ping", make_ping(obj, where, self.beacons, json_keys=True)
        cells = _csv_cells(s, where)
        if self.header is None:
            return "header", self._set_header(cells, where)
        if len(cells) != len(self.header):
            raise InputError(f"{where}: expected {len(self.header)} comma-separated fields "
                             f"(the header's), got {len(cells)}")
        return "ping", make_ping(dict(zip(self.header, cells, strict=True)), where,
                                 self.beacons)

    def _set_header(self, cells, where):
        names = [c.strip() for c in cells]
        missing = [c for c in PING_COLUMNS if c not in names]
        if missing:
            raise InputError(f"{where}: expected a CSV header with the columns "
                             f"{', '.join(PING_COLUMNS)} (or a JSON object), got {cells!r}; "
                             f"missing {', '.join(missing)}")
        self.header = names
        return None
