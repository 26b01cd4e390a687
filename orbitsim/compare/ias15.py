"""The two IAS15s of ``orbitsim compare``: orbitsim's native ``ias15`` and REBOUND's, side by side.

Both always run, from the scenario's state with the same settings (``epsilon`` and ``min_dt``
from the scenario when its integrator is ias15, else REBOUND's defaults; the first trial step is
the scenario's ``dt``) and the same forces (REBOUND's through REBOUNDx, in its equations of motion),
and land exactly on the same output times. Where REBOUNDx cannot express the scenario's forces
(:func:`orbitsim.reference.force_pairing.rebound_refusal`) REBOUND's IAS15 is not run at all.
One of them is the reference every run is measured against (``--reference``); the other is
reported beside it, with their mutual position difference. When ias15 is among the compared
integrators the two also form the matched pair :data:`~orbitsim.reference.pairs.IAS15_PAIR`.

Output times:

* an adaptive scenario (``integrator: ias15``): its own grid, ``min(k * output.interval, t_end)``
  for k = 0 .. ``steps`` (the last one t_end itself), run by orbitsim exactly as ``orbitsim run``
  runs it. Fixed-dt schemes in the same comparison take whole steps of the scenario's ``dt`` and
  are sampled at the step that lands on each output time (:func:`fixed_step_plan`);
* a fixed-dt scenario: the sampled steps' times. Sampled every K steps (``output.every``, or an
  interval that is a whole number of steps) orbitsim's IAS15 runs on the grid ``K * dt`` and both
  IAS15s stop at ``k * (K dt)``, the fixed-dt runs' ``(k K) * dt`` up to round-off; otherwise it runs
  on the grid of ``dt`` (stopping at every step, so at least one IAS15 step per ``dt``) and both stop
  at ``n * dt``.
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np

from orbitsim.compare.metrics import relative_position_difference
from orbitsim.record import RunRecord, record_from_result
from orbitsim.reference.adaptive import IAS15_DEFAULTS, run_rebound_ias15
from orbitsim.reference.bridge import ReboundScheme
from orbitsim.reference.force_pairing import orbitsim_force_lines, rebound_refusal

__all__ = ["REFERENCE_CHOICES", "escape_summary", "fixed_step_plan", "ias15_settings", "mutual_difference",
           "output_grid", "rebound_ias15_refusal", "run_ias15_references"]

#: ``--reference``: which IAS15 serves as the reference (the first is the default).
REFERENCE_CHOICES = ("rebound", "orbitsim")
#: How far (relative, in steps) an output time may sit from a whole step of a fixed-dt scheme.
WHOLE_STEP_RTOL = 1e-9


def ias15_settings(scenario: Any) -> dict[str, float]:
    """``epsilon`` and ``min_dt``: the scenario's when its integrator is ias15, else the defaults."""
    from orbitsim.integrators.registry import canonical_name  # noqa: PLC0415 -- lazy: loads numba

    settings = dict(IAS15_DEFAULTS)
    if canonical_name(scenario.integrator) == "ias15":
        given = getattr(scenario, "integrator_settings", None) or {}
        settings.update({k: float(given[k]) for k in IAS15_DEFAULTS if k in given})
    return settings


def output_grid(scenario: Any) -> tuple[float, float, np.ndarray, np.ndarray, np.ndarray]:
    """``(grid_dt, t_end, grid_points, sample_steps, times)`` of the comparison: orbitsim's ias15
    runs on the grid of ``grid_dt`` to ``grid_points``; ``sample_steps`` label the samples (the
    scenario's plan) and ``times`` are where both IAS15s stop (see the module docstring)."""
    plan = np.asarray(scenario.sample_steps(), dtype=np.int64)
    if getattr(scenario, "adaptive", False):
        grid_dt, t_end, points = float(scenario.grid_dt), float(scenario.t_end), plan
    else:
        every = int(plan[1] - plan[0]) if plan.size > 1 else 1
        regular = plan.size > 2 and np.array_equal(plan[:-1], every * np.arange(plan.size - 1)) and (
            0 < plan[-1] - plan[-2] <= every)
        # Samples every K steps: the grid is K * dt, so IAS15 stops only at the samples (the times
        # k * (K dt) are the fixed-dt runs' (k K) * dt up to round-off); otherwise it stops every dt.
        grid_dt = float(scenario.dt) * (every if regular else 1)
        points = np.arange(plan.size, dtype=np.int64) if regular else plan
        t_end = float(plan[-1]) * float(scenario.dt)
    # The same float64 expression as the run loop's grid time (t0 = 0), clipped at t_end.
    times = np.minimum(0.0 + points.astype(np.float64) * grid_dt, t_end)
    return grid_dt, t_end, points, plan, times


