"""Writing result files: the one writer behind every result's ``write()`` and every figure.

Details: ``docs/architecture.md``.
"""

from __future__ import annotations

import contextlib
import contextvars
import json
import os
import signal
import tempfile
import threading
from pathlib import Path

import numpy as np

from ..exceptions import InputError
from .documents import finite_json, json_text, numpy_to_json, split_timings
from .table_files import write_table_file

MARKER = "summary.json"
TIMINGS = "timings.json"
_RUNS: contextvars.ContextVar = contextvars.ContextVar("bayes_mpem_runs", default=())


def check_output_folder(out_dir, option: str = "out_dir") -> Path:
    """Check that ``out_dir`` is (or can become) a writable folder, without creating it.

    Parameters
    ----------
    out_dir : str or os.PathLike
    option : str, default "out_dir"
        The argument's name, for the message: the Python one by default (every ``write``
        method's), the option's (``"--out"``) from the command line.

    Returns
    -------
    pathlib.Path

    Raises
    ------
    InputError
        A file, a path under a file, or a folder that cannot be written.
    """
    out = Path(out_dir)
    if str(out_dir).strip() == "":
        raise InputError(f"{option}: expected a folder name, got an empty string")
    if out.exists() and not out.is_dir():
        raise InputError(f"{option} {str(out)!r}: is a file; expected a folder")
    base = out
    while not base.exists():
        if base.parent == base:
            break
        base = base.parent
    if base.exists() and not base.is_dir():
        raise InputError(f"{option} {str(out)!r}: lies under the file {str(base)!r}; "
                         "expected a folder")
    try:
        fd, probe = tempfile.mkstemp(prefix=".write-check-", dir=base)
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        raise InputError(f"{option} {str(out)!r}: cannot be written ({exc.strerror or exc} in "
                         f"{str(base)!r})") from None
    return out


@contextlib.contextmanager
def _interrupt_held():
    """Hold a Ctrl-C (SIGINT) to the end of the block, then deliver it to the handler then set.

    The renames of a commit are all or nothing: a Ctrl-C among them is delivered once
    they are done, to the handler in place then (Python's raises ``KeyboardInterrupt``; one
    that ``writing``'s ``on_commit`` set, e.g. ``SIG_IGN``, decides). Off the main thread
    (no signal handlers there) the block runs as it is.
    """
    if (threading.current_thread() is not threading.main_thread()
            or signal.getsignal(signal.SIGINT) is None):  # no handler of Python's to restore
        yield
        return
    held = []

    def hold(signum, frame):
        held.append(signum)

    previous = signal.signal(signal.SIGINT, hold)
    try:
        yield
    finally:
        if signal.getsignal(signal.SIGINT) is hold:  # else the block set its own
            signal.signal(signal.SIGINT, previous)
        if held:
            signal.raise_signal(signal.SIGINT)


