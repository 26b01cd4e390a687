"""Maps over a massless body: the massive bodies are stepped once, every pixel steps only its test body.

A map that varies a massless body (the bundled ``jupiter_saturn`` map moves a test planet between
Jupiter and Saturn) gives every pixel the same massive bodies: a body of mass 0 pulls nothing, its
Jacobi weight ``m / M`` is 0, and every term it adds to a massive body is ``0 * x``, a signed zero that
leaves the sum's bits alone. So in :func:`orbitsim.ensemble.kernels.run_system_variational` the massive
bodies and their tangent vectors take the same bits in every pixel, whatever the test body does (as
long as it stays finite, and it stops its pixel the step it does not). This module steps them once
per block of steps (:func:`massive_block`) and keeps, per step, the few numbers the test body reads
from them (the record below); every pixel then steps only its test body (:func:`pixel_block`),
with the same operations in the same order as the whole-system step, so its bits are those of
:func:`run_system_variational` (tests/ensemble/test_restricted.py compares them bit for bit).

The tangent vector of a pixel is ``(s * delta_massive, delta_test)``: its massive part is the shared
one times ``s = 2^(-200 h)``, ``h`` the pixel's rescalings (:func:`orbitsim.chaos.megno.rescale_power_of_two`
scales the whole vector by 2^-200). Scaling by a power of two commutes with every rounding of the
linear tangent map, so ``s * shared`` is the value the whole-system step holds (until it would be
subnormal, where it is at most 2^-1022 of the test body's part and moves none of its bits).

Conditions (:func:`restricted_applies`): the test body is the last body, massless in every system,
and the massive bodies' masses, start states, radii and initial variation are the same bits in every
system. A massive tangent vector that grows past 2^300 (a chaotic massive system) ends the shortcut:
:func:`run_restricted_variational` returns False and the caller runs the whole-system kernel.

Why one module: the shared pass, the record it writes and the pixel step that reads it are one
contract (the record's columns), and the pixel step is one long function on purpose: it is the
whole-system step restricted to one body, operation for operation, and reads best beside it.

Record of step ``s`` (row ``s`` of ``rec``, columns below; ``q = N - 1`` massive bodies): the interior
centres of mass of the start state (the test body's Jacobi origin), the centre of mass after the
first half drift and at the end (its inertial origin), the Jacobi-transform centres of mass of the
kick's accelerations, the massive bodies' positions at the kick and their state at the end of the step.
"""

from __future__ import annotations

import math

import numpy as np
from numba import prange

from orbitsim._jit import jit, jit_inline, jit_parallel_exact
from orbitsim.chaos.megno import (
    RESCALE_ABOVE,
    MegnoState,
    deltad_delta_sums,
    lyapunov,
    megno_update,
    megno_value,
    rescale_power_of_two,
    tangent_norm2,
)
from orbitsim.ensemble.kernels import _energy, _stop_reason, jacobi_elements_ae, track_orbit
from orbitsim.ensemble.status import (
    COLLIDED,
    COMPLETE,
    DELTA_A,
    DIVERGED,
    ENERGY_ERROR,
    ESCAPED,
    LYAPUNOV,
    MAX_E,
    MEGNO,
    SURVIVAL_TIME,
)
from orbitsim.integrators.wisdom_holman.tangent import (
    interaction_kick_tangent,
    kepler_drift_tangent,
    kepler_step_tangent,
)
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
def _scaled_massive(rec, s, q, scale, whole):
    """The massive bodies' tangent state after step ``s`` times ``scale`` into columns 0..q-1 of ``whole``
    (3, 3, N): dpos, dvel, dacc, the values the whole-system step holds for a pixel rescaled so far."""
    for c in range(3):
        for i in range(q):
            whole[0, c, i] = scale * _get(rec, s, V_DPOS, q, c, i)
            whole[1, c, i] = scale * _get(rec, s, V_DVEL, q, c, i)
            whole[2, c, i] = scale * _get(rec, s, V_DACC, q, c, i)


