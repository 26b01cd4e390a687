"""IAS15 with first-order variational equations and MEGNO, as REBOUND integrates them.

A tangent vector delta = (dr, dv) obeys d(dr)/dt = dv, d(dv)/dt = J(r) dr, with J the Jacobian of
the accelerations (:func:`~orbitsim.physics.tangent.tangent_accelerations`). REBOUND's IAS15
(``src/integrator_ias15.c``) integrates it as extra particles inside the same Gauss-Radau
predictor-corrector: the tangent components get their own polynomial (b, e, g and their
compensations), predicted at the same nodes and corrected by the same divided differences, with
J(r_node) dr_node as their "acceleration". :func:`step_try_tangent` does the same, component for
component, and these are the parts of REBOUND's behaviour it keeps, on purpose:

* **Convergence test.** The predictor-corrector stops when max |change of b_6| / max |a| over
  *every* component, tangent ones included, falls below 1e-16 or stops shrinking (REBOUND's
  default ``adaptive_mode`` PRS23 takes both maxima over all 3 (N + N_var) components). So the
  tangent vector can change the number of corrector passes, and with it the bodies' trajectory at
  round-off level: REBOUND's own run with ``init_megno`` differs from the same run without it by
  ~1e-11 over 1e4 time units (and its chaotic case takes 7% more steps), and so does this one.
* **Step control.** The next step comes from the PRS23 timescales of the *bodies* only: the tangent
  components never choose or reject a step.
* **MEGNO.** At the start of a step and at each of the seven nodes, the tangent positions and
  velocities are predicted (REBOUND's Horner forms), J(r_n) dr_n is evaluated, and the step's
  integral of 2 s (delta'.delta)/(delta.delta) ds is the Radau quadrature
  dt * sum_n w_n (t_n - t_0) deltad_delta_n (weights on an interval of length 2, so the factor 2
  is in them), from the last corrector pass; an accepted step then calls
  :func:`~orbitsim.chaos.megno.megno_update` (REBOUND's ``reb_tools_megno_update``) with it.

Everything the tangent part carries from step to step is one :class:`IAS15Tangent` record (the
tangent state, its polynomial, the MEGNO sums and the count of power-of-two rescalings), beside the
bodies' :class:`~orbitsim.integrators.ias15.core.IAS15Work`, so a checkpoint of both resumes bit
for bit. The plain step (:func:`~orbitsim.integrators.ias15.core.step_try`) and its loops are not
touched: a run without the tangent state compiles and runs exactly the code it ran before, which is
why the exact-finish loop (:func:`integrate_to_tangent`) is written here a second time rather than
threaded through the plain one.

Rescaling: REBOUND divides its variational particles by their largest component once it passes
1e100 (``reb_simulation_rescale_var``), without rescaling IAS15's polynomial. Here, after each
accepted step, a tangent state with |delta|^2 > 2^400 is scaled by 2^-200 together with every
array linear in it (its polynomial, predictions, compensations, accelerations): exact, so the ratio
MEGNO reads keeps its bits (:func:`~orbitsim.chaos.megno.rescale_power_of_two`). Only a chaotic
orbit gets there (|delta| > 1e60), long after round-off has decorrelated any two codes.

Forces: the bodies feel them as in the plain step, the tangent gets the position forces' derivatives
(:func:`orbitsim.forces.tangent.add_tangent_kick_forces`, which refuses unbuilt ones when typed); the
front door (:func:`orbitsim.integrators.registry.chaos_refusal`) refuses them in one line first.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from orbitsim._jit import jit, jit_inline, stop_requested
from orbitsim.chaos.megno import (
    RESCALE_ABOVE,
    MegnoState,
    deltad_delta,
    lyapunov,
    megno_start,
    megno_update,
    megno_value,
)
from orbitsim.forces.hooks import add_forces, add_node_forces
from orbitsim.forces.tangent import add_tangent_kick_forces
from orbitsim.integrators.base import is_finite_state
from orbitsim.integrators.ias15.core import (
    CLOCK_DT,
    CLOCK_DT_LAST_DONE,
    CLOCK_T,
    COUNT_ACCEPTED,
    COUNT_FORCE_EVALS,
    COUNT_REJECTED,
    COUNT_STATUS,
    COUNT_UNCONVERGED,
    MAX_ITERATIONS,
    SAFETY_FACTOR,
    STATUS_NON_FINITE,
    STATUS_STEP_UNDERFLOW,
    _copy3,
    _copy7,
    _correct,
    _end_of_step,
    _g_from_b,
    _predict_positions,
    _prs23_dt,
    predict_next,
)
from orbitsim.integrators.ias15.tables import H, W
from orbitsim.physics.force_context import newtonian_accelerations
from orbitsim.physics.tangent import ALL_PAIRS, tangent_accelerations

__all__ = ["TANGENT_FIELDS", "IAS15Tangent", "advance_grid_tangent", "integrate_to_tangent", "make_tangent",
           "megno_state", "refresh_tangent", "step_try_tangent"]


class IAS15Tangent(NamedTuple):
    """The tangent state of an IAS15 run and everything its step carries (:func:`make_tangent`)."""

    dpos: np.ndarray  #: (3, N) dr
    dvel: np.ndarray  #: (3, N) dv
    dacc: np.ndarray  #: (3, N) J(r) dr at the current positions
    b: np.ndarray  #: (7, 3N) the tangent polynomial, as IAS15Work's fields of the same names
    e: np.ndarray
    g: np.ndarray
    csb: np.ndarray
    br: np.ndarray
    er: np.ndarray
    x0: np.ndarray  #: (3N,)
    v0: np.ndarray
    a0: np.ndarray
    at: np.ndarray  #: (3, N)
    csx: np.ndarray  #: (3N,)
    csv: np.ndarray
    megno: np.ndarray  #: (8,) the MEGNO sums in :class:`~orbitsim.chaos.megno.MegnoState` order (n as a float)
    halvings: np.ndarray  #: int64 (1,) power-of-two rescalings by 2^-200 so far (as in base.Tangent)


#: The names of the tangent record's fields, in order (a checkpoint saves them in this order).
TANGENT_FIELDS = IAS15Tangent._fields


def make_tangent(dpos: np.ndarray, dvel: np.ndarray, t0: float = 0.0, halvings: int = 0) -> IAS15Tangent:
    """A tangent record starting from (``dpos``, ``dvel``), each (3, N), with MEGNO started at ``t0``
    and ``halvings`` rescalings counted. ``dacc`` is zero until :func:`refresh_tangent` evaluates it."""
    dpos = np.ascontiguousarray(dpos, dtype=np.float64).copy()
    dvel = np.ascontiguousarray(dvel, dtype=np.float64).copy()
    if dpos.shape != dvel.shape or dpos.ndim != 2 or dpos.shape[0] != 3:
        raise ValueError(f"a tangent state is two (3, N) arrays, got {dpos.shape} and {dvel.shape}")
    n3 = dpos.size
    return IAS15Tangent(
        dpos, dvel, np.zeros_like(dpos),
        *(np.zeros((7, n3)) for _ in range(6)),
        *(np.zeros(n3) for _ in range(3)),
        np.zeros_like(dpos),
        np.zeros(n3), np.zeros(n3),
        np.array(megno_start(t0), dtype=np.float64),
        np.array([halvings], dtype=np.int64),
    )


def megno_state(tangent: IAS15Tangent) -> MegnoState:
    """The MEGNO sums of ``tangent`` as a :class:`~orbitsim.chaos.megno.MegnoState`."""
    s = tangent.megno
    return MegnoState(*(float(x) for x in s[:7]), int(s[7]))


@jit_inline
def _read_megno(s):
    return MegnoState(s[0], s[1], s[2], s[3], s[4], s[5], s[6], np.int64(s[7]))


@jit_inline
def _write_megno(s, state):
    s[0], s[1], s[2], s[3] = state.ys, state.yss, state.cov_yt, state.var_t
    s[4], s[5], s[6], s[7] = state.mean_t, state.mean_y, state.initial_t, float(state.n)


@jit
def refresh_tangent(pos, m, force, tan):
    """dacc = J(pos) dpos (before the first step, or after the tangent state was set from outside)."""
    tangent_accelerations(pos, m, force.G, force.eps2, tan.dpos, tan.dacc, np.int64(ALL_PAIRS))
    add_tangent_kick_forces(force, pos, m, tan.dpos, tan.dacc)  # nothing without forces


@jit
def _predict_velocities(vel, v0, a0, b, csv, dt, hn):
    """Velocities at the node h_n from the current b's (REBOUND's Horner form, its operation order)."""
    for k in range(vel.shape[0]):
        vk = -csv[k] + (((((((b[6, k] * 7.0 * hn / 8.0 + b[5, k]) * 6.0 * hn / 7.0 + b[4, k])
                            * 5.0 * hn / 6.0 + b[3, k]) * 4.0 * hn / 5.0 + b[2, k]) * 3.0 * hn / 4.0
                          + b[1, k]) * 2.0 * hn / 3.0 + b[0, k]) * hn / 2.0 + a0[k]) * dt * hn
        vel[k] = vk + v0[k]


@jit
def step_try_tangent(pos, vel, acc, m, force, work, tan, initial_t):
    """:func:`~orbitsim.integrators.ias15.core.step_try` with the tangent state ``tan`` integrated
    as extra components (``tan.dacc`` = J(pos) dpos on entry, as ``acc`` = a(pos)).

    Returns (taken, dY): taken as ``step_try``'s result (on a rejection both states are as on
    entry); dY the step's increment of t Y(t) for MEGNO started at ``initial_t`` (0 when rejected).
    """
    b, e, g, csb, br, er = work.b, work.e, work.g, work.csb, work.br, work.er
    x0, v0, a0, at, csx, csv = work.x0, work.v0, work.a0, work.at, work.csx, work.csv
    tb, te, tg, tcsb, tbr, ter = tan.b, tan.e, tan.g, tan.csb, tan.br, tan.er
    tx0, tv0, ta0, tat, tcsx, tcsv = tan.x0, tan.v0, tan.a0, tan.at, tan.csx, tan.csv
    dpos, dvel, dacc = tan.dpos, tan.dvel, tan.dacc
    clock, counts = work.clock, work.counts
    epsilon, min_dt, adaptive = work.epsilon, work.min_dt, work.adaptive
    dt = clock[CLOCK_DT]
    t_beginning = clock[CLOCK_T]
    n3 = pos.size
    pf = pos.reshape(n3)
    vf = vel.reshape(n3)
    af = acc.reshape(n3)
    atf = at.reshape(n3)
    dpf = dpos.reshape(n3)
    dvf = dvel.reshape(n3)
    daf = dacc.reshape(n3)
    tatf = tat.reshape(n3)
    _copy3(x0, pf)
    _copy3(v0, vf)
    _copy3(a0, af)
    _copy3(tx0, dpf)
    _copy3(tv0, dvf)
    _copy3(ta0, daf)
    for s in range(7):
        for k in range(n3):
            csb[s, k] = 0.0
            tcsb[s, k] = 0.0
    _g_from_b(b, g)
    _g_from_b(tb, tg)
    G, eps2 = force.G, force.eps2
    megno_init = W[0] * (t_beginning - initial_t) * deltad_delta(dpos, dvel, dacc)
    megno_sum = megno_init
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
        megno_sum = megno_init  # each pass sums afresh: the last pass's nodes are the step's quadrature
        for n in range(1, 8):
            hn = H[n]
            t_node = t_beginning + dt * hn
            _predict_positions(pf, x0, v0, a0, b, csx, dt, hn)
            _predict_positions(dpf, tx0, tv0, ta0, tb, tcsx, dt, hn)
            _predict_velocities(dvf, tv0, ta0, tb, tcsv, dt, hn)
            newtonian_accelerations(force, pos, m, at)
            add_node_forces(force, pos, m, at, b, csv, v0, a0, dt, hn)  # nothing without forces
            tangent_accelerations(pos, m, G, eps2, dpos, tat, np.int64(ALL_PAIRS))
            add_tangent_kick_forces(force, pos, m, dpos, tat)
            megno_sum += W[n] * (t_node - initial_t) * deltad_delta(dpos, dvel, tat)
            # pf and dpf are the corrector's scratch, as in step_try: every path out rewrites them.
            max_b6, max_a = _correct(n, atf, a0, g, b, csb, pf)
            tmax_b6, tmax_a = _correct(n, tatf, ta0, tg, tb, tcsb, dpf)
            if n == 7:
                # REBOUND's PRS23 convergence test: both maxima over every component, tangent ones too.
                error = max(max_b6, tmax_b6) / max(max_a, tmax_a)
        counts[COUNT_FORCE_EVALS] += 7
    dt_done = dt
    if adaptive:
        dt_new = _prs23_dt(a0, b, epsilon, dt_done, SAFETY_FACTOR)  # the bodies' timescales only
        if abs(dt_new) < min_dt:
            dt_new = np.copysign(min_dt, dt_new)
        if abs(dt_new / dt_done) < SAFETY_FACTOR:
            _copy3(pf, x0)
            _copy3(af, a0)
            _copy3(dpf, tx0)
            _copy3(dvf, tv0)
            _copy3(daf, ta0)
            clock[CLOCK_DT] = dt_new
            if clock[CLOCK_DT_LAST_DONE] != 0.0:
                ratio = dt_new / clock[CLOCK_DT_LAST_DONE]
                predict_next(ratio, er, br, e, b)
                predict_next(ratio, ter, tbr, te, tb)
            counts[COUNT_REJECTED] += 1
            return False, 0.0
        if abs(dt_new / dt_done) > 1.0 and dt_new / dt_done > 1.0 / SAFETY_FACTOR:
            dt_new = dt_done / SAFETY_FACTOR
        clock[CLOCK_DT] = dt_new
    _end_of_step(x0, v0, a0, b, csx, csv, dt_done)
    _end_of_step(tx0, tv0, ta0, tb, tcsx, tcsv, dt_done)
    clock[CLOCK_T] += dt_done
    clock[CLOCK_DT_LAST_DONE] = dt_done
    _copy3(pf, x0)
    _copy3(vf, v0)
    _copy3(dpf, tx0)
    _copy3(dvf, tv0)
    _copy7(er, e)
    _copy7(br, b)
    _copy7(ter, te)
    _copy7(tbr, tb)
    ratio = clock[CLOCK_DT] / dt_done
    predict_next(ratio, e, b, e, b)
    predict_next(ratio, te, tb, te, tb)
    newtonian_accelerations(force, pos, m, acc)
    add_forces(force, pos, vel, m, acc)
    tangent_accelerations(pos, m, G, eps2, dpos, dacc, np.int64(ALL_PAIRS))
    add_tangent_kick_forces(force, pos, m, dpos, dacc)
    counts[COUNT_FORCE_EVALS] += 1
    counts[COUNT_ACCEPTED] += 1
    return True, dt_done * megno_sum


@jit
def _rescale_tangent(tan):
    """Scale the tangent state and every array linear in it by 2^-200 while |delta|^2 > 2^400."""
    dpos, dvel = tan.dpos, tan.dvel
    while True:
        norm2 = 0.0
        for c in range(3):
            for i in range(dpos.shape[1]):
                norm2 += dpos[c, i] * dpos[c, i] + dvel[c, i] * dvel[c, i]
        if not norm2 > RESCALE_ABOVE:
            return
        f = 2.0 ** -200
        for arr in (tan.dpos, tan.dvel, tan.dacc, tan.at):
            for c in range(3):
                for i in range(arr.shape[1]):
                    arr[c, i] *= f
        for arr in (tan.x0, tan.v0, tan.a0, tan.csx, tan.csv):
            for k in range(arr.shape[0]):
                arr[k] *= f
        for arr in (tan.b, tan.e, tan.g, tan.csb, tan.br, tan.er):
            for s in range(7):
                for k in range(arr.shape[1]):
                    arr[s, k] *= f
        tan.halvings[0] += 1


@jit
def _take_step_tangent(pos, vel, acc, m, force, work, tan):
    """One accepted step with the tangent state, then MEGNO's update and the rescaling check.
    Returns False, with the status in ``work``, as the plain ``_take_step``."""
    clock, counts = work.clock, work.counts
    sums = tan.megno
    while True:
        dt = clock[CLOCK_DT]
        t = clock[CLOCK_T]
        if not (t + dt != t and np.isfinite(dt)):
            counts[COUNT_STATUS] = STATUS_STEP_UNDERFLOW
            return False
        taken, dY = step_try_tangent(pos, vel, acc, m, force, work, tan, sums[6])
        if taken:
            break
    _write_megno(sums, megno_update(_read_megno(sums), clock[CLOCK_T], dY, clock[CLOCK_DT_LAST_DONE]))
    if not (is_finite_state(pos, vel) and is_finite_state(tan.dpos, tan.dvel)):
        counts[COUNT_STATUS] = STATUS_NON_FINITE
        return False
    _rescale_tangent(tan)
    return True


REACHED, FAILED = 0, 1  #: what :func:`integrate_to_tangent` ended with (the plain loop's codes)


@jit
def integrate_to_tangent(pos, vel, acc, m, force, work, tan, t_target):
    """Adaptive steps with the tangent state up to ``t_target`` exactly: the plain
    :func:`~orbitsim.integrators.ias15.integrate_to` (REBOUND's ``exact_finish_time = 1``) line for
    line, with :func:`_take_step_tangent` for its step. Returns :data:`REACHED` or :data:`FAILED`."""
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
        if stop_requested():
            break
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
            last_step = False
        if not _take_step_tangent(pos, vel, acc, m, force, work, tan):
            result = FAILED
            break
    clock[CLOCK_DT] = last_full_dt
    return result


@jit
def advance_grid_tangent(pos, vel, acc, m, force, work, tan, times):
    """Integrate to each of ``times`` in turn, writing after each the MEGNO <Y> and the mLCE
    (REBOUND's ``megno()`` and ``lyapunov()``) into ``out`` (len(times), 2).

    A kernel-level loop (no trace): the work's clock must be started. Returns the samples reached.
    """
    refresh_tangent(pos, m, force, tan)
    out = np.empty((times.shape[0], 2))
    for k in range(times.shape[0]):
        if integrate_to_tangent(pos, vel, acc, m, force, work, tan, times[k]) != REACHED:
            return k, out
        state = _read_megno(tan.megno)
        out[k, 0] = megno_value(state, work.clock[CLOCK_T])
        out[k, 1] = lyapunov(state)
    return times.shape[0], out
