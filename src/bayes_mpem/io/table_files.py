r"""Table files in and out: CSV (a typed C parser, exact line numbers) and Parquet."""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.compute as pc

from ..exceptions import InputError
from .boundary import open_input, sniff_delimiter, split_lines
from .cells import Problems

PARQUET_SUFFIXES = (".parquet", ".pq")
#: The formats of the tables a result writes (``--table-format``).
TABLE_FORMATS = ("csv", "parquet")


@dataclass
class TableText:
    """A table file as read, before validation.

    Attributes
    ----------
    frame : pandas.DataFrame
        Column names stripped, RangeIndex; CSV: every cell as text.
    lines : numpy.ndarray or None
        The file line of each row (CSV), ``None`` for Parquet.
    comments : int
        ``#`` comment lines skipped (CSV).
    """

    frame: pd.DataFrame
    lines: np.ndarray | None
    comments: int = 0


def _is_parquet(path) -> bool:
    """Whether ``path`` names a Parquet file (by its extension)."""
    return Path(path).suffix.lower() in PARQUET_SUFFIXES


def read_table_file(path, label: str, what: str = "table file") -> TableText:
    """Read a CSV or Parquet table file (CSV by pyarrow unless a field is quoted; lines kept).

    Parameters
    ----------
    path : str or os.PathLike
    label, what : str
        The file's name and what it is, for messages.

    Returns
    -------
    TableText

    Raises
    ------
    FileNotFoundError, InputError
        No file; an unreadable, binary, non-UTF-8, empty, ragged or not comma-separated file.
    """
    if _is_parquet(path):
        return _read_parquet(path, label, what)
    raw = open_input(path, what)
    if raw.startswith(b"\xef\xbb\xbf"):
        raw = raw[3:]
    if b"\x00" in raw:
        line = raw.count(b"\n", 0, raw.index(b"\x00")) + 1
        raise InputError(f"{label} line {line}: a NUL byte; expected a CSV text file, "
                         "not binary")
    fast = _read_csv_fast(raw, label)
    return fast if fast is not None else _read_csv_exact(raw, label)


def _read_parquet(path, label, what):
    import pyarrow.parquet as pq

    open_input(path, what)  # the same errors for a folder or a missing file
    try:
        table = pq.read_table(path)
    except (pa.ArrowException, OSError) as exc:
        raise InputError(f"{label}: not a readable Parquet file ({exc})") from None
    frame = table.to_pandas()
    frame.columns = [str(c).strip() for c in frame.columns]
    return TableText(frame.reset_index(drop=True), None)


def _decode_error(raw: bytes, label: str) -> None:
    try:
        raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = raw.count(b"\n", 0, exc.start) + 1
        raise InputError(f"{label} line {line}: not UTF-8 text ({exc.reason})") from None


def _line_bounds(arr: np.ndarray):
    r"""Start and end (exclusive, ``\r\n`` and ``\n`` dropped) of every line."""
    nl = np.flatnonzero(arr == 10)
    starts = np.concatenate([[0], nl + 1])
    ends = np.concatenate([nl, [arr.size]])
    if starts[-1] == arr.size:  # a final newline ends the last line
        starts, ends = starts[:-1], ends[:-1]
    cr = (ends > starts) & (arr[np.maximum(ends - 1, 0)] == 13)
    return starts, ends - cr


def _read_csv_fast(raw: bytes, label: str) -> TableText | None:
    """Pyarrow's parser on the data lines; ``None`` when only the exact reader is exact."""
    arr = np.frombuffer(raw, dtype=np.uint8)
    if b'"' in raw:
        return None
    cr = np.flatnonzero(arr == 13)
    if cr.size and np.any(arr[np.minimum(cr + 1, arr.size - 1)] != 10) or (
            cr.size and cr[-1] == arr.size - 1):
        return None  # a lone \r, which pyarrow would take for a line end
    starts, ends = _line_bounds(arr)
    first = arr[np.minimum(starts, arr.size - 1)] if arr.size else np.zeros(0, np.uint8)
    empty = ends == starts
    blank, comment = empty.copy(), ~empty & (first == 35)
    for i in np.flatnonzero(~empty & np.isin(first, (9, 11, 12, 32))):  # rare: leading spaces
        text = raw[starts[i]:ends[i]].strip()
        blank[i], comment[i] = not text, text.startswith(b"#")
    data = np.flatnonzero(~blank & ~comment)
    if data.size == 0:
        return None  # the exact reader says the file is empty
    comma_at = np.flatnonzero(arr == 44)
    n_commas = (np.searchsorted(comma_at, ends[data]) - np.searchsorted(comma_at, starts[data]))
    header = raw[starts[data[0]]:ends[data[0]]]
    if np.any(n_commas != n_commas[0]) or n_commas[0] == 0:
        return None  # ragged or not comma-separated: the exact reader names the lines
    try:
        names = [h.strip() for h in header.decode("utf-8").split(",")]
    except UnicodeDecodeError:
        return None
    body = data[1:]
    text = raw if (data.size == starts.size and not np.any(arr == 13)) else b"\n".join(
        raw[s:e] for s, e in zip(starts[data], ends[data], strict=True))
    frame = _arrow_parse(text, names)
    if frame is None:
        _decode_error(raw, label)
        return None
    if len(frame) != body.size:
        return None
    return TableText(frame, body + 1, int(comment.sum()))


