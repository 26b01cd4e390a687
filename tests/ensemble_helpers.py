"""What the ensemble tests share: the loop over Numba thread counts, the bit-for-bit comparison of two
ensemble results, and K systems of the giant planets."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar

import numba
import numpy as np

from orbitsim.scenario import load_scenario

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


def giants_systems(k: int, n: int = 4) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """K copies of the first ``n`` giants-scenario bodies (Sun, Jupiter, Saturn, Uranus, Neptune), the last
    body's x nudged differently in each: masses (K, N), positions and velocities (K, 3, N)."""
    sc = load_scenario("giants")
    m, x, v = sc.masses[:n], sc.positions[:n].T, sc.velocities[:n].T
    masses, pos, vel = np.tile(m, (k, 1)), np.tile(x, (k, 1, 1)), np.tile(v, (k, 1, 1))
    pos[:, 0, n - 1] *= 1.0 + 1e-3 * np.arange(k)
    return masses, pos, vel
