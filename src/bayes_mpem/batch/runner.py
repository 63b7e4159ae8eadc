"""Running a batch on Dask: one task per survey, resumable, failures recorded, tables gathered."""

from __future__ import annotations

import json
import os
import shutil
import sys
import time
import uuid
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from ..commands import load
from ..exceptions import InputError, Interrupted
from ..io.results import output_folder, write_json, write_parquet
from .commands import COMMANDS, flatten, run
from .tasks import BatchTask

#: where workers stage each survey's run, inside the batch's folder, until it is put in place
STAGING = ".batch-partial"
#: a batch's top-level files, its completion marker first (removed before a survey changes)
TOP_FILES = ("summary.json", "timings.json", "surveys.parquet", "beacons.parquet",
             "failures.parquet")


def run_task(task: BatchTask, out_dir: str, key: str | None = None) -> dict:
    """Run one survey and put its outputs in place: its folder, its partition, ``batch.json``.

    Never raises for a failure of the survey itself: it is returned, with its reason, and
    the survey's folder then holds only ``failed.json``. The survey is run into a staging
    folder of ``out_dir`` first: its earlier folder is replaced only once it has finished.

    Parameters
    ----------
    task : BatchTask
    out_dir : str
        The batch's output folder.
    key : str, optional
        :meth:`BatchTask.key`, if already computed.

    Returns
    -------
    dict
        ``name``, ``status`` (``done`` or ``failed``), ``seconds``, ``warnings``,
        and ``reason`` (failed) or ``rows`` (done: one flattened dict per beacon).
    """
    record, staged = _stage(task, out_dir, key)
    _put_in_place(task.name, record, staged, out_dir)
    return record


def _stage(task: BatchTask, out_dir: str, key: str | None = None) -> tuple:
    """Run one survey (on a Dask worker) into ``DIR/.batch-partial/<name>-<token>/``.

    Nothing else of ``out_dir`` is touched: a task cancelled or cut short by the cluster
    shutting down (Ctrl-C) leaves the survey's earlier folder as it was.

    Returns
    -------
    tuple
        The record (as :func:`run_task`'s) and the staging folder (``None`` when failed):
        ``survey/`` (the survey's folder, ``batch.json`` last) and ``classified.parquet``.
    """
    t0 = time.perf_counter()
    rows_of = load(COMMANDS[task.command].rows)
    staging = Path(out_dir) / STAGING / f"{task.name}-{uuid.uuid4().hex[:12]}"
    folder = staging / "survey"
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            _check_inputs(task)
            key = key or task.key()
            result = run(task.command, task.inputs, task.options)
            result.write(folder)
            beacons, classified, *own = rows_of(result)  # own: the survey's fields, if any
            rows = [{"name": task.name, "beacon": str(b), **flatten(v)}
                    for b, v in beacons.items()]
            if classified is not None:
                write_parquet(staging / "classified.parquet", _named(classified, task.name))
        except Exception as exc:  # noqa: BLE001 - a failed survey is a result of the batch
            shutil.rmtree(staging, ignore_errors=True)
            return _failure(task.name, exc, seconds=time.perf_counter() - t0,
                            warnings=[f"{w.category.__name__}: {w.message}"
                                      for w in caught]), None
        except BaseException:  # interrupted: nothing of this run is kept
            shutil.rmtree(staging, ignore_errors=True)
            raise
    record = {"name": task.name, "status": "done", "hash": key, "command": task.command,
              "seconds": time.perf_counter() - t0, "rows": rows,
              "warnings": [f"{w.category.__name__}: {w.message}" for w in caught]}
    if own and own[0]:
        record["fields"] = flatten(own[0])
    write_json(folder / "batch.json", record)  # last: its presence means the survey is complete
    return record, str(staging)


