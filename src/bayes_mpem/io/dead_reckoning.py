"""Dead-reckoning tables: a vehicle's own positions or velocities at their own rate."""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

from ..exceptions import InputError
from .tables import Problems, check_columns, load_table, numeric_column

#: The two forms of a dead-reckoning table: positions or velocities (east, north).
DR_FORMS = {"position": ("x", "y"), "velocity": ("ve", "vn")}


def read_dead_reckoning(source: Any, *, name: str | None = None) -> tuple[pd.DataFrame, str]:
    """Read and validate a dead-reckoning table (positions or velocities at its own rate).

    Parameters
    ----------
    source : str, os.PathLike or pandas.DataFrame
        ``time`` (s, increasing) and ``x``, ``y`` (m) or ``ve``, ``vn`` (m/s); ``depth`` optional.
    name : str, optional
        Label for error messages.

    Returns
    -------
    table : pandas.DataFrame
    form : {"position", "velocity"}

    Raises
    ------
    FileNotFoundError, InputError
    """
    table = load_table(source, name, "dead-reckoning")
    cols = set(table.frame.columns)
    forms = [f for f, c in DR_FORMS.items() if set(c) <= cols]
    if len(forms) != 1:
        raise InputError(f"{table.source}: expected columns 'time' and either 'x', 'y' "
                         f"(positions) or 've', 'vn' (velocities), found "
                         f"{'both' if forms else 'neither'}: "
                         f"{', '.join(map(repr, table.frame.columns)) or 'no columns'}")
    need = ("time", *DR_FORMS[forms[0]]) + (("depth",) if "depth" in cols else ())
    check_columns(table, need, "dead-reckoning")
    problems = Problems(table.source)
    out = pd.DataFrame({c: numeric_column(table, c, problems) for c in need})
    problems.raise_if_any()
    if table.lines is not None:  # file lines, for messages about its rows (as io.travel_time)
        out.attrs.update(source=table.source, lines=tuple(map(int, table.lines)))
    if len(out) < 2:
        raise InputError(f"{table.source}: the dead-reckoning table needs at least two rows, "
                         f"got {len(out)}")
    t = out["time"].to_numpy()
    for pos in np.flatnonzero(np.diff(t) <= 0)[:1] + 1:
        raise InputError(f"{table.where(int(pos), 'time')}: expected a time after the previous "
                         f"row's {float(t[pos - 1]):g} s, got {float(t[pos]):g} s")
    return out, forms[0]
