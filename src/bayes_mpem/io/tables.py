"""Reading and checking the pings and beacons tables (CSV or Parquet files, or DataFrames)."""

from __future__ import annotations

import numbers
import os
import re
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.compute as pc

from ..exceptions import InputError
from .boundary import LIMITS, out_of_limits
from .cells import MAX_LISTED, Problems, as_beacon_id, is_missing, show  # noqa: F401 (re-exported)
from .table_files import read_table_file

PING_COLUMNS = ("time", "beacon", "range", "x", "y", "depth")
#: Columns the results add to every input row; an input column of that name would be lost.
RESERVED_COLUMNS = ("p_dp", "p_mp", "p_ol", "p_dp_sd", "p_mp_sd", "p_ol_sd", "label", "reason")
BEACON_COLUMNS = ("beacon", "x", "y", "depth")
_UNITS = {"time": "s", "range": "m", "x": "m", "y": "m", "depth": "m"}
_NUMBER = r"^[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?$"  # no nan/inf/hex/"_"


def row_name(pos: int, lines=None, labels=None) -> str:
    """Name row ``pos`` (0-based) of a table in messages: its file line, else its label.

    Parameters
    ----------
    pos : int
    lines : array_like, optional
        The file line of each row (a CSV's, as ``grep -n`` counts them).
    labels : pandas.Index, optional
        A DataFrame's index (a label that is text is quoted).

    Returns
    -------
    str

    Examples
    --------
    >>> row_name(2, lines=[4, 5, 7]), row_name(1, labels=pd.Index(["a", "b"])), row_name(3)
    ('line 7', "row 'b'", 'row 3')
    """
    if lines is not None:
        return f"line {int(lines[pos])}"
    if labels is not None:
        lab = labels[pos]
        return f"row {lab!r}" if isinstance(lab, str) else f"row {lab}"
    return f"row {pos}"


@dataclass
class _Table:
    frame: pd.DataFrame  # RangeIndex, stripped column names
    source: str
    lines: np.ndarray | None = None  # file line of each row (CSV)
    labels: pd.Index | None = None  # index labels of a DataFrame
    comments: int = 0

    def row_name(self, pos: int) -> str:
        return row_name(pos, self.lines, self.labels)

    def where(self, pos: int, column: str) -> str:
        return f"{self.source} {self.row_name(pos)}, column {column!r}"


def load_table(source: Any, name: str | None, kind: str) -> _Table:
    """Read a CSV or Parquet file, or take a DataFrame, as a table with row names for messages.

    Parameters
    ----------
    source : str, os.PathLike or pandas.DataFrame
    name : str or None
        Label for messages (default: the path, or ``"<kind> DataFrame"``).
    kind : str

    Returns
    -------
    _Table

    Raises
    ------
    FileNotFoundError, InputError, TypeError
    """
    if isinstance(source, pd.DataFrame):
        label = name or f"{kind} DataFrame"
        frame = source.copy()
        frame.columns = [c.strip() if isinstance(c, str) else c for c in frame.columns]
        table = _Table(frame.reset_index(drop=True), label, labels=source.index)
        lines = source.attrs.get("lines")  # a table converted from a file (io.travel_time)
        if lines is not None and len(lines) == len(source) and source.attrs.get("source"):
            table = _Table(table.frame, name or str(source.attrs["source"]),
                           lines=np.asarray(lines))
    elif isinstance(source, (str, os.PathLike)):
        label = name or str(source)
        text = read_table_file(source, label, f"{kind} file")
        table = _Table(text.frame, label, lines=text.lines, comments=text.comments)
    else:
        raise TypeError(f"{kind}: expected a CSV path or a pandas DataFrame (or a Parquet "
                        f"file), got {type(source).__name__}")
    cols = list(table.frame.columns)
    dupes = sorted({str(c) for c in cols if cols.count(c) > 1})
    if dupes:
        # an empty name (a header ending in commas) is shown as such, with its columns
        named = [f"{d!r} (columns "
                 + ", ".join(str(j + 1) for j, c in enumerate(cols) if str(c) == d) + ")"
                 for d in dupes]
        raise InputError(f"{table.source}: duplicated column name(s) {'; '.join(named)} in "
                         "the header; expected each column named once")
    return table