@jit_inline
def _get(rec, s, block, q, c, i):
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
        tangent_accelerations(pos, m, G, eps2, dpos, dacc, ALL_PAIRS)
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


@jit_inline
def _tangent_row(x, y, z, dx_t, dy_t, dz_t, rec, s, pos_block, dpos_block, q, m, G, eps2, scale):
    """Row p (the test body, last) of :func:`orbitsim.physics.tangent.tangent_accelerations` against the
    recorded massive positions and (scaled) tangent positions: the same terms in the same order."""
    dax_sum = 0.0
    day_sum = 0.0
    daz_sum = 0.0
    for j in range(q):
        dx = x - _get(rec, s, pos_block, q, 0, j)
        dy = y - _get(rec, s, pos_block, q, 1, j)
        dz = z - _get(rec, s, pos_block, q, 2, j)
        r2 = dx * dx + dy * dy + dz * dz + eps2
        r = np.sqrt(r2)
        r3inv = 1.0 / (r2 * r)
        r5inv = 3.0 * r3inv / r2
        ddx = dx_t - scale * _get(rec, s, dpos_block, q, 0, j)
        ddy = dy_t - scale * _get(rec, s, dpos_block, q, 1, j)
        ddz = dz_t - scale * _get(rec, s, dpos_block, q, 2, j)
        dxdx = dx * dx * r5inv - r3inv
        dydy = dy * dy * r5inv - r3inv
        dzdz = dz * dz * r5inv - r3inv
        dxdy = dx * dy * r5inv
        dxdz = dx * dz * r5inv
        dydz = dy * dz * r5inv
        dax = ddx * dxdx + ddy * dxdy + ddz * dxdz
        day = ddx * dxdy + ddy * dydy + ddz * dydz
        daz = ddx * dxdz + ddy * dydz + ddz * dzdz
        gmj = G * m[j]
        dax_sum += gmj * dax
        day_sum += gmj * day
        daz_sum += gmj * daz
    return dax_sum, day_sum, daz_sum


@jit_inline
def _test_stop(rec, s, q, t, radius, radii, escape_r2, check_collisions):
    """_stop_reason of the whole system after step ``s``, from the massive bodies' record and the test
    body's position ``t`` (3, 1): the same precedence (diverged, escaped, collided)."""
    massive = rec[s, R_STATUS]
    if not (math.isfinite(t[0, 0]) and math.isfinite(t[1, 0]) and math.isfinite(t[2, 0])) or massive == DIVERGED:
        return DIVERGED
    if massive == ESCAPED:
        return ESCAPED
    dx = t[0, 0] - _get(rec, s, V_POS, q, 0, 0)
    dy = t[1, 0] - _get(rec, s, V_POS, q, 1, 0)
    dz = t[2, 0] - _get(rec, s, V_POS, q, 2, 0)
    if dx * dx + dy * dy + dz * dz > escape_r2:
        return ESCAPED
    if massive == COLLIDED:
        return COLLIDED
    if check_collisions:
        for i in range(q):
            reach = radii[i] + radius
            if reach <= 0.0:
                continue
            dx = t[0, 0] - _get(rec, s, V_POS, q, 0, i)
            dy = t[1, 0] - _get(rec, s, V_POS, q, 1, i)
            dz = t[2, 0] - _get(rec, s, V_POS, q, 2, i)
            if dx * dx + dy * dy + dz * dz < reach * reach:
                return COLLIDED
    return COMPLETE


