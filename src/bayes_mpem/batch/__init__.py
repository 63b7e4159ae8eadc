"""Many surveys at once on Dask: ``bayes-mpem batch``.

A *manifest* (CSV with a header) lists the surveys of an archive, one a row:
``name``, ``pings``, ``beacons`` for the LBL commands (``fit``, ``sample``,
``diagnose``, ``navigate``), or ``name``, ``survey``, ``format`` for the survey-in command
(``locate``); relative paths are relative to the manifest's folder. Other
columns are options of the command (the command line checks them as it checks
its own options, :mod:`bayes_mpem.cli.batch`).

:func:`run_batch` makes one Dask task per survey (the surveys of an archive far
outnumber the workers, so per-survey tasks keep every worker busy; a task per
beacon would pay only for batches of fewer dives than workers), on a local
cluster by default or on an existing scheduler. Each task writes the survey's
own output folder ``DIR/surveys/<name>/`` (as the single command would), its
classified rows to ``DIR/classified/survey-<name>.parquet`` (with a ``name``
column of text, so that ``pandas.read_parquet(DIR / "classified")`` reads them
all and a survey named ``001`` stays ``"001"``) and, last, ``batch.json`` with
the content hash of its inputs and options. A survey that fails leaves only
``failed.json`` (its reason) in its folder, never a previous run's results.
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

The commands are the entries of :data:`COMMANDS` (``navigate`` was added as one
more entry, with its option builder in :mod:`bayes_mpem.cli.batch`).
"""

from .commands import COMMANDS, Command, flatten, locate_raw
from .runner import BatchResult, completed, run_batch, run_task
from .tasks import BatchTask, read_manifest

__all__ = ["COMMANDS", "BatchResult", "BatchTask", "Command", "completed", "flatten",
           "locate_raw", "read_manifest", "run_batch", "run_task"]
