"""``run --from`` with another integrator or dt: the final state of a run, continued by a new scheme.

What carries over is the physical state alone: the inertial positions and velocities at the last
step K (and the masses). Everything a scheme keeps beside them (Wisdom-Holman's Jacobi
coordinates and phase, a hybrid's clock, the first-same-as-last accelerations) belongs to the old
scheme and step, so the new scheme makes its work and its accelerations from that state exactly
as a new run does (:class:`~orbitsim.simulation.Simulation`): the continuation is the same bits
as a new run of the new scheme started from the state at step K.

Step numbers keep counting from K, so the trace's ``step`` column stays increasing. A sample at
step n is at ``t0 + n * dt``; after a change of dt at step K (time T_K) the run's ``t0`` becomes
``T_K - K * dt_new``, kept in its checkpoints so that resuming and extending it keep the same
clock. ``t0 + K * dt_new`` equals T_K to round-off (an ulp or two of the larger of |T_K| and
``K * |dt_new|``), not bit for bit: the step count, not the time, is what is exact.

Every change is appended to the run's history, a JSON list kept in its checkpoints and in the
trace's ``integrator_history`` attribute: ``{"step": K, "time": T_K, "t0": t0_new, "from":
{"integrator": ..., "dt": ...}, "to": {...}}``.

Refused, each with one line (:class:`~orbitsim.io.checkpoint.CheckpointError`):

* an adaptive scheme (ias15) before or after: its run counts output intervals, not steps of dt;
* a run with ``events:``: its encounter and collision state is tied to the old scheme's steps;
* a new dt for a run sampled by ``output.interval``: that grid is laid on whole steps of one dt
  from t = 0.
"""

from __future__ import annotations

import dataclasses
import json
import math
from typing import TYPE_CHECKING, Any

from orbitsim.io.checkpoint import Checkpoint, CheckpointError

if TYPE_CHECKING:
    from pathlib import Path

    from orbitsim.scenario import Scenario

__all__ = ["Switch", "plan_switch", "resolve_request"]


@dataclasses.dataclass(frozen=True)
class Switch:
    """The continued run: its scenario, the checkpoint it starts from, and whether it is a new scheme."""

    scenario: Scenario
    checkpoint: Checkpoint
    rebuild: bool


def resolve_request(stored: Scenario, integrator: str | None, dt: float | None,
                    backward: bool) -> tuple[str, float]:
    """The integrator name and dt the continuation asks for (``backward``: dt = -|dt|)."""
    from orbitsim.integrators.registry import UnknownIntegratorError, canonical_name  # noqa: PLC0415 -- lazy: loads numba

    try:
        name = canonical_name(integrator) if integrator is not None else stored.integrator
    except UnknownIntegratorError as err:
        raise CheckpointError(f"--integrator {integrator}: {err}") from None
    step = float(dt) if dt is not None else float(stored.dt)
    return name, -abs(step) if backward else step


def plan_switch(src: Path, stored: Scenario, ckpt: Checkpoint, name: str, dt: float, steps: int | None,
                t_end: float | None) -> Switch:
    """The scenario and start of ``stored`` continued from ``ckpt`` with ``name`` at ``dt``.

    ``steps`` more steps, or as many whole steps of ``dt`` as fit between the run's end and
    ``t_end``. With the same integrator and dt, the work is restored (bit for bit as one longer
    run); otherwise it is rebuilt and the change is recorded.

    Raises
    ------
    CheckpointError
        For a change that cannot be honoured (see the module docstring) or a ``t_end`` not beyond
        the run's end in the direction of ``dt``.
    """
    from orbitsim.scenario import ScenarioError  # noqa: PLC0415 -- lazy: loads yaml
    from orbitsim.scenario.timing import resolve_steps  # noqa: PLC0415 -- lazy: loads yaml

    changed = name != stored.integrator or dt != stored.dt
    if changed:
        _check_switch(src, stored, name, dt)
    here = ckpt.steps_done
    now = ckpt.t0 + here * stored.dt  # the time the kernels gave the last sample (Simulation.time)
    try:
        if not changed and ckpt.t0 == stored.t_start and steps is None:
            scenario = stored.with_overrides(t_end=t_end)  # one longer run: its t_end resolved from t_start
        else:
            more = steps if steps is not None else resolve_steps(float(t_end) - now, dt)[0]
            changes: dict[str, Any] = {"steps": here + more}
            if changed:
                changes.update(integrator=name, dt=dt)
            scenario = stored.with_overrides(**changes)
    except ScenarioError as err:
        where = f"--t-end {t_end:g}" if steps is None else f"--steps {steps}"
        if steps is None and (float(t_end) - now) * dt <= 0.0:
            raise CheckpointError(f"{src}: {where} is not beyond the run's end (t = {now:.10g}) in the direction "
                                  f"of dt = {dt:g}") from None
        raise CheckpointError(f"{src}: {where}: {err.reason}") from None
    if not changed:
        return Switch(scenario, ckpt, rebuild=False)
    t0 = now - here * dt
    record = {"step": here, "time": now, "t0": t0, "from": {"integrator": stored.integrator, "dt": stored.dt},
              "to": {"integrator": name, "dt": dt}}
    history = [*json.loads(ckpt.history or "[]"), record]
    start = dataclasses.replace(ckpt, t0=t0, history=json.dumps(history))
    return Switch(scenario, start, rebuild=True)


def _check_switch(src: Path, stored: Scenario, name: str, dt: float) -> None:
    """Refuse, in one line, a change the continuation cannot honour."""
    from orbitsim.scenario.timing import adaptive_integrator  # noqa: PLC0415 -- lazy: loads yaml

    for scheme, settings in ((stored.integrator, stored.integrator_settings), (name, {})):
        if adaptive_integrator(scheme, settings):
            raise CheckpointError(f"{src}: {scheme} chooses its own steps and counts output intervals, not steps of "
                                  "dt, so `run --from` cannot switch to or from it; export the final state as a "
                                  "scenario and run that instead")
    if stored.events is not None:
        raise CheckpointError(f"{src}: the run watches events:, whose encounter and collision state is tied to its "
                              "steps, so it cannot continue with another integrator or dt; leave out --integrator, "
                              "--dt and --backward")
    if dt != stored.dt and stored.interval is not None:
        raise CheckpointError(f"{src}: the run samples every output.interval = {stored.interval:g}, a grid laid on "
                              f"whole steps of dt = {stored.dt:g} from t = 0, so its dt cannot change; leave out "
                              "--dt and --backward")
    if not math.isfinite(dt) or dt == 0.0:
        raise CheckpointError(f"{src}: dt must be a finite non-zero number, got {dt}")
