"""TRACE over the same steps, orbitsim beside REBOUND: the ``trace`` kind of a matrix.

Each repeat integrates one system from its initial state over the whole steps that reach
``t_end`` as REBOUND's ``integrate(t_end, exact_finish_time=0)`` counts them (steps of ``dt``
while the summed time is below ``t_end``: 58,824 steps of 0.034 to t = 2000.016 for REBOUND's
many-encounters set-up), the same count for both engines:

* orbitsim: ``Simulation(..., "trace", dt)`` through :meth:`~orbitsim.simulation.Simulation.chunks`
  (the loop every run uses), sampling the last step only; its counters (steps redone, encounter
  Bulirsch-Stoer sub-steps, ...) from :func:`orbitsim.integrators.trace.counters`;
* REBOUND: :func:`orbitsim.reference.bridge.rebound_simulation` with ``scheme="trace"`` (the same
  ``r_crit_hill``, ``peri_crit_eta`` and ``peri_mode``: REBOUND's defaults), ``sim.steps(steps)``.

Building each repeat's simulation is outside the timed span, and both engines are warmed up
first (orbitsim's first call compiles or loads the cache; its first whole span still touches
memory). The cases of one N are interleaved, repeat 1 of each then repeat 2, ...

The port does REBOUND 5.2.2's operations in REBOUND's order, so both codes meet the same
encounters and do the same work. Each orbitsim record says whether the two final states are equal
to the bit and, if not, their largest difference relative to the system's size: a timing of
different work (another encounter sequence) would compare nothing.

Ratios are orbitsim / REBOUND (< 1: orbitsim is faster): the best of the k repeats of each engine
(on a shared machine the noise only ever adds time, so the fastest repeat is what the code does
undisturbed), and the median over rounds of the ratio within a round, wall and CPU, as everywhere
else in the suite.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np

from orbitsim.bench._trace_fields import TraceCase
from orbitsim.bench.engines import jit_timed
from orbitsim.bench.interleave import by_n, prepare, rounds
from orbitsim.bench.stats import paired_median, summarise
from orbitsim.bench.systems import System
from orbitsim.reference.bridge import read_state, rebound_simulation

__all__ = ["OrbitsimTrace", "ReboundTrace", "agreement", "run_trace_group", "whole_steps"]

#: One timed repeat: (wall seconds, CPU seconds, engine counters, final (N, 3) positions, velocities).
Timed = tuple[float, float, dict[str, int], np.ndarray, np.ndarray]


def whole_steps(t_end: float, dt: float) -> int:
    """The steps REBOUND's ``integrate(t_end, exact_finish_time=0)`` takes: one more while the
    time, summed as REBOUND sums it (``t += dt``), is below ``t_end``."""
    t, steps = 0.0, 0
    while t < t_end:
        t += dt
        steps += 1
    return steps


class _Engine:
    """What both engines share: the case, its system, its step and its step count."""

    engine = ""

    def __init__(self, case: TraceCase, system: System) -> None:
        self.case = case
        self.system = system
        self.dt = float(system.dt or case.dt)
        self.softening = float(case.softening if system.softening is None else system.softening)
        self.steps = whole_steps(case.t_end, self.dt)
        self.threads_used = 1  # TRACE's kernels are serial in both codes
        self.jit = "n/a"


class OrbitsimTrace(_Engine):
    """orbitsim's ``trace`` over one case's steps, a fresh :class:`Simulation` per repeat."""

    engine = "orbitsim"

    def _simulation(self) -> Any:
        from orbitsim.simulation import Simulation  # noqa: PLC0415 -- lazy: loads numba

        s = self.system
        return Simulation(s.masses.copy(), s.positions.copy(), s.velocities.copy(), "trace", self.dt, s.G,
                          self.softening, threads=1)

    def _run(self, sim: Any, steps: int) -> None:
        for _ in sim.chunks(np.array([steps], dtype=np.int64), record_positions=False):
            pass
        if sim.diverged:
            raise RuntimeError(f"{self.case.case_id}: {sim.failure_detail() or 'the state became non-finite'}")

    def first_call(self) -> float:
        """Build and take one step; returns the seconds (JIT compilation or cache loading included)."""
        elapsed, self.jit = jit_timed("trace", lambda: self._run(self._simulation(), 1))
        return elapsed

    def once(self) -> Timed:
        """Integrate the case's steps from the initial state; (wall, CPU, counters, final state)."""
        from orbitsim.integrators.trace import counters  # noqa: PLC0415 -- lazy: loads numba

        sim = self._simulation()
        cpu, start = time.process_time(), time.perf_counter()
        self._run(sim, self.steps)
        wall, cpu = time.perf_counter() - start, time.process_time() - cpu
        return (wall, cpu, {k: int(v) for k, v in counters(sim.work).items()}, *sim.state())