def _arrow_parse(text: bytes, names: list[str]) -> pd.DataFrame | None:
    import pyarrow.csv as pcsv

    generic = [f"c{i}" for i in range(len(names))]
    try:
        table = pcsv.read_csv(
            pa.py_buffer(text),
            read_options=pcsv.ReadOptions(column_names=generic, skip_rows=1,
                                          block_size=1 << 24),
            parse_options=pcsv.ParseOptions(newlines_in_values=False, ignore_empty_lines=True),
            convert_options=pcsv.ConvertOptions(
                column_types={c: pa.string() for c in generic}, strings_can_be_null=False,
                quoted_strings_can_be_null=False))
    except (pa.ArrowInvalid, pa.ArrowException):
        return None
    cols = [pc.utf8_ltrim(col, characters=" ") for col in table.columns]  # skipinitialspace
    frame = pa.table(cols, names=[f"c{i}" for i in range(len(cols))]).to_pandas()
    frame.columns = names
    return frame


def _read_csv_exact(raw: bytes, label: str) -> TableText:
    """Python's csv module on lines split as ``grep -n`` splits them; names every problem."""
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        _decode_error(raw, label)
        raise  # pragma: no cover (_decode_error raised)
    lines = split_lines(text)
    kept = [(i, ln) for i, ln in enumerate(lines, start=1)
            if ln.strip() and not ln.lstrip().startswith("#")]
    n_comments = sum(1 for ln in lines if ln.lstrip().startswith("#"))
    if not kept:
        raise InputError(f"{label}: the file is empty (expected a header line of column names)")
    # each line with its newline: a quoted cell that spans lines keeps its line break
    reader = csv.reader((ln + "\n" for _, ln in kept), skipinitialspace=True)
    records, where, first = [], [], 0
    try:
        for rec in reader:
            records.append(rec)
            where.append(kept[first][0])  # the record's first line
            first = reader.line_num
    except csv.Error as exc:
        line = kept[min(reader.line_num, len(kept)) - 1][0]
        raise InputError(f"{label} line {line}: malformed CSV ({exc})") from None
    header = [h.strip() for h in records[0]]
    _check_shape(label, header, records[1:], where, kept)
    columns = list(zip(*records[1:], strict=True)) if len(records) > 1 else [()] * len(header)
    frame = pd.DataFrame({i: pd.Series(list(col), dtype="str") for i, col in enumerate(columns)})
    frame.columns = header
    return TableText(frame, np.asarray(where[1:], dtype=np.int64), n_comments)


def _check_shape(label, header, records, where, kept):
    looks = sniff_delimiter(kept[0][1], kept[1][1] if len(kept) > 1 else None)
    if looks and len(header) == 1:
        raise InputError(
            f"{label} line {where[0]}: the header {kept[0][1].strip()[:60]!r} is one column; "
            f"the file looks {looks}; expected comma-separated values with a decimal point "
            "(e.g. time,beacon,range,x,y,depth)")
    bad = [(line, len(rec)) for rec, line in zip(records, where[1:], strict=True)
           if len(rec) != len(header)]
    if not bad:
        return
    problems = Problems(label)
    for pos, (line, n) in enumerate(bad):
        problems.add(pos, f"{label} line {line}: expected {len(header)} fields (as in the "
                          f"header), got {n}")
    problems.raise_if_any()


# --------------------------------------------------------------------------- writing


