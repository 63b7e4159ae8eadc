"""Types of the command-line options: ``argparse`` ``type=`` refusing NaN and out-of-range values.

Examples
--------
>>> probability("1.5")
Traceback (most recent call last):
...
argparse.ArgumentTypeError: expected a probability in (0, 1), got '1.5'
"""

from __future__ import annotations

import argparse
import math

# the parser loads no numpy (`bayes-mpem --help` answers at once): these two are repeated
# from where they live, and tests/cli/test_reliability.py checks that they agree
#: :data:`bayes_mpem.lbl.survey.survey.MIN_PINGS`: the fewest replies a beacon can be fitted with.
MIN_PINGS = 3
#: :data:`bayes_mpem.io.table_files.TABLE_FORMATS`: the formats of a result's tables.
TABLE_FORMATS = ("csv", "parquet")
#: :data:`bayes_mpem.survey_in.travel_times.KNOT_MINUTES_RANGE`: ``locate --knot-minutes``'s.
KNOT_MINUTES_RANGE = (0.1, 1440.0)


def number(what: str, low: float = -math.inf, high: float = math.inf, *,
           include_low: bool = True, include_high: bool = True):
    """Make the ``type=`` of a finite number within ``low``, ``high`` (``what``: the message's).

    Examples
    --------
    >>> number("a number >= 1", 1.0)("1")
    1.0
    """
    def parse(text: str) -> float:
        try:
            v = float(text)
        except ValueError:
            v = math.nan
        ok = (math.isfinite(v) and (v >= low if include_low else v > low)
              and (v <= high if include_high else v < high))
        if not ok:
            raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}")
        return v

    parse.__name__ = "number"
    return parse


def at_least(minimum: int, maximum: int | None = None):
    """Make the ``type=`` of an integer in ``[minimum, maximum]``."""
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


#: The longest ``--correlation`` time (s): ``noise.CORRELATION_TIMES``' last (a longer one
#: widens the banded factor beyond what a few thousand replies afford).
MAX_CORRELATION_S = 1200.0


def correlation(text: str):
    """``--correlation``: ``auto``, ``off`` or ``MU_T[,MU_MT[,WHITE]]`` (GARPOS's, and white).

    Examples
    --------
    >>> correlation("60"), correlation("120,0"), correlation("300,0.5,0.4"), correlation("off")
    ((60.0, 0.5, 0.0), (120.0, 0.0, 0.0), (300.0, 0.5, 0.4), 'off')
    """
    if text in ("auto", "off"):
        return text
    what = (f"auto, off or MU_T[,MU_MT[,WHITE]] (MU_T seconds, 0 or in [1, "
            f"{MAX_CORRELATION_S:g}], MU_MT in [0, 1] (default 0.5), WHITE in [0, 1) (default 0))")
    parts = text.split(",")
    try:
        vals = [float(v) for v in parts]
    except ValueError:
        vals = [math.nan]
    if len(vals) > 3:
        vals = [math.nan]
    tau, share, white = (vals + [0.5, 0.0][len(vals) - 1:])[:3]
    # 1 s: array.MIN_CORRELATION_S (not imported: the parser stays light)
    if not ((tau == 0.0 or 1.0 <= tau <= MAX_CORRELATION_S) and 0.0 <= share <= 1.0
            and 0.0 <= white < 1.0):
        raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}")
    return tau, share, white


#: A finite number.
finite = number("a finite number")
#: A finite number > 0 (scales, ``--sigma-dp``, ``--concentration``).
positive = number("a positive number", 0.0, include_low=False)
#: A finite number >= 0 (``--min-gain``, ``--min-ess``).
non_negative = number("a number >= 0", 0.0)
#: A probability strictly between 0 and 1 (an interval's coverage, ``--pol``).
probability = number("a probability in (0, 1)", 0.0, 1.0, include_low=False,
                     include_high=False)
#: The probability of intervals from draws (``sample --ci``; ``_validate.MIN_SAMPLED_CI``).
sampled_probability = number("a probability in [0.5, 1)", 0.5, 1.0, include_high=False)
#: A number in (0, 1] (the paper's ``--alpha``).
fraction = number("a number in (0, 1]", 0.0, 1.0, include_low=False)
#: ``locate --knot-minutes``: below 0.1 min (6 s, under a shot cycle) a spacing only costs
#: memory (1e-9: 445 GiB).
knot_minutes = number(f"a knot spacing in minutes in [{KNOT_MINUTES_RANGE[0]:g}, "
                      f"{KNOT_MINUTES_RANGE[1]:g}]", *KNOT_MINUTES_RANGE)
#: A turn-around time in s (the limits of :data:`bayes_mpem.io.boundary.LIMITS`).
turn_around = number("a turn-around time in [0, 10] s", 0.0, 10.0)
#: ``--dr-noise`` of ``navigate`` and ``stream``: the dead reckoning's random walk, m/sqrt(s),
#: within the levels the filters are tested at (below 1e-4 the smoother's covariance is
#: singular; above 100 m/sqrt(s) the dead reckoning says nothing).
dr_noise = number("a positive number in [0.0001, 100] (a random walk, m/sqrt(s))", 1e-4, 100.0)
#: ``simulate --navigation --dr-noise``: the simulated random walk, m/sqrt(s) (0: none).
dr_noise_simulated = number("a number in [0, 100] (a random walk, m/sqrt(s))", 0.0, 100.0)
#: ``stream --max-gap``: seconds (below a second every ping cycle would be refused).
max_gap = number("a positive number in [1, 1e10] (seconds)", 1.0, 1e10)
#: ``navigate``'s priors: the first position's sd (m), the heading bias's (degrees), the speed
#: scale's, and a fixed sigma_DP (m), within what its smoother computes with (beyond them its
#: arithmetic overflows or divides by zero).
start_sd = number("a positive number in [0.01, 1e6] (m)", 0.01, 1e6)
heading_sd = number("a positive number in [1e-6, 180] (degrees)", 1e-6, 180.0)
scale_sd = number("a positive number in [1e-6, 1]", 1e-6, 1.0)
sigma_dp_nav = number("a positive number in [0.001, 10000] (m)", 1e-3, 1e4)
#: ``--seed``: a non-negative integer (NumPy's seeds).
seed = at_least(0)
#: ``--min-pings``: the EMs need at least :data:`bayes_mpem.lbl.survey.survey.MIN_PINGS` replies.
min_pings = at_least(MIN_PINGS)
