"""IAS15 over one time span, orbitsim beside REBOUND: the ``adaptive`` kind of a matrix.

An adaptive scheme chooses its own steps, so "time a fixed number of steps" (the ``steps`` kind)
does not apply: each repeat integrates the same system from the same initial state from t = 0 to
``t_end``, and the time per step is that time divided by the number of *accepted* steps the engine
took (rejected trials are part of the cost, as they are of a real run). The two engines do not
take the same number of steps, so both counts are recorded beside the times.

* orbitsim: ``Simulation(..., "ias15", dt=t_end)`` with the settings ``epsilon``, ``first_dt``
  and ``t_end``, run through :meth:`~orbitsim.simulation.Simulation.chunks` (the loop every run
  uses) sampling t = 0 and t_end only; the steps from
  :func:`orbitsim.integrators.ias15.counters`.
* REBOUND: ``sim.integrator = "ias15"`` with the same ``epsilon`` and first ``dt``,
  ``gravity = "basic"``, ``sim.integrate(t_end, exact_finish_time=1)`` (orbitsim also lands
  exactly on its last sample); the steps from ``sim.steps_done``.

Building each repeat's simulation is outside the timed span. The cases of one N are interleaved
(repeat 1 of each, then repeat 2, ...) and every ratio is the median over rounds of the ratio
within a round, as everywhere in the suite.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np

from orbitsim.bench._adaptive_fields import AdaptiveCase
from orbitsim.bench.engines import jit_timed
from orbitsim.bench.interleave import by_n, prepare, rounds
from orbitsim.bench.stats import paired_median, summarise
from orbitsim.bench.systems import System
from orbitsim.reference.bridge import rebound_simulation

__all__ = ["OrbitsimIAS15", "ReboundIAS15", "Timed", "run_adaptive_group"]

#: One timed repeat: (wall seconds, CPU seconds, accepted steps, engine counters).
Timed = tuple[float, float, int, dict[str, int]]


class OrbitsimIAS15:
    """orbitsim's ``ias15`` over one case's span, a fresh :class:`Simulation` per repeat."""

    engine = "orbitsim"

    def __init__(self, case: AdaptiveCase, system: System) -> None:
        self.case = case
        self.system = system
        self.threads_used = 0
        self.jit = "n/a"

    def _simulation(self, t_end: float) -> Any:
        from orbitsim.simulation import Simulation  # noqa: PLC0415 -- lazy: loads numba

        s, c = self.system, self.case
        softening = c.softening if s.softening is None else s.softening
        settings = {"epsilon": c.epsilon, "first_dt": s.dt or c.first_dt, "t_end": t_end}
        # dt is the output grid of an adaptive scheme: one interval, sampled at 0 and t_end only.
        from orbitsim._jit import set_num_threads  # noqa: PLC0415 -- lazy: loads numba

        # Numba's count (c.threads, else NUMBA_NUM_THREADS): a benchmark does not measure the load first.
        sim = Simulation(s.masses.copy(), s.positions.copy(), s.velocities.copy(), "ias15", t_end, s.G,
                         softening, threads=set_num_threads(c.threads), settings=settings)
        self.threads_used = sim.threads_used
        return sim

    def _run(self, sim: Any) -> None:
        for _ in sim.chunks(np.array([0, 1], dtype=np.int64), record_positions=False):
            pass
        if sim.diverged:
            raise RuntimeError(f"{self.case.case_id}: the state became non-finite; shorten t_end in the matrix")

    def first_call(self) -> float:
        """Build and integrate one first trial step's span; returns the seconds (JIT included)."""
        first_span = self.system.dt or self.case.first_dt
        elapsed, self.jit = jit_timed("ias15", lambda: self._run(self._simulation(first_span)))
        return elapsed

    def once(self) -> Timed:
        """Integrate the whole span from the initial state; (wall, CPU, accepted steps, counters)."""
        from orbitsim.integrators.ias15 import counters  # noqa: PLC0415 -- lazy: loads numba

        sim = self._simulation(self.case.t_end)
        cpu, start = time.process_time(), time.perf_counter()
        self._run(sim)
        wall, cpu = time.perf_counter() - start, time.process_time() - cpu
        c = counters(sim.work)
        return wall, cpu, int(c["steps_accepted"]), {k: int(c[k]) for k in ("steps_rejected", "force_evaluations")}


