"""TRACE's FULL_IAS15 pericentre step: the whole outer step by a fresh IAS15 (jitted, inertial frame).

Reuses :mod:`orbitsim.integrators.ias15.core`'s Gauss-Radau arithmetic; ``step_try`` itself is not
reused because its force sum (vectorised, reassociated) differs from REBOUND's basic gravity in the
last bits, which TRACE's bit-for-bit agreement with REBOUND forbids.

When TRACE flags a pericentre passage and ``peri_mode`` is FULL_IAS15 (REBOUND's mode 2), REBOUND
5.2.2 drops the Wisdom-Holman split for that step and integrates the plain Newtonian N-body
problem from t to t + dt with an IAS15 created for the step (``integrator_trace.c``,
``reb_integrator_trace_step_try``, lines 1030-1052 and 1105-1107). :func:`full_ias15_step` does
the same, in REBOUND's order of floating-point operations, so the two agree bit for bit:

* a fresh IAS15 (integrator_ias15.c:127-133, 244-275): epsilon 1e-9, min_dt 0, PRS23, every
  array zero: no polynomial, prediction or compensation term carried in from an earlier step;
* the first trial step is the outer dt; rejected tries are retried within one IAS15 step (874-883);
* after each step the next one is cut so as not to pass t + dt, and the loop runs while
  ``t < t + dt`` and ``|dt_next / dt| > 1e-14`` (integrator_trace.c:1042-1048). This is not the
  exact-finish loop of ``integrate`` (simulation.c:318-341): the cut comes after the step, and
  nothing restores the last full step;
* REBOUND's basic gravity (integrator_trace.c:1035; gravity.c:167-282): :func:`basic_accelerations`.

The Gauss-Radau arithmetic is :mod:`~orbitsim.integrators.ias15.core`'s, which follows ``integrator_ias15.c``
operation by operation. Only the force differs: orbitsim's IAS15 sums forces vectorised and
reassociated (equal to REBOUND's to round-off only), so :func:`_try_step` is ``ias15.core.step_try``
with :func:`basic_accelerations` swapped in. Keep the two in step.

One piece of simulation state reaches into the fresh IAS15: after a rejected try it predicts the
retry's polynomial only if REBOUND's ``r->dt_last_done != 0`` (integrator_ias15.c:740); from a
fresh state that prediction gives zeros, while skipping it keeps the rejected try's polynomial.
The retries differ in their last bits, so the caller passes REBOUND's value.
"""

from __future__ import annotations

import math

import numpy as np

from orbitsim._jit import jit
from orbitsim.integrators.base import is_finite_state
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
    MAX_ITERATIONS,
    SAFETY_FACTOR,
    STATUS_NON_FINITE,
    STATUS_OK,
    STATUS_STEP_UNDERFLOW,
    IAS15Work,
    _copy3,
    _copy7,
    _correct,
    _end_of_step,
    _g_from_b,
    _predict_positions,
    _prs23_dt,
    predict_next,
)
from orbitsim.integrators.ias15.tables import H

__all__ = ["FULL_IAS15_SETTINGS", "STATUS_NON_FINITE", "STATUS_OK", "STATUS_STEP_UNDERFLOW", "basic_accelerations",
           "full_ias15_step", "make_full_ias15_work", "new_full_ias15_work"]

#: REBOUND's ``reb_integrator_ias15_create`` (integrator_ias15.c:129-131); TRACE cannot change them.
FULL_IAS15_EPSILON, FULL_IAS15_MIN_DT = 1e-9, 0.0
FULL_IAS15_SETTINGS = {"epsilon": FULL_IAS15_EPSILON, "min_dt": FULL_IAS15_MIN_DT, "adaptive": True}
#: The loop stops once the next step falls to this fraction of the outer dt (REBOUND's guard
#: against a stalled clock, integrator_trace.c:1042). Here that ends the step with a failure.
MIN_STEP_FRACTION = 1e-14


def make_full_ias15_work(n_bodies: int) -> IAS15Work:
    """The IAS15 ``work`` (:data:`~orbitsim.integrators.ias15.core.WORK_FIELDS`) with :data:`FULL_IAS15_SETTINGS`:
    what :func:`new_full_ias15_work` makes inside a step, from Python (with the check of N)."""
    n = int(n_bodies)
    if n < 2:
        raise ValueError(f"a FULL_IAS15 step needs at least two bodies, got {n}")
    return new_full_ias15_work(n)


