"""Which steps a run samples: sampling plans that produce their step indices block by block.

A run records a sample at each *planned* step index (0 first, the last step last). Building all
of them up front costs 8 bytes a sample (80 MB at 10^7 samples, and several times that while an
``interval`` plan is computed), so a plan is a small frozen object whose :meth:`SamplePlan.blocks`
yields the same indices, increasing, in arrays of at most :data:`BLOCK_SAMPLES`. Memory then stays
flat however many samples a run takes, and the indices are bit for bit those of the whole-array
construction (``tests/test_sampling.py`` checks this against the reference in ``tests/naive.py``).

* :class:`EveryPlan`: 0, K, 2K, ... and always the last step (``output.every``);
* :class:`IntervalPlan`: the last whole step at or before each multiple of a time interval
  (``output.interval``);
* :class:`ExplicitPlan`: given indices (``simulate(sample_steps=...)``).

:meth:`SamplePlan.after_step` drops the indices up to a step, which is where a resumed run
continues. :class:`TargetWindow` and :func:`next_budget` are how
:class:`~orbitsim.simulation.Simulation` cuts a plan into jitted calls of about
:data:`TARGET_CALL_SECONDS`. This module imports only numpy: a scenario can count its samples
without Numba.
"""

from __future__ import annotations

import dataclasses
import math
from abc import ABC, abstractmethod
from collections.abc import Iterator
from typing import Any

import numpy as np

__all__ = [
    "BLOCK_SAMPLES",
    "TARGET_CALL_SECONDS",
    "EveryPlan",
    "ExplicitPlan",
    "IntervalPlan",
    "SamplePlan",
    "SimulationError",
    "TargetWindow",
    "as_state",
    "next_budget",
    "sample_steps_every",
    "sample_steps_interval",
]

#: Most step indices in one block: 512 KiB of int64, small beside a run's sample buffers.
BLOCK_SAMPLES = 2**16


class SimulationError(ValueError):
    """Invalid input to the simulation API (shapes, non-finite values, dt, steps)."""


class SamplePlan(ABC):
    """Increasing step indices to sample, produced lazily; only those above ``after`` are planned."""

    after: int

    @abstractmethod
    def blocks(self, size: int = BLOCK_SAMPLES) -> Iterator[np.ndarray]:
        """The planned steps in order, as non-empty int64 arrays of at most ``size`` entries."""

    def after_step(self, step: int) -> SamplePlan:
        """The same plan without its steps <= ``step`` (e.g. those a checkpoint has already written)."""
        return dataclasses.replace(self, after=max(self.after, int(step)))

    def count(self) -> int:
        """Number of planned steps (generic: walks the blocks, in bounded memory)."""
        return sum(block.size for block in self.blocks())

    def steps(self) -> np.ndarray:
        """Every planned step in one int64 array (memory grows with the samples: for small plans)."""
        return np.concatenate([np.zeros(0, dtype=np.int64), *self.blocks()])


