"""Symplectic correctors of orders 3, 5, 7, 11 and 17 for the Wisdom-Holman map (Jacobi).

A corrector C is a near-identity canonical map such that C W(dt) C^-1 is the Wisdom-Holman map
W with its O(eps dt^2) error removed up to O(eps dt^p) (eps = planet/star mass ratio). It is
applied only at output times: C once when the map starts from an inertial state, C^-1 on a copy
of the mapping state whenever an output is synchronised (Wisdom, Holman & Touma 1996; Rein &
Tamayo 2015, section 3.3).

Each corrector is a product of stages

    Z(a, b) = K(a) I(-b) K(-2a) I(b) K(a),        K = Kepler drift, I = interaction kick,

with ``Z(a_s dt, inv * b_s dt)`` applied for s = 1..S in the order of :data:`CORRECTOR_STAGES`;
``inv = +1`` gives C, ``inv = -1`` gives C^-1 (because Z(a, b)^-1 = Z(-a, b) and each table is
antisymmetric under reversal). To first order in b, Z(a, b) = exp(-2 b sinh(a ad_K) I), so the
stages act through the odd moments ``sum_s b_s a_s^(2k+1)``; the order-p table fixes the first
(p - 1)/2 of them, and all tables share those moments (tested in tests/integrators/test_wisdom_holman.py).

The numbers are those of Wisdom, Holman & Touma (1996) as extended to orders 11 and 17 and
tabulated by Rein & Tamayo (2015), Table 1, with ``a_k = k sqrt(7/40)``; they are the values
REBOUND's WHFast uses, so the two codes apply the same correctors.

References
----------
.. [1] Wisdom, J., Holman, M. & Touma, J. (1996), "Symplectic correctors", in *Integration
       Algorithms and Classical Mechanics*, Fields Inst. Commun. 10, 217.
.. [2] Rein, H. & Tamayo, D. (2015), "WHFast: a fast and unbiased implementation of a symplectic
       Wisdom-Holman integrator for long-term gravitational simulations", MNRAS 452, 376.
"""

from __future__ import annotations

import numpy as np

from orbitsim._jit import jit, jit_inline
from orbitsim.forces.hooks import gravity_only
from orbitsim.integrators.wisdom_holman.operators import (
    JACOBI,
    interaction_kick,
)
from orbitsim.integrators.wisdom_holman.settings import CORRECTOR_ORDERS
from orbitsim.physics.kepler import KEPLER_OK, kepler_drift_bodies

#: a_1 = sqrt(7/40); the stage drifts are multiples a_k = k a_1.
CORRECTOR_A1 = 0.41833001326703777398908601289259374469640768464934

#: Kick coefficients b_{p,k} of the order-p corrector (Rein & Tamayo 2015, Table 1).
CORRECTOR_B: dict[int, tuple[float, ...]] = {
    3: (-0.024900596027799867499350357910273437184309981229127,),
    5: (
        -0.0083001986759332891664501193034244790614366604097090,
        0.041500993379666445832250596517122395307183302048545,
    ),
    7: (
        0.0024926811426922105779030593952776964450539008582219,
        -0.018270923246702131478062356884535264841652263842597,
        0.053964399093127498721765893493510877532452806339655,
    ),
    11: (
        0.00020361579647854651301632818774633716473696537436847,
        -0.0023487215292295354188307328851055489876255097419754,
        0.012309078592019946317544564763237909911330686448336,
        -0.038121613681288650508647613260247372125243616270670,
        0.072593394748842738674253180742744961827622366521517,
    ),
    17: (
        -0.0000043347415473373580190650223498124944896789841432241,
        0.000076436355227935738363241846979413475106795392377415,
        -0.00063599983075817658983166881625078545864140848560259,
        0.0033132577069380655655490196833451994080066801611459,
        -0.012071760822342291062449751726959664253913904872527,
        0.032422198864713580293681523029577130832258806467604,
        -0.065192863576377893658290760803725762027864651086787,
        0.093056103771425958591541059067553547100903397724386,
    ),
}