def _put_in_place(name: str, record: dict, staged: str | None, out_dir) -> None:
    """Replace a survey's folder and partition by a staged run's (a failed one's ``failed.json``).

    The partition goes first: a new partition beside the earlier folder (an interrupt
    between the two renames) is redone by the next run, the folder's hash differing.
    """
    out = Path(out_dir)
    folder = out / "surveys" / name
    part = _classified_file(out, name)
    legacy = out / "classified" / f"name={name}"  # the layout of earlier versions
    if legacy.is_dir():
        shutil.rmtree(legacy)
    if staged is None:
        part.unlink(missing_ok=True)  # no stale rows for a failed survey
        _failed_folder(folder, record)
        return
    staged = Path(staged)
    if (staged / "classified.parquet").is_file():
        output_folder(part.parent)
        os.replace(staged / "classified.parquet", part)
    else:
        part.unlink(missing_ok=True)
    if folder.exists():
        folder.rename(staged / "earlier")
    output_folder(folder.parent)
    (staged / "survey").rename(folder)
    shutil.rmtree(staged, ignore_errors=True)


def _retire_top(out: Path) -> None:
    """Remove a batch's top-level files, ``summary.json`` first: they describe an earlier run."""
    for name in TOP_FILES:
        (out / name).unlink(missing_ok=True)


def _check_inputs(task) -> None:
    """Raise InputError naming the manifest's line and column of an input file not usable.

    Not found, a folder, or not a regular file (a pipe, a device: hashing it would wait).
    """
    for col in COMMANDS[task.command].files:
        path = Path(task.inputs[col])
        problem = ("not found" if not path.exists() else
                   "is a folder; expected a file" if path.is_dir() else
                   "is not a regular file (a pipe or a device); expected a file"
                   if not path.is_file() else None)
        if problem is None:
            continue
        if task.where:  # a manifest's row
            raise InputError(f"{task.where}, column {col!r}: {path} {problem} (a relative "
                             "path is taken from the manifest's folder)")
        raise InputError(f"{task.name}: input {col!r}: {path} {problem}")


def _classified_file(out_dir, name: str) -> Path:
    """Return ``DIR/classified/survey-<name>.parquet`` (``name`` a text column in it)."""
    return Path(out_dir) / "classified" / f"survey-{name}.parquet"


def _failure(name: str, exc: BaseException, **more) -> dict:
    """Return the record of a survey that failed with ``exc``."""
    return {"name": name, "status": "failed", "reason": f"{type(exc).__name__}: {exc}", **more}


def _named(table: pd.DataFrame, name: str) -> pd.DataFrame:
    """Return the classified rows with the survey's name first (an input ``name`` kept)."""
    table = table.rename(columns={"name": "name_input"})  # a copy
    table.insert(0, "name", pd.Series([name] * len(table), index=table.index, dtype=object))
    return table


def _failed_folder(folder: Path, record: dict) -> None:
    """Leave only ``failed.json`` (the reason) in a failed survey's folder."""
    try:
        if folder.is_dir():
            shutil.rmtree(folder)
        write_json(output_folder(folder) / "failed.json",
                   {k: record[k] for k in ("name", "status", "reason")})
    except OSError:  # the record says why the survey failed in any case
        pass


def _completed(task: BatchTask, out_dir, key: str | None) -> dict | None:
    """Return the survey's record if complete with the hash ``key``, else None.

    An array's ``locate`` record without ``fields`` (an earlier version's) is not complete.
    """
    done = Path(out_dir) / "surveys" / task.name / "batch.json"
    if key is None or not done.is_file():
        return None
    try:
        record = json.loads(done.read_text())
    except (OSError, ValueError):
        return None
    if record.get("hash") != key:
        return None
    if record.get("command") == "locate" and "fields" not in record:
        # an array located by an earlier version: its centre is not in the record (a review:
        # a rerun kept no centre columns and no note of a transponder not located); run again
        try:
            summary = json.loads((done.parent / "summary.json").read_text())
        except (OSError, ValueError):
            return None
        if "array_centre" in summary:
            return None
    return record


def _key_or_none(task: BatchTask):
    if not all(Path(task.inputs[c]).is_file() for c in COMMANDS[task.command].files):
        return None  # not found, a folder, a pipe: the task runs, and fails naming it
    try:
        return task.key()
    except OSError:  # unreadable: the task runs, and fails with the reader's message
        return None