class _Run:
    """The files staged by one ``writing()`` block, renamed into place at its commit."""

    def __init__(self, root: Path) -> None:
        self.root = root
        self.staged: dict[Path, Path] = {}  # final path -> temporary path
        self.markers: dict[Path, dict] = {}  # final path of a summary.json -> its document
        self.on_commit: list = []  # called once every file is in place, Ctrl-C still held
        self.committed = False

    def owns(self, path: Path) -> bool:
        return path.parent.resolve().is_relative_to(self.root.resolve())

    def commit(self) -> None:
        if not self.staged and not self.markers:
            self._committed()
            return  # nothing written: nothing to mark
        for path, doc in list(self.markers.items()):
            doc, timings = split_timings(doc)
            self.markers[path] = doc
            if timings:
                write_json(path.with_name(TIMINGS), timings)
        marker = self.root / MARKER
        old = read_marker(self.root, check=False) if marker.exists() else None
        texts, temps, path = self._marker_texts(marker, old), {}, marker
        try:  # every summary's text first: a full disk then leaves the earlier run as it was
            for path, text in texts.items():
                temps[path] = _temp_name(path)
                temps[path].write_text(text)
        except BaseException as exc:
            _discard(temps.values(), exc, path)
        with _interrupt_held():  # a Ctrl-C among the renames would leave half a run
            for path in temps:
                path.unlink(missing_ok=True)  # the top one last: from here on not complete
            for final, tmp in self.staged.items():
                os.replace(tmp, final)
            for path, tmp in temps.items():  # nested first, the top summary.json last
                os.replace(tmp, path)
            self._committed()
        self._clean_dead_partials()

    def _committed(self) -> None:
        self.committed = True
        for hook in self.on_commit:
            hook()

    def _marker_texts(self, marker: Path, old: dict | None) -> dict:
        """Return the run's ``summary.json`` texts (nested first), each listing its files."""
        new = {self._rel(p) for p in [*self.staged, *self.markers]} | {MARKER}
        doc = self.markers.pop(marker, None)
        old_files = set((old or {}).get("files", []))
        if doc is None and old is not None:
            doc = {k: v for k, v in old.items() if k != "files"}
            new |= {f for f in old_files if (self.root / f).exists()}
        # files of an earlier run that this one did not write stay (they may be the user's
        # inputs: `fit` into the folder `simulate` wrote), unlisted: not part of this result
        texts = {}
        for path in sorted(self.markers, key=lambda p: -len(p.parts)):  # nested, deepest first
            sub = path.parent
            files = sorted(self._rel(p, sub) for p in [*self.staged, *self.markers]
                           if p.parent.resolve().is_relative_to(sub.resolve()))
            texts[path] = json_text({**self.markers[path], "files": files}, 2)
        texts[marker] = json_text({**(doc or {}), "files": sorted(new)}, 2)
        return texts

    def abort(self) -> None:
        for tmp in self.staged.values():
            with contextlib.suppress(OSError):
                tmp.unlink()

    def _rel(self, path: Path, base: Path | None = None) -> str:
        return path.resolve().relative_to((base or self.root).resolve()).as_posix()

    def _clean_dead_partials(self) -> None:
        folders = {self.root} | {p.parent for p in self.staged}
        for folder in folders:
            for tmp in folder.glob(".*.partial-*"):
                pid = tmp.name.split(".partial-")[-1].split(".")[0]
                if pid.isdigit() and not _alive(int(pid)):
                    with contextlib.suppress(OSError):
                        tmp.unlink()


