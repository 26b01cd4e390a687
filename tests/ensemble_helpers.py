"""What the ensemble tests share: the loop over Numba thread counts, and the bit-for-bit comparison of two
ensemble results."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar

import numba
import numpy as np

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


def assert_same_bits(a: Any, b: Any) -> None:
    """Two :class:`~orbitsim.ensemble.run.EnsembleResult` s are the same bits: statuses, steps, indicators and
    final states."""
    assert np.array_equal(a.status, b.status)
    assert np.array_equal(a.steps, b.steps)
    # byte views: nan == nan and -0.0 != 0.0, as bit identity wants
    assert a.indicators.tobytes() == b.indicators.tobytes()
    assert a.pos.tobytes() == b.pos.tobytes()
    assert a.vel.tobytes() == b.vel.tobytes()
