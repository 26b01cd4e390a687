"""The record of a map's shared massive bodies: stepped once per block, read by every pixel.

:mod:`orbitsim.ensemble.restricted` explains the shortcut: in a map over a massless body every pixel has
the same massive bodies, to the bit. :func:`massive_block` steps them (and their tangent vectors) with
the whole-system step's operations and writes, per step, the few numbers a pixel's test body reads from
them: row ``s`` of ``rec``, the columns below (``q = N - 1`` massive bodies). The interior centres of mass
of the start state (the test body's Jacobi origin), the centre of mass after the first half drift and
at the end (its inertial origin), the Jacobi-transform centres of mass of the kick's accelerations, the
massive bodies' positions at the kick and their state at the end of the step.
:mod:`orbitsim.ensemble.lanes` reads it, LANES pixels at a time.
"""

from __future__ import annotations

import numpy as np

from orbitsim._jit import jit, jit_inline
from orbitsim.chaos.megno import deltad_delta_sums, tangent_norm2
from orbitsim.ensemble.kernels import _stop_reason
from orbitsim.ensemble.status import COMPLETE
from orbitsim.integrators.wisdom_holman.tangent import interaction_kick_tangent, kepler_step_tangent
from orbitsim.physics.coordinates import inertial_to_jacobi, jacobi_to_inertial
from orbitsim.physics.kepler import KEPLER_OK
from orbitsim.physics.tangent import ALL_PAIRS, tangent_accelerations

#: Columns of a step's record: centres of mass (3 each), then blocks of (3, q) massive-body vectors.
R_COM_POS, R_COM_VEL, R_COM_DPOS, R_COM_DVEL = 0, 3, 6, 9  # interior centres of mass at the start
R_HALF_COM, R_HALF_DCOM = 12, 15  # Jacobi column 0 (and its variation) after the first half drift
R_ACC_COM, R_DACC_COM = 18, 21  # centres of mass of the Jacobi transform of the kick's (tangent) accelerations
R_END_COM, R_END_VCOM, R_END_DCOM, R_END_DVCOM = 24, 27, 30, 33  # Jacobi column 0 at the end
R_STATUS = 36  # the massive bodies' stop reason (COMPLETE, ...), or -1: a Kepler failure in the step
# the massive bodies' part of deltad_delta's two sums (body by body, from 0: a pixel never rescaled starts
# from them) and of rescale_power_of_two's |delta|^2, unscaled
R_DELTAD_M, R_DELTA2_M, R_NORM2_M = 37, 38, 39
R_VECTORS = 40
#: The (3, q) blocks after R_VECTORS, in this order.
V_KICK_POS, V_KICK_DPOS, V_POS, V_VEL, V_DPOS, V_DVEL, V_DACC = range(7)
N_VECTOR_BLOCKS = 7
#: Steps recorded per block of the shared pass.
BLOCK_STEPS = 512
#: |delta_massive|^2 beyond which the shortcut gives up (the shared part is never rescaled).
SHARED_NORM2_LIMIT = 2.0 ** 600
KEPLER_FAILED = -1


@jit_inline
def record_columns(q):
    """Columns of a step's record for ``q`` massive bodies."""
    return R_VECTORS + N_VECTOR_BLOCKS * 3 * q


@jit_inline
def _put(rec, s, block, q, src):
    base = R_VECTORS + block * 3 * q
    for c in range(3):
        for i in range(q):
            rec[s, base + c * q + i] = src[c, i]


@jit_inline
def _put_com(rec, s, column, src):
    """Column 0 of ``src`` (3, q), a centre of mass, into ``rec[s, column:column + 3]``."""
    for c in range(3):
        rec[s, column + c] = src[c, 0]


@jit_inline
def scaled_massive_tangent(rec, s, q, scale, whole):
    """The massive bodies' tangent state after step ``s`` times ``scale`` into columns 0..q-1 of ``whole``
    (3, 3, N): dpos, dvel, dacc, the values the whole-system step holds for a pixel rescaled so far."""
    for c in range(3):
        for i in range(q):
            whole[0, c, i] = scale * record_value(rec, s, V_DPOS, q, c, i)
            whole[1, c, i] = scale * record_value(rec, s, V_DVEL, q, c, i)
            whole[2, c, i] = scale * record_value(rec, s, V_DACC, q, c, i)