@jit_inline
def pixel_block(tp, tv, tdp, tdv, jp, jv, djp, djv, whole, q, m, G, eps2, dt, mu_t, mu_one, rec, n_rec, step0,
                t_start, halvings, megno, a0, max_e, delta_a, radius, radii, escape_r2, check_collisions):
    """Steps ``step0 .. step0 + n_rec - 1`` of one pixel's test body (state ``tp``, ``tv``, tangent ``tdp``,
    ``tdv``, inertial, each (3, 1); ``jp``.. (3, 1) and ``whole`` (3, 3, N) scratch) against the record. Returns
    ``(steps done in the block, status, halvings, megno, max_e, delta_a)``; a status other than
    COMPLETE stops the pixel at that step; :data:`KEPLER_FAILED`: a Kepler drift failed, and the state
    is left as it was before the step. ``mu_one`` (1,) holds ``mu_t`` for track_orbit."""
    half = 0.5 * dt
    scale = 2.0 ** (-200 * halvings)
    for s in range(n_rec):
        # to Jacobi coordinates: the test body is last, relative to the massive bodies' centre of mass
        for c in range(3):
            jp[c, 0] = tp[c, 0] - rec[s, R_COM_POS + c]
            jv[c, 0] = tv[c, 0] - rec[s, R_COM_VEL + c]
            djp[c, 0] = tdp[c, 0] - scale * rec[s, R_COM_DPOS + c]
            djv[c, 0] = tdv[c, 0] - scale * rec[s, R_COM_DVEL + c]
        if rec[s, R_STATUS] == KEPLER_FAILED:
            return s + 1, KEPLER_FAILED, halvings, megno, max_e, delta_a
        if kepler_drift_tangent(jp, jv, djp, djv, 0, mu_t, half) != KEPLER_OK:
            return s + 1, KEPLER_FAILED, halvings, megno, max_e, delta_a
        # the kick (interaction_kick, then interaction_kick_tangent's part for body p)
        ix = jp[0, 0] + rec[s, R_HALF_COM]
        iy = jp[1, 0] + rec[s, R_HALF_COM + 1]
        iz = jp[2, 0] + rec[s, R_HALF_COM + 2]
        ax = 0.0
        ay = 0.0
        az = 0.0
        for i in range(q):
            dx = ix - _get(rec, s, V_KICK_POS, q, 0, i)
            dy = iy - _get(rec, s, V_KICK_POS, q, 1, i)
            dz = iz - _get(rec, s, V_KICK_POS, q, 2, i)
            r2 = dx * dx + dy * dy + dz * dz + eps2
            g_r3 = G / (r2 * math.sqrt(r2))
            mi = m[i] * g_r3
            ax -= mi * dx
            ay -= mi * dy
            az -= mi * dz
        ax += 0.0  # the test body's own row of the pair loop adds its (empty) sum
        ay += 0.0
        az += 0.0
        x, y, z = jp[0, 0], jp[1, 0], jp[2, 0]
        ax = ax - rec[s, R_ACC_COM]
        ay = ay - rec[s, R_ACC_COM + 1]
        az = az - rec[s, R_ACC_COM + 2]
        r2 = x * x + y * y + z * z
        k = mu_t / (r2 * math.sqrt(r2))
        ax += k * x
        ay += k * y
        az += k * z
        jv[0, 0] += dt * ax
        jv[1, 0] += dt * ay
        jv[2, 0] += dt * az
        dix = djp[0, 0] + scale * rec[s, R_HALF_DCOM]
        diy = djp[1, 0] + scale * rec[s, R_HALF_DCOM + 1]
        diz = djp[2, 0] + scale * rec[s, R_HALF_DCOM + 2]
        dax, day, daz = _tangent_row(ix, iy, iz, dix, diy, diz, rec, s, V_KICK_POS, V_KICK_DPOS, q, m, G, eps2, scale)
        dax = dax - scale * rec[s, R_DACC_COM]
        day = day - scale * rec[s, R_DACC_COM + 1]
        daz = daz - scale * rec[s, R_DACC_COM + 2]
        rj2i = 1.0 / (x * x + y * y + z * z)
        rj3iM = math.sqrt(rj2i) * rj2i * mu_t
        prefac1 = dt * rj3iM
        rdr = djp[0, 0] * x + djp[1, 0] * y + djp[2, 0] * z
        prefac2 = -dt * 3.0 * rdr * (rj3iM * rj2i)
        djv[0, 0] += prefac1 * djp[0, 0] + prefac2 * x
        djv[1, 0] += prefac1 * djp[1, 0] + prefac2 * y
        djv[2, 0] += prefac1 * djp[2, 0] + prefac2 * z
        djv[0, 0] += dt * dax
        djv[1, 0] += dt * day
        djv[2, 0] += dt * daz
        if kepler_drift_tangent(jp, jv, djp, djv, 0, mu_t, half) != KEPLER_OK:
            return s + 1, KEPLER_FAILED, halvings, megno, max_e, delta_a
        for c in range(3):
            tp[c, 0] = jp[c, 0] + rec[s, R_END_COM + c]
            tv[c, 0] = jv[c, 0] + rec[s, R_END_VCOM + c]
            tdp[c, 0] = djp[c, 0] + scale * rec[s, R_END_DCOM + c]
            tdv[c, 0] = djv[c, 0] + scale * rec[s, R_END_DVCOM + c]
        # MEGNO's read (megno_after_step): the tangent row at the end, deltad_delta body by body
        t = t_start + (step0 + s + 1) * dt
        dax, day, daz = _tangent_row(tp[0, 0], tp[1, 0], tp[2, 0], tdp[0, 0], tdp[1, 0], tdp[2, 0], rec, s, V_POS,
                                     V_DPOS, q, m, G, eps2, scale)
        # the whole tangent state in ``whole`` (dpos, dvel, dacc rows; the test body in column q, the
        # massive bodies, scaled, in columns 0..q-1 only where they are read)
        for c in range(3):
            whole[0, c, q] = tdp[c, 0]
            whole[1, c, q] = tdv[c, 0]
        whole[2, 0, q], whole[2, 1, q], whole[2, 2, q] = dax, day, daz
        if halvings == 0:  # scale 1: the massive part is the record's, the same bits
            deltad, delta2 = rec[s, R_DELTAD_M], rec[s, R_DELTA2_M]
        else:
            _scaled_massive(rec, s, q, scale, whole)
            deltad, delta2 = deltad_delta_sums(whole[0, :, :q], whole[1, :, :q], whole[2, :, :q], 0.0, 0.0)
        deltad, delta2 = deltad_delta_sums(whole[0, :, q:], whole[1, :, q:], whole[2, :, q:], deltad, delta2)
        dY = dt * 2.0 * (t - megno.initial_t) * (deltad / delta2)
        megno = megno_update(megno, t, dY, dt)
        # |delta|^2 in another order is within 1e-14 of rescale_power_of_two's sum: only a vector near the
        # bar needs that exact sum (a nan skips both, as it skips the exact test)
        if rec[s, R_NORM2_M] * (scale * scale) + tangent_norm2(tdp, tdv) > RESCALE_ABOVE * (1.0 - 1e-9):
            _scaled_massive(rec, s, q, scale, whole)
            count = rescale_power_of_two(whole[0], whole[1])  # the whole vector, as the whole-system step
            if count > 0:
                for c in range(3):
                    tdp[c, 0] = whole[0, c, q]
                    tdv[c, 0] = whole[1, c, q]
                halvings += count
                scale = 2.0 ** (-200 * halvings)
        # track_orbit reads the test body's Jacobi state at the end of the step
        max_e, delta_a = track_orbit(jp, jv, mu_one, 0, a0, max_e, delta_a)
        status = _test_stop(rec, s, q, tp, radius, radii, escape_r2, check_collisions)
        if status != COMPLETE:
            return s + 1, status, halvings, megno, max_e, delta_a
    return n_rec, COMPLETE, halvings, megno, max_e, delta_a