def _stages(order: int) -> tuple[np.ndarray, np.ndarray]:
    """Signed ``(a_s, b_s)`` of the stages of one corrector, in the order they are applied.

    Order 3 is the pair Z(a_1, -b_31), Z(-a_1, b_31); order p >= 5 with K = (p - 1)/2 kick
    coefficients runs Z(-a_K, -b_p1), ..., Z(-a_1, -b_pK), then Z(a_1, b_pK), ..., Z(a_K, b_p1).
    """
    if order == 0:
        return np.zeros(0), np.zeros(0)
    b = CORRECTOR_B[order]
    if order == 3:
        return np.array([CORRECTOR_A1, -CORRECTOR_A1]), np.array([-b[0], b[0]])
    k_max = len(b)
    a_neg = [-(k_max - s) * CORRECTOR_A1 for s in range(k_max)]
    b_neg = [-b[s] for s in range(k_max)]
    a = np.array(a_neg + [-x for x in reversed(a_neg)])
    bs = np.array(b_neg + [-x for x in reversed(b_neg)])
    return a, bs


#: order -> (a_s, b_s) arrays of the stages, in application order.
CORRECTOR_STAGES: dict[int, tuple[np.ndarray, np.ndarray]] = {p: _stages(p) for p in CORRECTOR_ORDERS}


@jit_inline
def corrector_stage(jpos, jvel, m, G, eps2, a, b, weights, mu, ipos, acc, ks, kstage, kick_force):
    """One stage Z(a, b) = K(a) I(-b) K(-2a) I(b) K(a) (Jacobi); returns ``(status, body)``.

    ``kick_force``: a context without forces (:func:`~orbitsim.forces.hooks.gravity_only`): the
    correctors' kicks are by gravity alone.
    """
    status, body = kepler_drift_bodies(jpos, jvel, mu, a, 1, ks, kstage)
    if status != KEPLER_OK:
        return status, body
    # Jacobi: heliocentric None, as a Jacobi run's own kicks pass it (WHWork.heliocentric)
    interaction_kick(jpos, jvel, m, G, eps2, -b, None, weights, mu, ipos, acc, kick_force)
    status, body = kepler_drift_bodies(jpos, jvel, mu, -2.0 * a, 1, ks, kstage)
    if status != KEPLER_OK:
        return status, body
    interaction_kick(jpos, jvel, m, G, eps2, b, None, weights, mu, ipos, acc, kick_force)
    return kepler_drift_bodies(jpos, jvel, mu, a, 1, ks, kstage)


@jit
def apply_corrector(jpos, jvel, m, force, dt, inv, work, stage_a, stage_b):
    """C (``inv = 1.0``) or C^-1 (``inv = -1.0``) of the order whose stage tables ``stage_a``, ``stage_b``
    (``work.stage_a``, ``work.stage_b``) are; returns ``(status, body)``. Without a corrector they are
    None, and the function is ``return (KEPLER_OK, 0)``: Numba removes a branch on an argument that is
    None before typing, so a run without a corrector types and compiles no stage (they cost 5-8 s of a
    first Wisdom-Holman run).

    The tables are arguments, not read from ``work`` here, for that pruning; one layer of calls, not an
    overload around this function, which Numba would compile once more on its own (0.8 s).
    Correctors need Jacobi coordinates (enforced by the settings validation; checked here too).
    """
    if stage_a is None or stage_b is None:
        return np.int64(KEPLER_OK), np.int64(0)
    if work.config[0] != JACOBI:
        raise ValueError("wisdom_holman: symplectic correctors need Jacobi coordinates")
    G = force.G
    eps2 = force.eps2
    weights = work.weights
    mu = work.mu
    ipos = work.ipos
    acc = work.iacc
    ks = work.kscratch
    kstage = work.kstage
    kick_force = gravity_only(force)
    for s in range(stage_a.shape[0]):
        a = stage_a[s] * dt
        b = inv * stage_b[s] * dt
        status, body = corrector_stage(jpos, jvel, m, G, eps2, a, b, weights, mu, ipos, acc, ks, kstage,
                                       kick_force)
        if status != KEPLER_OK:
            return status, body
    return np.int64(KEPLER_OK), np.int64(0)
