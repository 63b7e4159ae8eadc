"""Writing result files: the one JSON and CSV writer behind every result's ``write()``.

Every output folder of ``bayes-mpem`` holds JSON documents (``summary.json``,
``compare.json``, ``diagnosis.json``, ...) and CSV tables (``classified.csv``,
``changed.csv``). They are all written here, with one set of serialisation
settings, so the files of every command look alike and stay byte-identical
from one release to the next.

Examples
--------
>>> import tempfile
>>> import pandas as pd
>>> with tempfile.TemporaryDirectory() as tmp:
...     out = output_folder(tmp + "/run")
...     p = write_json(out / "summary.json", {"n": 1})
...     print(p.read_text(), end="")
...     q = write_csv(out / "t.csv", pd.DataFrame({"a": [1, 2]}))
...     print(q.read_text(), end="")
{
  "n": 1
}
a
1
2
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np


def output_folder(out_dir) -> Path:
    """Create ``out_dir`` (and its parents) if missing.

    Parameters
    ----------
    out_dir : str or pathlib.Path

    Returns
    -------
    pathlib.Path
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    return out


def numpy_to_json(value):
    """Turn a NumPy scalar or array into a JSON-ready value (a ``json`` ``default=``).

    Parameters
    ----------
    value : object

    Returns
    -------
    int, float, bool or list

    Raises
    ------
    TypeError
        For any other type.

    Examples
    --------
    >>> import numpy as np
    >>> numpy_to_json(np.float64(1.5)), numpy_to_json(np.arange(2))
    (1.5, [0, 1])
    """
    if isinstance(value, (np.floating, np.integer)):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(f"not JSON serialisable: {type(value)}")


def write_json(path, document, *, indent: int | None = 2, numpy: bool = False) -> Path:
    """Write ``document`` as JSON followed by a newline.

    Parameters
    ----------
    path : str or pathlib.Path
    document : dict or list
    indent : int or None, default 2
        ``None`` writes one line (used for the large ``history.json``).
    numpy : bool, default False
        Also accept NumPy scalars and arrays (:func:`numpy_to_json`).

    Returns
    -------
    pathlib.Path
        ``path``.
    """
    path = Path(path)
    text = json.dumps(document, indent=indent, default=numpy_to_json if numpy else None)
    path.write_text(text + "\n")
    return path


def write_csv(path, table) -> Path:
    """Write a table as CSV without its index.

    Parameters
    ----------
    path : str or pathlib.Path
    table : pandas.DataFrame

    Returns
    -------
    pathlib.Path
        ``path``.
    """
    path = Path(path)
    table.to_csv(path, index=False)
    return path


def _uniform_column(col):
    """Return a column Parquet can store: mixed kinds of values become JSON text."""
    values = [v for v in col if v is not None and not (isinstance(v, float) and v != v)]
    kinds = {"text" if isinstance(v, str) else
             "number" if isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(
                 v, bool) else "bool" if isinstance(v, (bool, np.bool_)) else "other"
             for v in values}
    if len(kinds) <= 1 and "other" not in kinds:
        return col
    return col.map(lambda v: None if v is None else
                   v if isinstance(v, str) else json.dumps(v, default=numpy_to_json))


def write_parquet(path, table) -> Path:
    """Write a table as Parquet (pyarrow) without its index.

    Object columns that mix kinds of values (text and numbers, lists) are stored
    as JSON text, so that every column has one Parquet type.

    Parameters
    ----------
    path : str or pathlib.Path
    table : pandas.DataFrame

    Returns
    -------
    pathlib.Path
        ``path``.

    Examples
    --------
    >>> import tempfile
    >>> import pandas as pd
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     p = write_parquet(tmp + "/t.parquet", pd.DataFrame({"a": [1, None], "b": ["x", 2]}))
    ...     pd.read_parquet(p)["b"].tolist()
    ['x', '2']
    """
    path = Path(path)
    table = table.copy()
    for name in table.columns:
        if table[name].dtype == object:
            table[name] = _uniform_column(table[name])
    table.to_parquet(path, index=False)
    return path
