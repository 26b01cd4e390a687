"""One sampled run of any engine, in a single shape the metrics, figures and reports share.

orbitsim's :class:`~orbitsim.simulation.SimulationResult` and a REBOUND run sampled by
:mod:`orbitsim.reference.sampling` both become a :class:`RunRecord`. Energies and momenta of
REBOUND samples are computed here with orbitsim's own diagnostics kernels, so every run is
measured with one formula (the softened potential of :mod:`orbitsim.physics.diagnostics`) and
differences in ``|dE/E|`` are differences in the trajectories, not in bookkeeping.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

#: Engines a record can come from; ``reference`` is the high-accuracy IAS15 run.
ENGINES = ("orbitsim", "rebound", "reference")


@dataclass
class RunRecord:
    """Samples of one run: S samples of N bodies.

    Attributes
    ----------
    engine : str
        ``"orbitsim"``, ``"rebound"`` or ``"reference"``.
    integrator : str
        Scheme name inside its engine (``"leapfrog4"``; ``"leapfrog"``, ``"whfast"``, ``"ias15"``).
    key : str
        Short identifier, unique within its engine; it names the HDF5 group ``engine/key``.
    display : str
        Human-readable name for tables and legends, e.g. ``"REBOUND leapfrog (order 4)"``.
    order : int or None
        Declared order of accuracy in dt (None where it does not apply, e.g. the reference).
    options : dict
        Engine options that define the scheme (``{"order": 4}``), stored with the group.
    dt : float
        Fixed timestep (for the adaptive reference: the timestep of the runs it serves).
    time, step : (S,) arrays
        Sample times ``step * dt`` and step indices (float and int64).
    kinetic, potential : (S,) arrays
    momentum, angular_momentum : (S, 3) arrays
    positions, velocities : (S, N, 3) arrays
    wall_time_s : float
        Seconds spent stepping and sampling (see ``docs/compare.md`` for what is included).
    steps_done : int
        Whole steps taken (for the reference: the number of samples it was stopped at).
    status : str
        ``"complete"``, ``"diverged"`` or ``"failed"``.
    message : str
        Why a run stopped early, else ``""``.
    extra : dict
        Engine-specific extras (IAS15's accepted steps per sample, counters).
    forces : tuple of str
        How this run applies each of the scenario's forces, one phrase per force (empty without
        forces; :mod:`orbitsim.reference.force_pairing`).
    """

    engine: str
    integrator: str
    key: str
    display: str
    order: int | None
    options: dict[str, Any]
    dt: float
    time: np.ndarray
    step: np.ndarray
    kinetic: np.ndarray
    potential: np.ndarray
    momentum: np.ndarray
    angular_momentum: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray
    wall_time_s: float
    steps_done: int
    status: str = "complete"
    message: str = ""
    extra: dict[str, Any] = field(default_factory=dict)
    forces: tuple[str, ...] = ()

    @property
    def label(self) -> str:
        """``engine/key``: unique across a comparison and the record's HDF5 group path."""
        return f"{self.engine}/{self.key}"

    @property
    def energy(self) -> np.ndarray:
        """Total energy T + U of each sample."""
        return self.kinetic + self.potential

    @property
    def energy_error(self) -> np.ndarray:
        """(E - E0) / |E0|, or E - E0 when E0 is exactly zero (as in the trace format)."""
        energy = self.energy
        if energy.size == 0:
            return energy
        e0 = float(energy[0])
        return (energy - e0) / (abs(e0) if e0 != 0.0 else 1.0)

    @property
    def n_samples(self) -> int:
        """Number of samples S."""
        return int(self.time.shape[0])

    @property
    def steps_per_second(self) -> float:
        """Whole steps per wall-clock second (nan when the run took no measurable time)."""
        return self.steps_done / self.wall_time_s if self.wall_time_s > 0.0 else math.nan