def format_floats(values) -> pa.Array:
    """Format floats as ``repr`` does ('' for NaN), vectorised by pyarrow.

    Parameters
    ----------
    values : array_like

    Returns
    -------
    pyarrow.StringArray
    """
    v = np.asarray(values, dtype=float)
    arrow = pc.cast(pa.array(v), pa.string())
    if isinstance(arrow, pa.ChunkedArray):
        arrow = arrow.combine_chunks()
    mag = np.abs(v)
    with np.errstate(invalid="ignore"):
        positional = ((mag >= 1e-4) & (mag < 1e16)) | (mag == 0)  # repr: '0.0', '1e-05'
    offsets, data = _string_buffers(arrow)
    has_e, after_e = _where_byte(offsets, data, b"e")
    has_dot, _ = _where_byte(offsets, data, b".")
    two_digit_exp = has_e & (after_e >= 4)  # 'e', the sign, two digits or more
    finite = np.isfinite(v)
    same = finite & np.where(positional, has_dot & ~has_e, has_e & two_digit_exp)
    integral = finite & positional & ~has_e & ~has_dot
    one_digit_exp = finite & ~positional & has_e & ~two_digit_exp  # 1e-7 -> 1e-07
    out = arrow
    if integral.any():  # '1' -> '1.0', on those strings only
        part = out.take(pa.array(np.flatnonzero(integral)))
        out = pc.replace_with_mask(out, pa.array(integral),
                                   pc.binary_join_element_wise(part, ".0", ""))
    if one_digit_exp.any():  # '1e-7' -> '1e-07'
        part = out.take(pa.array(np.flatnonzero(one_digit_exp)))
        out = pc.replace_with_mask(out, pa.array(one_digit_exp),
                                   pc.replace_substring_regex(part, r"e([+-])(\d)$", r"e\10\2"))
    fix = np.flatnonzero(~same & ~integral & ~one_digit_exp)
    if fix.size:  # NaN, infinities and the few layouts pyarrow writes otherwise
        mask = np.zeros(v.size, bool)
        mask[fix] = True
        fixed = pa.array(["" if np.isnan(x) else repr(float(x)) for x in v[fix]], pa.string())
        out = pc.replace_with_mask(out, pa.array(mask), fixed)
    return out


def _quoted_characters() -> str:
    """Return the characters that make the csv writer quote a field (as pandas writes)."""
    import io

    chars = []
    for c in ",\"\r\n\t;":
        buf = io.StringIO()
        csv.writer(buf, lineterminator="\n").writerow(["a" + c, "b"])
        if buf.getvalue().startswith('"'):
            chars.append({"\r": "\\r", "\n": "\\n", "\t": "\\t"}.get(c, c))
    return "[" + "".join(chars) + "]"


_NEEDS_QUOTES = _quoted_characters()


def _string_buffers(arr: pa.Array):
    """Offsets (n + 1) and the bytes of a string array without nulls."""
    offsets = np.frombuffer(arr.buffers()[1], dtype=np.int32)[arr.offset:arr.offset + len(arr)
                                                                + 1]
    data = np.frombuffer(arr.buffers()[2], dtype=np.uint8) if len(arr) else np.zeros(0, np.uint8)
    return offsets, data


def _where_byte(offsets, data, byte: bytes):
    """Per string: holds ``byte``; the length from its last occurrence to the string's end."""
    n = offsets.size - 1
    pos = np.flatnonzero(data[offsets[0]:offsets[-1]] == byte[0]) + offsets[0]
    owner = np.searchsorted(offsets, pos, side="right") - 1
    has = np.zeros(n, bool)
    has[owner] = True
    tail = np.zeros(n, np.int64)
    tail[owner] = offsets[owner + 1] - pos  # the last occurrence wins (positions ascend)
    return has, tail


