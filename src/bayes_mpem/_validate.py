"""Small validators for options and scalar arguments, in one message style.

Every check raises ``ValueError`` with the message
``"<name>: expected <what>, got <value>"`` (the value as ``repr``), and returns
the value converted (``float`` or ``int``), so that a caller can write
``tol = check_positive("tol", tol)``. :func:`check_increasing`, a check of
an array, names the first element out of order instead. Tables read from files are checked by
:mod:`bayes_mpem.io.tables`, whose messages also name the row.

Examples
--------
>>> check_positive("sigma", 2)
2.0
>>> check_probability("ci", 1.5)
Traceback (most recent call last):
...
ValueError: ci: expected a probability in (0, 1), got 1.5
"""

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
    name : str
        The argument's name, for the message.
    value : Any
        The value to check.
    allow_none : bool, default False
        Accept ``None`` (and return it).
    what : str, optional
        What the message says is expected, instead of ``"a positive number"``
        (``"a positive sound speed in m/s"``).

    Returns
    -------
    float or None

    Raises
    ------
    ValueError
        Not a finite number > 0.

    Examples
    --------
    >>> check_positive("tol", 1e-9)
    1e-09
    >>> check_positive("scale", None, allow_none=True) is None
    True
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

    Parameters
    ----------
    name : str
        The argument's name, for the message.
    value : Any
        The value to check.

    Returns
    -------
    float

    Raises
    ------
    ValueError
        Not a finite number (NaN, inf, a string, a bool, ...).

    Examples
    --------
    >>> check_finite("offset", -3)
    -3.0
    """
    v = _as_float(value)
    if v is None or not math.isfinite(v):
        raise ValueError(f"{name}: expected a finite number, got {value!r}")
    return v


def check_probability(name: str, value: Any, *, open_interval: bool = True) -> float:
    """Check a probability, in ``(0, 1)`` (default) or in ``[0, 1]``; return it as ``float``.

    Parameters
    ----------
    name : str
        The argument's name, for the message.
    value : Any
        The value to check.
    open_interval : bool, default True
        Exclude 0 and 1 (an interval's coverage ``ci``, a weight that must
        leave room for both classes).

    Returns
    -------
    float

    Raises
    ------
    ValueError
        Not a number in the interval.

    Examples
    --------
    >>> check_probability("ci", 0.95)
    0.95
    >>> check_probability("weight", 1, open_interval=False)
    1.0
    """
    v = _as_float(value)
    ok = v is not None and ((0.0 < v < 1.0) if open_interval else (0.0 <= v <= 1.0))
    if not ok:
        interval = "(0, 1)" if open_interval else "[0, 1]"
        raise ValueError(f"{name}: expected a probability in {interval}, got {value!r}")
    return v


def check_choice(name: str, value: Any, choices: Iterable, *, words: bool = False) -> Any:
    """Check that ``value`` is one of ``choices``; return it unchanged.

    Parameters
    ----------
    name : str
        The argument's name, for the message.
    value : Any
        The value to check.
    choices : iterable
        The allowed values (shown in the message as a tuple).
    words : bool, default False
        Spell the choices out in the message (``expected 'a', 'b' or 'c'``)
        instead of ``expected one of ('a', 'b', 'c')``.

    Returns
    -------
    Any
        ``value``.

    Raises
    ------
    ValueError
        ``value`` is not among ``choices`` (an unhashable value is not either).

    Examples
    --------
    >>> check_choice("path", "double", ("triangle", "double"))
    'double'
    >>> check_choice("path", "single", ("triangle", "double"))
    Traceback (most recent call last):
    ...
    ValueError: path: expected one of ('triangle', 'double'), got 'single'
    >>> check_choice("side", "both", ("upper", "lower", "two-sided"), words=True)
    Traceback (most recent call last):
    ...
    ValueError: side: expected 'upper', 'lower' or 'two-sided', got 'both'
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
    """Check an integer (Python or NumPy, not a bool) ``>= minimum``; return it as ``int``.

    Parameters
    ----------
    name : str
        The argument's name, for the message.
    value : Any
        The value to check; floats are refused even when whole (``2.0``).
    minimum : int
        The least value allowed.

    Returns
    -------
    int

    Raises
    ------
    ValueError
        Not an integer, or below ``minimum``.

    Examples
    --------
    >>> check_int("n_walkers", 32, minimum=4)
    32
    """
    if (isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer))
            or value < minimum):
        raise ValueError(f"{name}: expected an integer >= {minimum}, got {value!r}")
    return int(value)


def check_range(name: str, value: Any, *, low: float | None = None, high: float | None = None,
                include_low: bool = False, include_high: bool = False) -> float:
    """Check a number between ``low`` and ``high``; return it as ``float``.

    NaN is refused; an infinite value passes when the bounds allow it
    (``min_ess=inf``: never stop on the effective sample size).

    Parameters
    ----------
    name : str
        The argument's name, for the message.
    value : Any
        The value to check.
    low, high : float, optional
        The bounds; ``None`` for none.
    include_low, include_high : bool, default False
        Whether the bound itself is allowed.

    Returns
    -------
    float

    Raises
    ------
    ValueError
        Not a number (a bool included), NaN, or out of the bounds; the message
        says ``a number in (low, high]``, ``a number >= low``, ...

    Examples
    --------
    >>> check_range("alpha", 1, low=0, high=1, include_high=True)
    1.0
    >>> check_range("min_ess", -1, low=0, include_low=True)
    Traceback (most recent call last):
    ...
    ValueError: min_ess: expected a number >= 0, got -1
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

    The message names the first element that is not greater than the one before:
    ``"<context><name>[i] = <value> is not greater than <name>[i-1] = <value>:
    expected <what>"``.

    Parameters
    ----------
    name : str
        The array's name, for the message.
    values : array_like
        1-D numbers (already checked to be finite).
    context : str, optional
        Put before the name (``"SoundSpeedProfile: "``).
    what : str, default "strictly increasing values"
        What the message says is expected.

    Returns
    -------
    numpy.ndarray
        ``values`` as a float array.

    Raises
    ------
    ValueError
        Two neighbours not strictly increasing.

    Examples
    --------
    >>> check_increasing("depth", [0.0, 10.0, 20.0]).tolist()
    [0.0, 10.0, 20.0]
    >>> check_increasing("z", [0.0, 10.0, 10.0])
    Traceback (most recent call last):
    ...
    ValueError: z[2] = 10.0 is not greater than z[1] = 10.0: expected strictly increasing values
    """
    arr = np.asarray(values, dtype=float)
    bad = np.flatnonzero(np.diff(arr) <= 0)
    if bad.size:
        i = bad[0] + 1
        raise ValueError(f"{context}{name}[{i}] = {arr[i]} is not greater than {name}[{i - 1}] = "
                         f"{arr[i - 1]}: expected {what}")
    return arr
