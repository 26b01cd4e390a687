"""Validation of a scenario's time and output fields (of its :class:`~orbitsim.scenario.data.ScenarioData`).

:func:`check_time` reads the raw fields (``dt``, ``steps``, ``t_start``, ``t_end``, ``output.every``,
``output.interval``, ``output.checkpoint``) and returns their normalised values, or raises the
:class:`~orbitsim.scenario.errors.ScenarioError` naming the key to fix. The counting rules are in
:mod:`orbitsim.scenario.timing`; fixed-dt and adaptive runs count differently (a fixed-dt run in
whole steps of dt, an adaptive one in output intervals, its dt only the first trial step).
"""

from __future__ import annotations

import math
from typing import Any

from orbitsim.scenario.data import DEFAULT_SAMPLES, ScenarioData
from orbitsim.scenario.direction import check_adaptive_t_end, check_dt, check_t_end
from orbitsim.scenario.errors import ScenarioError
from orbitsim.scenario.fields import check_count, check_number
from orbitsim.scenario.timing import (
    MAX_STEPS,
    adaptive_integrator,
    check_t_start,
    resolve_grid,
    resolve_steps,
    run_span,
    steps_limit_error,
)

__all__ = ["check_time"]


def check_time(s: ScenarioData) -> dict[str, Any]:
    """The normalised time and output fields of ``s`` (only those that are set), or a ScenarioError."""
    dt = check_dt(s.dt)  # < 0 runs backwards (orbitsim.scenario.direction)
    fields: dict[str, Any] = {"dt": dt, "steps": check_count(s.steps, "steps"), "t_start": check_t_start(s.t_start)}
    steps, t_start = fields["steps"], fields["t_start"]
    if adaptive_integrator(s.integrator, s.integrator_settings):
        fields.update(_adaptive(s, steps, t_start))
    else:
        fields.update(_fixed(s, dt, steps, t_start))
    every, seconds = s.checkpoint_every, s.checkpoint_seconds
    if every is not None:
        fields["checkpoint_every"] = check_count(every, "output.checkpoint.every")
    if seconds is not None:
        fields["checkpoint_seconds"] = check_number(seconds, "output.checkpoint.seconds", positive=True)
    return fields


def _fixed(s: ScenarioData, dt: float, steps: int, t_start: float) -> dict[str, Any]:
    """A fixed-dt run: ``steps`` whole steps of ``dt``; ``t_end``, when given, must agree."""
    fields: dict[str, Any] = {}
    if not math.isfinite(t_start + steps * dt):
        raise ScenarioError(f"steps * dt = {steps} * {dt:g} overflows float64: use a smaller dt "
                            "(or other units)", key="dt")
    if s.t_end is not None:
        t_end = fields["t_end"] = check_t_end(s.t_end, dt, t_start)
        expected, _ = resolve_steps(t_end, dt, t_start)
        if expected != steps:
            raise ScenarioError(f"steps = {steps} disagrees with t_end = {t_end:g} / dt = "
                                f"{dt:g} ({expected} whole steps): give only one", key="steps")
    if s.every is not None and s.interval is not None:
        raise ScenarioError("give only one of every or interval, not both", key="output.interval")
    if s.every is not None:
        fields["every"] = check_count(s.every, "output.every")
    if s.interval is not None:
        interval = fields["interval"] = check_number(s.interval, "output.interval", positive=True)
        if not interval / abs(dt) <= MAX_STEPS:  # sample numbers become steps of dt
            raise steps_limit_error(f"output.interval / |dt| = {interval / abs(dt):.3g} steps",
                                    "output.interval", "sample more often")
    return fields


def _adaptive(s: ScenarioData, steps: int, t_start: float) -> dict[str, Any]:
    """An adaptive scheme's run: ``t_end`` and ``output.interval`` make its grid, ``dt`` is
    only the first trial step, and ``steps`` counts output intervals."""
    name = s.integrator
    if s.t_end is None:
        raise ScenarioError(f"{name} chooses its own steps: give t_end (the end time), not steps", key="steps")
    t_end = check_adaptive_t_end(s.t_end, t_start)
    fields: dict[str, Any] = {"t_end": t_end}
    if s.every is not None:
        raise ScenarioError(f"{name} chooses its own steps, so samples are taken by time: give "
                            "output.interval instead of output.every", key="output.every")
    span = run_span(t_end, t_start)
    if s.interval is not None:
        fields["interval"] = check_number(s.interval, "output.interval", positive=True)
    grid = fields.get("interval", span / DEFAULT_SAMPLES)
    expected = resolve_grid(span, grid)
    if expected != steps:
        raise ScenarioError(f"steps = {steps} disagrees with t_end = {t_end:g} / output.interval = "
                            f"{grid:g} ({expected} output intervals)", key="steps")
    return fields
