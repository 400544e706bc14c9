"""Running independent pieces of array work on several threads.

numpy releases the GIL inside its array operations (ufuncs, einsum, matmul, take), so
pieces of a computation that write disjoint parts of an output run in parallel on
threads without copying their inputs. The result never depends on the number of threads:
every piece computes the same numbers whichever thread runs it.
"""

from __future__ import annotations

import os

#: Threads of the solver's and the sun table's loops over pieces (the machine's cores, at
#: most 2: the project's reference machine has 2).
SOLVER_THREADS = min(2, os.cpu_count() or 1)


def in_threads(work, starts, threads: int):
    """[work(i) for i in starts], on ``threads`` threads (numpy releases the GIL)."""
    starts = list(starts)
    if threads <= 1 or len(starts) <= 1:
        return [work(i) for i in starts]
    from concurrent.futures import ThreadPoolExecutor

    with ThreadPoolExecutor(max_workers=threads) as pool:
        return list(pool.map(work, starts))


def chunks_in_threads(work, starts, threads: int):
    """``work(own_starts)`` on each of ``threads`` threads, thread k taking the chunks
    ``starts[k::threads]``: for loops whose threads keep work arrays from one chunk to the
    next (each chunk must write its own part of the output)."""
    starts = list(starts)
    threads = max(1, int(threads))
    in_threads(lambda k: work(starts[k::threads]), range(min(threads, len(starts))), threads)
