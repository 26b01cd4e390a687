"""How long a scenario runs: the whole steps of ``dt`` that fit in ``t_end``.

A step is never shortened, so ``t_end`` resolves to the largest step count with
``steps * dt <= t_end``, except that a ``t_end`` a whole number of steps long up to round-off
means exactly that many steps.
"""

from __future__ import annotations

import math

from orbitsim.scenario.errors import ScenarioError

__all__ = ["resolve_steps"]

#: t_end / dt within this relative distance of a whole number counts as whole: ``t_end = 1`` with
#: ``dt = 0.1`` gives 9.999999999999998 by round-off and must mean 10 steps, not 9.
_WHOLE_STEPS_RTOL = 1e-9


def resolve_steps(t_end: float, dt: float) -> tuple[int, bool]:
    """Whole steps of ``dt`` that fit in ``t_end``, and whether they fill it exactly.

    Raises
    ------
    ScenarioError
        When not even one step fits.
    """
    ratio = t_end / dt
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
        raise ScenarioError(f"t_end = {t_end:g} is shorter than one step (dt = {dt:g})", key="t_end")
    return steps, False