def fixed_step_plan(scenario: Any, times: np.ndarray) -> np.ndarray:
    """Whole steps of the scenario's ``dt`` that land on ``times`` (an adaptive scenario's output
    times), for the fixed-dt schemes of the comparison.

    Raises
    ------
    ValueError
        When an output time is not a whole number of steps: their samples would be at other times
        than the references', and positions could not be compared.
    """
    dt = float(scenario.dt)
    ratio = np.asarray(times, dtype=np.float64) / dt
    steps = np.rint(ratio).astype(np.int64)
    bad = np.flatnonzero(np.abs(ratio - steps) > WHOLE_STEP_RTOL * np.maximum(1.0, ratio))
    if bad.size or np.any(np.diff(steps) <= 0):
        k = int(bad[0]) if bad.size else int(np.flatnonzero(np.diff(steps) <= 0)[0]) + 1
        fit = max(1, math.ceil(float(scenario.grid_dt) / dt - WHOLE_STEP_RTOL))
        raise ValueError(
            f"fixed-dt integrators step by dt = {dt:g}, which does not land on the output time t = {times[k]:.10g} "
            f"(output.interval = {scenario.grid_dt:g}, t_end = {scenario.t_end:g}); give a --dt that divides both, "
            f"e.g. --dt {float(scenario.grid_dt) / fit:.10g}, or a --t-end that is a multiple of the interval")
    return steps


def _run_native(scenario: Any, settings: dict[str, float], threads: int | None) -> RunRecord:
    """orbitsim's ias15 on the comparison's grid, timed after a warm-up that loads its kernels."""
    from orbitsim.results import collect_result  # noqa: PLC0415 -- lazy: loads numba
    from orbitsim.scenario_simulation import scenario_forces  # noqa: PLC0415 -- lazy: loads yaml
    from orbitsim.simulation import Simulation  # noqa: PLC0415 -- lazy: loads numba

    grid_dt, t_end, points, plan, _ = output_grid(scenario)
    run_settings = {**settings, "adaptive": True, "first_dt": float(scenario.dt), "t_end": t_end}

    def make() -> Simulation:
        return Simulation(scenario.masses, scenario.positions, scenario.velocities, "ias15", grid_dt, scenario.G,
                          scenario.softening, 0.0, threads, run_settings, forces=scenario_forces(scenario))

    for _ in make().chunks(np.zeros(1, dtype=np.int64)):  # compile or load the cached kernels
        pass

    sim = make()
    start = time.perf_counter()
    parts = list(sim.chunks(points, record_positions=True))
    wall = time.perf_counter() - start
    result = collect_result(sim, parts, True, wall)
    counters = sim.scheme.counters(sim.work)
    record = record_from_result(result, key="orbitsim_ias15", order=None,
                                display=f"orbitsim ias15 (epsilon {settings['epsilon']:g})",
                                options={**run_settings, "exact_finish_time": 1})
    record.forces = orbitsim_force_lines(scenario_forces(scenario), "ias15")
    record.step = plan[: record.n_samples].copy()  # the comparison's sample steps, as the other runs'
    record.engine = "reference"
    record.steps_done = int(counters["steps_accepted"])
    record.dt = float(scenario.dt)
    record.extra = {"counters": counters}
    return record


def rebound_ias15_refusal(scenario: Any) -> str | None:
    """Why REBOUND's IAS15 cannot carry the scenario's forces (then it is not run), or None."""
    from orbitsim.scenario_simulation import scenario_forces  # noqa: PLC0415 -- lazy: loads yaml

    return rebound_refusal(scenario_forces(scenario), ReboundScheme("ias15"))


def run_ias15_references(scenario: Any, threads: int | None = None) -> dict[str, RunRecord]:
    """Both IAS15s on the comparison's output times: ``{"rebound": ..., "orbitsim": ...}``, without
    ``"rebound"`` when REBOUND cannot carry the scenario's forces (:func:`rebound_ias15_refusal`)."""
    from orbitsim.scenario_simulation import scenario_forces  # noqa: PLC0415 -- lazy: loads yaml

    settings = ias15_settings(scenario)
    native = _run_native(scenario, settings, threads)
    if rebound_ias15_refusal(scenario):
        return {"orbitsim": native}
    _, _, _, plan, times = output_grid(scenario)
    rebound = run_rebound_ias15(scenario.masses, scenario.positions, scenario.velocities, G=scenario.G,
                                softening=scenario.softening, first_dt=float(scenario.dt), times=times, labels=plan,
                                settings=settings, display=f"REBOUND IAS15 (epsilon {settings['epsilon']:g})",
                                forces=scenario_forces(scenario))
    return {"rebound": rebound, "orbitsim": native}


