"""Which way a run goes in time: ``dt < 0`` integrates backwards.

A negative ``dt`` takes the same steps with ``h = dt`` (the kernels and the sample clock
``t0 + n * dt`` hold for either sign), so sample times decrease. ``t_end`` is still the end
*time*: with ``dt < 0`` it must be before ``t_start`` (default 0), so negative without one
(``dt: -0.01, t_end: -10`` is 1000 steps from t = 0 to t = -10); ``steps`` counts steps whatever
the sign, and ``output.interval`` is a duration (> 0).

Which schemes may step backwards, and why:

* every scheme whose ``SPEC.reversible`` is true (verlet, leapfrog, leapfrog4/6/8,
  wisdom_holman): one step of ``-h`` undoes one step of ``h`` up to round-off, so a backward run
  is the forward run's time reverse;
* the other fixed-step explicit schemes (euler, semi_implicit_euler, rk4): a step of ``-h`` is
  the same formula with a negative h, well defined and of the same order, but it does not undo a
  forward step (they are not time-symmetric), so forward then back does not return to the start;
* refused: ias15 (adaptive: its step control and its ``t_end`` clock assume time increases) and
  trace (its encounter switching and its Bulirsch-Stoer/IAS15 sub-steps assume the same); also a
  run with ``events:`` (encounter times are interpolated within a forward step) or ``forces:``
  (velocity-dependent forces and migration are not time-symmetric, and none is tested backwards).
"""

from __future__ import annotations

from typing import Any

from orbitsim.scenario.errors import ScenarioError
from orbitsim.scenario.fields import check_number

__all__ = ["BACKWARD_SCHEMES_REFUSED", "can_step_backward", "check_adaptive_t_end", "check_direction", "check_dt",
           "check_t_end"]

#: Schemes that never step backwards (see the module docstring for why).
BACKWARD_SCHEMES_REFUSED = ("ias15", "trace")


def check_dt(value: Any) -> float:
    """``dt`` as a finite, non-zero float (negative runs backwards)."""
    dt = check_number(value, "dt")
    if dt == 0.0:
        raise ScenarioError("must be non-zero (> 0 runs forwards, < 0 backwards), got 0", key="dt")
    return dt


def check_t_end(value: Any, dt: float, t_start: float = 0.0) -> float:
    """``t_end`` as a finite float on the side of ``t_start`` (default 0) that ``dt`` steps towards."""
    t_end = check_number(value, "t_end")
    after = f"t_start = {t_start:g}" if t_start else "0"  # the messages of runs without t_start stay as they were
    if dt > 0.0 and t_end <= t_start:
        raise ScenarioError(f"must be > {after} with dt = {dt:g} (a negative dt runs backwards, to an earlier "
                            f"t_end), got {t_end:g}", key="t_end")
    if dt < 0.0 and t_end >= t_start:
        raise ScenarioError(f"must be < {after} with dt = {dt:g}: the run goes backwards from t = {t_start:g}, so "
                            f"its end time is earlier (t_end: {t_start - abs(t_end - t_start):g}), got {t_end:g}",
                            key="t_end")
    return t_end


def check_adaptive_t_end(value: Any, t_start: float = 0.0) -> float:
    """An adaptive run's ``t_end``: after ``t_start`` (it never runs backwards)."""
    if not t_start:
        return check_number(value, "t_end", positive=True)  # the message runs without t_start always gave
    t_end = check_number(value, "t_end")
    if t_end <= t_start:
        raise ScenarioError(f"must be > t_start = {t_start:g} (an adaptive scheme runs forwards), got {t_end:g}",
                            key="t_end")
    return t_end


def can_step_backward(integrator: str) -> bool:
    """Whether ``integrator`` (a registry name) may run with ``dt < 0``."""
    return integrator not in BACKWARD_SCHEMES_REFUSED


def check_direction(integrator: str, dt: float, events: Any, forces: Any) -> None:
    """Refuse ``dt < 0`` where it is not supported, in one line naming ``dt``."""
    if dt > 0.0:
        return
    if not can_step_backward(integrator):
        raise ScenarioError(f"{integrator} cannot run backwards (dt = {dt:g} < 0): its step control assumes time "
                            "increases; use a fixed-step scheme such as leapfrog or wisdom_holman", key="dt")
    if events is not None:
        raise ScenarioError(f"dt = {dt:g} < 0: a run with events: cannot go backwards (encounter times are found "
                            "within forward steps)", key="dt")
    if forces:
        raise ScenarioError(f"dt = {dt:g} < 0: a run with forces: cannot go backwards (not every force is "
                            "time-symmetric, and none is tested backwards)", key="dt")
