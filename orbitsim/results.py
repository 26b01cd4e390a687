"""What a run produces: chunks of samples as they come, and the collected result of a whole run.

The jitted ``run`` of an integrator writes samples into the :class:`SampleBuffers` of one call;
:class:`~orbitsim.simulation.Simulation` hands them out as :class:`SampleChunk` copies, and
:func:`~orbitsim.simulation.simulate` joins the chunks into a :class:`SimulationResult`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from typing import Any, Protocol

import numpy as np

from orbitsim.integrators.base import SCALAR_COLUMNS, IntegratorSpec
from orbitsim.io.schema import NEAR_ZERO_ENERGY, energy_scale

__all__ = ["NEAR_ZERO_ENERGY", "FinishedRun", "SampleBuffers", "SampleChunk", "SimulationResult", "collect_result",
           "energy_scale", "relative_energy_error"]

@dataclass
class SampleChunk:
    """Consecutive samples of a run; ``positions``/``velocities`` are (k, N, 3) or None.

    ``extra`` holds further per-sample series by trace dataset name, each with k rows: a run with
    events adds ``energy_offset``, a run recording elements ``elements/a``, ... (:mod:`orbitsim.io.trace`).
    """

    time: np.ndarray
    step: np.ndarray
    kinetic: np.ndarray
    potential: np.ndarray
    momentum: np.ndarray
    angular_momentum: np.ndarray
    positions: np.ndarray | None
    velocities: np.ndarray | None
    extra: dict[str, np.ndarray] | None = None

    @property
    def energy(self) -> np.ndarray:
        """Total energy T + U of each sample."""
        return self.kinetic + self.potential

    @property
    def conserved_energy(self) -> np.ndarray:
        """E + the energy events took out (merges, removals): what the integrator conserves."""
        offset = (self.extra or {}).get("energy_offset")
        return self.energy if offset is None else self.energy + offset

    def __len__(self) -> int:
        return int(self.time.shape[0])

    def head(self, k: int) -> SampleChunk:
        """The first ``k`` samples (views)."""
        def head(value: Any) -> Any:
            if isinstance(value, dict):
                return {name: arr[:k] for name, arr in value.items()}
            return None if value is None else value[:k]

        return SampleChunk(**{f.name: head(getattr(self, f.name)) for f in fields(self)})

    def finite_energy_head(self) -> tuple[SampleChunk, np.ndarray, int | None]:
        """The samples before the first whose energy T + U is not finite, their energies, and that
        sample's index (None when every energy is finite, and the chunk is returned whole)."""
        with np.errstate(all="ignore"):  # inf + -inf is what is looked for: no RuntimeWarning on stderr
            energy = self.conserved_energy
        finite = np.isfinite(energy)
        if finite.all():
            return self, energy, None
        k = int(np.argmin(finite))
        return self.head(k), energy[:k], k


@dataclass
class SimulationResult:
    """Everything a finished (or stopped) run produced, as numpy arrays.

    ``energy_error`` is (E + offset - E0) / :func:`energy_scale` (|E0| for any bound system).
    ``status`` is ``complete``, ``diverged``, ``halted`` (an event the run was told to stop at)
    or ``interrupted``. ``energy_offset`` and ``events`` are set for a run with events.
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
    energy_offset: np.ndarray | None = None
    events: list[Any] = field(default_factory=list)

    @property
    def max_abs_energy_error(self) -> float:
        """max |dE/E| over the samples (nan when there are none)."""
        return float(np.max(np.abs(self.energy_error))) if self.energy_error.size else math.nan


def relative_energy_error(energy: np.ndarray, e0: float, scale: float | None = None) -> np.ndarray:
    """(E - E0) / ``scale``; ``scale`` defaults to |E0| (1 when E0 is exactly zero)."""
    if scale is None:
        scale = abs(e0) if e0 != 0.0 else 1.0
    return (np.asarray(energy) - e0) / scale


class SampleBuffers:
    """Reusable output arrays for one jitted call: ``size`` samples of ``n`` bodies."""

    def __init__(self, size: int, n: int, record_positions: bool) -> None:
        self.times = np.zeros(size)
        self.steps = np.zeros(size, dtype=np.int64)
        self.scalars = np.zeros((size, len(SCALAR_COLUMNS)))
        self.snapshots = np.zeros((size if record_positions else 0, 2, 3, n))

    def views(self, rows: np.ndarray) -> tuple[np.ndarray, ...]:
        """The ``out`` tuple of an integrator's ``run``."""
        return (self.times, self.steps, self.scalars, self.snapshots, rows)

    def chunk(self, k: int) -> SampleChunk:
        """Copies of the first ``k`` samples (the buffers are overwritten by the next call)."""
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