class ReboundIAS15:
    """REBOUND's IAS15 over the same span, a fresh :class:`rebound.Simulation` per repeat."""

    engine = "rebound"

    def __init__(self, case: AdaptiveCase, system: System) -> None:
        self.case = case
        self.system = system
        self.threads_used = 1  # REBOUND's basic gravity is serial unless built with OpenMP
        self.jit = "n/a"

    def _simulation(self) -> Any:
        s, c = self.system, self.case
        softening = c.softening if s.softening is None else s.softening
        sim = rebound_simulation(s.masses, s.positions, s.velocities, G=s.G, softening=softening,
                                 dt=s.dt or c.first_dt, scheme="ias15")
        sim.gravity = "basic"
        sim.integrator.epsilon = c.epsilon
        return sim

    def first_call(self) -> float:
        """Build the simulation and integrate one first trial step's span; returns the seconds."""
        start = time.perf_counter()
        self._simulation().integrate(self.system.dt or self.case.first_dt, exact_finish_time=1)
        return time.perf_counter() - start

    def once(self) -> Timed:
        """Integrate the whole span from the initial state; (wall, CPU, accepted steps, {})."""
        sim = self._simulation()
        cpu, start = time.process_time(), time.perf_counter()
        sim.integrate(self.case.t_end, exact_finish_time=1)
        wall, cpu = time.perf_counter() - start, time.process_time() - cpu
        return wall, cpu, int(sim.steps_done), {}


Stepper = OrbitsimIAS15 | ReboundIAS15


def _make(case: AdaptiveCase, system: System) -> Stepper:
    return (OrbitsimIAS15 if case.engine == "orbitsim" else ReboundIAS15)(case, system)


def _prepare(cases: list[AdaptiveCase], threads: tuple[int, int]) -> tuple[list, list[dict]]:
    """Build, compile and warm up each case of one N; (ready cases, skipped cases)."""
    # Only orbitsim is warmed up: its first whole span still loads caches and touches memory,
    # while REBOUND's C code has nothing to load, and at N = 1000 its warm-up would cost as
    # much as a repeat.
    return prepare(cases, threads, _make, warmups=lambda case: case.warmup if case.engine == "orbitsim" else 0)


def _record(case: AdaptiveCase, stepper: Stepper, first: float, runs: list[Timed]) -> dict[str, Any]:
    steps = [n for _, _, n, _ in runs]
    rec: dict[str, Any] = {
        "id": case.case_id, "group": case.group, "kind": "adaptive", "engine": case.engine,
        "integrator": case.integrator, "system": case.system, "n": case.n, "t_end": case.t_end,
        "first_dt": stepper.system.dt or case.first_dt, "epsilon": case.epsilon, "threads": stepper.threads_used,
        "repeats": len(runs), "warmup": case.warmup, "steps": steps[-1], "steps_values": steps,
        "time_s": summarise([w for w, _, _, _ in runs]), "cpu_s": summarise([c for _, c, _, _ in runs]),
        # Per repeat, each over its own count (the same in every repeat: both engines are deterministic).
        "per_step_s": summarise([w / max(1, n) for w, _, n, _ in runs]),
        "cpu_per_step_s": summarise([c / max(1, n) for _, c, n, _ in runs]),
        "first_call_s": first, "jit": stepper.jit,
    }
    rec.update(runs[-1][3])
    return rec


def _pair_with_rebound(records: list[dict[str, Any]]) -> None:
    """Give each orbitsim record of one N the REBOUND / orbitsim time per step (>1: orbitsim is
    faster), wall and CPU, paired round by round."""
    twin = next((r for r in records if r["engine"] == "rebound"), None)
    if twin is None:
        return
    for rec in records:
        if rec["engine"] == "orbitsim":
            rec["rebound_over_orbitsim"] = {
                "twin": twin["id"],
                "wall": paired_median(twin["per_step_s"]["values"], rec["per_step_s"]["values"]),
                "cpu": paired_median(twin["cpu_per_step_s"]["values"], rec["cpu_per_step_s"]["values"]),
                "rounds": min(rec["repeats"], twin["repeats"])}


def _run_n(cases: list[AdaptiveCase], progress: Callable[[str], None],
           threads: tuple[int, int]) -> tuple[list[dict], list[dict]]:
    """Every case of one N: prepared, then interleaved timed repeats."""
    ready, skipped = _prepare(cases, threads)
    times = rounds(ready)
    records = [_record(case, stepper, first, t) for (case, stepper, first), t in zip(ready, times, strict=True)]
    _pair_with_rebound(records)
    for rec in records:
        ratio = rec.get("rebound_over_orbitsim")
        tail = f", REBOUND / orbitsim {ratio['wall']:.2f}" if ratio else ""
        progress(f"{rec['id']}: {rec['steps']} steps to t = {rec['t_end']:g}, "
                 f"{rec['per_step_s']['median'] * 1e6:.3g} us/step{tail}")
    return records, skipped


def run_adaptive_group(cases: list[AdaptiveCase], progress: Callable[[str], None],
                       threads: tuple[int, int]) -> tuple[list[dict], list[dict]]:
    """The records and skipped cases of one group's cases, one N at a time.

    ``threads`` is (the default thread count for cases that name none, NUMBA_NUM_THREADS).
    """
    return by_n(cases, lambda of_n: _run_n(of_n, progress, threads))
