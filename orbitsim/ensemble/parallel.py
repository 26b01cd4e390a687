"""The ensemble's groups over threads: a jitted task function called on contiguous ranges, one per thread.

The whole-system lane kernels (:mod:`orbitsim.ensemble.system_lanes`, :mod:`orbitsim.ensemble.system_tangent_lanes`)
dealt their groups out with a ``prange``. Numba compiles a ``prange`` loop into three functions around its
body (the gufunc, its wrapper and the parallel wrapper), and each of them links the body's whole call tree
(a group's run: the inlined drifts, kicks and MEGNO) and optimises and emits it again. Here the loop body is
an ordinary ``@jit`` function of a range, ``task(first, last, *args)``; every orbitsim kernel is compiled
``nogil``, so Python threads run its ranges side by side, and the call tree is compiled once more, not three
times: the first call of the lanes took 28.0 -> 22.1 CPU-s (no variations) and 45.9 -> 36.3 (with MEGNO),
at the same speed warm (benchmarks/README.md, ninth pass).

The map's restricted kernel (:mod:`orbitsim.ensemble.restricted`) keeps its ``prange``: it meets its threads
once a block of 512 steps, and handed out from Python each block ran 6% slower (its first compile was
51 -> 36 s).

The split is the one a static ``prange`` schedule makes, ``n_tasks`` cut into ``threads`` contiguous ranges
of nearly equal length, and each task writes only its own rows, so the results are the same bits whatever
the number of threads. The thread count is Numba's, as a ``prange`` reads it: ``numba.get_num_threads()`` in
the calling thread (``orbitsim map --threads``, ``NUMBA_NUM_THREADS``).
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor, wait
from typing import Any

import numba
import numpy as np

__all__ = ["aligned_zeros", "over_threads", "thread_ranges"]

#: The pool's threads and the process that made them (a forked child makes its own: it has none of them).
_POOL: tuple[int, int, ThreadPoolExecutor] | None = None
_POOL_LOCK = threading.Lock()


def thread_ranges(n_tasks: int, threads: int) -> list[tuple[int, int]]:
    """``range(n_tasks)`` cut into ``min(threads, n_tasks)`` contiguous, nearly equal ranges (first, last)."""
    parts = max(1, min(int(threads), int(n_tasks)))
    return [(n_tasks * i // parts, n_tasks * (i + 1) // parts) for i in range(parts)]


def aligned_zeros(shape: tuple[int, ...], align: int = 64) -> np.ndarray:
    """A C-contiguous float64 array of zeros whose first element starts a cache line (``align`` bytes).

    The lane kernels load and store whole rows of a group (LANES numbers, a multiple of 64 bytes) in 512-bit
    registers; numpy places a large array 16 bytes past a page boundary (malloc's header), where every such
    row would straddle two cache lines."""
    count = int(np.prod(shape))
    buffer = np.zeros(count + align // 8)
    start = (-buffer.ctypes.data % align) // 8
    return buffer[start:start + count].reshape(shape)


def _pool(workers: int) -> ThreadPoolExecutor:
    """A process-wide pool of at least ``workers`` threads (made once, grown when a caller asks for more)."""
    global _POOL
    with _POOL_LOCK:
        if _POOL is None or _POOL[0] != os.getpid() or _POOL[1] < workers:
            old = _POOL
            _POOL = (os.getpid(), workers, ThreadPoolExecutor(max_workers=workers, thread_name_prefix="orbitsim-lanes"))
            if old is not None and old[0] == os.getpid():
                old[2].shutdown(wait=False)
        return _POOL[2]


def over_threads(task: Callable[..., Any], n_tasks: int, *args: Any) -> None:
    """``task(first, last, *args)`` for the ranges of :func:`thread_ranges` over ``numba.get_num_threads()``
    threads: the calling thread runs the first range, pool threads the others; returns when all are done
    (an exception of any range is raised here, after every range has ended)."""
    if n_tasks <= 0:
        return
    ranges = thread_ranges(n_tasks, numba.get_num_threads())
    if len(ranges) == 1:
        task(np.int64(0), np.int64(n_tasks), *args)
        return
    pool = _pool(len(ranges) - 1)
    futures = [pool.submit(task, np.int64(first), np.int64(last), *args) for first, last in ranges[1:]]
    interrupted: BaseException | None = None
    try:
        task(np.int64(ranges[0][0]), np.int64(ranges[0][1]), *args)
    finally:
        # every range ends before this returns or raises (none may write into its arrays after): a signal's
        # exception meanwhile (Ctrl-C) is raised once they have, as it would be after a prange kernel
        while True:
            try:
                wait(futures)
                break
            except BaseException as exc:  # kept, and raised below
                interrupted = exc
    if interrupted is not None:
        raise interrupted
    for future in futures:
        future.result()  # a range's error, raised here
