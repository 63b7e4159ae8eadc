"""One BLAS thread for the GNSS-A array's many small and banded factorizations.

A long array fit factors hundreds of small dense and banded matrices; OpenBLAS's threads
cost more to start and join than they save on them. On a 2-core machine the SeaGap survey
took 13.5-14.4 s with OpenBLAS's two threads and 10.0-10.5 s with one (docs/gnssa.md,
"Threads"). A thread count the user sets in the environment is left alone.
"""

from __future__ import annotations

import contextlib
import functools
import os

#: Environment variables by which a user sets the BLAS's threads (any one set: left alone).
THREAD_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
                    "BLIS_NUM_THREADS")


def one_blas_thread():
    """Return a context in which the BLAS runs on one thread, unless the user chose.

    Returns
    -------
    contextlib.AbstractContextManager
        ``threadpoolctl.threadpool_limits(1, "blas")``, or a null context where one of
        :data:`THREAD_VARIABLES` is set.
    """
    if any(os.environ.get(name) for name in THREAD_VARIABLES):
        return contextlib.nullcontext()
    from threadpoolctl import threadpool_limits

    return threadpool_limits(limits=1, user_api="blas")


def with_one_blas_thread(func):
    """Decorate ``func`` to run within :func:`one_blas_thread`."""

    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        with one_blas_thread():
            return func(*args, **kwargs)

    return wrapper