def check_columns(table: _Table, required: tuple[str, ...], kind: str) -> None:
    """Check that ``table`` has the ``required`` columns and at least one row.

    Parameters
    ----------
    table : _Table
    required : tuple of str
    kind : str

    Raises
    ------
    InputError
    """
    missing = [c for c in required if c not in table.frame.columns]
    if missing:
        found = ", ".join(map(repr, table.frame.columns)) or "no columns"
        hint = ""
        if len(table.frame.columns) == 1 and re.search(r"[;\t|]", str(table.frame.columns[0])):
            hint = ("; the header is one column: the file looks semicolon- or tab-separated "
                    "(perhaps with decimal commas), expected comma-separated values")
        raise InputError(
            f"{table.source}: missing required column(s) {', '.join(map(repr, missing))}; "
            f"expected {', '.join(map(repr, required))}; found {found}{hint}")
    if len(table.frame) == 0:
        raise InputError(f"{table.source}: the {kind} table is empty (expected at least one "
                         "data row)")


def _cell_text(v: Any) -> str:
    """Text of a non-string DataFrame cell for number parsing ('' = missing, '?' = no number)."""
    if isinstance(v, str):
        return v
    if is_missing(v):
        return ""
    real = isinstance(v, numbers.Real) and not isinstance(v, (bool, np.bool_))
    return repr(float(v)) if real else "?"


def _as_text_array(col: pd.Series) -> pa.Array:
    """Return a text (or mixed) column as a pyarrow string array ('' = missing)."""
    try:
        arr = pa.array(col, type=pa.string(), from_pandas=True)
    except (pa.ArrowInvalid, pa.ArrowTypeError):
        arr = pa.array(col.astype(object).map(_cell_text).to_numpy(dtype=object),
                       type=pa.string())
    if isinstance(arr, pa.ChunkedArray):
        arr = arr.combine_chunks()
    return pc.fill_null(arr, "")


def _np_bool(arr) -> np.ndarray:
    return np.asarray(arr.to_numpy(zero_copy_only=False), dtype=bool)


