"""Running independent pieces of array work on several threads.

numpy releases the GIL inside its array operations (ufuncs, einsum, matmul, take), so
pieces of a computation that write disjoint parts of an output run in parallel on
threads without copying their inputs. The result never depends on the number of threads:
every piece computes the same numbers whichever thread runs it.
"""

from __future__ import annotations

import contextlib
import os
import threading

#: Threads of the solver's and the sun table's loops over pieces (the machine's cores, at
#: most 2: the project's reference machine has 2).
SOLVER_THREADS = min(2, os.cpu_count() or 1)

_blas = {"lock": threading.Lock(), "depth": 0, "limiter": None, "controller": None}


@contextlib.contextmanager
def one_blas_thread():
    """numpy's BLAS on one thread inside the block (threadpoolctl); its thread count is
    restored after.

    The loops of :func:`in_threads` already keep every core busy; a matrix product in each
    of them could also start BLAS's own threads, which then spin (``sched_yield``) waiting
    for the cores the loops hold: measured with perf on a cold ``final`` 512x256 build, 11 %
    of its CPU time, and 1.5-2.7 s of its 26-29 s wall time on 2 cores. Nested or
    concurrent blocks (two loops from two threads) share one limit: the first sets it,
    the last one out gives BLAS its threads back. The limit is the process's: a product on
    another thread meanwhile (Blender's, beside a background build) also runs on one."""
    with _blas["lock"]:
        if _blas["depth"] == 0:
            if _blas["controller"] is None:  # made on first use: it finds the BLAS libraries loaded then
                from threadpoolctl import ThreadpoolController

                _blas["controller"] = ThreadpoolController()
            _blas["limiter"] = _blas["controller"].limit(limits=1, user_api="blas")
        _blas["depth"] += 1
    try:
        yield
    finally:
        with _blas["lock"]:
            _blas["depth"] -= 1
            if _blas["depth"] == 0:
                _blas["limiter"].restore_original_limits()
                _blas["limiter"] = None


def in_threads(work, starts, threads: int):
    """[work(i) for i in starts], on ``threads`` threads (numpy releases the GIL), with
    numpy's BLAS on one thread meanwhile (:func:`one_blas_thread`)."""
    starts = list(starts)
    if threads <= 1 or len(starts) <= 1:
        return [work(i) for i in starts]
    from concurrent.futures import ThreadPoolExecutor

    with one_blas_thread(), ThreadPoolExecutor(max_workers=threads) as pool:
        return list(pool.map(work, starts))


def chunks_in_threads(work, starts, threads: int):
    """``work(own_starts)`` on each of ``threads`` threads, thread k taking the chunks
    ``starts[k::threads]``: for loops whose threads keep work arrays from one chunk to the
    next (each chunk must write its own part of the output)."""
    starts = list(starts)
    threads = max(1, int(threads))
    in_threads(lambda k: work(starts[k::threads]), range(min(threads, len(starts))), threads)
