"""Many surveys at once on Dask: ``bayes-mpem batch``.

A *manifest* (CSV with a header) lists the surveys of an archive, one a row:
``name``, ``pings``, ``beacons`` for the LBL commands (``fit``, ``sample``,
``diagnose``), or ``name``, ``survey``, ``format`` for the survey-in command
(``locate``); relative paths are relative to the manifest's folder. Other
columns are options of the command (the command line checks them as it checks
its own options, :mod:`bayes_mpem.cli.batch`).

:func:`run_batch` makes one Dask task per survey (the surveys of an archive far
outnumber the workers, so per-survey tasks keep every worker busy; a task per
beacon would pay only for batches of fewer dives than workers), on a local
cluster by default or on an existing scheduler. Each task writes the survey's
own output folder ``DIR/surveys/<name>/`` (as the single command would), its
classified rows to ``DIR/classified/name=<name>/part-0.parquet`` (one Parquet
dataset partitioned by survey: ``pandas.read_parquet(DIR / "classified")``)
and, last, ``batch.json`` with the content hash of its inputs and options.
A re-run skips every survey whose ``batch.json`` carries the same hash, so an
interrupted batch resumes where it stopped, and a changed input or option is
redone. A survey that fails is recorded with its reason and the others go on.
When every task is done the tables are gathered under ``DIR``:

* ``beacons.parquet``: one row per survey and beacon (transponder for
  ``locate``): ``name``, ``beacon`` and every field of the survey's summary for
  that beacon, nested fields joined by ``_`` (``d0``, ``weights_dp``,
  ``d0_interval_0``, ...);
* ``surveys.parquet``: one row per survey: ``status`` (``done``, ``complete``
  when skipped as already complete, ``failed``), ``seconds``, ``warnings``, ``hash``;
* ``failures.parquet``: ``name`` and ``reason`` of every survey that failed.

A remote scheduler's workers must see ``DIR`` and the input files at the same
paths (a shared file system). See ``docs/cli.md``.

The commands are the entries of :data:`COMMANDS`; adding one (``navigate``, when
it lands) is one more entry.
"""

from __future__ import annotations

import hashlib
import json
import sys
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import pandas as pd

from . import __version__
from .exceptions import InputError
from .io.results import output_folder, write_json, write_parquet

LBL_INPUTS = ("pings", "beacons")
SURVEY_INPUTS = ("survey", "format")


def _run_fit(inputs, options):
    from .lbl.fitting import fit

    return fit(inputs["pings"], inputs["beacons"], **options)


def _run_sample(inputs, options):
    from .lbl.sampling import sample

    return sample(inputs["pings"], inputs["beacons"], **{"progress": False, **options})


def _run_diagnose(inputs, options):
    from .lbl.diagnosis.driver import diagnose

    return diagnose(inputs["pings"], inputs["beacons"], **{"progress": False, **options})


def locate_raw(raw, options: dict):
    """Locate the transponders of a read survey, sampling their posteriors if asked.

    Parameters
    ----------
    raw : RawSurvey
    options : dict
        Keyword arguments of :func:`~bayes_mpem.survey_in.survey.locate_survey`,
        and ``sample``: None, or those of
        :func:`~bayes_mpem.survey_in.location_sampling.locate_survey_bayes`'s sampler.

    Returns
    -------
    SurveyInResult
    """
    from .survey_in.location_sampling import locate_survey_bayes
    from .survey_in.result import SurveyInResult
    from .survey_in.survey import locate_survey

    options = dict(options)
    sampling = options.pop("sample", None)
    if sampling is None:
        return locate_survey(raw, **options)
    summary, classified, posteriors = locate_survey_bayes(raw, **options, **sampling)
    return SurveyInResult(summary=summary, classified=classified, posteriors=posteriors)


def _run_locate(inputs, options):
    from .io.formats import read_survey

    return locate_raw(read_survey(inputs["survey"], inputs["format"]), options)


