"""The drift-kick-drift leapfrog and its symmetric compositions of order 4, 6 and 8.

REBOUND has one ``leapfrog`` with an ``order`` setting (2, 4, 6, 8); orbitsim registers the same
four schemes under the names ``leapfrog``, ``leapfrog4``, ``leapfrog6`` and ``leapfrog8`` (a
scenario's ``{name: leapfrog, order: 4}`` is ``leapfrog4``, :mod:`.rebound_names`). They differ
only in a coefficient table (:data:`ORDERS` holds the four records by order).

Order 2, the plain leapfrog (the position-Verlet twin of :mod:`orbitsim.integrators.verlet`):

    x_{n+1/2} = x_n + (dt/2) v_n
    v_{n+1}   = v_n + dt a(x_{n+1/2})
    x_{n+1}   = x_{n+1/2} + (dt/2) v_{n+1}

Second order, symplectic, time-reversible; one force evaluation per step, at the midpoint.

A composition of s leapfrog substeps with weights w_1..w_s (a palindrome summing to 1) is written
as alternating drifts and kicks:

    drift(d_0 dt) kick(w_1 dt) drift(d_1 dt) kick(w_2 dt) ... kick(w_s dt) drift(d_s dt)

with d_0 = w_1 / 2, d_i = (w_i + w_{i+1}) / 2 and d_s = w_s / 2, so the drifts sum to 1 too.
Each kick needs one force evaluation at the current positions: s evaluations per step. Every
composition is symplectic and time-reversible.

* order 4: Yoshida's (1990) triple jump, three substeps with weights w1, 1 - 2 w1, w1,
  w1 = 1/(2 - 2^(1/3)); the middle one runs backwards in time;
* order 6: Blanes & Casas (2016), 9 stages;
* order 8: Blanes & Casas (2016, p. 91), 17 stages.

The tables are those REBOUND's ``leapfrog`` integrator uses for ``order`` 2, 4, 6 and 8
(``src/integrator_leapfrog.c``), to the digits REBOUND states them, so the two codes take the same
substeps and agree to round-off. :func:`drift_coefficients` forms the drifts exactly as REBOUND
does: ``(w_i + w_{i+1}) * 0.5``, where the product by 0.5 is exact.

Each order has its own ``advance``, ``step``, ``run`` and ``run_watched`` (``advance2``, ``step2``,
``run2``, ..., ``run_watched8``), each reading its order's tables as module globals, which Numba
compiles in as constants: one function per order is what keeps every order in the on-disk cache
(a factory's closures would miss it) and compiles only the order a run uses. The steps they share,
:func:`advance_dkd`, take the tables as arguments.

Why one module: the four orders are one family driven by one table each, and every entry point of an
order (``advance``, ``step``, ``run``, ``run_watched``, and ``run_chaos``, the variational run of
:func:`advance_dkd_chaos`) must read that order's tables as globals of the module that holds its
record; split, the chaos entry points would import the tables from here while the records here
import them back.
"""

from __future__ import annotations

import numpy as np

