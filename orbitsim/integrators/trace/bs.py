"""The Gragg-Bulirsch-Stoer step TRACE uses for close encounters and pericentre passages.

A port of REBOUND's ``integrator_bs.c`` (itself after Hairer, Norsett & Wanner, *Solving Ordinary
Differential Equations I*, section II.9, by way of Hipparchus), written for the one ODE TRACE
integrates at a time, with its derivative dispatched by kind (:func:`.forces.derivatives`).

One step of size H: the modified midpoint rule with ``n_k = 2, 6, 10, ..., 34`` sub-steps
(:data:`SEQUENCE`), each result a column of the Aitken-Neville extrapolation in ``h^2``
(:data:`COEFF` = 1/n_k^2). The error of column k is the max over components of
``|C_i| / (eps_abs + eps_rel |y_i|)`` (y at the start of the step), which sets the optimal step of
that column, ``H (0.94 / (err / 0.65)^(1/(2k+1)))`` clamped; the order (``target_iter``) and the
next step follow the cost per unit time of each column. A step is rejected when the midpoint
rule is unstable (the first sub-steps' derivative changed by more than twice its size), when
the error is not expected to converge by the column after the target, or when it exceeds 1.

What TRACE relies on, and this port keeps:

* a fresh state per TRACE Kepler step, FULL step and redo (:func:`bs_reset`): first trial step =
  the whole outer dt, ``target_iter`` chosen from ``eps_rel``, ``first_or_last_step = 1``;
* ``eps_abs = eps_rel = 1e-8``, no minimum or maximum step;
* every floating-point operation in REBOUND's order, including the interleaved layout of y.

The ODE state lives in the rows of one (:data:`N_ROWS`, 6N) array (``R_*`` constants), the step
controller's numbers in two small arrays (``BS_*`` constants), so a step allocates nothing.

This is orbitsim's only Bulirsch-Stoer, and only what TRACE needs, in REBOUND's layout: y
interleaved per body (a layout of (3, n) blocks would run the stability check's sums in another
order), a nan that REBOUND's ``MAX`` macro drops dropped here too, and the sub-step loops left to
the caller (:mod:`.substeps`), since TRACE needs two (the FULL_BS one clamps the step after the
proposal, the encounter one before it) with a hook after every accepted sub-step for the
collision search.
"""

from __future__ import annotations

import math

import numpy as np

from orbitsim._jit import jit, jit_inline
from orbitsim.integrators.trace.forces import derivatives

#: REBOUND's defaults inside TRACE (not user-settable there either).
EPS_ABS = 1e-8
EPS_REL = 1e-8
#: Step-size and order control constants of ``integrator_bs.c`` (Hairer et al.'s choices).
SEQUENCE_LENGTH = 9
STEP_CONTROL_1 = 0.65
STEP_CONTROL_2 = 0.94
STEP_CONTROL_3 = 0.02
STEP_CONTROL_4 = 4.0
ORDER_CONTROL_1 = 0.8
ORDER_CONTROL_2 = 0.9
STABILITY_REDUCTION = 0.5
#: The stability check runs at the first ``MAX_CHECKS`` midpoint sub-steps of the first
#: ``MAX_ITER`` columns.
MAX_ITER = 2
MAX_CHECKS = 1
#: An error above this is treated as divergence: halve the step.
ERROR_DIVERGED = 1.0e25

#: Sub-steps of column k, 4k + 2; extrapolation coefficients (1/n_k)^2; cost (derivative
#: evaluations) of columns 0..k.
SEQUENCE = np.array([4 * k + 2 for k in range(SEQUENCE_LENGTH)], dtype=np.int64)
COEFF = np.array([(1.0 / float(n)) * (1.0 / float(n)) for n in SEQUENCE])
COST_PER_STEP = np.cumsum(SEQUENCE) + 1
#: The first order REBOUND picks: floor(0.5 - 0.6 log10(eps_rel)) within [1, 7] (5 at 1e-8).
INITIAL_TARGET_ITER = max(1, min(SEQUENCE_LENGTH - 2, math.floor(0.5 - 0.6 * math.log10(max(1.0e-10, EPS_REL)))))

