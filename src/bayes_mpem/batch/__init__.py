"""Many surveys at once on Dask, resumable: ``bayes-mpem batch`` (``docs/cli.md``)."""

from .commands import COMMANDS, flatten, locate_raw
from .runner import BatchResult, run_batch, run_task
from .tasks import BatchTask, read_manifest

__all__ = ["COMMANDS", "BatchResult", "BatchTask", "flatten", "locate_raw", "read_manifest",
           "run_batch", "run_task"]
