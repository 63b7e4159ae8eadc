"""One BLAS thread for the GNSS-A array's many small and banded factorizations.

A long array fit factors hundreds of small dense and banded matrices; OpenBLAS's threads
cost more to start and join than they save on them. On a 2-core machine the SeaGap survey
took 13.5-14.4 s with OpenBLAS's two threads and 10.0-10.5 s with one (docs/gnssa.md,
"Threads"). A thread count the user sets in the environment is left alone.

A BLAS's thread count belongs to the process, not to a Python thread: the limit is held
while any fit runs (calls from several threads, or nested, share one limit, counted) and
the original counts come back when the last of them returns.
"""

from __future__ import annotations

import contextlib
import functools
import os
import threading

#: Environment variables by which a user sets the BLAS's threads (any one set: left alone).
THREAD_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
                    "BLIS_NUM_THREADS")

_LOCK = threading.Lock()
_HELD = {"count": 0, "limiter": None}


@contextlib.contextmanager
def _shared_limit():
    """Hold ``threadpool_limits(1, "blas")`` while any caller is inside; counted."""
    from threadpoolctl import threadpool_limits

    with _LOCK:
        if _HELD["count"] == 0:
            _HELD["limiter"] = threadpool_limits(limits=1, user_api="blas")
        _HELD["count"] += 1
    try:
        yield
    finally:
        with _LOCK:
            _HELD["count"] -= 1
            if _HELD["count"] == 0:
                limiter, _HELD["limiter"] = _HELD["limiter"], None
                limiter.restore_original_limits()


def one_blas_thread():
    """Return a context in which the BLAS runs on one thread, unless the user chose.

    The limit is process-wide and shared: it is set when the first caller enters, and the
    original thread counts are restored when the last caller leaves, whatever the order in
    which overlapping callers (threads) leave.

    Returns
    -------
    contextlib.AbstractContextManager
        The shared ``threadpoolctl.threadpool_limits(1, "blas")``, or a null context where
        one of :data:`THREAD_VARIABLES` is set.
    """
    if any(os.environ.get(name) for name in THREAD_VARIABLES):
        return contextlib.nullcontext()
    return _shared_limit()


def with_one_blas_thread(func):
    """Decorate ``func`` to run within :func:`one_blas_thread`."""

    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        with one_blas_thread():
            return func(*args, **kwargs)

    return wrapper