@jit
def new_full_ias15_work(n):
    """A fresh IAS15 ``work`` for ``n`` bodies: :func:`orbitsim.integrators.ias15.make_work`'s
    layout (a test holds them equal) with :data:`FULL_IAS15_SETTINGS`.

    Made by each pericentre step rather than kept in TRACE's ``work``: every :func:`full_ias15_step`
    starts a new integrator anyway, and 14 more arrays passed through every TRACE step cost their
    reference counts on every step, ~5% of a step on REBOUND's many-encounters set-up (measured),
    while these allocations come once per pericentre step, beside a whole IAS15 integration.
    """
    m = 3 * n
    return IAS15Work(np.zeros((7, m)), np.zeros((7, m)), np.zeros((7, m)), np.zeros((7, m)), np.zeros((7, m)),
                     np.zeros((7, m)), np.zeros(m), np.zeros(m), np.zeros(m), np.zeros((3, n)), np.zeros(m),
                     np.zeros(m), np.zeros(4), np.zeros(5, dtype=np.int64), FULL_IAS15_EPSILON, FULL_IAS15_MIN_DT,
                     True, np.inf, 0.0)


@jit
def basic_accelerations(pos, m, G, softening2, n_active, acc):
    """REBOUND's basic gravity at inertial ``pos`` (3, N) into ``acc`` (3, N), in its operation order.

    Pairs i = 1..n_active-1, j < i, both bodies updated as the pair is visited; then bodies
    n_active..N-1 (test particles, ``testparticle_type = 0``) feel bodies 0..n_active-1 and pull
    on nothing. ``dx = (0 + x_i) - x_j`` keeps REBOUND's ghost-box offset (it turns -0.0 into +0.0).
    """
    n = pos.shape[1]
    for c in range(3):
        for i in range(n):
            acc[c, i] = 0.0
    for i in range(1, n):
        for j in range(i if i < n_active else n_active):
            dx = (0.0 + pos[0, i]) - pos[0, j]
            dy = (0.0 + pos[1, i]) - pos[1, j]
            dz = (0.0 + pos[2, i]) - pos[2, j]
            r = math.sqrt(dx * dx + dy * dy + dz * dz + softening2)
            prefact = G / (r * r * r)
            prefact_j = -prefact * m[j]
            acc[0, i] += prefact_j * dx
            acc[1, i] += prefact_j * dy
            acc[2, i] += prefact_j * dz
            if i < n_active:
                prefact_i = prefact * m[i]
                acc[0, j] += prefact_i * dx
                acc[1, j] += prefact_i * dy
                acc[2, j] += prefact_i * dz


@jit
def _reset_ias15(work, t, dt, dt_last_done):
    """``work`` as a new IAS15 at t with trial step dt (what every try rewrites before reading,
    g, csb, x0, v0, a0 and at, is left)."""
    work.b[:] = 0.0
    work.e[:] = 0.0
    work.br[:] = 0.0
    work.er[:] = 0.0
    work.csx[:] = 0.0
    work.csv[:] = 0.0
    clock, counts = work.clock, work.counts
    clock[CLOCK_T] = t
    clock[CLOCK_DT] = dt
    clock[CLOCK_DT_LAST_DONE] = dt_last_done
    clock[CLOCK_STARTED] = 1.0
    counts[:] = 0


@jit
def _converge(pos, m, G, softening2, n_active, work, dt):
    """The predictor-corrector passes of one try (``ias15.core.step_try``; integrator_ias15.c:386-606)."""
    b, g, csb = work.b, work.g, work.csb
    x0, v0, a0, at, csx = work.x0, work.v0, work.a0, work.at, work.csx
    counts = work.counts
    n3 = pos.size
    pf = pos.reshape(n3)
    atf = at.reshape(n3)
    error = 1e300
    error_last = 2.0
    iterations = 0
    while True:
        if error < 1e-16:
            break
        if iterations > 2 and error_last <= error:
            break  # the corrections stopped shrinking: round-off level
        if iterations >= MAX_ITERATIONS:
            counts[COUNT_UNCONVERGED] += 1
            break
        error_last = error
        iterations += 1
        for n in range(1, 8):
            _predict_positions(pf, x0, v0, a0, b, csx, dt, H[n])
            basic_accelerations(pos, m, G, softening2, n_active, at)
            max_b6, max_a = _correct(n, atf, a0, g, b, csb, pf)  # pf: scratch, rewritten from x0 below
            if n == 7:
                error = max_b6 / max_a
        counts[COUNT_FORCE_EVALS] += 7