def _column_text(col: pd.Series) -> pa.Array:
    if isinstance(col.dtype, pd.StringDtype) or isinstance(col.dtype, pd.ArrowDtype):
        try:  # pyarrow-backed text: no Python string per cell
            arr = pa.array(col.array, from_pandas=True)
            if isinstance(arr, pa.ChunkedArray):
                arr = arr.combine_chunks()
            if pa.types.is_string(arr.type) or pa.types.is_large_string(arr.type):
                return _quote(pc.fill_null(arr.cast(pa.string()), ""))
        except (pa.ArrowInvalid, pa.ArrowTypeError):
            pass
    if pd.api.types.is_float_dtype(col.dtype):
        return format_floats(col.to_numpy(dtype=float, na_value=np.nan))
    if pd.api.types.is_integer_dtype(col.dtype) and not col.isna().any():
        return pc.cast(pa.array(col.to_numpy()), pa.string())
    if pd.api.types.is_bool_dtype(col.dtype) or not (
            pd.api.types.is_string_dtype(col.dtype) or col.dtype == object):
        return pa.array(col.astype(object).map(lambda x: "" if pd.isna(x) else str(x)),
                        type=pa.string())
    values = col.astype(object).where(col.notna(), "")
    if pd.api.types.infer_dtype(values, skipna=False) not in ("string", "empty"):
        values = values.map(lambda x: x if isinstance(x, str) else
                            (repr(x) if isinstance(x, float) else str(x)))
    return _quote(pa.array(values.to_numpy(dtype=object), type=pa.string()))


def _quote(arr: pa.Array) -> pa.Array:
    if isinstance(arr, pa.ChunkedArray):
        arr = arr.combine_chunks()
    if arr.null_count == 0 and pa.types.is_string(arr.type):
        offsets, data = _string_buffers(arr)
        special = np.frombuffer(_NEEDS_QUOTES[1:-1].encode().decode("unicode_escape").encode(),
                                np.uint8)
        if not np.isin(data[offsets[0]:offsets[-1]], special).any():
            return arr  # nothing to quote: the usual case, found on the raw bytes
    need = pc.match_substring_regex(arr, _NEEDS_QUOTES)
    if pc.any(need).as_py():
        quoted = pc.binary_join_element_wise('"', pc.replace_substring(arr, '"', '""'), '"', "")
        arr = pc.if_else(need, quoted, arr)
    return arr


def frame_as_text(frame: pd.DataFrame) -> pd.DataFrame:
    """Return every cell as the text CSV would hold ('' for missing; floats as ``repr``).

    Parameters
    ----------
    frame : pandas.DataFrame

    Returns
    -------
    pandas.DataFrame
    """
    cols = {}
    for j, name in enumerate(frame.columns):
        col = frame.iloc[:, j]
        if pd.api.types.is_float_dtype(col.dtype):
            arr = format_floats(col.to_numpy(dtype=float, na_value=np.nan))
            cols[j] = pd.Series(arr.to_pylist(), dtype="str")
        else:
            cols[j] = col.astype(object).where(col.notna(), "").astype(str)
    out = pd.DataFrame(cols)
    out.columns = list(frame.columns)
    return out


def table_to_csv_bytes(frame: pd.DataFrame) -> bytes:
    """Return the bytes ``frame.to_csv(index=False)`` writes, formatted by pyarrow kernels.

    Parameters
    ----------
    frame : pandas.DataFrame
        Text, float, integer or boolean columns.

    Returns
    -------
    bytes
    """
    header = frame.head(0).to_csv(index=False).encode()
    if len(frame) == 0:
        return header
    cols = [_column_text(frame.iloc[:, j]) for j in range(frame.shape[1])]
    if len(cols) == 1:  # csv quotes a row's only field when it is empty
        joined = pc.if_else(pc.equal(cols[0], ""), '""', cols[0])
    else:
        joined = pc.binary_join_element_wise(*cols, ",")
    lines = pc.binary_join_element_wise(joined, "", "\n")
    if isinstance(lines, pa.ChunkedArray):
        lines = lines.combine_chunks()
    lines = lines.cast(pa.large_string())
    offsets = np.frombuffer(lines.buffers()[1], dtype=np.int64)[
        lines.offset:lines.offset + len(lines) + 1]
    body = memoryview(lines.buffers()[2])[offsets[0]:offsets[-1]]
    return header + bytes(body)


def write_table_file(path, frame: pd.DataFrame) -> None:
    """Write ``frame`` as CSV, or as Parquet when ``path`` ends in ``.parquet``/``.pq``.

    Parameters
    ----------
    path : str or os.PathLike
    frame : pandas.DataFrame
        Written without its index.
    """
    if _is_parquet(path):
        import pyarrow.parquet as pq

        pq.write_table(pa.Table.from_pandas(frame, preserve_index=False), path)
        return
    with open(path, "wb") as fh:
        fh.write(table_to_csv_bytes(frame))
