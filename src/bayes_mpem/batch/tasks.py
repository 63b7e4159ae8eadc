"""A survey of a batch (:class:`BatchTask`, its content hash) and the manifest that lists them."""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass, field
from pathlib import Path

import pandas as pd

from .. import __version__
from ..exceptions import InputError
from .commands import COMMANDS


@dataclass(frozen=True)
class BatchTask:
    """One survey of a batch.

    Attributes
    ----------
    name : str
        Unique; names the survey's output folder.
    command : str
        A key of :data:`COMMANDS`.
    inputs : dict
        Manifest column -> value (absolute paths for files).
    options : dict
        Keyword arguments of the command's library call.
    where : str
        Where the task came from (``"manifest.csv line 3"``), for messages.
    """

    name: str
    command: str
    inputs: dict
    options: dict = field(default_factory=dict)
    where: str = ""

    def key(self) -> str:
        """Return the hex SHA-256 of the inputs (file bytes), options, command and version."""
        h = hashlib.sha256()
        h.update(json.dumps([self.command, __version__, self.inputs, self.options],
                            sort_keys=True, default=str).encode())
        for col in COMMANDS[self.command].files:
            with open(self.inputs[col], "rb") as fh:
                for block in iter(lambda: fh.read(1 << 20), b""):  # noqa: B023
                    h.update(block)
        return h.hexdigest()


def _manifest_table(path: Path):
    """Read a manifest as text cells: ``(table, the line number of each row)``."""
    import csv

    from ..io.boundary import read_text_lines

    text_lines = read_text_lines(path, "manifest")
    rows, numbers, header = [], [], None
    for i, cells in enumerate(csv.reader(text_lines, skipinitialspace=True), start=1):
        if not any(c.strip() for c in cells) or cells[0].lstrip().startswith("#"):
            continue
        if header is None:
            header = [c.strip() for c in cells]
            _check_header(path, i, header, text_lines)
            continue
        if len(cells) != len(header):
            raise InputError(f"{path} line {i}: expected {len(header)} comma-separated cells "
                             f"(the header's), got {len(cells)}")
        rows.append(cells)
        numbers.append(i)
    if header is None:
        raise InputError(f"{path}: an empty manifest; expected a CSV header line (name, then "
                         "the command's input columns) and one row per survey")
    if not rows:
        raise InputError(f"{path}: the manifest lists no survey (a header and no row)")
    return pd.DataFrame(rows, columns=header, dtype=object), numbers


def _check_header(path: Path, line: int, header: list, lines: list) -> None:
    """Refuse a manifest's header that would read wrongly, naming the manifest and the line.

    A header of one column that looks semicolon- or tab-separated (Excel's CSV where the
    list separator is ``;``: each row would be one cell), and a column named twice (a row's
    first cell of the two would be dropped).

    Parameters
    ----------
    path : pathlib.Path
    line : int
        The header's line number (1-based).
    header : list of str
        Its cells.
    lines : list of str
        The manifest's lines.

    Raises
    ------
    InputError
    """
    from ..io.boundary import sniff_delimiter

    text = lines[line - 1]
    row = next((t for t in lines[line:] if t.strip() and not t.lstrip().startswith("#")), None)
    looks = sniff_delimiter(text, row) if len(header) == 1 else None
    if looks:
        raise InputError(f"{path} line {line}: the header {text.strip()[:60]!r} is one column; "
                         f"the manifest looks {looks}; expected comma-separated values "
                         "(e.g. name,pings,beacons)")
    first = {}
    for pos, name in enumerate(header, start=1):
        if name in first:
            raise InputError(f"{path} line {line}: column {name!r} appears twice in the header "
                             f"(columns {first[name]} and {pos}); expected each column once")
        first[name] = pos


def read_manifest(path, command: str = "fit") -> tuple[list, pd.DataFrame]:
    """Read a manifest: the surveys' inputs, and the option columns left to the caller.

    Parameters
    ----------
    path : str or pathlib.Path
        CSV with a header: ``name`` and the command's input columns
        (``pings``, ``beacons``; or ``survey``, ``format``), then any option columns.
    command : str, default "fit"
        A key of :data:`COMMANDS`.

    Returns
    -------
    tasks : list of BatchTask
        One per row, without options.
    options : pandas.DataFrame
        The option columns, as text (empty cells are ``""``), one row per task.

    Raises
    ------
    InputError
        A missing column, an empty or repeated name, a name that is not a plain
        folder name, an empty input cell: the message names the file and line.
    FileNotFoundError
        When the manifest does not exist.
    """
    from .._validate import check_choice

    check_choice("command", command, tuple(COMMANDS))
    spec = COMMANDS[command]
    path = Path(path)
    table, lines = _manifest_table(path)
    missing = [c for c in ("name", *spec.inputs) if c not in table.columns]
    if missing:
        raise InputError(f"{path}: the manifest of '{command}' needs the columns "
                         f"{', '.join(('name', *spec.inputs))}; missing: {', '.join(missing)}")
    tasks, seen = [], {}
    for i, row in enumerate(table.to_dict("records")):
        where = f"{path} line {lines[i]}"
        name = row["name"].strip()
        if not name or name in (".", "..") or any(c in name for c in "/\\:"):
            raise InputError(f"{where}, column 'name': expected a plain folder name, "
                             f"got {row['name']!r}")
        if name.casefold() in seen:  # one folder on macOS's and Windows's file systems
            first, line = seen[name.casefold()]
            also = "" if first == name else f" as {first!r} (names differing only in case " \
                "would share one output folder on macOS and Windows)"
            raise InputError(f"{where}, column 'name': {name!r} already on line {line}{also}")
        seen[name.casefold()] = (name, lines[i])
        inputs = {}
        for col in spec.inputs:
            value = row[col].strip()
            if not value:
                raise InputError(f"{where}, column {col!r}: expected a value, got an empty cell")
            inputs[col] = str((path.parent / value).resolve()) if col in spec.files else value
        tasks.append(BatchTask(name, command, inputs, where=where))
    options = table.drop(columns=["name", *spec.inputs])
    return tasks, options


