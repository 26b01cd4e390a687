"""The Gauss-Radau step of IAS15: predictor-corrector, error estimate, step control, prediction.

One step of size dt approximates the acceleration over the step by a polynomial in the fraction
h of the step,

    a(h) = a0 + b0 h + b1 h^2 + ... + b6 h^7,

fixed by its values at the seven Gauss-Radau nodes h_1..h_7 (Everhart 1985). The b's are found by
iterating: positions and velocities predicted from the current b's at each node, the force
evaluated there, the divided differences g of the accelerations updated, and the change carried
into the b's. The iteration stops when the last coefficient's change falls below 1e-16 of the
largest acceleration, stops decreasing, or after 12 passes. Positions and velocities at the end
of the step are the integrals of that polynomial, summed with compensated (Kahan) summation, as
are the b's, so round-off grows like sqrt(steps) rather than linearly (Rein & Spiegel 2015).

Step control is the Pham, Rein & Spiegel (2024) criterion, REBOUND's default since January 2024:
each body's timescale tau^2 = 2 y2 / (y3 + sqrt(y2 y4)) from the acceleration, jerk and snap the
polynomial gives at the step's end, and dt_new = tau_min * (5040 epsilon)^(1/7). A step whose
dt_new is below a quarter of its dt is rejected and retried with dt_new; otherwise the next step
may grow by at most 4x. After a step, the next step's b's are predicted by rescaling the
polynomial to the new step (and after a rejection, from the last accepted step).

The order of every floating-point operation follows REBOUND's ``integrator_ias15.c`` where it
decides the bits: the Horner forms of the predictor, the compensated updates, the node-by-node
corrector and the machine-independent seventh root. That is what lets orbitsim and REBOUND choose
the same steps. The state lives in the ``work`` tuple (:data:`WORK_FIELDS`), so a checkpoint holds
all of it and a resumed run continues bit for bit.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from orbitsim._jit import jit, jit_inline
from orbitsim.forces.hooks import add_forces, add_node_forces
from orbitsim.integrators.ias15.tables import RR, C, D, H
from orbitsim.physics.force_context import newtonian_accelerations

#: Largest change of consecutive steps: a step is rejected below 1/4 of the last, grows at most 4x.
SAFETY_FACTOR = 0.25
#: Predictor-corrector passes before a step is taken unconverged.
MAX_ITERATIONS = 12

class IAS15Work(NamedTuple):
    """The ``work`` of an IAS15 run (:func:`orbitsim.integrators.ias15.make_work`)."""

    b: np.ndarray  #: (7, 3N) the polynomial coefficients (a (3, N) array flattened)
    e: np.ndarray  #: (7, 3N) their predictions
    g: np.ndarray  #: (7, 3N) the divided differences
    csb: np.ndarray  #: (7, 3N) b's compensation terms
    br: np.ndarray  #: (7, 3N) the last accepted b
    er: np.ndarray  #: (7, 3N) the last accepted e
    x0: np.ndarray  #: (3N,) the start-of-step positions
    v0: np.ndarray  #: (3N,) velocities
    a0: np.ndarray  #: (3N,) accelerations
    at: np.ndarray  #: (3, N) the node accelerations
    csx: np.ndarray  #: (3N,) the compensation of x
    csv: np.ndarray  #: (3N,) and of v
    clock: np.ndarray  #: (4,) CLOCK_* below
    counts: np.ndarray  #: int64 (5,) COUNT_* below
    epsilon: float  #: the settings, as constants
    min_dt: float
    adaptive: bool
    t_end: float
    first_dt: float


#: The names of the ``work`` fields, in order (a checkpoint saves them in this order).
WORK_FIELDS = IAS15Work._fields

#: clock: the time of the state, the step to try next, the last step taken (0 before the first of
#: an interval, as REBOUND resets it at every ``integrate``), and whether the clock is set.
CLOCK_T, CLOCK_DT, CLOCK_DT_LAST_DONE, CLOCK_STARTED = range(4)
#: counts: accepted and rejected steps, force evaluations, unconverged steps, and the failure code.
COUNT_ACCEPTED, COUNT_REJECTED, COUNT_FORCE_EVALS, COUNT_UNCONVERGED, COUNT_STATUS = range(5)
#: Failure codes in ``counts[COUNT_STATUS]``: the step no longer moves the clock (it fell below the
#: time's resolution, or is not a finite number), or the state became non-finite.
STATUS_OK, STATUS_STEP_UNDERFLOW, STATUS_NON_FINITE = 0, 1, 2


@jit_inline
def add_cs(p, cs, k, inp):
    """p[k] += inp with its compensation term cs[k] (Kahan summation, REBOUND's ``add_cs``)."""
    y = inp - cs[k]
    t = p[k] + y
    cs[k] = (t - p[k]) - y
    p[k] = t


@jit_inline
def add_cs7(p, cs, s, k, inp):
    """:func:`add_cs` on one coefficient p[s, k] of a (7, 3N) array (no view of p[s] made)."""
    y = inp - cs[s, k]
    t = p[s, k] + y
    cs[s, k] = (t - p[s, k]) - y
    p[s, k] = t


@jit_inline
def is_normal(x):
    """C's ``isnormal``: finite, non-zero and not subnormal."""
    ax = abs(x)
    return ax >= 2.2250738585072014e-308 and ax < np.inf


@jit
def seventh_root(a):
    """a^(1/7) by Newton's iteration with decimal rescaling: the same bits on every machine, which
    ``a ** (1 / 7)`` (the platform's pow) does not promise."""
    scale = 1.0
    while a < 1e-7 and is_normal(a):
        scale *= 0.1
        a *= 1e7
    while a > 1e2 and is_normal(a):
        scale *= 10.0
        a *= 1e-7
    x = 1.0
    for _ in range(20):
        x6 = x * x * x * x * x * x
        x += (a / x6 - x) / 7.0
    return x * scale


@jit
def _g_from_b(b, g):
    for k in range(b.shape[1]):
        b0, b1, b2, b3 = b[0, k], b[1, k], b[2, k], b[3, k]
        b4, b5, b6 = b[4, k], b[5, k], b[6, k]
        g[0, k] = b6 * D[15] + b5 * D[10] + b4 * D[6] + b3 * D[3] + b2 * D[1] + b1 * D[0] + b0
        g[1, k] = b6 * D[16] + b5 * D[11] + b4 * D[7] + b3 * D[4] + b2 * D[2] + b1
        g[2, k] = b6 * D[17] + b5 * D[12] + b4 * D[8] + b3 * D[5] + b2
        g[3, k] = b6 * D[18] + b5 * D[13] + b4 * D[9] + b3
        g[4, k] = b6 * D[19] + b5 * D[14] + b4
        g[5, k] = b6 * D[20] + b5
        g[6, k] = b6


@jit
def _predict_positions(pos, x0, v0, a0, b, csx, dt, hn):
    """Positions at the node h_n of the step from the current b's (REBOUND's Horner form).

    The Horner chain is cut into three passes over k, the partial sums held in ``pos`` (stored as
    doubles, so no bit changes): one pass over the whole chain is bound by the latency of its five
    divisions per component, while each shorter pass keeps the divider busy with independent k."""
    n3 = pos.shape[0]
    for k in range(n3):
        pos[k] = (((b[6, k] * 7.0 * hn / 9.0 + b[5, k]) * 3.0 * hn / 4.0 + b[4, k])
                  * 5.0 * hn / 7.0 + b[3, k])
    for k in range(n3):
        pos[k] = (pos[k] * 2.0 * hn / 3.0 + b[2, k]) * 3.0 * hn / 5.0 + b[1, k]
    for k in range(n3):
        xk = -csx[k] + ((((pos[k] * hn / 2.0 + b[0, k]) * hn / 3.0 + a0[k]) * dt * hn / 2.0
                         + v0[k]) * dt * hn)
        pos[k] = xk + x0[k]


@jit
def _correct(n, at, a0, g, b, csb, w):
    """Update g_(n-1) from the accelerations ``at`` at node n and carry its change into the b's.

    ``w`` (3N) is scratch. Each stage of the divided difference runs as its own pass over k, so the
    n dependent divisions of one component overlap with those of the others instead of forming one
    long chain per component; every value is rounded exactly as in the one-pass form.

    Returns (max |change of b_6|, max |a|) over the normal components when n = 7, else zeros."""
    j = n - 1
    r0 = j * (j + 1) // 2
    c0 = j * (j - 1) // 2
    n3 = at.shape[0]
    for k in range(n3):
        # (a_n - a_0) with REBOUND's two compensated additions (the second adds a zero
        # compensation of the start-of-step force, which still folds in the first's error).
        gk = at[k]
        cs = 0.0
        y = -a0[k] - cs
        t = gk + y
        cs = (t - gk) - y
        gk = t
        y = 0.0 - cs
        t = gk + y
        cs = (t - gk) - y
        gk = t
        w[k] = gk / RR[r0]
    for q in range(j):
        rq = RR[r0 + 1 + q]
        for k in range(n3):
            w[k] = (w[k] - g[q, k]) / rq
    for k in range(n3):
        val = w[k]
        w[k] = val - g[j, k]  # from here on w holds the change of g_j
        g[j, k] = val
    for q in range(j):
        cq = C[c0 + q]
        for k in range(n3):
            add_cs7(b, csb, q, k, w[k] * cq)
    for k in range(n3):
        add_cs7(b, csb, j, k, w[k])
    max_b6 = 0.0
    max_a = 0.0
    if n == 7:
        for k in range(n3):
            ak = abs(at[k])
            if is_normal(ak) and ak > max_a:
                max_a = ak
            b6k = abs(w[k])
            if is_normal(b6k) and b6k > max_b6:
                max_b6 = b6k
    return max_b6, max_a


@jit
def _prs23_dt(a0, b, epsilon, dt_done, safety):
    """The next step from the PRS23 timescale of each body (the smallest wins)."""
    min_ts2 = np.inf
    n = a0.shape[0] // 3
    for i in range(n):
        a0i = 0.0
        y2 = 0.0
        y3 = 0.0
        y4 = 0.0
        for c in range(3):
            k = c * n + i  # flat index of component c of body i in a (3, N) array
            b0, b1, b2, b3 = b[0, k], b[1, k], b[2, k], b[3, k]
            b4, b5, b6 = b[4, k], b[5, k], b[6, k]
            a0i += a0[k] * a0[k]
            tmp = a0[k] + b0 + b1 + b2 + b3 + b4 + b5 + b6
            y2 += tmp * tmp
            tmp = b0 + 2.0 * b1 + 3.0 * b2 + 4.0 * b3 + 5.0 * b4 + 6.0 * b5 + 7.0 * b6
            y3 += tmp * tmp
            tmp = 2.0 * b1 + 6.0 * b2 + 12.0 * b3 + 20.0 * b4 + 30.0 * b5 + 42.0 * b6
            y4 += tmp * tmp
        if not is_normal(a0i):
            continue  # no force on this body (or a non-finite one): it sets no timescale
        ts2 = 2.0 * y2 / (y3 + np.sqrt(y4 * y2))
        if is_normal(ts2) and ts2 < min_ts2:
            min_ts2 = ts2
    if is_normal(min_ts2):
        return np.sqrt(min_ts2) * dt_done * seventh_root(epsilon * 5040.0)
    return dt_done / safety  # every force cancelled to round-off: grow the step a little


@jit
def predict_next(ratio, e_src, b_src, e, b):
    """The next step's b's from the last ones rescaled by ``ratio`` = dt_next / dt_done, with the
    last correction (b - e) applied ahead (REBOUND's ``predict_next_step``); ``e`` and ``b`` may
    be ``e_src`` and ``b_src``."""
    if ratio > 20.0:
        for s in range(7):
            for k in range(b.shape[1]):
                e[s, k] = 0.0
                b[s, k] = 0.0
        return
    q1 = ratio
    q2 = q1 * q1
    q3 = q1 * q2
    q4 = q2 * q2
    q5 = q2 * q3
    q6 = q3 * q3
    q7 = q3 * q4
    for k in range(b.shape[1]):
        b0, b1, b2, b3 = b_src[0, k], b_src[1, k], b_src[2, k], b_src[3, k]
        b4, b5, b6 = b_src[4, k], b_src[5, k], b_src[6, k]
        be0 = b0 - e_src[0, k]
        be1 = b1 - e_src[1, k]
        be2 = b2 - e_src[2, k]
        be3 = b3 - e_src[3, k]
        be4 = b4 - e_src[4, k]
        be5 = b5 - e_src[5, k]
        be6 = b6 - e_src[6, k]
        e0 = q1 * (b6 * 7.0 + b5 * 6.0 + b4 * 5.0 + b3 * 4.0 + b2 * 3.0 + b1 * 2.0 + b0)
        e1 = q2 * (b6 * 21.0 + b5 * 15.0 + b4 * 10.0 + b3 * 6.0 + b2 * 3.0 + b1)
        e2 = q3 * (b6 * 35.0 + b5 * 20.0 + b4 * 10.0 + b3 * 4.0 + b2)
        e3 = q4 * (b6 * 35.0 + b5 * 15.0 + b4 * 5.0 + b3)
        e4 = q5 * (b6 * 21.0 + b5 * 6.0 + b4)
        e5 = q6 * (b6 * 7.0 + b5)
        e6 = q7 * b6
        e[0, k], e[1, k], e[2, k], e[3, k] = e0, e1, e2, e3
        e[4, k], e[5, k], e[6, k] = e4, e5, e6
        b[0, k], b[1, k], b[2, k], b[3, k] = e0 + be0, e1 + be1, e2 + be2, e3 + be3
        b[4, k], b[5, k], b[6, k] = e4 + be4, e5 + be5, e6 + be6


@jit
def _copy3(dst, src):
    for k in range(src.shape[0]):
        dst[k] = src[k]


@jit
def _copy7(dst, src):
    for s in range(7):
        for k in range(src.shape[1]):
            dst[s, k] = src[s, k]


@jit
def _end_of_step(x0, v0, a0, b, csx, csv, dt):
    """x and v at the end of the step: the integrals of the polynomial, each term compensated."""
    for k in range(x0.shape[0]):
        add_cs(x0, csx, k, b[6, k] / 72.0 * dt * dt)
        add_cs(x0, csx, k, b[5, k] / 56.0 * dt * dt)
        add_cs(x0, csx, k, b[4, k] / 42.0 * dt * dt)
        add_cs(x0, csx, k, b[3, k] / 30.0 * dt * dt)
        add_cs(x0, csx, k, b[2, k] / 20.0 * dt * dt)
        add_cs(x0, csx, k, b[1, k] / 12.0 * dt * dt)
        add_cs(x0, csx, k, b[0, k] / 6.0 * dt * dt)
        add_cs(x0, csx, k, a0[k] / 2.0 * dt * dt)
        add_cs(x0, csx, k, v0[k] * dt)
        add_cs(v0, csv, k, b[6, k] / 8.0 * dt)
        add_cs(v0, csv, k, b[5, k] / 7.0 * dt)
        add_cs(v0, csv, k, b[4, k] / 6.0 * dt)
        add_cs(v0, csv, k, b[3, k] / 5.0 * dt)
        add_cs(v0, csv, k, b[2, k] / 4.0 * dt)
        add_cs(v0, csv, k, b[1, k] / 3.0 * dt)
        add_cs(v0, csv, k, b[0, k] / 2.0 * dt)
        add_cs(v0, csv, k, a0[k] * dt)


@jit
def step_try(pos, vel, acc, m, force, work):
    """Try one step of ``work``'s clock dt from the state (``acc`` = a(pos) on entry).

    Returns True when the step is taken: pos, vel and the clock advance, ``acc`` is a(pos) at the
    new positions, and the clock holds the next step to try. Returns False when it is rejected:
    the state is as on entry, and the clock holds the smaller step to retry with.
    """
    b, e, g, csb, br, er = work.b, work.e, work.g, work.csb, work.br, work.er
    x0, v0, a0, at, csx, csv = work.x0, work.v0, work.a0, work.at, work.csx, work.csv
    clock, counts = work.clock, work.counts
    epsilon, min_dt, adaptive = work.epsilon, work.min_dt, work.adaptive
    dt = clock[CLOCK_DT]
    n3 = pos.size
    # Flat views: the polynomial arithmetic runs over 3N contiguous components, which vectorises.
    pf = pos.reshape(n3)
    vf = vel.reshape(n3)
    af = acc.reshape(n3)
    atf = at.reshape(n3)
    _copy3(x0, pf)
    _copy3(v0, vf)
    _copy3(a0, af)
    for s in range(7):
        for k in range(n3):
            csb[s, k] = 0.0
    _g_from_b(b, g)
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
            newtonian_accelerations(force, pos, m, at)
            add_node_forces(force, pos, m, at, b, csv, v0, a0, dt, H[n])  # nothing without forces
            # pf is the corrector's scratch: nothing reads the node's positions after the force
            # evaluation, and every path out of the step rewrites them from x0.
            max_b6, max_a = _correct(n, atf, a0, g, b, csb, pf)
            if n == 7:
                error = max_b6 / max_a
        counts[COUNT_FORCE_EVALS] += 7
    dt_done = dt
    if adaptive:
        dt_new = _prs23_dt(a0, b, epsilon, dt_done, SAFETY_FACTOR)
        if abs(dt_new) < min_dt:
            dt_new = np.copysign(min_dt, dt_new)
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
    newtonian_accelerations(force, pos, m, acc)
    add_forces(force, pos, vel, m, acc)  # nothing without forces
    counts[COUNT_FORCE_EVALS] += 1
    counts[COUNT_ACCEPTED] += 1
    return True
