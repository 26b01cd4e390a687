"""What :meth:`Scenario.with_overrides <orbitsim.scenario.Scenario.with_overrides>` changes.

Some fields hang together, so replacing one resolves the others: ``steps`` and ``t_end`` (with
``dt`` and ``t_start``), ``every`` and ``interval``, and an integrator with its settings.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from orbitsim.scenario.data import DEFAULT_SAMPLES, ScenarioData
from orbitsim.scenario.direction import check_adaptive_t_end, check_dt, check_t_end
from orbitsim.scenario.errors import ScenarioError
from orbitsim.scenario.fields import check_number, unknown_key_error
from orbitsim.scenario.quantities import scenario_time
from orbitsim.scenario.timing import adaptive_integrator, check_t_start, resolve_grid, resolve_steps, run_span

__all__ = ["OVERRIDABLE", "resolve_overrides"]

OVERRIDABLE = ("name", "description", "integrator", "integrator_settings", "dt", "t_start", "steps", "t_end", "every",
               "interval", "record_positions", "softening", "G", "names", "masses", "positions",
               "velocities", "source", "checkpoint_every", "checkpoint_seconds", "radii", "events", "record_elements",
               "elements_primary", "forces", "integrator_state", "device")
#: What an integrator state belongs to (orbitsim.scenario.integrator_state): a change drops the state.
_STATE_OF = ("integrator", "integrator_settings", "dt", "G", "softening", "names", "masses", "positions", "velocities")


def resolve_overrides(scenario: ScenarioData, changes: dict[str, Any]) -> dict[str, Any]:
    """The fields to replace in ``scenario`` for ``changes`` (``None`` values ignored).

    Raises
    ------
    ScenarioError
        For an unknown field or an invalid value (naming the field), located in the scenario's file.
    """
    changes = {k: v for k, v in changes.items() if v is not None}
    for key in changes:
        if key not in OVERRIDABLE:
            raise unknown_key_error(key, "", OVERRIDABLE).located(scenario.source)
    try:
        _convert_times(scenario, changes)
        _resolve_integrator_change(scenario, changes)
        _resolve_time_change(scenario, changes)
    except ScenarioError as err:
        raise err.located(scenario.source) from None
    if scenario.integrator_state is not None and "integrator_state" not in changes and set(_STATE_OF) & changes.keys():
        changes["integrator_state"] = None  # it belonged to the old bits: the run starts from the Cartesian bodies
    if "every" in changes:
        changes["interval"] = None
    elif "interval" in changes:
        changes["every"] = None
    return changes


#: Overridable fields that hold a time, and the key an error about each names.
_TIME_FIELDS = {"dt": "dt", "t_start": "t_start", "t_end": "t_end", "interval": "output.interval"}


def _convert_times(scenario: ScenarioData, changes: dict[str, Any]) -> None:
    """Times given with a unit (``dt="1 day"``, from ``run --dt "1 day"``) in the scenario's units; numbers
    are left as they are."""
    G = changes.get("G", scenario.G)
    for name, key in _TIME_FIELDS.items():
        if isinstance(changes.get(name), str):
            changes[name] = scenario_time(changes[name], scenario.units, G, key)


def _resolve_integrator_change(scenario: ScenarioData, changes: dict[str, Any]) -> None:
    integrator = changes.get("integrator")
    if isinstance(integrator, Mapping):
        settings = {k: v for k, v in integrator.items() if k != "name"}
        if "name" not in integrator:
            raise ScenarioError("an integrator mapping needs a name", key="integrator.name")
        changes["integrator"] = integrator["name"]
        changes.setdefault("integrator_settings", settings)
    if "integrator" in changes and "integrator_settings" not in changes:
        from orbitsim.integrators.registry import UnknownIntegratorError, canonical_name  # noqa: PLC0415 -- lazy: loads numba

        try:
            new = canonical_name(changes["integrator"])
        except UnknownIntegratorError as err:
            raise ScenarioError(str(err), key="integrator") from None
        if new != scenario.integrator:
            changes["integrator_settings"] = {}


def _resolve_time_change(scenario: ScenarioData, changes: dict[str, Any]) -> None:
    if "steps" in changes and "t_end" in changes:
        raise ScenarioError("give only one of steps or t_end, not both", key="t_end")
    if _adaptive_after(scenario, changes):
        _resolve_adaptive_time(scenario, changes)
        return
    dt = check_dt(changes.get("dt", scenario.dt))
    t_start = check_t_start(changes.get("t_start", scenario.t_start))  # a new t_start re-resolves steps from t_end
    if "steps" in changes:
        changes["t_end"] = None
        return
    t_end = changes.get("t_end", scenario.t_end)
    blame = "t_end" if "t_end" in changes or "dt" not in changes else "dt"  # a file's t_end with a new dt
    if t_end is not None:
        t_end = check_t_end(t_end, dt, t_start)
        changes["t_end"] = t_end
        try:
            changes["steps"] = resolve_steps(t_end, dt, t_start)[0]
        except ScenarioError as err:
            raise ScenarioError(err.reason, key=blame) from None


def _adaptive_after(scenario: ScenarioData, changes: dict[str, Any]) -> bool:
    """Whether the scenario's integrator after ``changes`` chooses its own steps (ias15)."""
    integrator = changes.get("integrator", scenario.integrator)
    settings = changes.get("integrator_settings", scenario.integrator_settings)
    return adaptive_integrator(integrator, settings)


def _resolve_adaptive_time(scenario: ScenarioData, changes: dict[str, Any]) -> None:
    """An adaptive run's grid is its output grid: ``t_end`` sets the end time exactly and
    ``steps`` becomes the number of output intervals; ``dt`` (the first trial step) changes neither.
    A ``steps`` override counts output intervals, so it needs ``output.interval``."""
    t_start = check_t_start(changes.get("t_start", scenario.t_start))
    interval = None if "every" in changes else changes.get("interval", scenario.interval)
    if interval is not None:
        interval = check_number(interval, "output.interval", positive=True)
    if "steps" in changes:
        if interval is None:
            raise ScenarioError(f"{changes.get('integrator', scenario.integrator)} chooses its own steps: give "
                                "t_end (the end time), not steps", key="steps")
        changes["t_end"] = t_start + changes["steps"] * interval
    t_end = check_adaptive_t_end(changes.get("t_end", scenario.t_end), t_start)
    changes["t_end"] = t_end
    span = run_span(t_end, t_start)
    changes["steps"] = resolve_grid(span, interval if interval is not None else span / DEFAULT_SAMPLES)
