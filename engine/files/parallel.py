"""
Thread-parallel chunks for the forward model's heavy numpy kernels.

numpy releases the GIL inside its array operations, so independent chunks of
a vectorised kernel (form factors, segment tests) run on several cores from
threads, without processes or pickling.  The worker count is the machine's
core count (at most :data:`MAX_WORKERS`), or ``LBSCENE_THREADS`` when set
(``1``: serial, as before).

Examples
--------
>>> import numpy as np
>>> out = np.empty(10)
>>> def work(a, b):
...     out[a:b] = np.arange(a, b) ** 2
>>> for_chunks(work, 10, 3)
>>> out[-1]
81.0
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor
from typing import Callable

__all__ = ["for_chunks", "worker_count", "MAX_WORKERS", "blas_single_thread", "map_forked", "process_count"]

#: more threads than this buys nothing on the kernels here (memory-bound)
MAX_WORKERS = 4
_POOL: ThreadPoolExecutor | None = None


def worker_count() -> int:
    """Threads used by :func:`for_chunks` (``LBSCENE_THREADS`` or the core count, ≤ MAX_WORKERS)."""
    return _count("LBSCENE_THREADS")


def _count(env: str) -> int:
    """``env``'s positive count when set (at most 64), else the cores this process may run on (at
    most :data:`MAX_WORKERS`)."""
    raw = os.environ.get(env, "").strip()
    if raw.isdigit() and int(raw) > 0:
        return min(int(raw), 64)
    try:
        n = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        n = os.cpu_count() or 1
    return max(1, min(n, MAX_WORKERS))


def for_chunks(work: Callable[[int, int], None], n: int, chunk: int) -> None:
    """Call ``work(a, b)`` for the consecutive ranges ``[a, b)`` of ``range(n)`` of size
    ``chunk``, on :func:`worker_count` threads; ``work`` writes its own slice of the output.
    Exceptions propagate (the first one raised)."""
    global _POOL
    ranges = [(a, min(a + chunk, n)) for a in range(0, n, chunk)]
    workers = worker_count()
    if workers == 1 or len(ranges) < 2:
        for a, b in ranges:
            work(a, b)
        return
    if _POOL is None or _POOL._max_workers != workers:
        _POOL = ThreadPoolExecutor(max_workers=workers, thread_name_prefix="lbscene")
    for f in [_POOL.submit(work, a, b) for a, b in ranges]:
        f.result()


def process_count() -> int:
    """Worker processes :func:`map_forked` uses: ``LBSCENE_PROCESSES`` when set (``1``: none),
    else the cores this process may run on (at most :data:`MAX_WORKERS`)."""
    return _count("LBSCENE_PROCESSES")


#: the work of the current :func:`map_forked` (read by the forked workers from their copy of
#: this process' memory)
_FORKED: tuple | None = None


def _run_forked(i: int):
    global _POOL
    _POOL = None               # the parent's thread pool did not survive the fork
    fn, items = _FORKED
    return fn(items[i])


def map_forked(fn: Callable, items: list) -> list:
    """``[fn(x) for x in items]``, the items shared among :func:`process_count` processes forked
    from this one.  Each worker starts as a copy of this process (its caches, closures, open
    models: nothing of ``fn`` is pickled); only the results travel back, pickled.  Serial with
    one worker or one item, or where processes cannot be forked (then exactly as the loop).
    The results are in the items' order whatever the order the workers finish in."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    global _FORKED
    items = list(items)
    workers = min(process_count(), len(items))
    if workers < 2 or "fork" not in multiprocessing.get_all_start_methods() or _FORKED is not None:
        return [fn(x) for x in items]
    _FORKED = (fn, items)
    try:
        with ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("fork")) as ex:
            return list(ex.map(_run_forked, range(len(items))))
    finally:
        _FORKED = None


_BLAS = None


def blas_single_thread():
    """Context limiting BLAS to one thread: the model's matrices are small, and threaded BLAS
    on a loaded 2-core machine spin-waits (a 255² LU took 80 ms threaded, 1 ms single).

    Every BLAS the model calls is limited: numpy's and scipy's (each wheel brings its own
    OpenBLAS).  The controller knows the libraries loaded when it is made, so scipy's linear
    algebra is loaded first: made before it, the controller left scipy's LU factorisations
    threaded, and two forked refits each running them on two threads took three times as long
    as one after the other."""
    import contextlib

    global _BLAS
    try:
        from threadpoolctl import ThreadpoolController
    except ImportError:  # optional: without it BLAS keeps its default threads
        return contextlib.nullcontext()
    if _BLAS is None:
        import scipy.linalg  # noqa: F401  (its BLAS among the libraries the controller limits)

        _BLAS = ThreadpoolController()
    return _BLAS.limit(limits=1)