#: Rows of the state array: y, the trial y1, f(y), f(y1), the midpoint's other leg, the error
#: scale, the extrapolation's C, then the columns D_0..D_8.
R_Y, R_Y1, R_Y0DOT, R_YDOT, R_YTMP, R_SCALE, R_C, R_D = range(8)
N_ROWS = R_D + SEQUENCE_LENGTH

#: Float controller state: optimal step and cost per unit time of each column, the next step.
BS_OPTIMAL_STEP = 0
BS_COST_PER_TIME = SEQUENCE_LENGTH
BS_DT_PROPOSED = 2 * SEQUENCE_LENGTH
BS_REAL_LENGTH = BS_DT_PROPOSED + 1
#: Integer controller state.
BS_TARGET_ITER, BS_FIRST_OR_LAST_STEP, BS_PREVIOUS_REJECTED = range(3)
BS_INT_LENGTH = 3

#: Results of :func:`bs_step`.
BS_REJECTED, BS_ACCEPTED, BS_NAN = 0, 1, -1


@jit_inline
def _cmax(a, b):
    """C's ``MAX(a, b)`` macro (``a > b ? a : b``): differs from max() when b is nan."""
    return a if a > b else b


@jit_inline
def _cmin(a, b):
    """C's ``MIN(a, b)`` macro (``a < b ? a : b``)."""
    return a if a < b else b


@jit
def bs_reset(bs_real, bs_int):
    """A freshly created controller (REBOUND's ``reb_integrator_bs_create``)."""
    for q in range(BS_REAL_LENGTH):
        bs_real[q] = 0.0
    bs_int[BS_TARGET_ITER] = 0
    bs_int[BS_FIRST_OR_LAST_STEP] = 1
    bs_int[BS_PREVIOUS_REJECTED] = 0


@jit
def _try_step(rows, length, k, step, kind, m, G, softening2, bodies, n_bodies, n_bodies_active, interacts,
              with_jump):
    """Modified midpoint over ``step`` with SEQUENCE[k] sub-steps into ``rows[R_Y1]``; False if unstable."""
    n = SEQUENCE[k]
    sub = step / n
    two_sub = 2.0 * sub
    # The first sub-step (an Euler step) and the n - 1 midpoint ones share one loop, so that the
    # derivatives are inlined here once (each copy cost ~2 s of a first run's compilation).
    for j in range(n):
        if j == 0:
            for i in range(length):
                rows[R_Y1, i] = rows[R_Y, i] + sub * rows[R_Y0DOT, i]
        else:
            for i in range(length):
                middle = rows[R_Y1, i]
                rows[R_Y1, i] = rows[R_YTMP, i] + two_sub * rows[R_YDOT, i]
                rows[R_YTMP, i] = middle
        derivatives(kind, rows, R_Y1, R_YDOT, m, G, softening2, bodies, n_bodies, n_bodies_active, interacts,
                    with_jump)
        if j == 0:
            for i in range(length):
                rows[R_YTMP, i] = rows[R_Y, i]
        elif j <= MAX_CHECKS and k < MAX_ITER:
            initial_norm = 0.0
            delta_norm = 0.0
            for i in range(length):
                ratio1 = rows[R_Y0DOT, i] / rows[R_SCALE, i]
                initial_norm += ratio1 * ratio1
                ratio2 = (rows[R_YDOT, i] - rows[R_Y0DOT, i]) / rows[R_SCALE, i]
                delta_norm += ratio2 * ratio2
            if delta_norm > 4.0 * _cmax(1.0e-15, initial_norm):
                return False
    for i in range(length):
        rows[R_Y1, i] = 0.5 * (rows[R_YTMP, i] + rows[R_Y1, i] + sub * rows[R_YDOT, i])
    return True