@dataclass(frozen=True)
class BatchResult:
    """What a batch did: the gathered tables.

    Attributes
    ----------
    surveys : pandas.DataFrame
        One row per survey: ``name``, ``status`` (``done``, ``complete``: skipped
        as already complete, ``failed``), ``seconds``, ``n_warnings``, ``warnings``,
        ``hash``; for ``locate`` on array surveys also the array centre (``centre_enu_*``,
        ``centre_transponders``) and ``centre_note`` (empty where every transponder was
        located).
    beacons : pandas.DataFrame
        One row per survey and beacon of every complete survey: ``name``,
        ``beacon`` and the flattened summary fields.
    failures : pandas.DataFrame
        ``name`` and ``reason`` of every survey that failed.
    command : str
    seconds : float
        Wall time of the batch (not written).
    """

    surveys: pd.DataFrame
    beacons: pd.DataFrame
    failures: pd.DataFrame
    command: str
    seconds: float = 0.0

    def write(self, out_dir) -> dict:
        """Write ``surveys.parquet``, ``beacons.parquet`` and ``failures.parquet``.

        Parameters
        ----------
        out_dir : str or pathlib.Path

        Returns
        -------
        dict
            Paths written.
        """
        out = output_folder(out_dir)
        return {k: write_parquet(out / f"{k}.parquet", getattr(self, k))
                for k in ("surveys", "beacons", "failures")}


def _gather(records: list, command: str, seconds: float) -> BatchResult:
    columns = ["name", "status", "seconds", "n_warnings", "warnings", "hash"]
    fields = list(dict.fromkeys(k for r in records for k in r.get("fields", {})))
    surveys = pd.DataFrame([{"name": r["name"], "status": r["status"],
                             "seconds": float(r.get("seconds", float("nan"))),
                             "n_warnings": len(r.get("warnings", [])),
                             "warnings": json.dumps(r.get("warnings", [])),
                             "hash": r.get("hash"), **r.get("fields", {})} for r in records],
                           columns=columns + [f for f in fields if f not in columns])
    rows = [row for r in records if r["status"] != "failed" for row in r["rows"]]
    beacons = pd.DataFrame(rows) if rows else pd.DataFrame(columns=["name", "beacon"])
    failures = pd.DataFrame([{"name": r["name"], "reason": r["reason"]}
                             for r in records if r["status"] == "failed"],
                            columns=["name", "reason"])
    return BatchResult(surveys, beacons, failures, command, seconds)


def _client(scheduler, n_workers):
    from distributed import Client, LocalCluster

    if scheduler:
        return Client(scheduler), None
    # ":0": the dashboard on a free port (None still asks for 8787, and a second cluster on
    # the machine then fails to start where warnings are errors)
    cluster = LocalCluster(n_workers=n_workers or 1, threads_per_worker=1, processes=True,
                           dashboard_address=":0", silence_logs=40)
    return Client(cluster), cluster


def _report(record, done, total):
    """Print the progress line of one survey on standard error."""
    what = (f"failed: {record['reason']}" if record["status"] == "failed" else
            "already complete" if record["status"] == "complete" else
            f"done in {record.get('seconds', 0.0):.1f} s")
    print(f"[{done}/{total}] {record['name']}: {what}", file=sys.stderr, flush=True)