class ReboundTrace(_Engine):
    """REBOUND's TRACE over the same steps, a fresh :class:`rebound.Simulation` per repeat."""

    engine = "rebound"

    def _simulation(self) -> Any:
        s = self.system
        return rebound_simulation(s.masses, s.positions, s.velocities, G=s.G, softening=self.softening, dt=self.dt,
                                  scheme="trace")

    def first_call(self) -> float:
        """Build the simulation and take one step; returns the seconds."""
        start = time.perf_counter()
        self._simulation().steps(1)
        return time.perf_counter() - start

    def once(self) -> Timed:
        """Integrate the case's steps from the initial state; (wall, CPU, {}, final state)."""
        sim = self._simulation()
        cpu, start = time.process_time(), time.perf_counter()
        sim.steps(self.steps)
        wall, cpu = time.perf_counter() - start, time.process_time() - cpu
        return (wall, cpu, {}, *read_state(sim))


Engine = OrbitsimTrace | ReboundTrace


def _make(case: TraceCase, system: System) -> Engine:
    return (OrbitsimTrace if case.engine == "orbitsim" else ReboundTrace)(case, system)


def _record(case: TraceCase, engine: Engine, first: float, runs: list[Timed]) -> dict[str, Any]:
    wall = summarise([r[0] for r in runs])
    cpu = summarise([r[1] for r in runs])
    return {
        "id": case.case_id, "group": case.group, "kind": "trace", "engine": case.engine,
        "integrator": case.integrator, "system": case.system, "n": case.n, "t_end": case.t_end, "dt": engine.dt,
        "softening": engine.softening, "steps": engine.steps, "threads": engine.threads_used,
        "repeats": len(runs), "warmup": case.warmup, "time_s": wall, "cpu_s": cpu,
        "per_step_s": summarise([w / engine.steps for w in wall["values"]]),
        "first_call_s": first, "jit": engine.jit, "counters": runs[-1][2],
    }


def agreement(ours: tuple[np.ndarray, np.ndarray], theirs: tuple[np.ndarray, np.ndarray]) -> dict[str, Any]:
    """How two final states compare: equal to the bit, and the largest position and velocity
    differences relative to REBOUND's largest distance from the origin and largest speed."""
    (x, v), (xr, vr) = ours, theirs
    size, speed = float(np.max(np.linalg.norm(xr, axis=1))), float(np.max(np.linalg.norm(vr, axis=1)))
    return {"bitwise": bool(np.array_equal(x, xr) and np.array_equal(v, vr)),
            "position": float(np.max(np.linalg.norm(x - xr, axis=1))) / size,
            "velocity": float(np.max(np.linalg.norm(v - vr, axis=1))) / speed}


def _pair_with_rebound(records: list[dict[str, Any]], states: list[tuple[np.ndarray, np.ndarray]]) -> None:
    """Give each orbitsim record of one N its time over REBOUND's (< 1: orbitsim is faster) and
    how its final state agrees with REBOUND's."""
    k = next((k for k, r in enumerate(records) if r["engine"] == "rebound"), None)
    if k is None:
        return
    twin = records[k]
    for rec, state in zip(records, states, strict=True):
        if rec["engine"] != "orbitsim":
            continue
        rec["orbitsim_over_rebound"] = {
            "twin": twin["id"], "best": rec["time_s"]["min"] / twin["time_s"]["min"],
            "wall": paired_median(rec["time_s"]["values"], twin["time_s"]["values"]),
            "cpu": paired_median(rec["cpu_s"]["values"], twin["cpu_s"]["values"]),
            "rounds": min(rec["repeats"], twin["repeats"])}
        rec["agreement"] = agreement(state, states[k])


def _run_n(cases: list[TraceCase], progress: Callable[[str], None],
           threads: tuple[int, int]) -> tuple[list[dict], list[dict]]:
    """Every case of one N: prepared, then interleaved timed repeats."""
    ready, skipped = prepare(cases, threads, _make)  # both engines warmed up: the timing excludes start-up
    times = rounds(ready)
    records = [_record(case, engine, first, t) for (case, engine, first), t in zip(ready, times, strict=True)]
    _pair_with_rebound(records, [(t[-1][3], t[-1][4]) for t in times])
    for rec in records:
        ratio, same = rec.get("orbitsim_over_rebound"), rec.get("agreement")
        tail = (f", orbitsim / REBOUND {ratio['best']:.3f} best, {ratio['wall']:.3f} paired; final states "
                + ("bit-identical" if same["bitwise"] else f"differ by {same['position']:.2e}")) if ratio else ""
        progress(f"{rec['id']}: {rec['steps']} steps to t = {rec['t_end']:g}, best {rec['time_s']['min']:.3g} s"
                 f"{tail}")
    return records, skipped


def run_trace_group(cases: list[TraceCase], progress: Callable[[str], None],
                    threads: tuple[int, int]) -> tuple[list[dict], list[dict]]:
    """The records and skipped cases of one group's cases, one N at a time.

    ``threads`` is (the default thread count, NUMBA_NUM_THREADS); TRACE's cases run on one.
    """
    return by_n(cases, lambda of_n: _run_n(of_n, progress, threads))
