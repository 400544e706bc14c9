"""Running independent pieces of array work on several threads.

numpy releases the GIL inside its array operations (ufuncs, einsum, matmul, take), so
pieces of a computation that write disjoint parts of an output run in parallel on
threads without copying their inputs. The result never depends on the number of threads:
every piece computes the same numbers whichever thread runs it.
"""

from __future__ import annotations

import contextlib
import os
import sys
import threading

#: Threads of the solver's and the sun table's loops over pieces (the machine's cores, at
#: most 2: the project's reference machine has 2).
SOLVER_THREADS = min(2, os.cpu_count() or 1)

_blas = {"lock": threading.Lock(), "depth": 0, "limiter": None, "controller": None, "modules": -1}


def _off_main_thread(fn):
    """fn() on a new thread, its result (or its exception) returned here. OpenBLAS (0.3.23,
    numpy's and scipy's wheels) ignores a thread count set from any other thread once the
    main thread has set one, so the count is set from a thread of its own: a limit set
    (and restored) from the main thread would lock every later build on a background
    thread (the add-on's) out of it (measured: after a scripted build, a background
    build's BLAS stayed on 2 threads)."""
    box = {}

    def run():
        try:
            box["value"] = fn()
        except BaseException as ex:  # re-raised on the caller's thread
            box["error"] = ex

    t = threading.Thread(target=run, name="skymodel-blas-limit")
    t.start()
    t.join()
    if "error" in box:
        raise box["error"]
    return box["value"]


def _blas_controller():
    """threadpoolctl's controller of the BLAS libraries loaded now: made again when modules
    were imported since (scipy loads its own OpenBLAS with its first linear-algebra module,
    which a controller made before would not know)."""
    n = len(sys.modules)
    if _blas["controller"] is None or _blas["modules"] != n:
        from threadpoolctl import ThreadpoolController

        _blas["controller"], _blas["modules"] = ThreadpoolController(), n
    return _blas["controller"]


def _limit_blas_to_one():
    """Set every BLAS library to one thread; the limiter that restores them, and the way to call it."""
    controller = _blas_controller()
    limiter = _off_main_thread(lambda: controller.limit(limits=1, user_api="blas"))
    blas = [lib for lib in controller.lib_controllers if lib.user_api == "blas"]
    if any(lib.num_threads != 1 for lib in blas) and threading.current_thread() is threading.main_thread():
        # the main thread set a count before (the caller's own code): only it can set one now
        _off_main_thread(limiter.restore_original_limits)
        return controller.limit(limits=1, user_api="blas"), (lambda fn: fn())
    return limiter, _off_main_thread


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
    another thread meanwhile (Blender's, beside a background build) also runs on one. The
    count is set from a thread of its own (:func:`_off_main_thread`); where the main thread
    had set one before, from the main thread (a block entered on another thread then
    cannot limit BLAS: OpenBLAS ignores it)."""
    with _blas["lock"]:
        if _blas["depth"] == 0:
            _blas["limiter"] = _limit_blas_to_one()
        _blas["depth"] += 1
    try:
        yield
    finally:
        with _blas["lock"]:
            _blas["depth"] -= 1
            if _blas["depth"] == 0:
                limiter, call = _blas["limiter"]
                call(limiter.restore_original_limits)
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