@jit_inline
def record_value(rec, s, block, q, c, i):
    return rec[s, R_VECTORS + block * 3 * q + c * q + i]


@jit
def massive_block(pos, vel, dpos, dvel, m, force, dt, weights, mu, scratch, escape_r2, radii, check_collisions,
                  n_steps, rec):
    """Step the massive system (pos, vel, dpos, dvel (3, q)) up to ``n_steps`` times, recording each step
    into ``rec``; stops after the first step whose status is not COMPLETE. Returns (steps recorded, ok):
    ok False when the shared tangent vector outgrew :data:`SHARED_NORM2_LIMIT`."""
    jpos, jvel, djpos, djvel = scratch[0], scratch[1], scratch[2], scratch[3]
    ipos, acc, dipos, dacc = scratch[4], scratch[5], scratch[6], scratch[7]
    q = pos.shape[1]
    G = force.G
    eps2 = force.eps2
    half = 0.5 * dt
    for s in range(n_steps):
        inertial_to_jacobi(pos, weights, jpos)
        inertial_to_jacobi(vel, weights, jvel)
        inertial_to_jacobi(dpos, weights, djpos)
        inertial_to_jacobi(dvel, weights, djvel)
        _put_com(rec, s, R_COM_POS, jpos)
        _put_com(rec, s, R_COM_VEL, jvel)
        _put_com(rec, s, R_COM_DPOS, djpos)
        _put_com(rec, s, R_COM_DVEL, djvel)
        status, _ = kepler_step_tangent(jpos, jvel, djpos, djvel, mu, half)
        if status != KEPLER_OK:
            rec[s, R_STATUS] = KEPLER_FAILED
            return s + 1, True
        _put_com(rec, s, R_HALF_COM, jpos)
        _put_com(rec, s, R_HALF_DCOM, djpos)
        interaction_kick_tangent(jpos, jvel, djpos, djvel, m, G, eps2, dt, weights, mu, ipos, acc, dipos, dacc, force)
        _put(rec, s, V_KICK_POS, q, ipos)
        _put(rec, s, V_KICK_DPOS, q, dipos)
        for c in range(3):
            # the kick's Jacobi transform left acc[c, 0] inertial and acc[c, 1:] relative: its centre
            # of mass again, by the same additions; inertial_to_jacobi left dacc's in column 0
            com = acc[c, 0]
            for i in range(1, q):
                com = com + weights[i] * acc[c, i]
            rec[s, R_ACC_COM + c] = com
            rec[s, R_DACC_COM + c] = dacc[c, 0]
        status, _ = kepler_step_tangent(jpos, jvel, djpos, djvel, mu, half)
        if status != KEPLER_OK:
            rec[s, R_STATUS] = KEPLER_FAILED
            return s + 1, True
        _put_com(rec, s, R_END_COM, jpos)
        _put_com(rec, s, R_END_VCOM, jvel)
        _put_com(rec, s, R_END_DCOM, djpos)
        _put_com(rec, s, R_END_DVCOM, djvel)
        jacobi_to_inertial(jpos, weights, pos)
        jacobi_to_inertial(jvel, weights, vel)
        jacobi_to_inertial(djpos, weights, dpos)
        jacobi_to_inertial(djvel, weights, dvel)
        tangent_accelerations(pos, m, G, eps2, dpos, dacc, np.int64(ALL_PAIRS))
        _put(rec, s, V_POS, q, pos)
        _put(rec, s, V_VEL, q, vel)
        _put(rec, s, V_DPOS, q, dpos)
        _put(rec, s, V_DVEL, q, dvel)
        _put(rec, s, V_DACC, q, dacc)
        norm2 = tangent_norm2(dpos, dvel)
        if not norm2 < SHARED_NORM2_LIMIT:
            return s + 1, False
        rec[s, R_NORM2_M] = norm2
        rec[s, R_DELTAD_M], rec[s, R_DELTA2_M] = deltad_delta_sums(dpos, dvel, dacc, 0.0, 0.0)
        status = _stop_reason(pos, radii, escape_r2, check_collisions)
        rec[s, R_STATUS] = status
        if status != COMPLETE:
            return s + 1, True
    return n_steps, True
