"""The suite's one loop over Numba thread counts, for the tests that results do not depend on them."""

from __future__ import annotations

from collections.abc import Callable
from typing import TypeVar

import numba

T = TypeVar("T")


def by_thread_count(run: Callable[[], T]) -> dict[int, T]:
    """``run()`` on 1 thread and on 2 (or as many as ``NUMBA_NUM_THREADS`` allows), keyed by the count; the
    caller's thread count is restored whatever happens."""
    before = numba.get_num_threads()
    results = {}
    try:
        for threads in (1, min(2, numba.config.NUMBA_NUM_THREADS)):
            numba.set_num_threads(threads)
            results[threads] = run()
    finally:
        numba.set_num_threads(before)
    return results