def _parse_numbers(col: pd.Series) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Return (float values, missing mask, not-a-number mask); values are NaN where unusable.

    Text is parsed by pyarrow's (correctly rounded) cast, with the grammar of
    :data:`_NUMBER` checked by a vectorised regular expression only when the cast fails.
    """
    if pd.api.types.is_numeric_dtype(col) and not pd.api.types.is_bool_dtype(col):
        vals = np.array(col.to_numpy(dtype=float, na_value=np.nan), dtype=float)  # own copy
        return vals, np.isnan(vals), np.zeros(len(col), bool)
    text = pc.utf8_trim_whitespace(_as_text_array(col))
    missing = _np_bool(pc.equal(text, ""))
    try:
        vals = pc.cast(pc.if_else(pa.array(missing), "0", text), pa.float64()).to_numpy(
            zero_copy_only=False).copy()
        grammar = ~missing & ~np.isfinite(vals)  # "nan"/"inf" text is not a number
        if np.any(_np_bool(pc.match_substring(text, "_"))):
            raise pa.ArrowInvalid("underscore")  # pyarrow may take "1_000"; the grammar not
    except (pa.ArrowInvalid, pa.ArrowNotImplementedError):
        ok = _np_bool(pc.match_substring_regex(text, _NUMBER))
        grammar = ~ok & ~missing
        vals = pc.cast(pc.if_else(pa.array(ok), text, "0"), pa.float64()).to_numpy(
            zero_copy_only=False).copy()
        vals[~ok] = np.nan
    vals[missing] = np.nan
    return vals, missing, grammar


def numeric_column(table: _Table, column: str, problems: Problems, *,
                   allow_missing: bool = False, positive: bool = False) -> np.ndarray:
    """Parse and check one numeric column (vectorised); bad cells go to ``problems``.

    Parameters
    ----------
    table : _Table
    column : str
    problems : Problems
    allow_missing : bool, default False
        Empty cells allowed (NaN: a ping with no reply).
    positive : bool, default False

    Returns
    -------
    numpy.ndarray
        float64, NaN where missing or bad.
    """
    col = table.frame[column]
    vals, missing, bad = _parse_numbers(col)
    unit = _UNITS.get(column, "m")
    wrong = bad | (~missing & ~np.isfinite(vals))
    if positive:
        with np.errstate(invalid="ignore"):
            wrong |= ~missing & ~bad & ~(vals > 0)
    if not allow_missing:
        wrong |= missing
    what = f"a positive number ({unit})" if positive else f"a finite number ({unit})"

    def word(pos):
        raw = col.iloc[pos]
        hint = ""
        if positive and isinstance(raw, str) and raw.strip().lower().lstrip("+-") in (
                "nan", "inf", "infinity", "na", "n/a", "none", "null"):
            hint = " (leave the cell empty for a ping with no reply)"
        return f"{table.where(pos, column)}: expected {what}, got {show(raw)}{hint}"

    problems.add_mask(wrong, word)
    kind = column if column in LIMITS else "x"
    lim = LIMITS[kind]
    beyond = ~wrong & ~missing & out_of_limits(kind, vals)
    problems.add_mask(beyond, lambda pos: (
        f"{table.where(pos, column)}: expected {column} within {lim.describe()} (a "
        f"physically possible value), got {show(col.iloc[pos])}"))
    vals[missing] = np.nan
    return vals


def _beacon_column(table: _Table, problems: Problems) -> np.ndarray:
    col = table.frame["beacon"]
    if pd.api.types.is_string_dtype(col.dtype) or pd.api.types.infer_dtype(
            col, skipna=False) == "string":  # text (CSV, Parquet): ids as written
        arr = pc.utf8_trim_whitespace(_as_text_array(col)).dictionary_encode()
        uniques = np.asarray(arr.dictionary.to_pylist(), dtype=object)
        ids = uniques[np.asarray(arr.indices.to_numpy(zero_copy_only=False), dtype=np.intp)]
    elif pd.api.types.is_numeric_dtype(col.dtype) and not pd.api.types.is_bool_dtype(col.dtype):
        codes, uniques = pd.factorize(col)  # numeric ids (Parquet): one conversion per id
        ids = np.asarray([as_beacon_id(u) for u in uniques] + [""], dtype=object)[codes]
    else:
        ids = np.array([as_beacon_id(v) for v in col], dtype=object)
    problems.add_mask(ids == "", lambda pos: f"{table.where(pos, 'beacon')}: expected a beacon "
                                             f"id, got {show(col.iloc[pos])}")
    return ids


def pings_table(source: Any, name: str | None) -> tuple[_Table, dict[str, np.ndarray], Problems]:
    """Parse pings; cell problems are collected, not raised (load_survey adds to them).

    Parameters
    ----------
    source : str, os.PathLike or pandas.DataFrame
    name : str or None

    Returns
    -------
    table, arrays, problems
    """
    table = load_table(source, name, "pings")
    check_columns(table, PING_COLUMNS, "pings")
    taken = [c for c in RESERVED_COLUMNS if c in table.frame.columns]
    if taken:
        raise InputError(
            f"{table.source}: column(s) {', '.join(map(repr, taken))} would be overwritten by "
            f"the results, which add {', '.join(map(repr, RESERVED_COLUMNS))} to every row; "
            "rename them (a classified.csv from an earlier run is read back by "
            "'bayes-mpem plot', not by 'fit')")
    problems = Problems(table.source)
    arrays = {c: numeric_column(table, c, problems, allow_missing=c == "range",
                                 positive=c == "range")
              for c in PING_COLUMNS if c != "beacon"}
    arrays["beacon"] = _beacon_column(table, problems)
    return table, {c: arrays[c] for c in PING_COLUMNS}, problems


def read_pings(source: Any, *, name: str | None = None
               ) -> tuple[pd.DataFrame, dict[str, np.ndarray]]:
    """Read and validate a pings table on its own (no cross-check against beacons).

    Parameters
    ----------
    source : str, os.PathLike or pandas.DataFrame
        A CSV or Parquet path, or a DataFrame (never modified).
    name : str, optional
        Label for error messages; default the path or ``"pings DataFrame"``.

    Returns
    -------
    table : pandas.DataFrame
        The pings as given (CSV: all text), column names stripped, RangeIndex.
    arrays : dict of str to numpy.ndarray
        Keys :data:`PING_COLUMNS` (``range`` NaN = no reply).

    Raises
    ------
    FileNotFoundError, InputError
        No such file; missing columns, an empty table, or bad cells (all in one message).

    Examples
    --------
    >>> df = pd.DataFrame({"time": [0.0, 1.0], "beacon": [1, 1], "range": [10.0, None],
    ...                    "x": [0.0, 1.0], "y": [0.0, 0.0], "depth": [5.0, 5.0]})
    >>> table, arrays = read_pings(df)
    >>> arrays["beacon"].tolist(), int(np.isnan(arrays["range"]).sum())
    (['1', '1'], 1)
    """
    table, arrays, problems = pings_table(source, name)
    problems.raise_if_any()
    return table.frame, arrays


#: The rows a duplicated beacon id's message lists (a pings table given as the beacons
#: repeats each id thousands of times).
MAX_DUPLICATE_ROWS = 5


def beacons_frame(source: Any, name: str | None) -> tuple[pd.DataFrame, str]:
    """Read and check a beacons table (the work of :func:`read_beacons`).

    Parameters
    ----------
    source : Any
    name : str or None

    Returns
    -------
    frame : pandas.DataFrame
    source : str

    Raises
    ------
    InputError
    """
    table = load_table(source, name, "beacons")
    check_columns(table, BEACON_COLUMNS, "beacons")
    problems = Problems(table.source)
    xyz = {c: numeric_column(table, c, problems) for c in ("x", "y", "depth")}
    ids = _beacon_column(table, problems)
    seen: dict[str, list[int]] = {}
    for pos, b in enumerate(ids):
        if b:
            seen.setdefault(b, []).append(pos)
    for b, where in seen.items():
        if len(where) > 1:
            rows = ", ".join(table.row_name(p) for p in where[:MAX_DUPLICATE_ROWS])
            if len(where) > MAX_DUPLICATE_ROWS:
                rows += f" and {len(where) - MAX_DUPLICATE_ROWS} more"
            problems.add(where[1], f"{table.source}, column 'beacon': beacon id {b!r} is "
                                   f"duplicated ({rows})")
    problems.raise_if_any()
    out = pd.DataFrame(xyz, index=pd.Index(list(ids), dtype=object, name="beacon"))
    return out, table.source


def read_beacons(source: Any, *, name: str | None = None) -> pd.DataFrame:
    """Read and validate a beacons table (``beacon``, ``x``, ``y``, ``depth``; extras ignored).

    Parameters
    ----------
    source : str, os.PathLike or pandas.DataFrame
    name : str, optional
        Label for error messages; default the path or ``"beacons DataFrame"``.

    Returns
    -------
    pandas.DataFrame
        Index ``beacon`` (str ids, file order), float64 columns ``x``, ``y``, ``depth``.

    Raises
    ------
    FileNotFoundError, InputError
        No such file; missing columns, bad coordinates, empty or duplicated ids.
    """
    return beacons_frame(source, name)[0]