@jit
def _extrapolate(rows, length, k):
    """Aitken-Neville: fold column k (in ``rows[R_C]``) into D_0..D_k; ``rows[R_Y1]`` = sum of D."""
    for j in range(k):
        xi = COEFF[k - j - 1]
        xim1 = COEFF[k]
        fac_c = xi / (xi - xim1)
        fac_d = xim1 / (xi - xim1)
        d_row = R_D + k - j - 1
        for i in range(length):
            cd = rows[R_C, i] - rows[d_row, i]
            rows[R_C, i] = fac_c * cd
            rows[d_row, i] = fac_d * cd
    for i in range(length):
        rows[R_Y1, i] = rows[R_D, i]
    for j in range(1, k + 1):
        for i in range(length):
            rows[R_Y1, i] += rows[R_D + j, i]


@jit
def _lower_target(target, bs_real):
    """One order lower when the column below is cheaper per unit time (``orderControl1``)."""
    if target > 1 and bs_real[BS_COST_PER_TIME + target - 1] < ORDER_CONTROL_1 * bs_real[BS_COST_PER_TIME + target]:
        return target - 1
    return target


@jit
def _judge_column(k, error, step, bs_real, bs_int):
    """Step-size estimate of column k and the convergence decision: ``(go_on, reject, step)``."""
    ex = 1.0 / (2 * k + 1)
    fac = STEP_CONTROL_2 / math.pow(error / STEP_CONTROL_1, ex)
    power = math.pow(STEP_CONTROL_3, ex)
    fac = _cmax(power / STEP_CONTROL_4, _cmin(1.0 / power, fac))
    bs_real[BS_OPTIMAL_STEP + k] = abs(step * fac)
    bs_real[BS_COST_PER_TIME + k] = COST_PER_STEP[k] / bs_real[BS_OPTIMAL_STEP + k]
    target = bs_int[BS_TARGET_ITER]
    d = k - target
    if d == -1:
        if target > 1 and not bs_int[BS_PREVIOUS_REJECTED]:
            if error <= 1.0:
                return False, False, step
            ratio = (float(SEQUENCE[target]) * SEQUENCE[target + 1]) / (SEQUENCE[0] * SEQUENCE[0])
            if error > ratio * ratio:
                # Not expected to converge at the target: reject now, at this order or one lower.
                target = _lower_target(k, bs_real)
                bs_int[BS_TARGET_ITER] = target
                return False, True, bs_real[BS_OPTIMAL_STEP + target]
        return True, False, step
    if d == 0:
        if error <= 1.0:
            return False, False, step
        ratio = float(SEQUENCE[k + 1]) / SEQUENCE[0]
        if error > ratio * ratio:
            target = _lower_target(target, bs_real)
            bs_int[BS_TARGET_ITER] = target
            return False, True, bs_real[BS_OPTIMAL_STEP + target]
        return True, False, step
    if d == 1:
        if error > 1.0:
            target = _lower_target(target, bs_real)
            bs_int[BS_TARGET_ITER] = target
            return False, True, bs_real[BS_OPTIMAL_STEP + target]
        return False, False, step
    if bs_int[BS_FIRST_OR_LAST_STEP] and error <= 1.0:
        return False, False, step
    return True, False, step