@jit
def _try_step(pos, vel, acc, m, G, softening2, n_active, work):
    """Try one step of the clock's dt (``ias15.core.step_try`` with :func:`basic_accelerations`).

    True: taken; pos, vel, the clock and ``acc`` = a(pos) advance. False: rejected; the state is
    as on entry and the clock holds the smaller step to retry (integrator_ias15.c:707-811)."""
    b, e, g, csb, br, er = work.b, work.e, work.g, work.csb, work.br, work.er
    x0, v0, a0, csx, csv = work.x0, work.v0, work.a0, work.csx, work.csv
    clock, counts = work.clock, work.counts
    n3 = pos.size
    pf = pos.reshape(n3)
    vf = vel.reshape(n3)
    af = acc.reshape(n3)
    _copy3(x0, pf)
    _copy3(v0, vf)
    _copy3(a0, af)
    for s in range(7):
        for k in range(n3):
            csb[s, k] = 0.0
    _g_from_b(b, g)
    dt_done = clock[CLOCK_DT]
    _converge(pos, m, G, softening2, n_active, work, dt_done)
    dt_new = _prs23_dt(a0, b, work.epsilon, dt_done, SAFETY_FACTOR)
    if abs(dt_new) < work.min_dt:
        dt_new = np.copysign(work.min_dt, dt_new)
    if abs(dt_new / dt_done) < SAFETY_FACTOR:
        _copy3(pf, x0)
        _copy3(af, a0)
        clock[CLOCK_DT] = dt_new
        if clock[CLOCK_DT_LAST_DONE] != 0.0:
            predict_next(dt_new / clock[CLOCK_DT_LAST_DONE], er, br, e, b)
        counts[COUNT_REJECTED] += 1
        return False
    if abs(dt_new / dt_done) > 1.0 and dt_new / dt_done > 1.0 / SAFETY_FACTOR:
        dt_new = dt_done / SAFETY_FACTOR
    clock[CLOCK_DT] = dt_new
    _end_of_step(x0, v0, a0, b, csx, csv, dt_done)
    clock[CLOCK_T] += dt_done
    clock[CLOCK_DT_LAST_DONE] = dt_done
    _copy3(pf, x0)
    _copy3(vf, v0)
    _copy7(er, e)
    _copy7(br, b)
    predict_next(clock[CLOCK_DT] / dt_done, e, b, e, b)
    basic_accelerations(pos, m, G, softening2, n_active, acc)
    counts[COUNT_FORCE_EVALS] += 1
    counts[COUNT_ACCEPTED] += 1
    return True


@jit
def full_ias15_step(pos, vel, acc, m, G, softening2, n_active, dt, t, dt_last_done, work):
    """Integrate the inertial Newtonian problem from t to t + dt with a fresh IAS15, in place.

    ``pos``, ``vel``: inertial (3, N) C-contiguous; ``acc`` (3, N): scratch; ``m`` (N,), bodies
    ``n_active..N-1`` test particles (N if none); ``softening2``: softening squared, added inside
    the square root. ``dt > 0`` (for dt <= 0 REBOUND's loop, and this one, take no step).
    ``dt_last_done``: REBOUND's ``r->dt_last_done`` now (module doc): 0 on the first step of an
    ``integrate`` call, else the previous TRACE step's dt; on a redo, what the first try left in
    ``work.clock[CLOCK_DT_LAST_DONE]``. ``work``: :func:`make_full_ias15_work`, reset here.

    Returns ``STATUS_OK``, ``STATUS_STEP_UNDERFLOW`` (the step fell to zero, or below 1e-14 of
    dt short of t + dt, where REBOUND stops silently) or ``STATUS_NON_FINITE`` (pos, vel are then
    non-finite; after an underflow they hold the time reached, ``work.clock[CLOCK_T]``).
    ``work.counts``: this call's accepted and rejected IAS15 steps, force evaluations,
    unconverged steps and the status.
    """
    _reset_ias15(work, t, dt, dt_last_done)
    clock, counts = work.clock, work.counts
    t_needed = t + dt
    basic_accelerations(pos, m, G, softening2, n_active, acc)
    counts[COUNT_FORCE_EVALS] += 1
    while clock[CLOCK_T] < t_needed and abs(clock[CLOCK_DT] / dt) > MIN_STEP_FRACTION:
        while not _try_step(pos, vel, acc, m, G, softening2, n_active, work):
            # Each rejection cuts the step at least 4x, so this ends: at the latest at zero,
            # where REBOUND would take a step of zero and leave its polynomial as nan.
            if not (clock[CLOCK_DT] != 0.0 and np.isfinite(clock[CLOCK_DT])):
                counts[COUNT_STATUS] = STATUS_STEP_UNDERFLOW
                return STATUS_STEP_UNDERFLOW
        if not is_finite_state(pos, vel):
            counts[COUNT_STATUS] = STATUS_NON_FINITE
            return STATUS_NON_FINITE
        if clock[CLOCK_T] + clock[CLOCK_DT] > t_needed:
            clock[CLOCK_DT] = t_needed - clock[CLOCK_T]
        # Collision hook: REBOUND searches all pairs here (inertial frame) after every IAS15 step
        # and sets TRACE's force_accept if it merged any.
    if clock[CLOCK_T] < t_needed:
        counts[COUNT_STATUS] = STATUS_STEP_UNDERFLOW
    return counts[COUNT_STATUS]
