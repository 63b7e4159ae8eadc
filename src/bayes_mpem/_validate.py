"""Validators of options and scalar arguments (``name``: the argument's, for messages)."""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import Any

import numpy as np


def _as_float(value: Any) -> float | None:
    """``float(value)`` for a real number (not a bool); None for anything else."""
    if isinstance(value, (bool, np.bool_)):
        return None
    try:
        return float(value)
    except (TypeError, ValueError):
        return None


def check_positive(name: str, value: Any, *, allow_none: bool = False,
                   what: str | None = None) -> float | None:
    """Check a finite number > 0; return it as ``float``.

    Parameters
    ----------
    allow_none : bool, default False
        Accept ``None`` (and return it).
    what : str, optional
        What the message says is expected.

    Raises
    ------
    ValueError
    """
    if value is None and allow_none:
        return None
    v = _as_float(value)
    if v is None or not (math.isfinite(v) and v > 0):
        if what is None:
            what = "a positive number" + (" or None" if allow_none else "")
        raise ValueError(f"{name}: expected {what}, got {value!r}")
    return v


def check_finite(name: str, value: Any) -> float:
    """Check a finite number; return it as ``float``.

    Raises
    ------
    ValueError
    """
    v = _as_float(value)
    if v is None or not math.isfinite(v):
        raise ValueError(f"{name}: expected a finite number, got {value!r}")
    return v


def check_probability(name: str, value: Any, *, open_interval: bool = True) -> float:
    """Check a probability, in ``(0, 1)`` (default) or in ``[0, 1]``; return it as ``float``.

    Raises
    ------
    ValueError
    """
    v = _as_float(value)
    ok = v is not None and ((0.0 < v < 1.0) if open_interval else (0.0 <= v <= 1.0))
    if not ok:
        interval = "(0, 1)" if open_interval else "[0, 1]"
        raise ValueError(f"{name}: expected a probability in {interval}, got {value!r}")
    return v


#: Least probability of an interval from draws (``sample``, ``locate --sample``): below it the
#: highest-density interval holds a few draws and sits on those the sampler repeated (a 1 %
#: interval of zero width half an sd from the mean; 0.01 % at the smallest draw).
MIN_SAMPLED_CI = 0.5


def check_sampled_ci(value: Any) -> float:
    """Check the probability of intervals from draws, in ``[MIN_SAMPLED_CI, 1)``.

    Raises
    ------
    ValueError
    """
    v = check_probability("ci", value)
    if v < MIN_SAMPLED_CI:
        raise ValueError(f"ci: expected a probability in [{MIN_SAMPLED_CI:g}, 1) for intervals "
                         f"from draws, got {value!r} (below {MIN_SAMPLED_CI:g} a highest-density "
                         "interval holds a few draws and sits on those the sampler repeated)")
    return v


def check_choice(name: str, value: Any, choices: Iterable, *, words: bool = False) -> Any:
    """Check that ``value`` is one of ``choices``; return it unchanged.

    Parameters
    ----------
    words : bool, default False
        Spell the choices out (``expected 'a', 'b' or 'c'``) instead of a tuple.

    Raises
    ------
    ValueError
    """
    choices = tuple(choices)
    try:
        ok = value in choices
    except TypeError:
        ok = False
    if not ok:
        listed = [repr(c) for c in choices]
        what = (f"one of {choices}" if not words or len(listed) < 2
                else f"{', '.join(listed[:-1])} or {listed[-1]}")
        raise ValueError(f"{name}: expected {what}, got {value!r}")
    return value


def check_int(name: str, value: Any, *, minimum: int) -> int:
    """Check an integer (Python or NumPy, not a bool or a float) ``>= minimum``; return an ``int``.

    Raises
    ------
    ValueError
    """
    if (isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer))
            or value < minimum):
        raise ValueError(f"{name}: expected an integer >= {minimum}, got {value!r}")
    return int(value)


def check_range(name: str, value: Any, *, low: float | None = None, high: float | None = None,
                include_low: bool = False, include_high: bool = False) -> float:
    """Check a number (not NaN) between ``low`` and ``high``; return it as ``float``.

    Parameters
    ----------
    low, high : float, optional
        The bounds; ``None`` for none.

    Raises
    ------
    ValueError
    """
    v = _as_float(value)
    ok = v is not None and not math.isnan(v)
    if ok and low is not None:
        ok = v >= low if include_low else v > low
    if ok and high is not None:
        ok = v <= high if include_high else v < high
    if not ok:
        if low is not None and high is not None:
            what = (f"a number in {'[' if include_low else '('}{low}, "
                    f"{high}{']' if include_high else ')'}")
        elif low is not None:
            what = f"a number {'>=' if include_low else '>'} {low}"
        elif high is not None:
            what = f"a number {'<=' if include_high else '<'} {high}"
        else:
            what = "a number"
        raise ValueError(f"{name}: expected {what}, got {value!r}")
    return v


def check_increasing(name: str, values: Any, *, context: str = "",
                     what: str = "strictly increasing values") -> np.ndarray:
    """Check that a 1-D array of numbers is strictly increasing; return it as floats.

    Parameters
    ----------
    context : str, optional
        Put before the name (``"SoundSpeedProfile: "``).

    Raises
    ------
    ValueError
        Naming the first element not greater than the one before.
    """
    arr = np.asarray(values, dtype=float)
    bad = np.flatnonzero(np.diff(arr) <= 0)
    if bad.size:
        i = bad[0] + 1
        raise ValueError(f"{context}{name}[{i}] = {arr[i]} is not greater than {name}[{i - 1}] = "
                         f"{arr[i - 1]}: expected {what}")
    return arr