@dataclasses.dataclass(frozen=True)
class EveryPlan(SamplePlan):
    """Every ``every`` steps from 0 to ``n_steps``, and always ``n_steps`` itself."""

    n_steps: int
    every: int
    after: int = -1

    def __post_init__(self) -> None:
        if self.every < 1:
            raise SimulationError(f"every must be >= 1, got {self.every}")

    def blocks(self, size: int = BLOCK_SAMPLES) -> Iterator[np.ndarray]:
        every, end = self.every, self.n_steps + 1
        first = (self.after // every + 1) * every  # the first multiple of every above `after`
        span = every * size
        for lo in range(first, end, span):
            yield np.arange(lo, min(lo + span, end), every, dtype=np.int64)
        if self.n_steps % every and self.n_steps > self.after:
            yield np.array([self.n_steps], dtype=np.int64)

    def count(self) -> int:
        multiples = max(0, self.n_steps // self.every - self.after // self.every)
        return multiples + int(bool(self.n_steps % self.every) and self.n_steps > self.after)


@dataclasses.dataclass(frozen=True)
class IntervalPlan(SamplePlan):
    """Samples every ``interval`` time units from 0 to ``n_steps * dt``, on whole steps of ``dt``.

    Sample time k * interval lands on the last whole step n with n * dt <= k * interval (a run
    records that step's true time); times closer together than dt collapse onto one step. The
    last step is always sampled.
    """

    n_steps: int
    dt: float
    interval: float
    after: int = -1

    def __post_init__(self) -> None:
        if not (self.interval > 0.0 and math.isfinite(self.interval)):
            raise SimulationError(f"interval must be a positive number, got {self.interval}")

    @property
    def n_times(self) -> int:
        """Number of sample times k * interval up to the end time (before collapsing onto steps)."""
        return math.floor(self.n_steps * self.dt / self.interval) + 1

    def step_at(self, k: np.ndarray) -> np.ndarray:
        """The step of each sample number ``k`` (float64 array of whole numbers)."""
        wanted = k * self.interval
        steps = np.floor(wanted / self.dt).astype(np.int64)
        # floor of a quotient can land one step either side of the true answer by round-off.
        steps -= (steps * self.dt > wanted).astype(np.int64)
        steps += ((steps + 1) * self.dt <= wanted).astype(np.int64)
        return np.clip(steps, 0, self.n_steps)

    def blocks(self, size: int = BLOCK_SAMPLES) -> Iterator[np.ndarray]:
        # step_at never decreases with k: the wanted time k * interval grows with k, and every
        # correction compares it with the same float64 product n * dt, which grows with n. So
        # dropping repeats of the previous step, within a block and across blocks, equals
        # np.unique over all sample times at once (and is 100x faster than np.unique per block).
        last, n_times = self.after, self.n_times
        for lo in range(self._first_time_past(self.after), n_times, size):
            k = np.arange(lo, min(lo + size, n_times), dtype=np.int64).astype(np.float64)
            steps = self.step_at(k)
            new = np.empty(steps.size, dtype=np.bool_)
            new[0] = steps[0] > last
            np.greater(steps[1:], steps[:-1], out=new[1:])
            steps = steps[new]
            if steps.size:
                yield steps
                last = int(steps[-1])
        if last < self.n_steps:
            yield np.array([self.n_steps], dtype=np.int64)

    def _first_time_past(self, step: int) -> int:
        """The first sample number whose step is above ``step`` (bisection: step_at is monotone)."""
        lo, hi = 0, self.n_times
        while lo < hi:
            mid = (lo + hi) // 2
            if self.step_at(np.array([mid], dtype=np.float64))[0] > step:
                hi = mid
            else:
                lo = mid + 1
        return lo


@dataclasses.dataclass(frozen=True, eq=False)
class ExplicitPlan(SamplePlan):
    """Given step indices (strictly increasing)."""

    given: np.ndarray
    after: int = -1

    def __post_init__(self) -> None:
        given = np.asarray(self.given, dtype=np.int64).reshape(-1)
        if np.any(np.diff(given) <= 0):
            raise SimulationError("sample steps must increase and start at or after the current step")
        object.__setattr__(self, "given", given)  # frozen: only normalisation may set fields

    def _planned(self) -> np.ndarray:
        return self.given[self.given > self.after]

    def blocks(self, size: int = BLOCK_SAMPLES) -> Iterator[np.ndarray]:
        planned = self._planned()
        for lo in range(0, planned.size, size):
            yield planned[lo:lo + size]

    def count(self) -> int:
        return int(self._planned().size)


def sample_steps_every(n_steps: int, every: int) -> np.ndarray:
    """Step indices sampled with ``every`` K steps: 0, K, 2K, ..., and always the last step."""
    return EveryPlan(n_steps, every).steps()


def sample_steps_interval(n_steps: int, dt: float, interval: float) -> np.ndarray:
    """Step indices for samples every ``interval`` time units, on whole steps (see :class:`IntervalPlan`)."""
    return IntervalPlan(n_steps, dt, interval).steps()


#: Wall time one jitted call aims for: long enough that the Python round trip is noise (~20 us),
#: short enough that Ctrl-C and progress updates feel immediate.
TARGET_CALL_SECONDS = 0.2


class TargetWindow:
    """The next planned targets of a run, drawn from the plan's blocks as the run consumes them.

    It holds at least ``want`` targets (or all that are left), one call's worth of samples, so
    each call sees the same targets as it would in the plan's whole array: the calls, and
    therefore the chunks, are cut exactly as if the whole plan had been built up front.
    """

    def __init__(self, plan: SamplePlan, want: int) -> None:
        self._blocks = plan.blocks()
        self.want = want
        self.exhausted = False
        self.pending = np.zeros(0, dtype=np.int64)
        self._fill()

    def _fill(self) -> None:
        parts, size = [self.pending], self.pending.size
        while size < self.want and not self.exhausted:
            block = next(self._blocks, None)
            if block is None:
                self.exhausted = True
            else:
                parts.append(block)
                size += block.size
        if len(parts) > 1:
            self.pending = np.concatenate(parts)

    def max_samples(self) -> int:
        """Samples one call may record: ``want``, or fewer when the whole plan is shorter."""
        return max(1, min(self.pending.size, self.want))

    def plan_call(self, n_done: int, budget: int) -> tuple[np.ndarray, np.ndarray]:
        """Targets and record flags for one jitted call: the next samples that fit in ``budget``
        steps, or an intermediate unrecorded target when the next sample is farther away."""
        limit = n_done + budget
        stop = min(int(np.searchsorted(self.pending, limit, side="right")), self.want)
        if stop == 0:
            return np.array([limit], dtype=np.int64), np.zeros(1, dtype=np.bool_)
        return self.pending[:stop].copy(), np.ones(stop, dtype=np.bool_)

    def consume(self, k: int) -> None:
        """Drop the ``k`` targets a call has recorded, and top the window up from the plan."""
        self.pending = self.pending[k:]
        self._fill()


def next_budget(budget: int, elapsed: float) -> int:
    """Scale the step budget so the next call takes about :data:`TARGET_CALL_SECONDS`."""
    if elapsed <= 0.0:
        return budget * 4
    factor = min(4.0, max(0.25, TARGET_CALL_SECONDS / elapsed))
    return max(1, int(budget * factor))


def as_state(masses: Any, positions: Any, velocities: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(N,) masses and (3, N) positions and velocities from (N,), (N, 3), (N, 3), copied; SimulationError
    (one line) for no bodies, wrong shapes, non-finite values or a negative mass. The CPU and GPU
    simulations both start from it."""
    m = np.ascontiguousarray(masses, dtype=np.float64).reshape(-1)
    x = np.asarray(positions, dtype=np.float64)
    v = np.asarray(velocities, dtype=np.float64)
    n = m.shape[0]
    if n < 1:
        raise SimulationError("a system needs at least one body")
    if x.shape != (n, 3) or v.shape != (n, 3):
        raise SimulationError(f"positions and velocities must have shape ({n}, 3); got {x.shape} and {v.shape}")
    for label, arr in (("masses", m), ("positions", x), ("velocities", v)):
        if not np.all(np.isfinite(arr)):
            raise SimulationError(f"{label} contain NaN or infinite values")
    if np.any(m < 0.0):
        raise SimulationError("masses must be >= 0")
    # Always copies: the integrators work in place, and a caller's (N, 3) view of a (3, N) array
    # (e.g. Simulation.state() of another run, transposed back) must not be overwritten.
    return m.copy(), np.array(x.T, order="C"), np.array(v.T, order="C")
