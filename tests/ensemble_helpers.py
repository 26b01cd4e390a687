"""What the ensemble tests share: the loop over Numba thread counts, the bit-for-bit comparison of two
ensemble results, and K systems of the giant planets (one group of them that stop at steps of their own)."""

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


def stopping_group(k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`giants_systems` (4 bodies, K >= 15) with lanes that stop alone: Uranus escapes on hyperbolas of
    its own in systems 1, 4 and 9; Jupiter and Saturn, inflated, collide in 2, 7 and 12; 14 diverges in its
    first drift and 5 in its first kick. Masses, positions, velocities and radii (K, 4)."""
    masses, pos, vel = giants_systems(k)
    radii = np.zeros((k, 4))
    for lane, factor in zip((1, 4, 9), (2.5, 3.0, 4.0), strict=True):  # Uranus leaves on hyperbolas of its own
        vel[lane, :, 3] *= factor
    for lane, radius in zip((2, 7, 12), (2.08, 2.1, 2.14), strict=True):  # Jupiter and Saturn (4.36 apart) inflated
        radii[lane, 1] = radii[lane, 2] = radius
    vel[14, 0, 2] = 1e300  # Saturn's v^2 overflows: its drift fails at the first step
    masses[5, 3] = 1e200  # Uranus pulls the others to non-finite velocities in the first kick
    return masses, pos, vel, radii