from orbitsim._jit import jit, jit_inline
from orbitsim.chaos.step import megno_after_step
from orbitsim.events.kernels import watched_run
from orbitsim.forces.hooks import add_kick_forces, refresh_accelerations, velocity_operator
from orbitsim.forces.tangent import add_tangent_kick_forces
from orbitsim.integrators.base import (
    Integrator,
    IntegratorSpec,
    chaos_sample_loop,
    drift,
    grid_time,
    kick_drift,
    sample_loop,
)
from orbitsim.physics.force_context import newtonian_accelerations
from orbitsim.physics.tangent import ALL_PAIRS, tangent_accelerations

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
    drift; velocity-dependent forces are an operator around each step, ``V(dt/2) S(dt) V(dt/2)``
    (nothing without them).

    ``acc`` is not read on entry; on exit it holds the accelerations of the last kick (gravity and
    the position-only forces), which were evaluated half a substep before the final positions.
    """
    half_dt = 0.5 * dt
    for _ in range(steps):
        velocity_operator(force, pos, vel, m, half_dt)
        drift(pos, vel, dt * drifts[0])
        for s in range(kicks.shape[0]):
            newtonian_accelerations(force, pos, m, acc)
            add_kick_forces(force, pos, m, acc)
            kick_drift(pos, vel, acc, dt * kicks[s], dt * drifts[s + 1])
        velocity_operator(force, pos, vel, m, half_dt)


@jit_inline
def advance_dkd_chaos(pos, vel, acc, m, force, dt, t0, n_done, n_to, drifts, kicks, tangent, megno):
    """:func:`advance_dkd` with the tangent vector stepped beside the bodies (the tangent of a drift
    is a drift, of a kick a kick with the tangent accelerations at the kick's positions) and MEGNO's
    read after each step. The bodies take the same operations as in :func:`advance_dkd`, so the same
    bits. Returns ``(n_done, True, megno)``."""
    dpos, dvel, dacc = tangent.dpos, tangent.dvel, tangent.dacc
    G = force.G
    eps2 = force.eps2
    while n_done < n_to:
        drift(pos, vel, dt * drifts[0])
        drift(dpos, dvel, dt * drifts[0])
        for s in range(kicks.shape[0]):
            newtonian_accelerations(force, pos, m, acc)
            add_kick_forces(force, pos, m, acc)
            tangent_accelerations(pos, m, G, eps2, dpos, dacc, np.int64(ALL_PAIRS))
            add_tangent_kick_forces(force, pos, m, dpos, dacc)
            kick_drift(pos, vel, acc, dt * kicks[s], dt * drifts[s + 1])
            kick_drift(dpos, dvel, dacc, dt * kicks[s], dt * drifts[s + 1])
        n_done += 1
        megno, halvings = megno_after_step(megno, pos, m, force, dpos, dvel, dacc, t0 + n_done * dt, dt)
        tangent.halvings[0] += halvings
    return n_done, True, megno


# -- order 2: leapfrog --------------------------------------------------------------------------

KICKS2 = LEAPFROG2_WEIGHTS
DRIFTS2 = drift_coefficients(KICKS2)


@jit_inline
def advance2(pos, vel, acc, m, force, dt, work, t0, n_done, n_to):
    """Steps from ``n_done`` to ``n_to`` of order 2 (:func:`advance_dkd` with its tables)."""
    advance_dkd(pos, vel, acc, m, force, dt, n_to - n_done, DRIFTS2, KICKS2)
    return n_to, True


@jit
def step2(pos, vel, acc, m, force, dt, work):
    """One leapfrog step of size ``dt`` (1 force evaluation), in place."""
    advance_dkd(pos, vel, acc, m, force, dt, 1, DRIFTS2, KICKS2)


@jit
def run2(state, force, dt, work, t0, n_done, targets, record, out):
    """:func:`~orbitsim.integrators.base.sample_loop` of :func:`advance2`; a forced run's ``acc``
    afresh first (:func:`~orbitsim.forces.hooks.refresh_accelerations`)."""
    pos, vel, acc, m = state
    refresh_accelerations(force, pos, vel, m, acc, False)
    return sample_loop(advance2, grid_time, state, force, dt, work, t0, n_done, targets, record, out)


@jit_inline
def advance_chaos2(pos, vel, acc, m, force, dt, work, t0, n_done, n_to, tangent, megno):
    """:func:`advance_dkd_chaos` with the order-2 tables."""
    return advance_dkd_chaos(pos, vel, acc, m, force, dt, t0, n_done, n_to, DRIFTS2, KICKS2, tangent, megno)


@jit
def run_chaos2(state, tangent, force, dt, work, t0, n_done, targets, record, out, indicators, megno):
    """:func:`~orbitsim.integrators.base.chaos_sample_loop` of :func:`advance_chaos2`."""
    return chaos_sample_loop(advance_chaos2, grid_time, state, tangent, force, dt, work, t0, n_done, targets,
                             record, out, indicators, megno)


@jit
def run_watched2(state, force, dt, work, t0, n_done, targets, record, out, watch):
    """:func:`run2` one step at a time with the events watch after each (:mod:`orbitsim.events`)."""
    return watched_run(advance2, state, force, dt, work, t0, n_done, targets, record, out, watch)


LEAPFROG = Integrator(
    spec=IntegratorSpec(
        name="leapfrog",
        aliases=("dkd",),
        order=2,
        symplectic=True,
        reversible=True,
        force_evals=1,
        work_slots=0,
        fsal=False,
        summary="drift-kick-drift leapfrog, the scheme REBOUND calls leapfrog",
        reference="Hairer, Lubich & Wanner (2003), Acta Numerica 12, 399 (Stoermer-Verlet); REBOUND leapfrog "
        "order 2",
        module=__name__,
    ),
    step=step2,
    run=run2,
    run_watched=run_watched2,
    run_chaos=run_chaos2,
    kicks=KICKS2,
    drifts=DRIFTS2,
)


# -- order 4: leapfrog4 -------------------------------------------------------------------------

KICKS4 = LEAPFROG4_WEIGHTS
DRIFTS4 = drift_coefficients(KICKS4)


@jit_inline
def advance4(pos, vel, acc, m, force, dt, work, t0, n_done, n_to):
    """Steps from ``n_done`` to ``n_to`` of order 4 (:func:`advance_dkd` with its tables)."""
    advance_dkd(pos, vel, acc, m, force, dt, n_to - n_done, DRIFTS4, KICKS4)
    return n_to, True


@jit
def step4(pos, vel, acc, m, force, dt, work):
    """One leapfrog4 step of size ``dt`` (3 force evaluations), in place."""
    advance_dkd(pos, vel, acc, m, force, dt, 1, DRIFTS4, KICKS4)


@jit
def run4(state, force, dt, work, t0, n_done, targets, record, out):
    """:func:`~orbitsim.integrators.base.sample_loop` of :func:`advance4`; a forced run's ``acc``
    afresh first (:func:`~orbitsim.forces.hooks.refresh_accelerations`)."""
    pos, vel, acc, m = state
    refresh_accelerations(force, pos, vel, m, acc, False)
    return sample_loop(advance4, grid_time, state, force, dt, work, t0, n_done, targets, record, out)


@jit_inline
def advance_chaos4(pos, vel, acc, m, force, dt, work, t0, n_done, n_to, tangent, megno):
    """:func:`advance_dkd_chaos` with the order-4 tables."""
    return advance_dkd_chaos(pos, vel, acc, m, force, dt, t0, n_done, n_to, DRIFTS4, KICKS4, tangent, megno)


@jit
def run_chaos4(state, tangent, force, dt, work, t0, n_done, targets, record, out, indicators, megno):
    """:func:`~orbitsim.integrators.base.chaos_sample_loop` of :func:`advance_chaos4`."""
    return chaos_sample_loop(advance_chaos4, grid_time, state, tangent, force, dt, work, t0, n_done, targets,
                             record, out, indicators, megno)


@jit
def run_watched4(state, force, dt, work, t0, n_done, targets, record, out, watch):
    """:func:`run4` one step at a time with the events watch after each (:mod:`orbitsim.events`)."""
    return watched_run(advance4, state, force, dt, work, t0, n_done, targets, record, out, watch)


LEAPFROG4 = Integrator(
    spec=IntegratorSpec(
        name="leapfrog4",
        aliases=("yoshida4",),
        order=4,
        symplectic=True,
        reversible=True,
        force_evals=3,
        work_slots=0,
        fsal=False,
        summary="Yoshida's 4th-order triple-jump composition of the DKD leapfrog",
        reference="H. Yoshida (1990), Phys. Lett. A 150, 262; REBOUND leapfrog order 4",
        module=__name__,
    ),
    step=step4,
    run=run4,
    run_watched=run_watched4,
    run_chaos=run_chaos4,
    kicks=KICKS4,
    drifts=DRIFTS4,
)


# -- order 6: leapfrog6 -------------------------------------------------------------------------

KICKS6 = LEAPFROG6_WEIGHTS
DRIFTS6 = drift_coefficients(KICKS6)


@jit_inline
def advance6(pos, vel, acc, m, force, dt, work, t0, n_done, n_to):
    """Steps from ``n_done`` to ``n_to`` of order 6 (:func:`advance_dkd` with its tables)."""
    advance_dkd(pos, vel, acc, m, force, dt, n_to - n_done, DRIFTS6, KICKS6)
    return n_to, True


@jit
def step6(pos, vel, acc, m, force, dt, work):
    """One leapfrog6 step of size ``dt`` (9 force evaluations), in place."""
    advance_dkd(pos, vel, acc, m, force, dt, 1, DRIFTS6, KICKS6)


@jit
def run6(state, force, dt, work, t0, n_done, targets, record, out):
    """:func:`~orbitsim.integrators.base.sample_loop` of :func:`advance6`; a forced run's ``acc``
    afresh first (:func:`~orbitsim.forces.hooks.refresh_accelerations`)."""
    pos, vel, acc, m = state
    refresh_accelerations(force, pos, vel, m, acc, False)
    return sample_loop(advance6, grid_time, state, force, dt, work, t0, n_done, targets, record, out)


@jit_inline
def advance_chaos6(pos, vel, acc, m, force, dt, work, t0, n_done, n_to, tangent, megno):
    """:func:`advance_dkd_chaos` with the order-6 tables."""
    return advance_dkd_chaos(pos, vel, acc, m, force, dt, t0, n_done, n_to, DRIFTS6, KICKS6, tangent, megno)


@jit
def run_chaos6(state, tangent, force, dt, work, t0, n_done, targets, record, out, indicators, megno):
    """:func:`~orbitsim.integrators.base.chaos_sample_loop` of :func:`advance_chaos6`."""
    return chaos_sample_loop(advance_chaos6, grid_time, state, tangent, force, dt, work, t0, n_done, targets,
                             record, out, indicators, megno)


@jit
def run_watched6(state, force, dt, work, t0, n_done, targets, record, out, watch):
    """:func:`run6` one step at a time with the events watch after each (:mod:`orbitsim.events`)."""
    return watched_run(advance6, state, force, dt, work, t0, n_done, targets, record, out, watch)


LEAPFROG6 = Integrator(
    spec=IntegratorSpec(
        name="leapfrog6",
        aliases=(),
        order=6,
        symplectic=True,
        reversible=True,
        force_evals=9,
        work_slots=0,
        fsal=False,
        summary="6th-order 9-stage symmetric composition of the DKD leapfrog",
        reference="S. Blanes & F. Casas (2016), A Concise Introduction to Geometric Numerical Integration, "
        "CRC Press; REBOUND leapfrog order 6",
        module=__name__,
    ),
    step=step6,
    run=run6,
    run_watched=run_watched6,
    run_chaos=run_chaos6,
    kicks=KICKS6,
    drifts=DRIFTS6,
)


# -- order 8: leapfrog8 -------------------------------------------------------------------------

KICKS8 = LEAPFROG8_WEIGHTS
DRIFTS8 = drift_coefficients(KICKS8)


@jit_inline
def advance8(pos, vel, acc, m, force, dt, work, t0, n_done, n_to):
    """Steps from ``n_done`` to ``n_to`` of order 8 (:func:`advance_dkd` with its tables)."""
    advance_dkd(pos, vel, acc, m, force, dt, n_to - n_done, DRIFTS8, KICKS8)
    return n_to, True


@jit
def step8(pos, vel, acc, m, force, dt, work):
    """One leapfrog8 step of size ``dt`` (17 force evaluations), in place."""
    advance_dkd(pos, vel, acc, m, force, dt, 1, DRIFTS8, KICKS8)


@jit
def run8(state, force, dt, work, t0, n_done, targets, record, out):
    """:func:`~orbitsim.integrators.base.sample_loop` of :func:`advance8`; a forced run's ``acc``
    afresh first (:func:`~orbitsim.forces.hooks.refresh_accelerations`)."""
    pos, vel, acc, m = state
    refresh_accelerations(force, pos, vel, m, acc, False)
    return sample_loop(advance8, grid_time, state, force, dt, work, t0, n_done, targets, record, out)


@jit_inline
def advance_chaos8(pos, vel, acc, m, force, dt, work, t0, n_done, n_to, tangent, megno):
    """:func:`advance_dkd_chaos` with the order-8 tables."""
    return advance_dkd_chaos(pos, vel, acc, m, force, dt, t0, n_done, n_to, DRIFTS8, KICKS8, tangent, megno)


@jit
def run_chaos8(state, tangent, force, dt, work, t0, n_done, targets, record, out, indicators, megno):
    """:func:`~orbitsim.integrators.base.chaos_sample_loop` of :func:`advance_chaos8`."""
    return chaos_sample_loop(advance_chaos8, grid_time, state, tangent, force, dt, work, t0, n_done, targets,
                             record, out, indicators, megno)


@jit
def run_watched8(state, force, dt, work, t0, n_done, targets, record, out, watch):
    """:func:`run8` one step at a time with the events watch after each (:mod:`orbitsim.events`)."""
    return watched_run(advance8, state, force, dt, work, t0, n_done, targets, record, out, watch)


LEAPFROG8 = Integrator(
    spec=IntegratorSpec(
        name="leapfrog8",
        aliases=(),
        order=8,
        symplectic=True,
        reversible=True,
        force_evals=17,
        work_slots=0,
        fsal=False,
        summary="8th-order 17-stage symmetric composition of the DKD leapfrog",
        reference="S. Blanes & F. Casas (2016), A Concise Introduction to Geometric Numerical Integration, "
        "CRC Press, p. 91; REBOUND leapfrog order 8",
        module=__name__,
    ),
    step=step8,
    run=run8,
    run_watched=run_watched8,
    run_chaos=run_chaos8,
    kicks=KICKS8,
    drifts=DRIFTS8,
)

#: REBOUND's ``order`` -> the record with its coefficients (the names are :data:`.rebound_names.LEAPFROG_ORDERS`).
ORDERS: dict[int, Integrator] = {2: LEAPFROG, 4: LEAPFROG4, 6: LEAPFROG6, 8: LEAPFROG8}