@jit_inline
def _finish_pixel(k, status, n_steps_done, t_start, dt, megno, max_e, delta_a, e0, pos, vel, m, G, rows, out):
    """A stopped (or finished) pixel's indicator row, as :func:`run_system_variational` writes it; ``pos``,
    ``vel`` (3, N) hold its whole state at the stop."""
    t = t_start + n_steps_done * dt
    out[k, SURVIVAL_TIME] = t
    out[k, MAX_E] = max_e
    out[k, DELTA_A] = delta_a
    out[k, MEGNO] = megno_value(megno, t)
    out[k, LYAPUNOV] = lyapunov(megno)
    if status == DIVERGED:
        out[k, ENERGY_ERROR] = np.nan
    else:
        out[k, ENERGY_ERROR] = abs((_energy(pos, vel, m, G, rows) - e0) / e0)


@jit_inline
def _place(pos, vel, k, q, mpos, mvel, rec, row, tp, tv):
    """Whole state of pixel ``k``: the massive bodies from ``rec`` row ``row`` (or ``mpos``, ``mvel`` when
    ``row`` < 0) and the test body (column q) from ``tp``, ``tv``."""
    for c in range(3):
        for i in range(q):
            if row < 0:
                pos[k, c, i] = mpos[c, i]
                vel[k, c, i] = mvel[c, i]
            else:
                pos[k, c, i] = _get(rec, row, V_POS, q, c, i)
                vel[k, c, i] = _get(rec, row, V_VEL, q, c, i)
        pos[k, c, q] = tp[c, 0]
        vel[k, c, q] = tv[c, 0]


