"""The hardware ceiling of the force loop on this machine, measured, not assumed.

Every pair interaction needs one square root and one division (``1 / (r2 * sqrt(r2))``), and
on this class of CPU that unit, not memory and not the adds, bounds the force loop. This probe
times exactly that work in a vectorised loop over an L1-resident array, on one thread:

* ``full_per_core``: pair interactions per second when each interaction is computed (the
  plain double loop over j != i);
* ``pairs_once_per_core``: twice that, because a third-law kernel computes each pair once and
  counts it twice (N(N-1) per evaluation);
* the ceiling for T threads is T times the per-core figure (the cores share no such unit).

docs/design.md#fast-kernels quotes 1.15e9/s per core for the full loop on the development machine.
"""

from __future__ import annotations

import time

import numpy as np

from orbitsim._jit import jit_force

__all__ = ["measure_ceiling"]


@jit_force
def _rsqrt3_sum(r2, reps):
    """sum over reps of sum_j 1 / (r2_j sqrt(r2_j)); reassociation lets the sum vectorise."""
    total = 0.0
    for k in range(reps):
        shift = k * 1e-12  # stops LLVM hoisting the inner loop out of the repeat loop
        for j in range(r2.shape[0]):
            s = r2[j] + shift
            total += 1.0 / (s * np.sqrt(s))
    return total


def measure_ceiling(rounds: int = 7, seconds: float = 0.05) -> dict[str, float]:
    """Best of ``rounds`` timings of the square-root/division loop; rates per core.

    Returns
    -------
    dict
        ``full_per_core`` and ``pairs_once_per_core`` in interactions per second, and the
        measurement settings.
    """
    r2 = np.linspace(1.0, 2.0, 1024)  # 8 KiB: stays in L1, so only the arithmetic is timed
    _rsqrt3_sum(r2, 1)
    reps = 64
    while True:
        start = time.perf_counter()
        _rsqrt3_sum(r2, reps)
        if time.perf_counter() - start > seconds / 4 or reps > 2**24:
            break
        reps *= 4
    best = float("inf")
    for _ in range(rounds):
        start = time.perf_counter()
        _rsqrt3_sum(r2, reps)
        best = min(best, time.perf_counter() - start)
    rate = r2.shape[0] * reps / best
    return {"full_per_core": rate, "pairs_once_per_core": 2.0 * rate, "rounds": rounds,
            "work_per_round": r2.shape[0] * reps}
