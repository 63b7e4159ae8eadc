"""Checked values of text fields, and where they came from (file, line, column)."""

from __future__ import annotations

import math


def where(source, line=None, column=None, name=None) -> str:
    """Name a place in a file: ``"FILE line L, column C (NAME)"`` (1-based)."""
    out = str(source)
    if line is not None:
        out += f" line {line}"
    if column is not None:
        out += f", column {column}"
    if name is not None:
        out += f" ({name})"
    return out


def number(text, name, *, lo=None, hi=None, lo_open=False, integer=False) -> float:
    """Parse one numeric field and check that it is finite and in range.

    Parameters
    ----------
    text, name : str
        The field as read, and what it is.
    lo, hi : float, optional
        Bounds, inclusive (``lo_open=True`` excludes ``lo``).
    integer : bool, default False
        Require a whole number.

    Raises
    ------
    ValueError
        Naming the field, the range expected and the text that arrived.
    """
    lo_s = "-inf" if lo is None else f"{lo:g}"
    hi_s = "inf" if hi is None else f"{hi:g}"
    left = "(" if lo_open or lo is None else "["
    right = "]" if hi is not None else ")"
    expected = (f"expected {'a whole number' if integer else 'a number'} in "
                f"{left}{lo_s}, {hi_s}{right}")
    try:
        if "_" in str(text):  # float() takes 1_000 and 2.5_0; a file's numbers do not
            raise ValueError
        v = float(str(text).strip())
    except ValueError:
        raise ValueError(f"{name}: {expected}, got {str(text).strip()!r}") from None
    if (not math.isfinite(v) or (lo is not None and (v <= lo if lo_open else v < lo))
            or (hi is not None and v > hi) or (integer and v != round(v))):
        raise ValueError(f"{name}: {expected}, got {str(text).strip()!r}")
    return v


def flag(text, name) -> bool:
    """Parse a true/false field (``True``/``False``, ``1``/``0``, any case).

    Raises
    ------
    ValueError
    """
    s = str(text).strip().lower()
    if s in ("true", "1"):
        return True
    if s in ("false", "0"):
        return False
    raise ValueError(f"{name}: expected True or False, got {str(text).strip()!r}")
