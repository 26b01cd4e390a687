"""IAS15: the adaptive 15th-order Gauss-Radau integrator (Rein & Spiegel 2015), REBOUND's default.

The package: :mod:`.core`, the step (predictor-corrector, error estimate, step control,
prediction); :mod:`.tables`, the Gauss-Radau constants (and the quadrature weights MEGNO uses);
:mod:`.tangent`, the step with first-order variational equations and MEGNO, as REBOUND's IAS15
integrates its variational particles (the tangent components ride in the same predictor-corrector
and count in its convergence test; the step control reads the bodies only; the MEGNO integrand is
summed with the Radau weights over the nodes); :mod:`.chaos`, that step behind the run contract's
variational run (``run_chaos``, on the same output grid as :func:`run`); :mod:`.grid`, the output
grid's clock; this module, the scheme's record (:data:`IAS15`) and its contract with the run loop,
which for an adaptive scheme reads:

* the run's grid is its output grid. ``dt`` given to :func:`run` is the sampling interval: the
  "step" ``n`` of a trace is the sample at time ``t0 + n * dt`` (the last one at ``t_end`` when
  the interval does not divide it), and between two samples IAS15 takes as many steps of its own
  choosing as it needs;
* each sample lands exactly on its time: the last step before it is shortened to end there, and
  the step before the shortening is the first one tried afterwards (REBOUND's
  ``exact_finish_time = 1``, interval by interval as ``sim.integrate(t)`` does it);
* the first trial step is the setting ``first_dt`` (a scenario's ``dt``), then IAS15's own choice;
* with ``adaptive: false`` the run is Gauss-Radau at the constant step ``dt``, one step per grid
  point, like every fixed-dt scheme.

Everything IAS15 carries from step to step (the polynomial, its prediction, the compensation
terms, the clock and the step counters) is in ``work``, so checkpoints resume bit for bit.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from orbitsim._jit import jit, jit_inline, stop_requested
from orbitsim.events.kernels import after_step, remember_start
from orbitsim.forces.hooks import refresh_accelerations
from orbitsim.integrators.base import (
    Integrator,
    IntegratorSpec,
    Setting,
    is_finite_state,
    record_sample,
    sample_loop,
    setting_defaults,
)
from orbitsim.integrators.ias15.chaos import check_chaos, make_chaos_tangent, run_chaos
from orbitsim.integrators.ias15.core import (
    CLOCK_DT,
    CLOCK_DT_LAST_DONE,
    CLOCK_STARTED,
    CLOCK_T,
    COUNT_ACCEPTED,
    COUNT_FORCE_EVALS,
    COUNT_REJECTED,
    COUNT_STATUS,
    COUNT_UNCONVERGED,
    STATUS_NON_FINITE,
    STATUS_STEP_UNDERFLOW,
    WORK_FIELDS,
    IAS15Work,
    step_try,
)
from orbitsim.integrators.ias15.grid import grid_target, sample_time, start_clock

__all__ = ["IAS15", "SETTINGS", "SPEC", "carry_over", "check_chaos", "clock_time", "counters", "failure_message",
           "make_chaos_tangent", "make_work", "run", "run_chaos", "run_watched", "step", "validate_settings"]

SPEC = IntegratorSpec(
    name="ias15",
    aliases=("gauss_radau",),
    order=15,
    symplectic=False,
    reversible=False,
    force_evals=16,
    work_slots=0,
    fsal=True,
    summary="IAS15, adaptive 15th-order Gauss-Radau predictor-corrector with compensated summation "
    "(REBOUND's default); samples land exactly on output times",
    reference="Rein & Spiegel (2015), MNRAS 446, 1424; Everhart (1985), ASSL 115, 185; "
    "Pham, Rein & Spiegel (2024), OJAp 7, 1 (step control)",
    module=__name__,
    adaptive=True,
)

#: Settings a scenario may give (``integrator: {name: ias15, epsilon: 1e-9}``): REBOUND's names and defaults.
SETTINGS: dict[str, Setting] = {
    "epsilon": Setting(1e-9, "accuracy of the step control: each step is (5040 epsilon)^(1/7) of the shortest "
                       "timescale of the motion (Pham, Rein & Spiegel 2024); 0: a constant step, the scenario's dt"),
    "min_dt": Setting(0.0, "the smallest step the control may choose (0: no floor; a floor lets a run pass a "
                      "singular encounter, at a loss of accuracy, rather than stop)"),
    "adaptive": Setting(True, "false: Gauss-Radau at the constant step dt, one step per grid point, like every "
                        "fixed-dt scheme", (True, False)),
}
#: Settings the run loop passes beside them (from the scenario's ``dt`` and ``t_end``).
RUN_SETTINGS = ("first_dt", "t_end")
#: Work entries a restored checkpoint does not override: the end of the run (``run --from``
#: continues a finished run to a later t_end from its checkpoint).
RUN_CONSTANTS = (WORK_FIELDS.index("t_end"),)


def validate_settings(settings: Mapping[str, Any] | None) -> dict[str, Any]:
    """Check ``epsilon`` (>= 0; 0 means a constant step), ``min_dt`` (>= 0) and ``adaptive``.

    ``first_dt`` and ``t_end`` are accepted from the API (the run loop sets them from the
    scenario's ``dt`` and ``t_end``). Raises ValueError naming the key.
    """
    given = dict(settings or {})
    given.pop("name", None)
    unknown = sorted(set(given) - set(SETTINGS) - set(RUN_SETTINGS))
    if unknown:
        raise ValueError(f"ias15 setting {unknown[0]!r} is unknown; valid keys: {', '.join(SETTINGS)}")
    out = setting_defaults(SETTINGS)
    for key in ("epsilon", "min_dt"):
        value = given.get(key, SETTINGS[key].default)
        if isinstance(value, bool) or not isinstance(value, int | float) or not (math.isfinite(value) and value >= 0):
            raise ValueError(f"ias15 setting {key!r} must be a number >= 0, got {value!r}")
        out[key] = float(value)
    adaptive = given.get("adaptive", True)
    if not isinstance(adaptive, bool):
        raise ValueError(f"ias15 setting 'adaptive' must be true or false, got {adaptive!r}")
    out["adaptive"] = adaptive
    for key in RUN_SETTINGS:
        if key in given and given[key] is not None:
            value = float(given[key])
            if not (math.isfinite(value) and value != 0.0):
                raise ValueError(f"ias15 setting {key!r} must be a finite non-zero number, got {given[key]!r}")
            out[key] = value
    return out


def make_work(m: np.ndarray, G: float, settings: Mapping[str, Any] | None = None) -> IAS15Work:
    """The ``work`` (:class:`~orbitsim.integrators.ias15.core.IAS15Work`) for masses ``m``."""
    config = validate_settings(settings)
    n = int(np.asarray(m).shape[0])
    clock = np.zeros(4)
    counts = np.zeros(5, dtype=np.int64)
    return IAS15Work(
        *(np.zeros((7, 3 * n)) for _ in range(6)),
        *(np.zeros(3 * n) for _ in range(3)),
        np.zeros((3, n)),
        np.zeros(3 * n),
        np.zeros(3 * n),
        clock,
        counts,
        float(config["epsilon"]),
        float(config["min_dt"]),
        bool(config["adaptive"] and config["epsilon"] > 0.0),
        float(config.get("t_end", np.inf)),
        float(config.get("first_dt", 0.0)),
    )


def carry_over(old: tuple[Any, ...], new: tuple[Any, ...]) -> None:
    """After the bodies changed (a merge, a removal): keep the clock and the counters, and start
    the polynomial afresh, as REBOUND resets IAS15 when particles are removed."""
    new.clock[:] = old.clock
    new.clock[CLOCK_DT_LAST_DONE] = 0.0
    new.counts[:] = old.counts


def clock_time(work: tuple[Any, ...], fallback: float) -> float:
    """The time of the state (the clock, once started; else ``fallback``)."""
    clock = work.clock
    return float(clock[CLOCK_T]) if clock[CLOCK_STARTED] else fallback


def counters(work: tuple[Any, ...]) -> dict[str, int | float]:
    """Accepted and rejected steps, force evaluations, unconverged steps, and the next trial step."""
    counts, clock = work.counts, work.clock
    return {"steps_accepted": int(counts[COUNT_ACCEPTED]), "steps_rejected": int(counts[COUNT_REJECTED]),
            "force_evaluations": int(counts[COUNT_FORCE_EVALS]),
            "steps_unconverged": int(counts[COUNT_UNCONVERGED]), "dt_next": float(clock[CLOCK_DT])}


def failure_message(work: tuple[Any, ...]) -> str | None:
    """Why the run stopped, when IAS15 knows."""
    status, clock = int(work.counts[COUNT_STATUS]), work.clock
    if status == STATUS_STEP_UNDERFLOW:
        return (f"IAS15's step fell to {clock[CLOCK_DT]:.3g} at t = {clock[CLOCK_T]:.17g}, too small to move the "
                "clock (a collision or a singular encounter); give the bodies radii and an events: collisions "
                "section, soften the force, or set min_dt")
    if status == STATUS_NON_FINITE:
        return f"IAS15's state became non-finite at t = {clock[CLOCK_T]:.17g}"
    return None


@jit_inline
def _take_step(pos, vel, acc, m, force, work):
    """One accepted step (rejected tries retried, as REBOUND's ``reb_integrator_ias15_step``).
    Returns False, with the status in ``work``, when the clock cannot move or the state is lost.

    Inlined, as are :func:`_watched_step` and :func:`integrate_to`: Numba links a callee's machine
    code into each caller and LLVM optimises and compiles the whole again, so every call layer above
    :func:`~orbitsim.integrators.ias15.core.step_try` compiled the step (with a run's forces) once
    more, ~1 CPU-s each in a first run. Three layers fewer: run, advance_grid and step_try remain."""
    clock, counts = work.clock, work.counts
    while True:
        dt = clock[CLOCK_DT]
        t = clock[CLOCK_T]
        if not (t + dt != t and np.isfinite(dt)):
            counts[COUNT_STATUS] = STATUS_STEP_UNDERFLOW
            return False
        if step_try(pos, vel, acc, m, force, work):
            break
    if not is_finite_state(pos, vel):
        counts[COUNT_STATUS] = STATUS_NON_FINITE
        return False
    return True


#: What :func:`integrate_to` ended with: the target reached, a failure (status in ``work``), or an
#: event the Python side must act on before the next step (a run with ``events:``).
REACHED, FAILED, ACT = 0, 1, 2


@jit_inline
def _watched_step(pos, vel, acc, m, force, work, watch):
    """:func:`_take_step`, then the events check on the step IAS15 took. The check's step number
    is IAS15's own (accepted steps), and its clock is set so that step n ends at the state's time."""
    if watch is None:
        return REACHED if _take_step(pos, vel, acc, m, force, work) else FAILED
    remember_start(watch, pos, vel)
    if not _take_step(pos, vel, acc, m, force, work):
        return FAILED
    clock, counts = work.clock, work.counts
    dt_done = clock[CLOCK_DT_LAST_DONE]
    n = counts[COUNT_ACCEPTED]
    if after_step(watch, pos, vel, m, n, clock[CLOCK_T] - n * dt_done, dt_done, None):
        return ACT
    return REACHED


@jit_inline
def integrate_to(pos, vel, acc, m, force, work, t_target, watch):
    """Adaptive steps up to ``t_target`` exactly (REBOUND's ``exact_finish_time = 1`` loop of one
    ``integrate`` call: the step that would overshoot is shortened to end on the target, and the
    last full step is restored afterwards). Returns :data:`REACHED`, :data:`FAILED` (the status is
    in ``work``) or, with an events ``watch``, :data:`ACT`."""
    clock = work.clock
    sign = 1.0 if t_target >= clock[CLOCK_T] else -1.0
    clock[CLOCK_DT] = np.copysign(clock[CLOCK_DT], sign)
    last_full_dt = clock[CLOCK_DT]
    clock[CLOCK_DT_LAST_DONE] = 0.0
    last_step = False
    tscale = 1e-12 * abs(t_target)
    if tscale < 1e-200:
        tscale = 1e-12
    result = REACHED
    while True:
        if stop_requested():  # a stop (orbitsim.stopping): the caller undoes the call, whatever it returns;
            break  # without this the steps left in the interval would go on, on forces cut short
        t, dt = clock[CLOCK_T], clock[CLOCK_DT]
        if (t + dt) * sign >= t_target * sign:
            if t == t_target:
                break
            if last_step:
                if abs(t - t_target) < tscale:
                    break
                clock[CLOCK_DT] = t_target - t
            else:
                last_step = True
                if clock[CLOCK_DT_LAST_DONE] != 0.0:
                    last_full_dt = clock[CLOCK_DT_LAST_DONE]
                clock[CLOCK_DT] = t_target - t
        elif last_step:
            last_step = False  # a rejected try shrank what was meant to be the last step
        result = _watched_step(pos, vel, acc, m, force, work, watch)
        if result != REACHED:
            if result == ACT:
                return result  # mid-interval: the next call goes on from the clock's time
            break
    clock[CLOCK_DT] = last_full_dt
    return result


@jit
def advance_grid(pos, vel, acc, m, force, work, t0, dt, n_from, n_to, watch):
    """From grid point ``n_from`` to ``n_to``: adaptive steps landing on each grid time, or one
    constant step per grid point without adaptivity. Returns the grid points reached and how it
    ended (:data:`REACHED`, :data:`FAILED`, :data:`ACT`)."""
    start_clock(work, grid_target(work, t0, dt, n_from), dt)
    adaptive = work.adaptive
    clock = work.clock
    for n in range(n_from + 1, n_to + 1):
        if adaptive:
            result = integrate_to(pos, vel, acc, m, force, work, grid_target(work, t0, dt, n), watch)
        else:
            clock[CLOCK_DT] = dt
            result = _watched_step(pos, vel, acc, m, force, work, watch)
            clock[CLOCK_T] = t0 + n * dt  # whole steps: the grid time, not a running sum
            if result == ACT:
                return n, ACT  # the step is whole: its grid point is reached
        if result != REACHED:
            return n - 1, result
    return n_to, REACHED


@jit
def step(pos, vel, acc, m, force, dt, work):
    """Advance by one grid interval ``dt`` (adaptive steps inside it, or one constant step)."""
    clock = work.clock
    t = clock[CLOCK_T] if clock[CLOCK_STARTED] else 0.0
    # Grid points as run-time int64, as run() passes them: literals would compile advance_grid again.
    advance_grid(pos, vel, acc, m, force, work, t, dt, np.int64(0), np.int64(1), None)


@jit_inline
def advance(pos, vel, acc, m, force, dt, work, t0, n_done, n_to):
    """Grid points ``n_done`` to ``n_to`` (:func:`advance_grid` without events); False on a failure."""
    n_done, result = advance_grid(pos, vel, acc, m, force, work, t0, dt, n_done, n_to, None)
    return n_done, result == REACHED


@jit
def run(state, force, dt, work, t0, n_done, targets, record, out):
    """:func:`~orbitsim.integrators.base.sample_loop` of :func:`advance` (``dt`` is the output
    grid): each sample is recorded at the exact time IAS15's clock reached. A forced run's ``acc``
    is evaluated afresh first (:func:`~orbitsim.forces.hooks.refresh_accelerations`)."""
    pos, vel, acc, m = state
    refresh_accelerations(force, pos, vel, m, acc, True)
    return sample_loop(advance, sample_time, state, force, dt, work, t0, n_done, targets, record, out)


@jit
def run_watched(state, force, dt, work, t0, n_done, targets, record, out, watch):
    """:func:`run` with the events check after every step IAS15 takes (:mod:`orbitsim.events`);
    a fourth result, True when the call stopped for the Python side, possibly mid-interval. The
    steps between grid points are IAS15's own, so it watches them inside :func:`advance_grid`
    rather than through the fixed-step watched loop."""
    pos, vel, acc, m = state
    written = np.int64(0)  # not the literal 0: record_sample would compile twice (for Literal[int](0) and int64)
    for k in range(targets.shape[0]):
        if n_done < targets[k]:
            n_done, result = advance_grid(pos, vel, acc, m, force, work, t0, dt, n_done, targets[k], watch)
            if result != REACHED:
                return written, n_done, result != FAILED, result == ACT
        if record[k]:
            if not record_sample(written, n_done, sample_time(work, t0, n_done, dt), pos, vel, m, force, out):
                return written, n_done, False, False
            written += 1
    return written, n_done, True, False


IAS15 = Integrator(
    spec=SPEC,
    step=step,
    run=run,
    run_watched=run_watched,
    settings=SETTINGS,
    validate_settings=validate_settings,
    make_work=make_work,
    carry_over=carry_over,
    clock_time=clock_time,
    failure_message=failure_message,
    counters=counters,
    run_constants=RUN_CONSTANTS,
    run_chaos=run_chaos,
    check_chaos=check_chaos,
    make_tangent=make_chaos_tangent,
)