@jit_parallel_exact
def run_restricted_variational(pos, vel, dpos, dvel, m, force, dt, t_start, n_steps, escape_r2, radii,
                               check_collisions, watch, weights, mu, rows, status, steps, out):
    """:func:`orbitsim.ensemble.kernels.run_ensemble_variational` for systems whose last body is massless
    and whose other bodies (and their variations) are the same in every system (module docstring).
    Same arguments and results, less its scratch; ``watch`` must be the last body. Returns False, having
    written nothing meaningful, where the shortcut gave up (the caller then runs the whole-system kernel)."""
    n_sys = pos.shape[0]
    n = pos.shape[2]
    q = n - 1
    G = force.G
    eps2 = force.eps2
    mpos = pos[0, :, :q].copy()
    mvel = vel[0, :, :q].copy()
    mdpos = dpos[0, :, :q].copy()
    mdvel = dvel[0, :, :q].copy()
    mprev_pos = mpos.copy()
    mprev_vel = mvel.copy()
    mm = m[0, :q].copy()
    mweights = weights[0, :q].copy()
    mmu = mu[0, :q].copy()
    mradii = radii[0, :q].copy()
    mscratch = np.zeros((8, 3, q))
    mu_t = mu[0, q]
    mu_one = np.full(1, mu_t)
    radius = radii[0, q]
    rec = np.zeros((BLOCK_STEPS, record_columns(q)))
    state = np.zeros((n_sys, 8, 3, 1))  # tp, tv, tdp, tdv, then the Jacobi scratch jp, jv, djp, djv
    whole = np.zeros((n_sys, 3, 3, n))  # each pixel's whole tangent state, for MEGNO's sums and the rescaling
    sums = np.zeros((n_sys, 7))  # MegnoState's float fields
    counts = np.zeros((n_sys, 2), dtype=np.int64)  # MegnoState.n, halvings
    track = np.zeros((n_sys, 4))  # e0, a0, max_e, delta_a
    active = np.ones(n_sys, dtype=np.bool_)
    jfull = np.zeros((n_sys, 2, 3, n))
    for k in prange(n_sys):
        track[k, 0] = _energy(pos[k], vel[k], m[k], G, rows)
        inertial_to_jacobi(pos[k], weights[k], jfull[k, 0])
        inertial_to_jacobi(vel[k], weights[k], jfull[k, 1])
        a0, e_start = jacobi_elements_ae(jfull[k, 0], jfull[k, 1], mu[k], watch)
        track[k, 1] = a0
        track[k, 2] = e_start
        for c in range(3):
            state[k, 0, c, 0] = pos[k, c, q]
            state[k, 1, c, 0] = vel[k, c, q]
            state[k, 2, c, 0] = dpos[k, c, q]
            state[k, 3, c, 0] = dvel[k, c, q]
        sums[k, 6] = t_start
    done = 0
    while done < n_steps:
        for c in range(3):
            for i in range(q):
                mprev_pos[c, i] = mpos[c, i]
                mprev_vel[c, i] = mvel[c, i]
        recorded, ok = massive_block(mpos, mvel, mdpos, mdvel, mm, force, dt, mweights, mmu, mscratch, escape_r2,
                                     mradii, check_collisions, min(BLOCK_STEPS, n_steps - done), rec)
        if not ok:
            return False
        for k in prange(n_sys):
            if not active[k]:
                continue
            st = state[k]
            megno = MegnoState(sums[k, 0], sums[k, 1], sums[k, 2], sums[k, 3], sums[k, 4], sums[k, 5], sums[k, 6],
                               counts[k, 0])
            n_done, code, halvings, megno, max_e, delta_a = pixel_block(
                st[0], st[1], st[2], st[3], st[4], st[5], st[6], st[7], whole[k], q, m[k], G, eps2, dt, mu_t, mu_one,
                rec,
                recorded, done, t_start, counts[k, 1], megno, track[k, 1], track[k, 2], track[k, 3], radius, radii[k],
                escape_r2, check_collisions)
            sums[k, 0], sums[k, 1], sums[k, 2], sums[k, 3] = megno.ys, megno.yss, megno.cov_yt, megno.var_t
            sums[k, 4], sums[k, 5], sums[k, 6] = megno.mean_t, megno.mean_y, megno.initial_t
            counts[k, 0] = megno.n
            counts[k, 1] = halvings
            track[k, 2] = max_e
            track[k, 3] = delta_a
            if code == COMPLETE:
                continue
            active[k] = False
            steps[k] = done + n_done
            row = n_done - 1
            if code == KEPLER_FAILED:
                code = DIVERGED
                row = n_done - 2  # the state before the failed step
                _place(pos, vel, k, q, mprev_pos, mprev_vel, rec, row, st[0], st[1])
            else:
                _place(pos, vel, k, q, mpos, mvel, rec, row, st[0], st[1])
            status[k] = code
            _finish_pixel(k, code, steps[k], t_start, dt, megno, max_e, delta_a, track[k, 0], pos[k], vel[k], m[k],
                          G, rows, out)
        done += recorded
        if recorded == 0:
            break
    for k in prange(n_sys):
        if not active[k]:
            continue
        st = state[k]
        megno = MegnoState(sums[k, 0], sums[k, 1], sums[k, 2], sums[k, 3], sums[k, 4], sums[k, 5], sums[k, 6],
                           counts[k, 0])
        _place(pos, vel, k, q, mpos, mvel, rec, -1, st[0], st[1])
        steps[k] = n_steps
        status[k] = COMPLETE
        _finish_pixel(k, COMPLETE, n_steps, t_start, dt, megno, track[k, 2], track[k, 3], track[k, 0], pos[k],
                      vel[k], m[k], G, rows, out)
    return True


def restricted_applies(masses: np.ndarray, positions: np.ndarray, velocities: np.ndarray, radii: np.ndarray,
                       dpos: np.ndarray, dvel: np.ndarray, watch: int) -> bool:
    """Whether :func:`run_restricted_variational` can run these systems: N >= 3, the last body massless in
    every system and watched, and the other bodies' masses, states, radii and variations the same bits."""
    n = masses.shape[1]
    if n < 3 or watch != n - 1 or (masses[:, n - 1] != 0.0).any():
        return False

    def same(a: np.ndarray) -> bool:
        head = np.ascontiguousarray(a[..., : n - 1]).view(np.uint64)
        return bool((head == head[:1]).all())

    return all(same(a) for a in (masses, positions, velocities, radii, dpos, dvel))