def record_from_result(result: Any, *, key: str, display: str, order: int | None,
                       options: dict[str, Any] | None = None) -> RunRecord:
    """Wrap an orbitsim :class:`~orbitsim.simulation.SimulationResult` (recorded positions)."""
    if result.positions is None:
        raise ValueError("a comparison needs runs with recorded positions")
    return RunRecord(
        engine="orbitsim", integrator=result.integrator, key=key, display=display, order=order,
        options=dict(options or {}), dt=float(result.dt), time=result.time, step=result.step,
        kinetic=result.kinetic, potential=result.potential, momentum=result.momentum,
        angular_momentum=result.angular_momentum, positions=result.positions,
        velocities=result.velocities, wall_time_s=float(result.wall_time_s),
        steps_done=int(result.steps_done), status=result.status, message=result.message,
    )


class StateDiagnostics:
    """Energies and momenta of (N, 3) states with orbitsim's kernels, for one system.

    Parameters
    ----------
    masses : (N,) array
    G, softening : float
    forces : ForceSet, optional
        The run's forces: their energy (:func:`orbitsim.forces.kernels.force_energy`) joins the
        potential, as orbitsim's forced runs record it, so both codes' |dE/E| measure one quantity.
    """

    def __init__(self, masses: np.ndarray, G: float, softening: float, forces: Any | None = None) -> None:
        from orbitsim.physics.diagnostics import potential_rows_scratch  # noqa: PLC0415 -- lazy: loads numba

        self.m = np.ascontiguousarray(masses, dtype=np.float64)
        self.G = float(G)
        self.eps2 = float(softening) ** 2
        self.rows = potential_rows_scratch(self.m.shape[0])
        self._out = np.zeros(3)
        self.forces = forces if forces is not None and forces.ids.shape[0] else None

    def __call__(self, pos: np.ndarray, vel: np.ndarray) -> tuple[float, float, np.ndarray, np.ndarray]:
        """``(kinetic, potential, momentum, angular_momentum)`` of one state (N, 3)."""
        from orbitsim.physics.diagnostics import (  # noqa: PLC0415 -- lazy: loads numba
            angular_momentum_into,
            kinetic_energy,
            momentum_into,
            potential_energy,
        )

        x = np.ascontiguousarray(pos.T)
        v = np.ascontiguousarray(vel.T)
        momentum = np.zeros(3)
        angular = np.zeros(3)
        momentum_into(v, self.m, momentum)
        angular_momentum_into(x, v, self.m, angular)
        kinetic = float(kinetic_energy(v, self.m))
        potential = float(potential_energy(x, self.m, self.G, self.eps2, self.rows))
        if self.forces is not None:
            from orbitsim.forces.kernels import force_energy  # noqa: PLC0415 -- lazy: loads numba
            from orbitsim.forces.terms import terms_of  # noqa: PLC0415 -- beside the kernels it feeds

            potential += float(force_energy(x, v, self.m, self.G, terms_of(*self.forces.arrays)))
        return kinetic, potential, momentum, angular


class SampleCollector:
    """Accumulates per-sample states and diagnostics, then builds a :class:`RunRecord`."""

    def __init__(self, diagnostics: StateDiagnostics) -> None:
        self.diagnostics = diagnostics
        self.rows: dict[str, list[Any]] = {name: [] for name in (
            "time", "step", "kinetic", "potential", "momentum", "angular_momentum", "positions",
            "velocities")}

    def add(self, t: float, step: int, pos: np.ndarray, vel: np.ndarray) -> bool:
        """Record one sample; returns False (recording nothing) if the state is not finite."""
        if not (np.all(np.isfinite(pos)) and np.all(np.isfinite(vel))):
            return False
        kinetic, potential, momentum, angular = self.diagnostics(pos, vel)
        values = (t, step, kinetic, potential, momentum, angular, pos.copy(), vel.copy())
        for name, value in zip(self.rows, values, strict=True):
            self.rows[name].append(value)
        return True

    def arrays(self, n_bodies: int) -> dict[str, np.ndarray]:
        """The collected samples as arrays (empty arrays of the right shapes when none)."""
        shapes = {"momentum": (3,), "angular_momentum": (3,), "positions": (n_bodies, 3),
                  "velocities": (n_bodies, 3)}
        out: dict[str, np.ndarray] = {}
        for name, values in self.rows.items():
            dtype = np.int64 if name == "step" else np.float64
            tail = shapes.get(name, ())
            out[name] = np.array(values, dtype=dtype) if values else np.zeros((0, *tail), dtype=dtype)
        return out
