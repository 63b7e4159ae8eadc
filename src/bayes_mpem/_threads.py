"""One BLAS thread for the GNSS-A array's many small and banded factorizations.

A long array fit factors hundreds of small dense and banded matrices; OpenBLAS's threads
cost more to start and join than they save on them. On a 2-core machine the SeaGap survey
took 13.5-14.4 s with OpenBLAS's two threads and 10.0-10.5 s with one (docs/gnssa.md,
"Threads"). A thread count the user sets in the environment is left alone.

A BLAS's thread count belongs to the process, not to a Python thread: the limit is held
while any fit runs (calls from several threads, or nested, share one limit, counted) and
the original counts come back when the last of them returns.

Within one fit, independent pieces of large dense work (the rows of the intervals' grid:
each a Cholesky factor, an inverse and two products of the full normal matrix) run on the
machine's cores through :func:`thread_map`, each on one BLAS thread: NumPy's products and
SciPy's dense Cholesky release the GIL. Each piece computes what it would in the loop, so
the numbers are the loop's to the bit. Where several fits run at once in this process
(threads of a caller), or inside a piece, the pieces run in order; where the environment sets
a thread count (``OMP_NUM_THREADS=1`` under Dask, joblib or MPI), at most that many run.
"""

from __future__ import annotations

import contextlib
import functools
import os
import threading
from concurrent.futures import ThreadPoolExecutor

#: Environment variables by which a user sets the BLAS's threads (any one set: left alone).
THREAD_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
                    "BLIS_NUM_THREADS")

#: Most threads :func:`thread_map` uses (the cores available, at most this).
MAX_WORKERS = 4

_LOCK = threading.Lock()
_HELD = {"count": 0, "limiter": None}
_FITS = {"count": 0}
_POOL = {"pool": None, "workers": 0, "pid": None}
_PREFIX = "bayes_mpem_map"


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
    """Decorate ``func`` to run within :func:`one_blas_thread`, counted as a fit running.

    :func:`thread_map` spreads work over the cores only while one such fit runs.
    """

    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        with _LOCK:
            _FITS["count"] += 1
        try:
            with one_blas_thread():
                return func(*args, **kwargs)
        finally:
            with _LOCK:
                _FITS["count"] -= 1

    return wrapper


def workers() -> int:
    """Return how many threads :func:`thread_map` would use now.

    The cores this process may run on (at most :data:`MAX_WORKERS`, and at most the least
    count of :data:`THREAD_VARIABLES` where the environment sets one: a user who sets
    ``OMP_NUM_THREADS=1`` under Dask, joblib or MPI asks for one thread) where at most one fit
    decorated by :func:`with_one_blas_thread` runs, else 1.

    Returns
    -------
    int
    """
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        cores = os.cpu_count() or 1
    for name in THREAD_VARIABLES:
        value = os.environ.get(name, "").strip()
        if value.isdigit() and int(value) > 0:
            cores = min(cores, int(value))
    with _LOCK:
        alone = _FITS["count"] <= 1
    return max(1, min(cores, MAX_WORKERS)) if alone else 1


def thread_map(func, items):
    """Return ``[func(x) for x in items]``, the calls spread over :func:`workers` threads.

    For independent pieces of dense linear algebra (LAPACK and BLAS release the GIL): each
    call computes what it would in the loop, so the results are the loop's to the bit. The
    first exception raised is raised, as in the loop.

    Parameters
    ----------
    func : callable
        Of one argument; must not depend on the order of the calls.
    items : iterable

    Returns
    -------
    list
    """
    items = list(items)
    n = min(workers(), len(items))
    if n <= 1 or threading.current_thread().name.startswith(_PREFIX):  # nested: in order
        return [func(x) for x in items]
    with _LOCK:
        if _POOL["workers"] < n or _POOL["pid"] != os.getpid():  # a forked child: new threads
            if _POOL["pool"] is not None and _POOL["pid"] == os.getpid():
                _POOL["pool"].shutdown(wait=False)
            _POOL.update(pool=ThreadPoolExecutor(n, thread_name_prefix=_PREFIX), workers=n,
                         pid=os.getpid())
        pool = _POOL["pool"]
    return list(pool.map(func, items))
