"""Types of the command-line options: every value checked by argparse, before any work.

Each function here is an ``argparse`` ``type=``: it turns the option's text into
a value or raises :class:`argparse.ArgumentTypeError`, which argparse reports
as ``bayes-mpem COMMAND: error: argument --ci: expected a probability in (0,
1), got '1.5'`` with exit status 2, naming the option, before any file is read.
No NaN, infinity or out-of-range value gets through.

Examples
--------
>>> probability("0.9")
0.9
>>> probability("1.5")
Traceback (most recent call last):
...
argparse.ArgumentTypeError: expected a probability in (0, 1), got '1.5'
>>> at_least(3)("2")
Traceback (most recent call last):
...
argparse.ArgumentTypeError: expected an integer >= 3, got '2'
"""

from __future__ import annotations

import argparse
import math

from ..io.boundary import limit_problem

#: The fewest replies a beacon can be fitted with (the EMs need 3 ranges).
MIN_PINGS = 3


def _number(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not math.isfinite(v):
        raise argparse.ArgumentTypeError(f"expected a finite number, got {text!r}")
    return v


def finite(text: str) -> float:
    """Parse a finite number.

    Parameters
    ----------
    text : str

    Returns
    -------
    float

    Raises
    ------
    argparse.ArgumentTypeError
        NaN, an infinity, or not a number.
    """
    return _number(text)


def positive(text: str) -> float:
    """Parse a finite number > 0.

    Parameters
    ----------
    text : str

    Returns
    -------
    float

    Raises
    ------
    argparse.ArgumentTypeError
        Otherwise.
    """
    v = _number(text)
    if not v > 0:
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}")
    return v


def non_negative(text: str) -> float:
    """Parse a finite number >= 0.

    Parameters
    ----------
    text : str

    Returns
    -------
    float

    Raises
    ------
    argparse.ArgumentTypeError
        Otherwise.
    """
    v = _number(text)
    if not v >= 0:
        raise argparse.ArgumentTypeError(f"expected a number >= 0, got {text!r}")
    return v


def probability(text: str) -> float:
    """Parse a probability strictly between 0 and 1 (an interval's coverage, ``--pol``).

    Parameters
    ----------
    text : str

    Returns
    -------
    float

    Raises
    ------
    argparse.ArgumentTypeError
        Otherwise.
    """
    try:
        v = float(text)
    except ValueError:
        v = math.nan
    if not 0.0 < v < 1.0:
        raise argparse.ArgumentTypeError(f"expected a probability in (0, 1), got {text!r}")
    return v


def fraction(text: str) -> float:
    """Parse a number in (0, 1] (the paper's ``--alpha``).

    Parameters
    ----------
    text : str

    Returns
    -------
    float

    Raises
    ------
    argparse.ArgumentTypeError
        Otherwise.
    """
    try:
        v = float(text)
    except ValueError:
        v = math.nan
    if not 0.0 < v <= 1.0:
        raise argparse.ArgumentTypeError(f"expected a number in (0, 1], got {text!r}")
    return v


def at_least(minimum: int, maximum: int | None = None):
    """Make the ``type=`` of an integer option with bounds.

    Parameters
    ----------
    minimum : int
    maximum : int, optional

    Returns
    -------
    callable
        The ``type=`` function.
    """
    def parse(text: str) -> int:
        try:
            v = int(text)
        except ValueError:
            v = None
        if v is None or v < minimum or (maximum is not None and v > maximum):
            what = (f"an integer >= {minimum}" if maximum is None
                    else f"an integer in [{minimum}, {maximum}]")
            raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}")
        return v

    parse.__name__ = "integer"
    return parse


def turn_around(text: str) -> float:
    """Parse a turn-around time in s, within the limits of :data:`bayes_mpem.io.boundary.LIMITS`.

    Parameters
    ----------
    text : str

    Returns
    -------
    float

    Raises
    ------
    argparse.ArgumentTypeError
        Otherwise.
    """
    v = non_negative(text)
    why = limit_problem("tat", v)
    if why:
        raise argparse.ArgumentTypeError(f"expected a turn-around time in [0, 10] s, "
                                         f"got {text!r}")
    return v


#: ``--seed``: a non-negative integer (NumPy's seeds).
seed = at_least(0)
#: ``--min-pings``: the EMs need at least :data:`MIN_PINGS` replies.
min_pings = at_least(MIN_PINGS)
