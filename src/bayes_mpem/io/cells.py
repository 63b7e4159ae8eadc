"""The cells of input tables: how an offending cell is worded, beacon ids, collected problems."""

from __future__ import annotations

import math
import numbers
from typing import Any

import numpy as np
import pandas as pd

from ..exceptions import InputError

#: problems worded per check (the rest are counted)
MAX_LISTED = 10


def is_missing(v: Any) -> bool:
    """Whether a cell is missing: None, ``pd.NA``, ``pd.NaT`` or a float NaN."""
    return v is None or v is pd.NA or v is pd.NaT or (
        isinstance(v, (float, np.floating)) and math.isnan(v))


def show(v: Any) -> str:
    """Describe an offending cell for an error message (its ``repr`` cut at 40 characters)."""
    if isinstance(v, str):
        return repr(v) if v.strip() else "an empty cell"
    if isinstance(v, np.generic):
        v = v.item()
    if is_missing(v):
        return f"a missing value ({'NaN' if isinstance(v, float) else v})"
    text = repr(v)
    return text if len(text) <= 40 else text[:37] + "..."


def as_beacon_id(v: Any) -> str:
    """Canonical string form of a beacon id ('' if missing); integral floats print as ints."""
    if is_missing(v):
        return ""
    if isinstance(v, str):
        return v.strip()
    if isinstance(v, (bool, np.bool_)):
        return str(bool(v))
    if isinstance(v, numbers.Integral):
        return str(int(v))
    if isinstance(v, numbers.Real):
        f = float(v)
        return str(int(f)) if f.is_integer() else repr(f)
    return str(v).strip()


class Problems:
    """Collects problems by row position and raises one InputError for all of them.

    Only the first :data:`MAX_LISTED` flagged cells of each check are worded, the rest counted.

    Parameters
    ----------
    source : str
        The file or table named in the message.
    """

    def __init__(self, source: str) -> None:
        self.source, self.items, self.count = source, [], 0

    def add(self, pos: int, message: str) -> None:
        """Record ``message`` for the row at position ``pos`` (listed in row order)."""
        self.items.append((pos, len(self.items), message))
        self.count += 1

    def add_mask(self, mask: np.ndarray, word) -> None:
        """Record the rows flagged by the boolean ``mask``; ``word(pos)`` words the first few."""
        flagged = np.flatnonzero(mask)
        for pos in flagged[:MAX_LISTED]:
            self.items.append((int(pos), len(self.items), word(int(pos))))
        self.count += int(flagged.size)

    def raise_if_any(self) -> None:
        """Raise one :class:`InputError` listing the problems (the first ten), if any."""
        if not self.items:
            return
        msgs = [m for _, _, m in sorted(self.items)][:MAX_LISTED]
        if self.count == 1:
            raise InputError(msgs[0])
        lines = [f"{self.count} problems in {self.source}:"] + ["  " + m for m in msgs]
        if self.count > MAX_LISTED:
            lines.append(f"  ... and {self.count - MAX_LISTED} more problems")
        raise InputError("\n".join(lines))