def run_batch(tasks: list, out_dir, *, scheduler: str | None = None, n_workers: int | None = None,
              progress="auto", report: Callable | None = None) -> BatchResult:
    """Run every survey of a batch as a Dask task; skip those already complete.

    Parameters
    ----------
    tasks : list of BatchTask
        From :func:`read_manifest` (with options filled in as needed).
    out_dir : str or pathlib.Path
        The batch's folder (its contents: ``docs/cli.md``).
    scheduler : str, optional
        Address of a running Dask scheduler (``tcp://host:8786``); default a
        local cluster of ``n_workers`` processes (one thread each).
    n_workers : int, optional
        Workers of the local cluster (default 1, or the scheduler's own).
    progress : bool or "auto"
        A line on standard error per survey done (``"auto"``: when it is a terminal).
    report : callable, optional
        ``report(record, done, total)`` after each survey, instead of the progress line.

    Returns
    -------
    BatchResult
        Also written to ``out_dir`` (:meth:`BatchResult.write`).

    Raises
    ------
    InputError
        For tasks of unknown commands or repeated names, or ``n_workers`` < 1.
    """
    t0 = time.perf_counter()
    if n_workers is not None and (isinstance(n_workers, bool) or not isinstance(n_workers, int)
                                  or n_workers < 1):
        raise InputError(f"n_workers (--workers): expected an integer >= 1, got {n_workers!r}")
    names = [t.name for t in tasks]
    if len(set(names)) != len(names):
        raise InputError("batch: survey names must be unique")
    unknown = sorted({t.command for t in tasks} - set(COMMANDS))
    if unknown:
        raise InputError(f"batch: unknown command(s) {unknown}; expected one of {list(COMMANDS)}")
    out = output_folder(out_dir)
    if report is None and (sys.stderr.isatty() if progress == "auto" else progress):
        report = _report
    records, todo = {}, []
    for task in tasks:
        key = _key_or_none(task)
        old = _completed(task, out, key)
        if old is not None:
            records[task.name] = {**old, "status": "complete"}
        else:
            todo.append((task, key))
    total = len(tasks)
    for i, r in enumerate(records.values()):
        if report:
            report(r, i + 1, total)
    if todo:
        records.update(_submit(todo, out, scheduler, n_workers, report, len(records), total))
    shutil.rmtree(out / STAGING, ignore_errors=True)  # an interrupted run's, never put in place
    result = _gather([records[n] for n in names], tasks[0].command if tasks else "",
                     time.perf_counter() - t0)
    result.write(out)
    return result


def _submit(todo, out, scheduler, n_workers, report, n_done, total) -> dict:
    """Submit the tasks, put each survey in place as it completes, collect their records.

    Only this process changes ``surveys/`` and ``classified/``: the workers stage their
    runs (:func:`_stage`), so that after Ctrl-C (the tasks cancelled, the cluster shutting
    down) every survey not yet collected keeps its earlier folder. The batch's earlier
    top-level files are removed before the first survey is put in place.

    Raises
    ------
    Interrupted
        Ctrl-C after a survey was put in place: the message names the surveys kept.
    """
    from distributed import as_completed

    client, cluster = _client(scheduler, n_workers)
    records, first = {}, True
    try:
        futures = {client.submit(_stage, task, str(out), key, key=f"survey-{task.name}-"
                                 f"{key or 'unreadable'}", pure=False): task
                   for task, key in todo}
        for fut in as_completed(futures):
            task = futures[fut]
            if fut.status == "cancelled":  # not a failure of the survey: the batch stops
                raise InputError(
                    f"survey {task.name!r}: its task was cancelled by the Dask scheduler "
                    f"({scheduler or 'the local cluster'}, restarted or closed) before it "
                    "finished; expected it to run to its end. Its earlier folder is kept; "
                    "run the batch again to resume")
            if fut.status == "error":  # the worker itself died (memory, a crash)
                record, staged = _failure(task.name, fut.exception(), warnings=[]), None
            else:
                record, staged = fut.result()
            fut.release()
            if first:  # from here on the earlier top-level files would not match the surveys
                _retire_top(out)
                first = False
            _put_in_place(task.name, record, staged, out)
            records[task.name] = record
            n_done += 1
            if report:
                report(record, n_done, total)
    except KeyboardInterrupt:
        if records:  # "no result written" would be false: say what was kept
            raise Interrupted(_kept(out, records, len(todo))) from None
        raise
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
        shutil.rmtree(out / STAGING, ignore_errors=True)  # runs cut short, never put in place
    return records


def _kept(out, records: dict, n_todo: int) -> str:
    """Say what an interrupted batch kept: the surveys collected, and what the others keep."""
    shown = ", ".join(f"{name} ({r['status']})" for name, r in list(records.items())[:10])
    more = len(records) - 10
    n, rest = len(records), n_todo - len(records)
    return (f"the {n} survey{'s' if n > 1 else ''} collected before it "
            f"{'are' if n > 1 else 'is'} kept in {Path(out) / 'surveys'}: {shown}"
            + (f" and {more} more" if more > 0 else "")
            + f"; the {rest} not collected keep their earlier folders, if any; no top-level "
              "table written (surveys.parquet, beacons.parquet, failures.parquet, "
              "summary.json): run the batch again to finish it")