def _alive(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


@contextlib.contextmanager
def writing(out_dir, *, option: str = "out_dir", create: bool = True, on_commit=None):
    """Write one run's files into ``out_dir``, all or nothing; nested blocks join the outer run.

    A run that writes no ``summary.json`` keeps the folder's (``bayes-mpem plot`` adds figures).
    A Ctrl-C while the files are renamed into place is held until they all are (then
    raised); one after that leaves them in place.

    Parameters
    ----------
    out_dir : str or os.PathLike
    option : str, default "out_dir"
        The argument named in messages (:func:`check_output_folder`).
    create : bool, default True
        Create the folder now, else at the first file written.
    on_commit : callable, optional
        Called without arguments once the run's files are all in place (the commit), a
        Ctrl-C still held; in a nested block, at the outer run's commit.

    Yields
    ------
    pathlib.Path

    Raises
    ------
    InputError
        For an unusable folder.
    """
    out = check_output_folder(out_dir, option)
    if create:
        out.mkdir(parents=True, exist_ok=True)
    outer = next((run for run in _RUNS.get() if run.owns(out / "x")), None)
    if outer is not None:
        if on_commit is not None:
            outer.on_commit.append(on_commit)
        yield out
        return
    run = _Run(out)
    if on_commit is not None:
        run.on_commit.append(on_commit)
    token = _RUNS.set((*_RUNS.get(), run))
    try:
        yield out
        run.commit()
    except BaseException:
        if not run.committed:  # after the commit the files are the result, not temporaries
            run.abort()
        raise
    finally:
        _RUNS.reset(token)


def abort_open_runs() -> int:
    """Remove the temporary files of every open run (for a signal handler); return how many."""
    runs = _RUNS.get()
    for run in runs:
        run.abort()
    return len(runs)


def output_folder(out_dir) -> Path:
    """Create ``out_dir`` (and its parents) if missing, after :func:`check_output_folder`.

    Parameters
    ----------
    out_dir : str or pathlib.Path

    Returns
    -------
    pathlib.Path
    """
    out = check_output_folder(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    return out


def _current_run(path: Path):
    for run in reversed(_RUNS.get()):
        if run.owns(path):
            return run
    return None


def _temp_name(path: Path) -> Path:
    return path.with_name(f".{path.stem}.partial-{os.getpid()}{path.suffix}")


def _discard(temps, exc: BaseException, path: Path) -> None:
    """Remove the temporary files ``temps`` and raise ``exc`` (:func:`_named` for ``path``)."""
    for tmp in temps:
        with contextlib.suppress(OSError):
            tmp.unlink()
    named = _named(exc, path)
    if named is exc:
        raise exc
    raise named from None


def _named(exc: BaseException, path: Path) -> BaseException:
    """Return ``exc``, or where it is an ``OSError`` naming no file, one naming ``path``.

    A full disk's "[Errno 28] No space left on device" named no file.
    """
    if isinstance(exc, OSError) and not exc.filename and exc.errno is not None:
        return OSError(exc.errno, exc.strerror or str(exc), str(path))
    return exc


def write_file(path, write) -> Path:
    """Write a file through ``write(temporary_path)``, then rename it (or stage it in the run).

    Parameters
    ----------
    path : str or os.PathLike
    write : callable
        ``write(tmp)`` writes the whole file at ``tmp`` (same folder and suffix).

    Returns
    -------
    pathlib.Path
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = _temp_name(path)
    try:
        write(tmp)
    except BaseException as exc:
        _discard([tmp], exc, path)
    run = _current_run(path)
    if run is None:
        os.replace(tmp, path)
    else:
        run.staged.pop(path, None)
        run.staged[path] = tmp
    return path


def write_json(path, document, *, indent: int | None = 2, numpy: bool = False) -> Path:
    """Write ``document`` as strict JSON (a run's ``summary.json`` last, with ``"files"``).

    Parameters
    ----------
    path : str or pathlib.Path
    document : dict or list
    indent : int or None, default 2
    numpy : bool, default False
        Also accept NumPy scalars and arrays.

    Returns
    -------
    pathlib.Path
    """
    path = Path(path)
    run = _current_run(path)
    if run is not None and path.name == MARKER:
        path.parent.mkdir(parents=True, exist_ok=True)
        clean, replaced = finite_json(document, numpy)
        if replaced and isinstance(clean, dict):
            clean = {**clean, "non_finite": replaced}
        run.markers[path] = clean
        return path
    text = json_text(document, indent, numpy)
    return write_file(path, lambda tmp: tmp.write_text(text))


def write_table(path, table) -> Path:
    """Write a table without its index: CSV (vectorised), or Parquet for a ``.parquet`` path.

    Parameters
    ----------
    path : str or pathlib.Path
    table : pandas.DataFrame

    Returns
    -------
    pathlib.Path
    """
    return write_file(path, lambda tmp: write_table_file(tmp, table))


# the name the result classes use for their CSV tables
write_csv = write_table


def read_document(path) -> dict:
    """Read the JSON object a result wrote (``summary.json``, ...).

    Parameters
    ----------
    path : str or os.PathLike

    Raises
    ------
    InputError
        When the file is not a JSON object.
    """
    try:
        doc = json.loads(Path(path).read_text())
    except (ValueError, UnicodeDecodeError) as exc:
        raise InputError(f"{path}: not valid JSON ({exc}); the file is damaged") from None
    if not isinstance(doc, dict):
        raise InputError(f"{path}: expected a JSON object, got {type(doc).__name__}")
    return doc


def read_marker(folder, *, check: bool = True) -> dict:
    """Read a folder's ``summary.json`` and check that the run it describes is complete.

    Parameters
    ----------
    folder : str or os.PathLike
    check : bool, default True
        Check that every file listed under ``"files"`` exists.

    Returns
    -------
    dict

    Raises
    ------
    FileNotFoundError, InputError
        No ``summary.json``; one that is not valid JSON, or a listed file missing.
    """
    path = Path(folder) / MARKER
    if not path.is_file():
        raise FileNotFoundError(f"{path}: not found; the folder holds no complete output "
                                "(an interrupted run leaves none)")
    doc = read_document(path)
    if check:
        missing = [f for f in doc.get("files", []) if not (Path(folder) / f).exists()]
        if missing:
            raise InputError(f"{path}: lists {', '.join(missing[:5])}, which "
                             f"{'is' if len(missing) == 1 else 'are'} missing: the folder is "
                             "not a complete output")
    return doc


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
    """Write a table as Parquet without its index (mixed object columns as JSON text).

    Parameters
    ----------
    path : str or pathlib.Path
    table : pandas.DataFrame

    Returns
    -------
    pathlib.Path
    """
    table = table.copy()
    for name in table.columns:
        if table[name].dtype == object:
            table[name] = _uniform_column(table[name])
    return write_file(path, lambda tmp: table.to_parquet(tmp, index=False))
