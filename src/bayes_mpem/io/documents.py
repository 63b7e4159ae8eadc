"""JSON documents of the result files: NumPy values, non-finite numbers, timings."""

from __future__ import annotations

import json
import math

import numpy as np


def numpy_to_json(value):
    """Turn a NumPy scalar or array into a JSON-ready value (a ``json`` ``default=``).

    Raises
    ------
    TypeError
    """
    if isinstance(value, (np.floating, np.integer, np.bool_)):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(f"not JSON serialisable: {type(value)}")


def finite_json(document, numpy: bool = False):
    """Replace every NaN and infinity in ``document`` by ``None``, saying where.

    Parameters
    ----------
    numpy : bool, default False
        Also convert NumPy scalars and arrays.

    Returns
    -------
    clean : same structure
    replaced : dict
        ``{"dotted.path[i]": "nan" | "inf" | "-inf"}``.
    """
    replaced = {}

    def clean(v, where):
        if numpy and isinstance(v, (np.generic, np.ndarray)):
            v = numpy_to_json(v)
        if isinstance(v, float) and not math.isfinite(v):
            replaced[where] = repr(v)
            return None
        if isinstance(v, dict):
            return {k: clean(x, f"{where}.{k}" if where else str(k)) for k, x in v.items()}
        if isinstance(v, (list, tuple)):
            return [clean(x, f"{where}[{i}]") for i, x in enumerate(v)]
        return v

    return clean(document, ""), replaced


def split_timings(document):
    """Split a copy of ``document`` into ``(document, timings)`` (``seconds``, ``*_seconds``)."""
    def is_timing(key):
        return isinstance(key, str) and (key == "seconds" or key.endswith("_seconds"))

    if not isinstance(document, dict):
        return document, {}
    kept, timings = {}, {}
    for k, v in document.items():
        if is_timing(k):
            timings[k] = v
        elif isinstance(v, dict):
            kept[k], sub = split_timings(v)
            if sub:
                timings[k] = sub
        else:
            kept[k] = v
    return kept, timings


#: Float arrays at least this large are formatted in one vectorised pass (one-line JSON).
BIG_ARRAY = 10_000


def _array_text(a: np.ndarray) -> str:
    """``json.dumps(a.tolist())`` of a finite 1-D or 2-D float array, formatted vectorised."""
    import pyarrow as pa
    import pyarrow.compute as pc

    from .table_files import format_floats

    flat = a.ravel()
    cells = None
    probe = flat[:: max(1, flat.size // 4096)]
    if np.unique(probe).size * 2 <= probe.size and not np.any((flat == 0) & np.signbit(flat)):
        # few distinct values (rounded probabilities): each formatted once, as json.dumps
        # does (float.__repr__); -0.0 would be merged with 0.0 by unique, so it goes below
        uniq, inverse = np.unique(flat, return_inverse=True)
        if uniq.size * 8 <= flat.size:
            cells = pa.array([float.__repr__(float(u)) for u in uniq]).take(
                inverse.astype(np.int32))
    if cells is None:
        cells = format_floats(flat)
    if a.ndim == 1:
        return "[" + ", ".join(cells.to_pylist()) + "]"
    cols = [cells.take(np.arange(j, a.size, a.shape[1])) for j in range(a.shape[1])]
    rows = pc.binary_join_element_wise(*cols, ", ") if len(cols) > 1 else cols[0]
    return "[[" + "], [".join(rows.to_pylist()) + "]]"


def _with_arrays(document) -> str:
    """One-line JSON of ``document``, its big finite float arrays formatted vectorised."""
    arrays = []

    def default(value):
        if (isinstance(value, np.ndarray) and value.dtype.kind == "f" and value.ndim in (1, 2)
                and value.size >= BIG_ARRAY and np.isfinite(value).all()):
            arrays.append(value)
            return f"\x00{len(arrays) - 1}\x00"
        return numpy_to_json(value)

    text = json.dumps(document, allow_nan=False, default=default)
    for i, a in enumerate(arrays):
        text = text.replace(f'"\\u0000{i}\\u0000"', _array_text(a), 1)
    return text


def json_text(document, indent, numpy=False) -> str:
    r"""Return ``document`` as strict JSON text and a newline (see :func:`finite_json`)."""
    try:  # the common case, in C: nothing to replace
        if numpy and indent is None:
            return _with_arrays(document) + "\n"
        return json.dumps(document, indent=indent, allow_nan=False,
                          default=numpy_to_json if numpy else None) + "\n"
    except ValueError:
        pass
    clean, replaced = finite_json(document, numpy)
    if replaced and isinstance(clean, dict):
        clean = {**clean, "non_finite": {**clean.get("non_finite", {}), **replaced}}
    return json.dumps(clean, indent=indent, allow_nan=False) + "\n"
