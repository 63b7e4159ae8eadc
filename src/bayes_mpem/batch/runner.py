"""Running a batch on Dask: one task per survey, resumable, failures recorded, tables gathered."""

from __future__ import annotations

import json
import shutil
import sys
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from ..commands import load
from ..exceptions import InputError
from ..io.results import output_folder, write_json, write_parquet
from .commands import COMMANDS, flatten, run
from .tasks import BatchTask


def run_task(task: BatchTask, out_dir: str, key: str | None = None) -> dict:
    """Run one survey (on a Dask worker): write its outputs, its partition and ``batch.json``.

    Never raises for a failure of the survey itself: it is returned, with its reason.

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
    t0 = time.perf_counter()
    rows_of = load(COMMANDS[task.command].rows)
    out = Path(out_dir)
    folder = out / "surveys" / task.name
    done = folder / "batch.json"
    done.unlink(missing_ok=True)
    part = _classified_file(out, task.name)
    part.unlink(missing_ok=True)  # no stale rows if this run fails
    old = out / "classified" / f"name={task.name}"  # the layout of earlier versions
    if old.is_dir():
        shutil.rmtree(old)
    if folder.is_dir():  # a previous run's results would look complete if this one fails
        shutil.rmtree(folder)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            _check_inputs(task)
            key = key or task.key()
            result = run(task.command, task.inputs, task.options)
            result.write(folder)
            beacons, classified = rows_of(result)
            rows = [{"name": task.name, "beacon": str(b), **flatten(v)}
                    for b, v in beacons.items()]
            if classified is not None:
                output_folder(part.parent)
                write_parquet(part, _named(classified, task.name))
        except Exception as exc:  # noqa: BLE001 - a failed survey is a result of the batch
            record = _failure(task.name, exc, seconds=time.perf_counter() - t0,
                              warnings=[f"{w.category.__name__}: {w.message}" for w in caught])
            _failed_folder(folder, record)
            return record
    record = {"name": task.name, "status": "done", "hash": key, "command": task.command,
              "seconds": time.perf_counter() - t0, "rows": rows,
              "warnings": [f"{w.category.__name__}: {w.message}" for w in caught]}
    tmp = write_json(folder / "batch.json.tmp", record)
    tmp.replace(done)  # last, atomically: its presence means the survey is complete
    return record


def _check_inputs(task) -> None:
    """Raise InputError naming the manifest's line and column of an input file not found."""
    for col in COMMANDS[task.command].files:
        if not Path(task.inputs[col]).exists():
            if task.where:  # a manifest's row
                raise InputError(f"{task.where}, column {col!r}: {task.inputs[col]} not found "
                                 "(a relative path is taken from the manifest's folder)")
            raise InputError(f"{task.name}: input {col!r}: {task.inputs[col]} not found")


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
    """Return the survey's record if complete with the hash ``key``, else None."""
    done = Path(out_dir) / "surveys" / task.name / "batch.json"
    if key is None or not done.is_file():
        return None
    try:
        record = json.loads(done.read_text())
    except (OSError, ValueError):
        return None
    return record if record.get("hash") == key else None


def _key_or_none(task: BatchTask):
    try:
        return task.key()
    except OSError:  # a missing input: the task runs, and fails with the reader's message
        return None


@dataclass(frozen=True)
class BatchResult:
    """What a batch did: the gathered tables.

    Attributes
    ----------
    surveys : pandas.DataFrame
        One row per survey: ``name``, ``status`` (``done``, ``complete``: skipped
        as already complete, ``failed``), ``seconds``, ``n_warnings``, ``warnings``,
        ``hash``.
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
    surveys = pd.DataFrame([{"name": r["name"], "status": r["status"],
                             "seconds": float(r.get("seconds", float("nan"))),
                             "n_warnings": len(r.get("warnings", [])),
                             "warnings": json.dumps(r.get("warnings", [])),
                             "hash": r.get("hash")} for r in records],
                           columns=["name", "status", "seconds", "n_warnings", "warnings",
                                    "hash"])
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
    result = _gather([records[n] for n in names], tasks[0].command if tasks else "",
                     time.perf_counter() - t0)
    result.write(out)
    return result


def _submit(todo, out, scheduler, n_workers, report, n_done, total) -> dict:
    """Submit the tasks, collect their records as they complete."""
    from distributed import as_completed

    client, cluster = _client(scheduler, n_workers)
    records = {}
    try:
        futures = {client.submit(run_task, task, str(out), key, key=f"survey-{task.name}-"
                                 f"{key or 'unreadable'}", pure=False): task
                   for task, key in todo}
        for fut in as_completed(futures):
            task = futures[fut]
            if fut.status == "error":  # the worker itself died (memory, a crash)
                record = _failure(task.name, fut.exception(), warnings=[])
            else:
                record = fut.result()
            fut.release()
            records[task.name] = record
            n_done += 1
            if report:
                report(record, n_done, total)
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    return records
