"""How long a scenario runs: the whole steps of ``dt`` that fit in ``t_end``.

A step is never shortened, so ``t_end`` resolves to the largest step count with
``steps * dt <= t_end`` (``>=`` for a backward run, ``dt < 0``: the same count as for ``-dt``),
except that a ``t_end`` a whole number of steps long up to round-off means exactly that many steps.

Every step count of a scenario (``steps``, ``t_end / dt``, ``output.every``,
``output.interval / dt``, ``output.checkpoint.every``) is at most :data:`MAX_STEPS` (2**53, defined
with the single-value checks in :mod:`orbitsim.scenario.fields`, which refuse a count beyond it).

A run's clock starts at ``t_start`` (default 0; :func:`check_t_start`): sample n is at
``t_start + n * dt`` and ``t_end`` is still the absolute end time, so the steps are counted over
:func:`run_span` ``= t_end - t_start``.

An adaptive integrator (:func:`adaptive_integrator`) takes no fixed steps: its run is counted in
output intervals instead (:func:`resolve_grid`), the last one ending on ``t_end`` exactly.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from orbitsim.scenario.errors import ScenarioError
from orbitsim.scenario.fields import MAX_STEPS, check_number, steps_limit_error

__all__ = ["MAX_STEPS", "adaptive_integrator", "check_t_start", "resolve_grid", "resolve_steps", "run_span",
           "steps_limit_error", "whole_count"]

#: t_end / dt within this relative distance of a whole number counts as whole: ``t_end = 1`` with
#: ``dt = 0.1`` gives 9.999999999999998 by round-off and must mean 10 steps, not 9.
_WHOLE_STEPS_RTOL = 1e-9


def check_t_start(value: Any) -> float:
    """``t_start`` as a finite float; ``-0.0`` becomes ``0.0`` (it is written only when non-zero, so
    both must mean the same clock)."""
    return check_number(value, "t_start") + 0.0


def run_span(t_end: float, t_start: float) -> float:
    """How long the run is: ``t_end - t_start``, exactly ``t_end`` when ``t_start`` is 0 (so
    scenarios without ``t_start`` resolve to the same steps as before it existed)."""
    return t_end - t_start if t_start else t_end


def resolve_steps(t_end: float, dt: float, t_start: float = 0.0) -> tuple[int, bool]:
    """Whole steps of ``dt`` that fit between ``t_start`` and ``t_end``, and whether they fill it exactly.

    Raises
    ------
    ScenarioError
        When not even one step fits, or more than :data:`MAX_STEPS` do.
    """
    what = "t_end - t_start" if t_start else "t_end"
    counted = "(t_end - t_start)" if t_start else "t_end"
    t_end = run_span(t_end, t_start)  # from here on a duration, counted from t_start
    if dt < 0.0:  # backwards (orbitsim.scenario.direction): the mirror image of the forward count
        t_end, dt = -t_end, -dt
    ratio = t_end / dt
    if not ratio <= 2.0 * MAX_STEPS:  # also inf (1e308 / 0.01) and nan, which round() cannot take
        raise steps_limit_error(f"{counted} / dt = {ratio:.3g} steps", "t_end")
    steps, whole = _whole_steps(t_end, dt, ratio, what)
    if steps > MAX_STEPS:
        raise steps_limit_error(f"{counted} / dt = {ratio:.3g} steps", "t_end")
    return steps, whole


def adaptive_integrator(integrator: str, settings: Mapping[str, Any] | None) -> bool:
    """Whether ``integrator`` with ``settings`` chooses its own steps (False for an unknown name:
    the integrator check reports that)."""
    from orbitsim.integrators.registry import UnknownIntegratorError, get_spec  # noqa: PLC0415 -- lazy: loads numba

    try:
        spec = get_spec(integrator)
    except UnknownIntegratorError:
        return False
    return bool(spec.adaptive and (settings or {}).get("adaptive", True) is not False)


def resolve_grid(t_end: float, interval: float) -> int:
    """Output intervals of an adaptive run up to ``t_end``: the last one ends at ``t_end`` itself,
    shorter than ``interval`` when ``interval`` does not divide ``t_end``.

    Raises
    ------
    ScenarioError
        When more than :data:`MAX_STEPS` samples would be taken.
    """
    ratio = t_end / interval
    if not ratio <= MAX_STEPS:
        raise steps_limit_error(f"t_end / output.interval = {ratio:.3g} samples", "output.interval")
    nearest = round(ratio)
    if nearest >= 1 and abs(ratio - nearest) <= _WHOLE_STEPS_RTOL * ratio:
        return int(nearest)
    return max(1, math.ceil(ratio))


def whole_count(ratio: float) -> int:
    """How many whole steps a ``ratio`` of a time to a step holds: rounded down, except that a ratio within
    1e-9 (relative) of a whole number is that number, as for ``t_end / dt``; 0 for a ratio that is not finite."""
    if not math.isfinite(ratio):
        return 0
    nearest = round(ratio)
    if nearest >= 1 and abs(ratio - nearest) <= _WHOLE_STEPS_RTOL * ratio:
        return int(nearest)
    return max(0, math.floor(ratio))


def _whole_steps(t_end: float, dt: float, ratio: float, what: str = "t_end") -> tuple[int, bool]:
    nearest = round(ratio)
    if nearest >= 1 and abs(ratio - nearest) <= _WHOLE_STEPS_RTOL * ratio:
        return int(nearest), True
    steps = math.floor(ratio)
    # floor of a rounded quotient can be one off; the definition is steps * dt <= t_end.
    while steps > 0 and steps * dt > t_end:
        steps -= 1
    while (steps + 1) * dt <= t_end:
        steps += 1
    if steps < 1:
        raise ScenarioError(f"{what} = {t_end:g} is shorter than one step (dt = {dt:g})", key="t_end")
    return steps, False