class FinishedRun(Protocol):
    """What :func:`collect_result` reads of the run that made the chunks.

    :class:`orbitsim.simulation.Simulation` is one. It is declared here, by what is read, so that the
    result types do not import the engine that produces them (which imports them).
    """

    spec: IntegratorSpec
    dt: float
    G: float
    softening: float
    t0: float
    n: int
    steps_done: int
    diverged: bool
    watcher: Any  # the run's events (orbitsim.events.driver.Watcher), or None without events

    @property
    def halted(self) -> Any:
        """The event the run halted at, or None."""

    def state(self) -> tuple[np.ndarray, np.ndarray]:
        """Current positions and velocities as (N, 3) copies."""

    def failure_detail(self) -> str | None:
        """The scheme's own account of a divergence, if it has one."""

    def non_finite_bodies(self) -> list[int]:
        """Indices of the bodies whose state is not finite."""


def collect_result(sim: FinishedRun, parts: list[SampleChunk], record_positions: bool,
                   wall: float) -> SimulationResult:
    """Join the chunks of a run of ``sim`` into one :class:`SimulationResult`."""

    def cat(name: str, shape: tuple[int, ...]) -> np.ndarray:
        arrays = [getattr(p, name) for p in parts]
        return np.concatenate(arrays) if arrays else np.zeros((0, *shape))

    kinetic = cat("kinetic", ())
    potential = cat("potential", ())
    energy = kinetic + potential
    watcher = sim.watcher
    offset = np.concatenate([p.extra["energy_offset"] for p in parts]) if watcher and parts else None
    conserved = energy if offset is None else energy + offset
    e0 = float(energy[0]) if energy.size else 0.0
    scale = energy_scale(float(kinetic[0]), float(potential[0]), e0) if energy.size else 1.0
    final_pos, final_vel = sim.state()
    n = sim.n if watcher is None else watcher.n0
    if watcher is not None and n != sim.n:
        final_pos, final_vel = watcher.to_scenario_bodies(final_pos), watcher.to_scenario_bodies(final_vel)
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
        energy_error=relative_energy_error(conserved, e0, scale),
        momentum=cat("momentum", (3,)),
        angular_momentum=cat("angular_momentum", (3,)),
        positions=cat("positions", (n, 3)) if record_positions else None,
        velocities=cat("velocities", (n, 3)) if record_positions else None,
        final_positions=final_pos,
        final_velocities=final_vel,
        steps_done=sim.steps_done,
        status="diverged" if sim.diverged else "halted" if sim.halted is not None else "complete",
        message=_divergence_message(sim, parts) if sim.diverged else "",
        wall_time_s=wall,
        energy_offset=offset,
        events=list(watcher.outcome().events) if watcher is not None else [],
    )


def _divergence_message(sim: FinishedRun, parts: list[SampleChunk]) -> str:
    bodies = sim.non_finite_bodies()
    t_last = float(parts[-1].time[-1]) if parts else sim.t0
    message = (
        f"state became non-finite after t = {t_last:.6g} (by step {sim.steps_done}); "
        f"bodies {bodies[:10]}{' ...' if len(bodies) > 10 else ''}"
    )
    # A scheme may know why (e.g. wisdom_holman: which body's Kepler solve failed, in which step).
    detail = sim.failure_detail()
    return f"{detail}; {message}" if detail else message
