"""Symmetric compositions of the drift-kick-drift leapfrog, driven by coefficient tables.

A composition of s leapfrog substeps with weights w_1..w_s (a palindrome summing to 1) is written
as alternating drifts and kicks:

    drift(d_0 dt) kick(w_1 dt) drift(d_1 dt) kick(w_2 dt) ... kick(w_s dt) drift(d_s dt)

with d_0 = w_1 / 2, d_i = (w_i + w_{i+1}) / 2 and d_s = w_s / 2, so the drifts sum to 1 too.
Each kick needs one force evaluation at the current positions: s evaluations per step.

The tables are those REBOUND's ``leapfrog`` integrator uses for ``order`` 2, 4, 6 and 8
(``src/integrator_leapfrog.c``), to the digits REBOUND states them, so the two codes take the same
substeps and agree to round-off. :func:`drift_coefficients` forms the drifts exactly as REBOUND
does: ``(w_i + w_{i+1}) * 0.5``, where the product by 0.5 is exact.
"""

from __future__ import annotations

import numpy as np

from orbitsim._jit import jit, jit_inline
from orbitsim.integrators.base import drift, kick_drift, record_sample
from orbitsim.physics.gravity import SMALL_N_MAX, accelerations, all_pairs_accelerations

#: Order 2: the plain drift-kick-drift leapfrog, one substep.
LEAPFROG2_WEIGHTS = np.array([1.0])

#: Yoshida (1990), Phys. Lett. A 150, 262, eq. (4.4): the triple jump w1 = 1 / (2 - 2^(1/3)),
#: w0 = 1 - 2 w1. REBOUND stores a = w1 / 2 = 0.675603595979828817...
_YOSHIDA4_HALF_W1 = 0.675603595979828817023843904485
LEAPFROG4_WEIGHTS = np.array([2.0 * _YOSHIDA4_HALF_W1, 1.0 - 4.0 * _YOSHIDA4_HALF_W1, 2.0 * _YOSHIDA4_HALF_W1])

#: Blanes & Casas (2016), A Concise Introduction to Geometric Numerical Integration, CRC Press,
#: the 6th-order symmetric composition with 9 stages (first five weights; the rest mirror them).
_BC6_HALF = (0.1867, 0.5554970237124784, 0.1294669489134754, -0.843265623387734, 0.9432033015235604)

#: Blanes & Casas (2016), p. 91: the 8th-order symmetric composition with 17 stages.
_BC8_HALF = (
    0.128865979381443,
    0.581514087105251,
    -0.410175371469850,
    0.1851469357165877,
    -0.4095523434208514,
    0.1444059410800120,
    0.2783355003936797,
    0.3149566839162949,
    -0.6269948254051343979,
)


def palindrome(half: tuple[float, ...]) -> np.ndarray:
    """Weights of a symmetric composition from its first half and its middle weight (last entry)."""
    return np.array([*half, *reversed(half[:-1])])


LEAPFROG6_WEIGHTS = palindrome(_BC6_HALF)
LEAPFROG8_WEIGHTS = palindrome(_BC8_HALF)


def drift_coefficients(weights: np.ndarray) -> np.ndarray:
    """Drift fractions d_0..d_s between the kicks of a DKD composition with kick ``weights``."""
    drifts = np.empty(weights.shape[0] + 1)
    drifts[0] = weights[0] * 0.5
    drifts[1:-1] = (weights[:-1] + weights[1:]) * 0.5
    drifts[-1] = weights[-1] * 0.5
    return drifts


@jit_inline
def advance_dkd(pos, vel, acc, m, force, dt, steps, drifts, kicks):
    """``steps`` composed steps, each a drift(d_0 dt), then for each substep an evaluation, kick and
    drift.

    ``acc`` is not read on entry; on exit it holds the accelerations of the last kick, which were
    evaluated half a substep before the final positions. The force kernels are called from this
    loop, not through an inlined helper: see :mod:`orbitsim.physics.gravity`.
    """
    G, eps2, slabs, bounds = force
    small = pos.shape[1] <= SMALL_N_MAX
    for _ in range(steps):
        drift(pos, vel, dt * drifts[0])
        for s in range(kicks.shape[0]):
            if small:
                all_pairs_accelerations(pos, m, G, eps2, acc)
            else:
                accelerations(pos, m, G, eps2, acc, slabs, bounds)
            kick_drift(pos, vel, acc, dt * kicks[s], dt * drifts[s + 1])


@jit_inline
def compose_dkd(pos, vel, acc, m, force, dt, drifts, kicks):
    """One composed step (:func:`advance_dkd`)."""
    advance_dkd(pos, vel, acc, m, force, dt, 1, drifts, kicks)


@jit
def run_dkd(state, force, dt, work, t0, n_done, targets, record, out, drifts, kicks):
    """Fixed-dt loop of :func:`advance_dkd` for one coefficient table.

    The leapfrog, leapfrog4/6/8 modules share this loop (tables are data, so it caches once for
    all of them); the contract is :mod:`orbitsim.integrators.base`'s ``run``.
    """
    pos, vel, acc, m = state
    written = 0
    for k in range(targets.shape[0]):
        if n_done < targets[k]:
            advance_dkd(pos, vel, acc, m, force, dt, targets[k] - n_done, drifts, kicks)
            n_done = targets[k]
        if record[k]:
            if not record_sample(written, n_done, t0, dt, pos, vel, m, force, out):
                return written, n_done, False
            written += 1
    return written, n_done, True
