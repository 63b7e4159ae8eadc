"""Many surveys at once on Dask: ``bayes-mpem batch``.

:func:`run_batch` runs one command (an entry of :data:`COMMANDS`) on every survey of a
manifest, one Dask task per survey, on a local cluster or an existing scheduler. Each
survey writes its own output folder and ``batch.json`` with the hash of its inputs and
options, so a re-run skips what is done; a failed survey leaves ``failed.json`` and the
others go on. The tables gathered at the end (``beacons.parquet``, ``surveys.parquet``,
``failures.parquet``) and the manifest's columns are described in ``docs/cli.md``.
"""

from .commands import COMMANDS, flatten, locate_raw
from .runner import BatchResult, completed, run_batch, run_task
from .tasks import BatchTask, read_manifest

__all__ = ["COMMANDS", "BatchResult", "BatchTask", "completed", "flatten",
           "locate_raw", "read_manifest", "run_batch", "run_task"]