@jit
def _next_step(k, step, bs_real, bs_int):
    """Order and step size after an accepted step that converged in column k."""
    cost = bs_real[BS_COST_PER_TIME:BS_COST_PER_TIME + SEQUENCE_LENGTH]
    target = bs_int[BS_TARGET_ITER]
    previous_rejected = bs_int[BS_PREVIOUS_REJECTED]
    if k == 1:
        optimal_iter = 1 if previous_rejected else 2
    elif k <= target:
        optimal_iter = k
        if cost[k - 1] < ORDER_CONTROL_1 * cost[k]:
            optimal_iter = k - 1
        elif cost[k] < ORDER_CONTROL_2 * cost[k - 1]:
            optimal_iter = min(k + 1, SEQUENCE_LENGTH - 2)
    else:
        optimal_iter = k - 1
        if k > 2 and cost[k - 2] < ORDER_CONTROL_1 * cost[k - 1]:
            optimal_iter = k - 2
        if cost[k] < ORDER_CONTROL_2 * cost[optimal_iter]:
            optimal_iter = min(k, SEQUENCE_LENGTH - 2)
    if previous_rejected:
        # After a rejection neither the order nor the step may grow.
        bs_int[BS_TARGET_ITER] = min(optimal_iter, k)
        return _cmin(abs(step), bs_real[BS_OPTIMAL_STEP + bs_int[BS_TARGET_ITER]])
    if optimal_iter <= k:
        step = bs_real[BS_OPTIMAL_STEP + optimal_iter]
    elif k < target and cost[k] < ORDER_CONTROL_2 * cost[k - 1]:
        step = bs_real[BS_OPTIMAL_STEP + k] * COST_PER_STEP[optimal_iter + 1] / COST_PER_STEP[k]
    else:
        step = bs_real[BS_OPTIMAL_STEP + k] * COST_PER_STEP[optimal_iter] / COST_PER_STEP[k]
    bs_int[BS_TARGET_ITER] = optimal_iter
    return step


@jit
def bs_step(rows, length, step, bs_real, bs_int, kind, m, G, softening2, bodies, n_bodies, n_bodies_active,
            interacts, with_jump):
    """One BS step of ``step`` from ``rows[R_Y, :length]``: BS_ACCEPTED, BS_REJECTED or BS_NAN.

    Accepted: ``rows[R_Y]`` holds the new state. Either way ``bs_real[BS_DT_PROPOSED]`` holds the
    step to try next (the unchanged ``step`` after BS_NAN, as REBOUND leaves it).
    """
    bs_real[BS_DT_PROPOSED] = step
    if bs_int[BS_TARGET_ITER] == 0:
        bs_int[BS_TARGET_ITER] = INITIAL_TARGET_ITER
    # REBOUND recomputes this scale after every extrapolation, from the same start-of-step y
    # (identical values), so it is computed once.
    for i in range(length):
        rows[R_SCALE, i] = EPS_ABS + EPS_REL * abs(rows[R_Y, i])
    derivatives(kind, rows, R_Y, R_Y0DOT, m, G, softening2, bodies, n_bodies, n_bodies_active, interacts, with_jump)
    forward = step >= 0.0
    k = -1
    reject = False
    go_on = True
    # k stays below SEQUENCE_LENGTH - 1: column target_iter + 1 <= 8 always ends the loop; the
    # bound only guards the arrays.
    while go_on and k < SEQUENCE_LENGTH - 1:
        k += 1
        if not _try_step(rows, length, k, step, kind, m, G, softening2, bodies, n_bodies, n_bodies_active,
                         interacts, with_jump):
            step = abs(step * STABILITY_REDUCTION)
            reject = True
            break
        for i in range(length):
            rows[R_C, i] = rows[R_Y1, i]
            rows[R_D + k, i] = rows[R_Y1, i]
        if k == 0:
            continue
        _extrapolate(rows, length, k)
        error = 0.0
        for i in range(length):
            e = rows[R_C, i] / rows[R_SCALE, i]
            error = _cmax(error, e * e)
        error = math.sqrt(error)
        if math.isnan(error):
            return BS_NAN
        if error > ERROR_DIVERGED:
            step = abs(step * STABILITY_REDUCTION)
            reject = True
            break
        go_on, reject, step = _judge_column(k, error, step, bs_real, bs_int)
    if not reject:
        for i in range(length):
            rows[R_Y, i] = rows[R_Y1, i]
        step = _next_step(k, step, bs_real, bs_int)
    step = abs(step)
    bs_real[BS_DT_PROPOSED] = step if forward else -step
    bs_int[BS_PREVIOUS_REJECTED] = 1 if reject else 0
    if not reject:
        bs_int[BS_FIRST_OR_LAST_STEP] = 0
    return BS_REJECTED if reject else BS_ACCEPTED
