"""The Python side of a run (``orbitsim.simulation``; ``orbitsim.simulate`` is its main function):

The jitted ``run`` of each integrator takes whole steps and records samples; this module decides
*which* steps are sampled, cuts the run into calls of about :data:`TARGET_CALL_SECONDS` each (so
Ctrl-C, progress bars and checkpoints get a say between calls without slowing the loop) and hands
every chunk of samples to the caller. Chunking never changes the arithmetic: the same input gives
the same bits however the run is cut.

Public entry points: :func:`simulate` (collect everything into a :class:`SimulationResult`) and
:class:`Simulation` (iterate over :class:`SampleChunk` objects, e.g. to append to an HDF5 trace).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from orbitsim.integrators.base import SCALAR_COLUMNS, IntegratorSpec

#: Wall time one jitted call aims for: long enough that the Python round trip is noise (~20 us),
#: short enough that Ctrl-C and progress updates feel immediate.
TARGET_CALL_SECONDS = 0.2

#: Upper bound on the sample buffer of one call, so recording positions stays flat in memory.
MAX_BUFFER_BYTES = 32 * 2**20


class SimulationError(ValueError):
    """Invalid input to the simulation API (shapes, non-finite values, dt, steps)."""


@dataclass
class SampleChunk:
    """Consecutive samples of a run; ``positions``/``velocities`` are (k, N, 3) or None."""

    time: np.ndarray
    step: np.ndarray
    kinetic: np.ndarray
    potential: np.ndarray
    momentum: np.ndarray
    angular_momentum: np.ndarray
    positions: np.ndarray | None
    velocities: np.ndarray | None

    @property
    def energy(self) -> np.ndarray:
        """Total energy T + U of each sample."""
        return self.kinetic + self.potential

    def __len__(self) -> int:
        return int(self.time.shape[0])


@dataclass
class SimulationResult:
    """Everything a finished (or stopped) run produced, as numpy arrays.

    ``energy_error`` is (E - E0) / |E0| (or E - E0 when E0 == 0). ``status`` is ``complete``,
    ``diverged`` or ``interrupted``.
    """

    integrator: str
    dt: float
    G: float
    softening: float
    time: np.ndarray
    step: np.ndarray
    kinetic: np.ndarray
    potential: np.ndarray
    energy: np.ndarray
    energy_error: np.ndarray
    momentum: np.ndarray
    angular_momentum: np.ndarray
    positions: np.ndarray | None
    velocities: np.ndarray | None
    final_positions: np.ndarray
    final_velocities: np.ndarray
    steps_done: int
    status: str
    message: str
    wall_time_s: float

    @property
    def max_abs_energy_error(self) -> float:
        """max |dE/E| over the samples (nan when there are none)."""
        return float(np.max(np.abs(self.energy_error))) if self.energy_error.size else math.nan


def relative_energy_error(energy: np.ndarray, e0: float) -> np.ndarray:
    """(E - E0) / |E0|, or E - E0 when E0 is exactly zero."""
    scale = abs(e0) if e0 != 0.0 else 1.0
    return (np.asarray(energy) - e0) / scale


def sample_steps_every(n_steps: int, every: int) -> np.ndarray:
    """Step indices sampled with ``every`` K steps: 0, K, 2K, ..., and always the last step."""
    if every < 1:
        raise SimulationError(f"every must be >= 1, got {every}")
    steps = np.arange(0, n_steps + 1, every, dtype=np.int64)
    if steps[-1] != n_steps:
        steps = np.append(steps, np.int64(n_steps))
    return steps


def sample_steps_interval(n_steps: int, dt: float, interval: float) -> np.ndarray:
    """Step indices for samples every ``interval`` time units, on whole steps.

    Sample k lands on the last whole step n with n*dt <= k*interval (it records that step's true
    time); sample times closer together than dt collapse onto one step. The last step is always
    sampled.
    """
    if not (interval > 0.0 and math.isfinite(interval)):
        raise SimulationError(f"interval must be a positive number, got {interval}")
    t_end = n_steps * dt
    k = np.arange(0, math.floor(t_end / interval) + 1, dtype=np.float64)
    wanted = k * interval
    steps = np.floor(wanted / dt).astype(np.int64)
    # floor of a quotient can land one step either side of the true answer by round-off.
    steps -= (steps * dt > wanted).astype(np.int64)
    steps += ((steps + 1) * dt <= wanted).astype(np.int64)
    steps = np.unique(np.clip(steps, 0, n_steps))
    if steps[-1] != n_steps:
        steps = np.append(steps, np.int64(n_steps))
    return steps


def _as_state(masses: Any, positions: Any, velocities: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
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


@dataclass
class Simulation:
    """A system ready to step with one integrator at a fixed ``dt``.

    Parameters
    ----------
    masses : (N,) array
    positions, velocities : (N, 3) arrays
    integrator : str
        A registry name or alias (see ``orbitsim list integrators``).
    dt : float
        The fixed timestep (> 0 forward; < 0 integrates backwards, e.g. for reversibility tests).
    G : float
        Gravitational constant of the unit system.
    softening : float
        Plummer softening length eps (>= 0).
    t0 : float
        Time of step 0; sample n is at ``t0 + n * dt``.
    threads : int, optional
        Numba threads for the parallel kernels (default: ``NUMBA_NUM_THREADS``).
    """

    masses: Any
    positions: Any
    velocities: Any
    integrator: str
    dt: float
    G: float = 1.0
    softening: float = 0.0
    t0: float = 0.0
    threads: int | None = None
    settings: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        from orbitsim._jit import set_num_threads
        from orbitsim.integrators.registry import get_module
        from orbitsim.physics.diagnostics import potential_rows_scratch
        from orbitsim.physics.gravity import make_force, update_accelerations

        if not (math.isfinite(self.dt) and self.dt != 0.0):
            raise SimulationError(f"dt must be a finite non-zero number, got {self.dt}")
        if not (math.isfinite(self.softening) and self.softening >= 0.0):
            raise SimulationError(f"softening must be >= 0, got {self.softening}")
        if not (math.isfinite(self.G) and self.G > 0.0):
            raise SimulationError(f"G must be > 0, got {self.G}")
        self._module = get_module(self.integrator)
        self.spec: IntegratorSpec = self._module.SPEC
        self.m, self.pos, self.vel = _as_state(self.masses, self.positions, self.velocities)
        self.n = int(self.m.shape[0])
        self.threads_used = set_num_threads(self.threads)
        self.force = make_force(self.G, self.softening, self.n)
        make_work = getattr(self._module, "make_work", None)
        self.work = (
            make_work(self.m, self.G, self.settings) if make_work else np.zeros((self.spec.work_slots, 3, self.n))
        )
        self.acc = np.zeros((3, self.n))
        self.rows = potential_rows_scratch(self.n)
        self.steps_done = 0
        update_accelerations(self.pos, self.m, self.force, self.acc)

    @property
    def time(self) -> float:
        """Time of the current state, ``t0 + steps_done * dt``."""
        return self.t0 + self.steps_done * self.dt

    def state(self) -> tuple[np.ndarray, np.ndarray]:
        """Current positions and velocities as (N, 3) copies."""
        return self.pos.T.copy(), self.vel.T.copy()

    def chunks(
        self,
        sample_steps: np.ndarray,
        *,
        record_positions: bool = True,
        deadline: float | None = None,
        yield_empty: bool = False,
    ) -> Iterator[SampleChunk]:
        """Run to ``sample_steps[-1]``, yielding the samples at ``sample_steps`` chunk by chunk.

        ``sample_steps`` are absolute step indices, increasing, none below ``steps_done``. The run
        stops early, leaving :attr:`diverged` true, at the first sample whose state is not finite.
        With ``yield_empty`` a chunk (possibly of no samples) follows every jitted call, so the
        caller gets control about every :data:`TARGET_CALL_SECONDS` even when samples are sparse;
        at each yield the state is consistent with the samples yielded so far (every sample step
        <= ``steps_done`` has been yielded), which is what a checkpoint needs.
        """
        targets = np.asarray(sample_steps, dtype=np.int64)
        if targets.size == 0:
            return
        if np.any(np.diff(targets) <= 0) or targets[0] < self.steps_done:
            raise SimulationError("sample steps must increase and start at or after the current step")
        self.diverged = False
        per_sample = (2 * 3 * self.n * 8 if record_positions else 0) + 80
        max_samples = max(1, min(targets.size, MAX_BUFFER_BYTES // per_sample))
        buffers = _SampleBuffers(max_samples, self.n, record_positions)
        budget = max(1, int(2e5 // max(1, self.n * self.n * self.spec.force_evals)))
        state = (self.pos, self.vel, self.acc, self.m)
        i = 0
        while i < targets.size:
            chunk_targets, record = _plan_call(targets, i, self.steps_done, budget, max_samples)
            out = buffers.views(self.rows)
            start = time.perf_counter()
            written, n_done, finite = self._module.run(
                state, self.force, self.dt, self.work, self.t0, self.steps_done, chunk_targets, record, out
            )
            elapsed = time.perf_counter() - start
            self.steps_done = int(n_done)
            # Every recorded target is one sample, so the samples written are the targets consumed.
            i += int(written)
            if written or (yield_empty and finite):
                yield buffers.chunk(int(written))
            if not finite:
                self.diverged = True
                return
            budget = _next_budget(budget, elapsed)

    def non_finite_bodies(self) -> list[int]:
        """Indices of bodies whose position or velocity is not finite."""
        bad = ~(np.all(np.isfinite(self.pos), axis=0) & np.all(np.isfinite(self.vel), axis=0))
        return [int(k) for k in np.flatnonzero(bad)]


def _plan_call(
    targets: np.ndarray, i: int, n_done: int, budget: int, max_samples: int
) -> tuple[np.ndarray, np.ndarray]:
    """Targets for one jitted call: the next samples that fit in ``budget`` steps, or an
    intermediate unrecorded target when the next sample is farther than the budget."""
    limit = n_done + budget
    stop = int(np.searchsorted(targets, limit, side="right"))
    stop = min(max(stop, i), i + max_samples)
    if stop == i:
        return np.array([limit], dtype=np.int64), np.zeros(1, dtype=np.bool_)
    return targets[i:stop].copy(), np.ones(stop - i, dtype=np.bool_)


def _next_budget(budget: int, elapsed: float) -> int:
    """Scale the step budget so the next call takes about :data:`TARGET_CALL_SECONDS`."""
    if elapsed <= 0.0:
        return budget * 4
    factor = min(4.0, max(0.25, TARGET_CALL_SECONDS / elapsed))
    return max(1, int(budget * factor))


class _SampleBuffers:
    """Reusable output arrays for one jitted call."""

    def __init__(self, size: int, n: int, record_positions: bool) -> None:
        self.times = np.zeros(size)
        self.steps = np.zeros(size, dtype=np.int64)
        self.scalars = np.zeros((size, len(SCALAR_COLUMNS)))
        self.snapshots = np.zeros((size if record_positions else 0, 2, 3, n))

    def views(self, rows: np.ndarray) -> tuple[np.ndarray, ...]:
        return (self.times, self.steps, self.scalars, self.snapshots, rows)

    def chunk(self, k: int) -> SampleChunk:
        has_state = self.snapshots.shape[0] > 0
        return SampleChunk(
            time=self.times[:k].copy(),
            step=self.steps[:k].copy(),
            kinetic=self.scalars[:k, 0].copy(),
            potential=self.scalars[:k, 1].copy(),
            momentum=self.scalars[:k, 2:5].copy(),
            angular_momentum=self.scalars[:k, 5:8].copy(),
            positions=self.snapshots[:k, 0].transpose(0, 2, 1).copy() if has_state else None,
            velocities=self.snapshots[:k, 1].transpose(0, 2, 1).copy() if has_state else None,
        )


def simulate(
    masses: Any,
    positions: Any,
    velocities: Any,
    *,
    integrator: str,
    dt: float,
    steps: int,
    every: int = 1,
    sample_steps: np.ndarray | None = None,
    G: float = 1.0,
    softening: float = 0.0,
    record_positions: bool = True,
    threads: int | None = None,
    settings: dict[str, Any] | None = None,
    on_chunk: Callable[[SampleChunk], None] | None = None,
) -> SimulationResult:
    """Integrate an N-body system for ``steps`` whole steps of ``dt`` and return its samples.

    Parameters
    ----------
    masses, positions, velocities
        (N,), (N, 3), (N, 3) arrays in a consistent unit system.
    integrator : str
        Registry name or alias, e.g. ``"verlet"`` or ``"leapfrog4"``.
    dt : float
        Fixed timestep; never shortened.
    steps : int
        Number of whole steps.
    every : int
        Sample every K steps (the first sample is step 0, the last is the final step).
    sample_steps : array, optional
        Explicit increasing step indices to sample instead of ``every``.
    G, softening : float
        Gravitational constant and Plummer softening length.
    record_positions : bool
        Keep positions and velocities at every sample.
    threads : int, optional
        Numba threads (default: ``NUMBA_NUM_THREADS``); results do not depend on it.
    on_chunk : callable, optional
        Called with every :class:`SampleChunk` as it is produced.

    Returns
    -------
    SimulationResult
    """
    if int(steps) != steps or steps < 0:
        raise SimulationError(f"steps must be a whole number >= 0, got {steps}")
    sim = Simulation(masses, positions, velocities, integrator, dt, G, softening, 0.0, threads, settings or {})
    plan = sample_steps_every(int(steps), int(every)) if sample_steps is None else np.asarray(sample_steps)
    start = time.perf_counter()
    parts: list[SampleChunk] = []
    for chunk in sim.chunks(plan, record_positions=record_positions):
        parts.append(chunk)
        if on_chunk is not None:
            on_chunk(chunk)
    wall = time.perf_counter() - start
    return _collect(sim, parts, record_positions, wall)


def _collect(sim: Simulation, parts: list[SampleChunk], record_positions: bool, wall: float) -> SimulationResult:
    def cat(name: str, shape: tuple[int, ...]) -> np.ndarray:
        arrays = [getattr(p, name) for p in parts]
        return np.concatenate(arrays) if arrays else np.zeros((0, *shape))

    kinetic = cat("kinetic", ())
    potential = cat("potential", ())
    energy = kinetic + potential
    e0 = float(energy[0]) if energy.size else 0.0
    status = "diverged" if sim.diverged else "complete"
    message = ""
    if sim.diverged:
        bodies = sim.non_finite_bodies()
        t_last = float(parts[-1].time[-1]) if parts else sim.t0
        message = (
            f"state became non-finite after t = {t_last:.6g} (by step {sim.steps_done}); "
            f"bodies {bodies[:10]}{' ...' if len(bodies) > 10 else ''}"
        )
        # A scheme may know why (e.g. wisdom_holman: which body's Kepler solve failed, in which step).
        describe = getattr(sim._module, "failure_message", None)
        detail = describe(sim.work) if describe is not None else None
        if detail:
            message = f"{detail}; {message}"
    final_pos, final_vel = sim.state()
    return SimulationResult(
        integrator=sim.spec.name,
        dt=sim.dt,
        G=sim.G,
        softening=sim.softening,
        time=cat("time", ()),
        step=cat("step", ()).astype(np.int64),
        kinetic=kinetic,
        potential=potential,
        energy=energy,
        energy_error=relative_energy_error(energy, e0),
        momentum=cat("momentum", (3,)),
        angular_momentum=cat("angular_momentum", (3,)),
        positions=cat("positions", (sim.n, 3)) if record_positions else None,
        velocities=cat("velocities", (sim.n, 3)) if record_positions else None,
        final_positions=final_pos,
        final_velocities=final_vel,
        steps_done=sim.steps_done,
        status=status,
        message=message,
        wall_time_s=wall,
    )