@dataclass(frozen=True)
class Command:
    """How the batch runs one command on one survey.

    Attributes
    ----------
    name : str
    inputs : tuple of str
        Manifest columns naming the survey's inputs (files, or the ``format``).
    files : tuple of str
        Those of ``inputs`` that are files (hashed, resolved against the manifest).
    run : callable
        ``run(inputs, options)`` returns the command's result (with ``write``).
    beacons : callable
        ``beacons(result)`` returns ``{beacon id: summary dict}``.
    classified : callable or None
        ``classified(result)`` returns the classified table, if the command has one.
    """

    name: str
    inputs: tuple
    files: tuple
    run: Callable = field(repr=False)
    beacons: Callable = field(repr=False)
    classified: Callable | None = field(default=None, repr=False)


def _diagnosis_beacons(result) -> dict:
    d = result.to_dict()
    effects = ",".join(e["name"] for e in d["effects"]) or "none"
    return {b: {**v, "effects": effects} for b, v in d["final_model"]["beacons"].items()}


#: The commands a batch can run, by name (``bayes-mpem batch --command``).
COMMANDS = {
    "fit": Command("fit", LBL_INPUTS, LBL_INPUTS, _run_fit,
                   lambda r: r.summary()["beacons"], lambda r: r.classified()),
    "sample": Command("sample", LBL_INPUTS, LBL_INPUTS, _run_sample,
                      lambda r: r.summary()["beacons"], lambda r: r.classified()),
    "diagnose": Command("diagnose", LBL_INPUTS, LBL_INPUTS, _run_diagnose, _diagnosis_beacons),
    "locate": Command("locate", SURVEY_INPUTS, ("survey",), _run_locate,
                      lambda r: r.summary["transponders"], lambda r: r.classified),
}


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
        """Content hash of the inputs (file bytes), options, command and package version.

        Returns
        -------
        str
            Hex SHA-256.
        """
        h = hashlib.sha256()
        h.update(json.dumps([self.command, __version__, self.inputs, self.options],
                            sort_keys=True, default=str).encode())
        for col in COMMANDS[self.command].files:
            with open(self.inputs[col], "rb") as fh:
                for block in iter(lambda: fh.read(1 << 20), b""):  # noqa: B023
                    h.update(block)
        return h.hexdigest()


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
    from ._validate import check_choice

    check_choice("command", command, tuple(COMMANDS))
    spec = COMMANDS[command]
    path = Path(path)
    table = pd.read_csv(path, dtype=str, keep_default_na=False, skipinitialspace=True)
    table.columns = [str(c).strip() for c in table.columns]
    missing = [c for c in ("name", *spec.inputs) if c not in table.columns]
    if missing:
        raise InputError(f"{path}: the manifest of '{command}' needs the columns "
                         f"{', '.join(('name', *spec.inputs))}; missing: {', '.join(missing)}")
    tasks, seen = [], {}
    for i, row in enumerate(table.to_dict("records")):
        where = f"{path} line {i + 2}"
        name = row["name"].strip()
        if not name or name in (".", "..") or any(c in name for c in "/\\:"):
            raise InputError(f"{where}, column 'name': expected a plain folder name, "
                             f"got {row['name']!r}")
        if name in seen:
            raise InputError(f"{where}, column 'name': {name!r} already on line {seen[name]}")
        seen[name] = i + 2
        inputs = {}
        for col in spec.inputs:
            value = row[col].strip()
            if not value:
                raise InputError(f"{where}, column {col!r}: expected a value, got an empty cell")
            inputs[col] = str((path.parent / value).resolve()) if col in spec.files else value
        tasks.append(BatchTask(name, command, inputs, where=where))
    options = table.drop(columns=["name", *spec.inputs])
    return tasks, options


