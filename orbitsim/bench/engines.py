"""Timed stepping with each engine: orbitsim through its own loop, REBOUND through ``sim.steps``.

Both engines expose the same three operations to the runner, so one N's cases can be measured
interleaved (repeat 1 of every case, then repeat 2, ...): on a shared machine the load changes
from second to second, and only times taken side by side give honest ratios.

* :meth:`first_call` times the first step, which includes JIT compilation or loading the
  on-disk cache (orbitsim); it is reported separately from the run time.
* :meth:`once` times ``steps`` whole steps and returns the wall and the CPU seconds (CPU time of
  the whole process, all threads: for a one-thread case it shows the cost without the waiting
  that other processes on a busy machine add to the wall time).

orbitsim is timed through :meth:`orbitsim.simulation.Simulation.chunks`, the loop every run
uses, sampling only the last step (one energy evaluation per repeat is part of the time).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np

from orbitsim.bench.matrix import StepsCase
from orbitsim.bench.systems import System

__all__ = ["OrbitsimStepper", "ReboundStepper", "jit_timed", "make_stepper"]


def _jit_counts(dispatcher: Any) -> tuple[int, int]:
    """(cache hits, cache misses = compilations) a Numba dispatcher has seen in this process."""
    stats = getattr(dispatcher, "stats", None)
    if stats is None:
        return 0, 0
    return sum(stats.cache_hits.values()), sum(stats.cache_misses.values())


def jit_timed(integrator: str, call: Callable[[], None]) -> tuple[float, str]:
    """The seconds ``call()`` takes and how the integrator's jitted ``run`` was made ready in it:
    ``compiled``, loaded from the ``cache``, or already ``in-memory``."""
    from orbitsim.integrators.registry import get_integrator  # noqa: PLC0415 -- lazy: loads numba

    run = get_integrator(integrator).run
    before = _jit_counts(run)
    start = time.perf_counter()
    call()
    elapsed = time.perf_counter() - start
    hits, misses = (a - b for a, b in zip(_jit_counts(run), before, strict=True))
    return elapsed, "compiled" if misses else ("cache" if hits else "in-memory")


class OrbitsimStepper:
    """Steps one orbitsim :class:`~orbitsim.simulation.Simulation` of a benchmark case."""

    engine = "orbitsim"

    def __init__(self, case: StepsCase, system: System) -> None:
        self.case = case
        self.system = system
        self.sim: Any = None
        self.threads_used = 0
        self.jit = "n/a"

    def _threads(self) -> None:
        from orbitsim._jit import set_num_threads  # noqa: PLC0415 -- lazy: loads numba

        self.threads_used = set_num_threads(self.case.threads)

    def first_call(self) -> float:
        """Build the simulation and take one step; returns the seconds (JIT included)."""
        elapsed, self.jit = jit_timed(self.case.integrator, self._build_and_step)
        return elapsed

    def _build_and_step(self) -> None:
        from orbitsim.simulation import Simulation  # noqa: PLC0415 -- lazy: loads numba

        s, c = self.system, self.case
        self._threads()
        self.sim = Simulation(s.masses.copy(), s.positions.copy(), s.velocities.copy(), c.integrator,
                              s.dt or c.dt, s.G, c.softening if s.softening is None else s.softening,
                              threads=self.threads_used)  # the count set above, not orbitsim.cores' choice
        self._advance(1)

    def _advance(self, steps: int) -> None:
        target = np.array([self.sim.steps_done + steps], dtype=np.int64)
        for _ in self.sim.chunks(target, record_positions=False):
            pass
        if self.sim.diverged:
            raise RuntimeError(f"{self.case.case_id}: the system diverged; lower dt in the matrix")

    def once(self) -> tuple[float, float]:
        """Take ``case.steps`` steps; returns (wall, CPU) seconds."""
        self._threads()
        cpu, start = time.process_time(), time.perf_counter()
        self._advance(self.case.steps)
        return time.perf_counter() - start, time.process_time() - cpu


class ReboundStepper:
    """Steps one :class:`rebound.Simulation` with direct-summation gravity, matched settings."""

    engine = "rebound"

    def __init__(self, case: StepsCase, system: System) -> None:
        self.case = case
        self.system = system
        self.sim: Any = None
        self.threads_used = 1  # REBOUND's basic gravity is serial unless built with OpenMP
        self.jit = "n/a"

    def first_call(self) -> float:
        """Build the REBOUND simulation and take one step; returns the seconds."""
        import rebound  # noqa: PLC0415 -- lazy: loads rebound

        s, c = self.system, self.case
        start = time.perf_counter()
        sim = rebound.Simulation()
        sim.G = float(s.G)
        sim.softening = float(c.softening if s.softening is None else s.softening)
        m, x, v = s.masses, s.positions, s.velocities
        for i in range(m.shape[0]):
            sim.add(m=float(m[i]), x=float(x[i, 0]), y=float(x[i, 1]), z=float(x[i, 2]),
                    vx=float(v[i, 0]), vy=float(v[i, 1]), vz=float(v[i, 2]))
        name, _, order = c.integrator.partition(":")
        sim.integrator = name
        if name == "leapfrog":
            sim.integrator.order = int(order or 2)
        sim.gravity = "basic"
        sim.dt = float(s.dt or c.dt)
        sim.steps(1)
        self.sim = sim
        return time.perf_counter() - start

    def once(self) -> tuple[float, float]:
        """Take ``case.steps`` steps; returns (wall, CPU) seconds."""
        cpu, start = time.process_time(), time.perf_counter()
        self.sim.steps(int(self.case.steps))
        return time.perf_counter() - start, time.process_time() - cpu


def make_stepper(case: StepsCase, system: System) -> OrbitsimStepper | ReboundStepper:
    """The stepper of the case's engine."""
    return OrbitsimStepper(case, system) if case.engine == "orbitsim" else ReboundStepper(case, system)
