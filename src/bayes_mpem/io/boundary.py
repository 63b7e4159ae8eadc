"""The input boundary every reader passes: lines as ``grep -n`` counts them, shapes, limits.

Details: ``docs/input.md``.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..exceptions import InputError

__all__ = ["COMMENT", "LIMITS", "Limit", "Shape", "classify", "limit_problem", "open_input",
           "out_of_limits", "read_text_lines", "sniff_delimiter", "split_lines"]


@dataclass(frozen=True)
class Limit:
    """The physically possible interval of one kind of value.

    Attributes
    ----------
    what, unit : str
        Name and unit in messages.
    low, high : float
    include_low : bool
        Whether ``low`` itself is possible.
    """

    what: str
    unit: str
    low: float
    high: float
    include_low: bool = True

    def describe(self) -> str:
        """Return the interval as text, e.g. ``"(0, 100000] m"``."""
        return (f"{'[' if self.include_low else '('}{self.low:g}, {self.high:g}] "
                f"{self.unit}")


#: The ceilings of every value the readers accept (docs/input.md lists them). Ranges are
#: one-way, travel times two-way; 100 km is beyond any acoustic positioning geometry (the
#: ocean's deepest point is 11 km; LBL baselines are a few km), so a larger value is a unit
#: or a parsing error, not a range. Coordinates are local metres from the survey's origin.
LIMITS = {
    "range": Limit("range", "m", 0.0, 1.0e5, include_low=False),
    "twtt": Limit("two-way travel time", "s", 0.0, 150.0, include_low=False),
    "x": Limit("x", "m", -1.0e7, 1.0e7),
    "y": Limit("y", "m", -1.0e7, 1.0e7),
    "east": Limit("east", "m", -1.0e7, 1.0e7),
    "north": Limit("north", "m", -1.0e7, 1.0e7),
    "depth": Limit("depth", "m", -1.0e3, 1.1e4),
    "up": Limit("up", "m", -1.1e4, 1.0e3),
    "time": Limit("time", "s", -1.0e10, 1.0e10),
    "lat": Limit("latitude", "degrees", -90.0, 90.0),
    "lon": Limit("longitude", "degrees", -180.0, 180.0),
    "minutes": Limit("arc-minutes", "minutes", 0.0, 60.0),
    "heading": Limit("heading", "degrees", -1.0e5, 1.0e5),  # SeaGap unwraps its heading
    "angle": Limit("attitude angle", "degrees", -360.0, 360.0),
    "sound_speed": Limit("sound speed", "m/s", 1300.0, 1800.0),
    "tat": Limit("turn-around time", "s", 0.0, 10.0),
    "ve": Limit("velocity east", "m/s", -100.0, 100.0),
    "vn": Limit("velocity north", "m/s", -100.0, 100.0),
}


def out_of_limits(kind: str, values) -> np.ndarray:
    """Mask of values that are not finite or outside ``LIMITS[kind]`` (vectorised).

    Parameters
    ----------
    kind : str
        A key of :data:`LIMITS`.
    """
    lim = LIMITS[kind]
    v = np.asarray(values, dtype=float)
    with np.errstate(invalid="ignore"):
        ok = (v >= lim.low) if lim.include_low else (v > lim.low)
        ok &= v <= lim.high
    return ~ok  # NaN compares False: out


def limit_problem(kind: str, value) -> str | None:
    """Why one value is unusable (``None`` when it is fine).

    E.g. ``"range 1e+300 outside (0, 100000] m"``.
    """
    lim = LIMITS[kind]
    v = float(value)
    if not math.isfinite(v):
        return f"{lim.what} is {v!r}, not a finite number"
    if out_of_limits(kind, v).item():
        return f"{lim.what} {v:g} outside {lim.describe()}"
    return None


# --------------------------------------------------------------------------- text lines


def open_input(path, what: str = "input file") -> bytes:
    """Read a file's bytes, turning every way it can fail into a clear error.

    Parameters
    ----------
    what : str, default "input file"
        What the file is, for the messages.

    Raises
    ------
    FileNotFoundError, InputError
    """
    p = Path(path)
    if p.is_dir():
        raise InputError(f"{what} {str(path)!r} is a folder; expected a file")
    if not p.exists():
        raise FileNotFoundError(f"{what} not found: {str(path)!r}")
    try:
        return p.read_bytes()
    except OSError as exc:
        raise InputError(f"{what} {str(path)!r} cannot be read: {exc.strerror or exc}") from None


def split_lines(text: str) -> list[str]:
    r"""Split text into lines as ``grep -n`` numbers them: only ``\n`` (or ``\r\n``) ends a line."""
    lines = text.split("\n")
    if lines and lines[-1] == "":
        lines.pop()
    return [ln[:-1] if ln.endswith("\r") else ln for ln in lines]


def read_text_lines(path, what: str = "survey file") -> list[str]:
    """Read a UTF-8 text file as lines numbered as ``grep -n`` numbers them (:func:`split_lines`).

    Raises
    ------
    FileNotFoundError, InputError
        No file; a folder, an unreadable or binary file, or bytes that are not UTF-8.
    """
    raw = open_input(path, what)
    if raw.startswith(b"\xef\xbb\xbf"):
        raw = raw[3:]
    if b"\x00" in raw:
        line = raw.count(b"\n", 0, raw.index(b"\x00")) + 1
        raise InputError(f"{path} line {line}: a NUL byte; expected a text file, not binary")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = raw.count(b"\n", 0, exc.start) + 1
        raise InputError(f"{path} line {line}: not UTF-8 text ({exc.reason})") from None
    return split_lines(text)


# --------------------------------------------------------------------------- shapes


@dataclass(frozen=True)
class Shape:
    """One kind of line, recognised by its whole text.

    Attributes
    ----------
    kind : str
        What such a line is (``"ping"``, ``"header"``, ``"comment"``, ``"event"``).
    pattern : str
        A regular expression the stripped line must match whole; its named groups are fields.
    """

    kind: str
    pattern: str

    def match(self, text: str):
        """Match the stripped ``text``; ``None`` when it has another shape."""
        return _compiled(self.pattern).fullmatch(text.strip())


_CACHE: dict[str, re.Pattern] = {}


def _compiled(pattern: str) -> re.Pattern:
    if pattern not in _CACHE:
        _CACHE[pattern] = re.compile(pattern)
    return _CACHE[pattern]


#: A comment line: ``#`` first (after spaces), anything after.
COMMENT = Shape("comment", r"#.*")
#: A blank line (spaces, tabs, form feeds only).
BLANK = Shape("blank", r"")


def classify(lines, shapes):
    r"""Give every line the kind of the first shape it has.

    Parameters
    ----------
    shapes : sequence of Shape
        Tried in order (blank lines are recognised first).

    Returns
    -------
    list of tuple
        ``(line number, kind or None, match or None)``, 1-based.
    """
    out = []
    for i, text in enumerate(lines, start=1):
        if not text.strip():
            out.append((i, BLANK.kind, None))
            continue
        for shape in shapes:
            m = shape.match(text)
            if m is not None:
                out.append((i, shape.kind, m))
                break
        else:
            out.append((i, None, None))
    return out


def sniff_delimiter(header: str, first_row: str | None = None) -> str | None:
    """Say what a table's first lines look like when they are not comma-separated values.

    Parameters
    ----------
    first_row : str, optional
        The first data line, to spot decimal commas.

    Returns
    -------
    str or None
        ``None`` when the header has commas.
    """
    if "," in header:
        return None
    for sep, name in ((";", "semicolon-separated"), ("\t", "tab-separated"),
                      ("|", "pipe-separated")):
        if sep in header:
            decimal = first_row is not None and re.search(r"\d,\d", first_row)
            return name + (", with decimal commas" if decimal else "")
    if len(header.split()) > 1:
        return "separated by spaces"
    return None