def rebound_ias15_twin(scenario: Any, perturbation: float) -> RunRecord:
    """REBOUND's IAS15 again, from positions scaled by ``1 + perturbation`` (the ias15 pair's twin)."""
    from orbitsim.scenario_simulation import scenario_forces  # noqa: PLC0415 -- lazy: loads yaml

    _, _, _, plan, times = output_grid(scenario)
    positions = np.asarray(scenario.positions, dtype=np.float64) * (1.0 + perturbation)
    return run_rebound_ias15(scenario.masses, positions, scenario.velocities, G=scenario.G,
                             softening=scenario.softening, first_dt=float(scenario.dt), times=times, labels=plan,
                             settings=ias15_settings(scenario), engine="rebound_twin", key="ias15",
                             display="REBOUND IAS15 twin", forces=scenario_forces(scenario))


def mutual_difference(a: RunRecord, b: RunRecord) -> tuple[float, float]:
    """Largest relative position difference of two runs over their shared samples, and its time
    (scaled by ``b``'s size, as :func:`~orbitsim.compare.metrics.relative_position_difference`)."""
    diff = relative_position_difference(a.positions, b.positions)
    if diff.size == 0 or not np.any(np.isfinite(diff)):
        return math.nan, math.nan
    k = int(np.nanargmax(diff))
    return float(diff[k]), float(b.time[k])


def _two_body_energy(r: np.ndarray, v: np.ndarray, mu: float) -> float:
    """Specific orbital energy of a relative orbit: v^2 / 2 - mu / r."""
    return 0.5 * float(v @ v) - mu / float(np.linalg.norm(r))


#: Bodies named in "has ... bound to it" before the rest are counted.
_BOUND_NAMES_SHOWN = 3


def escape_summary(record: RunRecord, masses: np.ndarray, G: float, names: list[str]) -> str:
    """The final state in a phrase per body, the lighter of a bound pair bound to the heavier.

    * ``b: bound to star``: the body's most bound partner (the lowest negative two-body energy)
      among the bodies at least as heavy (of equal masses, the earlier one);
    * ``star: has b, c bound to it``: a body no heavier one holds, which holds lighter ones;
    * ``escaping``, ``unbound`` or ``bound`` (with its distance): a body in no bound pair, by its
      energy against the barycentre of all the others (escaping: positive and receding).

    A star used to read ``star: bound to b``, its innermost planet being its most bound partner.
    """
    if record.n_samples == 0:
        return "no samples"
    m = np.asarray(masses, dtype=np.float64)
    pos, vel = record.positions[-1], record.velocities[-1]

    def name(i: int) -> str:
        return names[i] if i < len(names) else f"body {i}"

    def heavier(i: int, j: int) -> bool:
        return m[j] > m[i] or (m[j] == m[i] and j < i)

    holder: dict[int, int] = {}
    for i in range(m.size):
        energy = {j: _two_body_energy(pos[i] - pos[j], vel[i] - vel[j], G * (m[i] + m[j]))
                  for j in range(m.size) if j != i and heavier(i, j) and np.any(pos[i] != pos[j])}
        j = min(energy, key=energy.__getitem__, default=None)
        if j is not None and energy[j] < 0.0:
            holder[i] = j
    parts = []
    for i in range(m.size):
        if i in holder:
            parts.append(f"{name(i)}: bound to {name(holder[i])}")
            continue
        held = [name(k) for k in range(m.size) if holder.get(k) == i]
        if held:
            shown = ", ".join(held[:_BOUND_NAMES_SHOWN])
            more = f" and {len(held) - _BOUND_NAMES_SHOWN} more" if len(held) > _BOUND_NAMES_SHOWN else ""
            parts.append(f"{name(i)}: has {shown}{more} bound to it")
            continue
        others = np.arange(m.size) != i
        rest = float(m[others].sum())
        if rest <= 0.0:
            continue
        r = pos[i] - (m[others] @ pos[others]) / rest
        v = vel[i] - (m[others] @ vel[others]) / rest
        dist = float(np.linalg.norm(r))
        energy_i = 0.5 * float(v @ v) - G * (rest + m[i]) / dist if dist > 0 else -math.inf
        state = "escaping" if energy_i > 0.0 and float(r @ v) > 0.0 else ("unbound" if energy_i > 0.0 else "bound")
        parts.append(f"{name(i)}: {state} (r = {dist:.4g} from the others' barycentre)")
    return "; ".join(parts)
