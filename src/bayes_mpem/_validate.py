"""Small validators for options and scalar arguments, in one message style.

Every check raises ``ValueError`` with the message
``"<name>: expected <what>, got <value>"`` (the value as ``repr``), and returns
the value converted (``float`` or ``int``), so that a caller can write
``tol = check_positive("tol", tol)``. Tables read from files are checked by
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


def check_positive(name: str, value: Any, *, allow_none: bool = False) -> float | None:
    """Check a finite number > 0; return it as ``float``.

    Parameters
    ----------
    name : str
        The argument's name, for the message.
    value : Any
        The value to check.
    allow_none : bool, default False
        Accept ``None`` (and return it).

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


def check_choice(name: str, value: Any, choices: Iterable) -> Any:
    """Check that ``value`` is one of ``choices``; return it unchanged.

    Parameters
    ----------
    name : str
        The argument's name, for the message.
    value : Any
        The value to check.
    choices : iterable
        The allowed values (shown in the message as a tuple).

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
    """
    choices = tuple(choices)
    try:
        ok = value in choices
    except TypeError:
        ok = False
    if not ok:
        raise ValueError(f"{name}: expected one of {choices}, got {value!r}")
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