def flatten(d: dict, prefix: str = "") -> dict:
    """Flatten a nested summary into one row: keys joined by ``_``, short lists numbered.

    Parameters
    ----------
    d : dict
    prefix : str, default ""

    Returns
    -------
    dict
        Scalars (and JSON text for what is neither a scalar nor a short list of them).

    Examples
    --------
    >>> flatten({"d0": {"mean": 1.0, "interval": [0.5, 1.5]}, "flags": []})
    {'d0_mean': 1.0, 'd0_interval_0': 0.5, 'd0_interval_1': 1.5, 'flags': '[]'}
    """
    out = {}
    for k, v in d.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict):
            out.update(flatten(v, key + "_"))
        elif (isinstance(v, (list, tuple)) and 0 < len(v) <= 4
              and all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in v)):
            out.update({f"{key}_{i}": x for i, x in enumerate(v)})
        elif isinstance(v, (list, tuple)):
            out[key] = json.dumps(v, default=str)
        else:
            out[key] = v
    return out


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
    spec = COMMANDS[task.command]
    out = Path(out_dir)
    folder = out / "surveys" / task.name
    done = folder / "batch.json"
    done.unlink(missing_ok=True)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            key = key or task.key()
            result = spec.run(task.inputs, task.options)
            result.write(folder)
            rows = [{"name": task.name, "beacon": str(b), **flatten(v)}
                    for b, v in spec.beacons(result).items()]
            if spec.classified is not None:
                part = output_folder(out / "classified" / f"name={task.name}")
                write_parquet(part / "part-0.parquet", spec.classified(result))
        except Exception as exc:  # noqa: BLE001 - a failed survey is a result of the batch
            return {"name": task.name, "status": "failed",
                    "reason": f"{type(exc).__name__}: {exc}",
                    "seconds": time.perf_counter() - t0,
                    "warnings": [f"{w.category.__name__}: {w.message}" for w in caught]}
    record = {"name": task.name, "status": "done", "hash": key, "command": task.command,
              "seconds": time.perf_counter() - t0, "rows": rows,
              "warnings": [f"{w.category.__name__}: {w.message}" for w in caught]}
    tmp = write_json(folder / "batch.json.tmp", record)
    tmp.replace(done)  # last, atomically: its presence means the survey is complete
    return record


def completed(task: BatchTask, out_dir, key: str | None) -> dict | None:
    """Return the record of the survey if already complete with this hash, else None.

    Parameters
    ----------
    task : BatchTask
    out_dir : str or pathlib.Path
    key : str or None
        :meth:`BatchTask.key` (None when an input could not be read).

    Returns
    -------
    dict or None
    """
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
    cluster = LocalCluster(n_workers=n_workers or 1, threads_per_worker=1, processes=True,
                           dashboard_address=None, silence_logs=40)
    return Client(cluster), cluster


def _progress(progress):
    if progress == "auto":
        progress = sys.stderr.isatty()
    return progress


def run_batch(tasks: list, out_dir, *, scheduler: str | None = None, n_workers: int | None = None,
              progress="auto", report: Callable | None = None) -> BatchResult:
    """Run every survey of a batch as a Dask task; skip those already complete.

    Parameters
    ----------
    tasks : list of BatchTask
        From :func:`read_manifest` (with options filled in as needed).
    out_dir : str or pathlib.Path
        The batch's folder (see the module's description of its contents).
    scheduler : str, optional
        Address of a running Dask scheduler (``tcp://host:8786``); default a
        local cluster of ``n_workers`` processes (one thread each).
    n_workers : int, optional
        Workers of the local cluster (default 1, or the scheduler's own).
    progress : bool or "auto"
        A line on standard error per survey done (``"auto"``: when it is a terminal).
    report : callable, optional
        ``report(record, done, total)`` after each survey (the command line's
        progress lines); overrides ``progress``.

    Returns
    -------
    BatchResult
        Also written to ``out_dir`` (:meth:`BatchResult.write`).

    Raises
    ------
    InputError
        For tasks of unknown commands or repeated names.
    """
    t0 = time.perf_counter()
    names = [t.name for t in tasks]
    if len(set(names)) != len(names):
        raise InputError("batch: survey names must be unique")
    unknown = sorted({t.command for t in tasks} - set(COMMANDS))
    if unknown:
        raise InputError(f"batch: unknown command(s) {unknown}; expected one of {list(COMMANDS)}")
    out = output_folder(out_dir)
    if report is None and _progress(progress):
        def report(record, done, total):
            print(f"[{done}/{total}] {record['name']}: {record['status']}"
                  + (f" ({record['reason']})" if record["status"] == "failed" else
                     f" in {record.get('seconds', 0.0):.1f} s"), file=sys.stderr, flush=True)
    records, todo = {}, []
    for task in tasks:
        key = _key_or_none(task)
        old = completed(task, out, key)
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
                exc = fut.exception()
                record = {"name": task.name, "status": "failed",
                          "reason": f"{type(exc).__name__}: {exc}", "warnings": []}
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
