"""An output folder read back: the survey and the classes of its classified table.

What the ``read`` of :class:`~.fitting.SurveyFit`, :class:`~.sampling.SurveyPosterior`
and :class:`~bayes_mpem.lbl.navigate.result.Navigation` share.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from ...exceptions import InputError
from ...io.results import MARKER
from ...io.survey import load_survey
from ...io.table_files import frame_as_text, read_table_file
from ...io.tables import RESERVED_COLUMNS
from ...mixture.densities import CLASSES

_ADDED = set(RESERVED_COLUMNS)


def survey_and_classes(folder: Path, summary: dict):
    """Read the classified table of an output folder, checked against its ``summary.json``.

    Parameters
    ----------
    folder : pathlib.Path
        The output folder.
    summary : dict
        Its ``summary.json``.

    Returns
    -------
    survey : Survey
        The pings and the summary's ``beacons_table``.
    probs : numpy.ndarray
        ``(N, 3)`` ``p_dp``, ``p_mp``, ``p_ol`` of every input row (NaN without a reply).
    columns : dict
        Every added probability column (``p_dp_sd``, ...) as floats.

    Raises
    ------
    InputError
        When the table is truncated, lacks the class columns or holds a cell that is not
        a probability.
    """
    name = next((f for f in ("classified.parquet", "classified.csv")
                 if f in summary.get("files", [])), "classified.csv")
    path = folder / name
    text = read_table_file(path, str(path), "classified table")
    frame = text.frame
    if summary.get("n_rows") is not None and len(frame) != summary["n_rows"]:
        raise InputError(f"{path}: {len(frame)} rows, but {folder / MARKER} says n_rows = "
                         f"{summary['n_rows']}: the table is truncated or from another run")
    missing = [c for c in ("p_dp", "p_mp", "p_ol", "label") if c not in frame.columns]
    if missing:
        raise InputError(f"{path}: missing column(s) {', '.join(missing)}; not a "
                         "classified table of 'bayes-mpem fit', 'sample' or 'navigate'")
    classified = frame_as_text(frame) if name.endswith(".parquet") else frame
    table = classified[[c for c in classified.columns if c not in _ADDED]]
    if text.lines is not None:  # messages name the file's lines, not a DataFrame's rows
        table.attrs.update(source=str(path), lines=np.asarray(text.lines))
    entries = summary.get("beacons_table")
    if not isinstance(entries, dict) or not all(isinstance(v, dict) for v in entries.values()):
        raise InputError(f"{folder / MARKER}: beacons_table: expected an object of beacons, "
                         f"each an object of x, y, depth; got {_shown(entries)}")
    beacons = pd.DataFrame([{"beacon": b, **v} for b, v in entries.items()])
    try:
        survey = load_survey(table, beacons)
    except InputError as exc:
        said = str(exc).replace("beacons DataFrame", "beacons_table")
        raise InputError(f"{path} and {folder / MARKER}'s beacons_table do not fit together "
                         f"(was one edited?): {said}") from None
    num = {}
    for c in sorted(_ADDED - {"label", "reason"}):
        if c in classified.columns:
            num[c] = pd.to_numeric(classified[c].replace("", np.nan), errors="coerce").to_numpy()
            bad = np.flatnonzero(np.isnan(num[c]) & (classified[c] != "").to_numpy()
                                 | (num[c] < 0) | (num[c] > 1))
            if bad.size:
                raise InputError(f"{folder} classified table, row {int(bad[0]) + 1}, column "
                                 f"{c!r}: expected a probability, got "
                                 f"{classified[c].iloc[bad[0]]!r}")
    probs = np.column_stack([num["p_" + c] for c in CLASSES])
    return survey, probs, num


def together(folder, load, *args):
    """Return ``load(*args)``; a key or a type missing in the files is an ``InputError``.

    Parameters
    ----------
    folder : str or pathlib.Path
        The output folder (named in the error).
    load : callable
        The reader.
    *args
        Its arguments.

    Returns
    -------
    object
        What ``load`` returns.
    """
    try:
        return load(*args)
    except InputError:  # a ValueError that names its file already
        raise
    except (KeyError, TypeError, IndexError, AttributeError, ValueError) as exc:
        raise InputError(f"{Path(folder) / MARKER}: the output files do not fit together "
                         f"({type(exc).__name__}: {exc}); was it edited? Run the command "
                         "again") from None


def numbers(folder, entry, keys, where) -> None:
    """Refuse an entry of ``summary.json`` whose ``keys`` are not finite numbers.

    ``null`` (how strict JSON writes a non-finite value) or text in a hand-edited summary
    ended as an internal error in the figures.

    Parameters
    ----------
    folder : str or pathlib.Path
        The output folder (its ``summary.json`` named in the error).
    entry : dict
        The entry.
    keys : sequence of str
    where : str
        The entry's path in the document (``beacons.4``).

    Raises
    ------
    InputError
    """
    if not isinstance(entry, dict):
        raise InputError(f"{Path(folder) / MARKER}: {where}: expected an object of "
                         f"{', '.join(keys)}, got {type(entry).__name__}")
    for key in keys:
        v = entry.get(key)
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v):
            raise InputError(f"{Path(folder) / MARKER}: {where}.{key}: expected a finite "
                             f"number, got {_shown(v)}; was it edited? Run the command "
                             "again")


def _shown(v) -> str:
    """``v`` as JSON writes it (``null``, quoted text), for messages."""
    import json

    try:
        return json.dumps(v)[:60]
    except (TypeError, ValueError):
        return repr(v)[:60]
