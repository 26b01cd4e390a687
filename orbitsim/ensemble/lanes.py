"""A map's pixels in SIMD lanes: LANES test bodies stepped side by side, each with its own bits.

:mod:`orbitsim.ensemble.restricted` steps the shared massive bodies once and every pixel's test body
against their record (:mod:`orbitsim.ensemble.massive_record`). Here LANES pixels take each step together:
their states live in one flat array per group, row by row (:data:`TP` .. :data:`NROWS`, LANES numbers a
row), and every part of the step is a loop over the lanes with no branch that LLVM cannot turn into a
select, so it compiles to vector instructions (8 doubles in an AVX-512 register: a Kepler drift with its
tangent map took 22 ns per pixel against 125 ns one pixel at a time, measured in benchmarks/README.md).

Same bits as one pixel at a time: each lane performs the scalar step's operations in the same order
(no fastmath; a vector add or multiply rounds as the scalar one). Where the scalar step would branch,
the lanes take the common case and a lane that is not in it is redone by the scalar code itself:

* the Kepler drift (:func:`drift_lanes`): every lane Newton-iterates from the series start with the
  Stumpff series (:func:`orbitsim.physics.kepler_solver.setup_short`, ``stiefel_short``), a lane
  stopping when its residual settles; a lane that is not a short step, leaves the series range, does not
  settle in :data:`NEWTON_FAST_ITERATIONS` or needs a quartered G6 is redone from its start by
  :func:`orbitsim.integrators.wisdom_holman.tangent.kepler_drift_tangent`;
* MEGNO's sums of a rescaled pixel and the rescaling itself are per-lane scalar code (rare); the stop
  tests, like the rest, are loops over the lanes, each lane's status the scalar test's precedence.

A lane stops alone (its status and step in :data:`STOP_CODE`, :data:`STOP_STEP`); its state rows are then
no longer written, and it is no longer solved, so it cannot slow or poison the others.

Why one module: :func:`pixel_block_lanes` is one pixel's step (the whole-system step restricted to the
test body) written lane-wise, part for part, and reads best in one piece beside the scalar parts it
reuses; the drift, the kick and the tangent gravity are functions of their own (the first two called from
one place each, so that their long code is inlined and compiled once).
"""

from __future__ import annotations

import math

from orbitsim._jit import jit, jit_inline, jit_llvm_inline, wide_vectors
from orbitsim.chaos.megno import (
    RESCALE_ABOVE,
    MegnoState,
    deltad_delta_body,
    deltad_delta_sums,
    megno_update,
    rescale_power_of_two,
)
from orbitsim.ensemble.kernels import elements_ae
from orbitsim.ensemble.massive_record import (
    KEPLER_FAILED,
    R_ACC_COM,
    R_COM_DPOS,
    R_COM_DVEL,
    R_COM_POS,
    R_COM_VEL,
    R_DACC_COM,
    R_DELTA2_M,
    R_DELTAD_M,
    R_END_COM,
    R_END_DCOM,
    R_END_DVCOM,
    R_END_VCOM,
    R_HALF_COM,
    R_HALF_DCOM,
    R_NORM2_M,
    R_STATUS,
    V_DPOS,
    V_KICK_DPOS,
    V_KICK_POS,
    V_POS,
    record_value,
    scaled_massive_tangent,
)
from orbitsim.ensemble.status import COLLIDED, COMPLETE, DIVERGED, ESCAPED
from orbitsim.integrators.wisdom_holman.tangent import drift_derivative, kepler_drift_tangent, stiefel_g6_short
from orbitsim.physics.kepler import KEPLER_OK, fg_apply, lagrange_coefficients
from orbitsim.physics.kepler_solver import (
    NEWTON_FAST_ITERATIONS,
    STUMPFF_SERIES_MAX_Z,
    newton_terms,
    setup_short,
    stiefel_short,
)
from orbitsim.physics.tangent import pair_tangent_acceleration

#: Pixels per group: 24 doubles, three AVX-512 registers (six AVX2 ones). With 512-bit vectors
#: (:func:`orbitsim._jit.wide_vectors`) the 20 x 20 Jupiter-Saturn map's kernel took 0.68-0.70 s on one thread
#: against 0.71-0.72 with 16 lanes and 0.68-0.69 with 32 (whose 13 groups of its 400 pixels then split
#: unevenly over two threads); with 256-bit vectors 8 gained less than 16, 32 no more.
LANES = 24

# Rows of a group (each LANES numbers). The pixel's own state, kept between steps and blocks:
TP, TV, TDP, TDV = 0, 3, 6, 9  # the test body's inertial position, velocity and their tangent vector (3 rows each)
SCALE, HALVINGS = 12, 13  # 2^(-200 h) and h, the rescalings of its tangent vector
TRACK_A0, TRACK_MAX_E, TRACK_DELTA_A = 14, 15, 16  # track_orbit's start a, largest e, largest |a - a0| / |a0|
M_YS, M_YSS, M_COV_YT, M_VAR_T, M_MEAN_T, M_MEAN_Y = 17, 18, 19, 20, 21, 22  # MegnoState's sums
LIVE = 23  # 1: stepping; 0: stopped in this block (STOP_CODE, STOP_STEP), to be written out; -1: done or padding
STOP_CODE, STOP_STEP = 24, 25  # the status of a stopped lane and the steps of the block it took (the stop's included)
# Scratch of a step: the Jacobi state the drifts move (3 rows each), the kick's inertial position and
# accelerations, the drift's per-lane terms, the end-of-step tangent acceleration.
JP, JV, DJP, DJV = 26, 29, 32, 35
IPOS, ACC, DIPOS, DACC = 38, 41, 44, 47
K_R0, K_ETA0, K_ZETA0, K_BETA, K_X, K_R0I, K_PENDING, K_FAST, K_G1, K_G2, K_G3, K_R, K_DONE = range(50, 63)
K_DELTAD, K_DELTA2, K_RESCALE = 63, 64, 65  # MEGNO's sums over the massive bodies, and a lane to rescale
NROWS = 66


@jit_inline
def _row(g, row, lane):
    return g[row * LANES + lane]


@jit_llvm_inline
def drift_lanes(g, views, mu, dt):
    """Kepler drift by ``dt`` of the live lanes' Jacobi rows (JP, JV) and their tangent rows (DJP, DJV) about
    ``mu``, each with the bits of :func:`kepler_drift_tangent`; ``views`` are the (3, LANES) views of those
    rows. Returns the number of live lanes whose drift failed (their LIVE set to 0, STOP_CODE to
    KEPLER_FAILED; the caller sets STOP_STEP)."""
    wide_vectors()
    for lane in range(LANES):
        x, y, z = _row(g, JP, lane), _row(g, JP + 1, lane), _row(g, JP + 2, lane)
        vx, vy, vz = _row(g, JV, lane), _row(g, JV + 1, lane), _row(g, JV + 2, lane)
        r0 = math.sqrt(x * x + y * y + z * z)
        eta0 = x * vx + y * vy + z * vz
        r0i, zeta0, beta, X, short = setup_short(r0, vx * vx + vy * vy + vz * vz, eta0, mu, dt)
        live = _row(g, LIVE, lane) > 0.0
        g[K_R0 * LANES + lane] = r0
        g[K_ETA0 * LANES + lane] = eta0
        g[K_ZETA0 * LANES + lane] = zeta0
        g[K_BETA * LANES + lane] = beta
        g[K_X * LANES + lane] = X
        g[K_R0I * LANES + lane] = r0i
        g[K_PENDING * LANES + lane] = 1.0 if (short and live) else 0.0
        g[K_FAST * LANES + lane] = 1.0 if short else 0.0
    for _ in range(NEWTON_FAST_ITERATIONS):
        pending = 0
        for lane in range(LANES):
            r0, eta0, zeta0 = _row(g, K_R0, lane), _row(g, K_ETA0, lane), _row(g, K_ZETA0, lane)
            beta, X = _row(g, K_BETA, lane), _row(g, K_X, lane)
            _, G1, G2, G3, zz = stiefel_short(beta, X)
            dX, r, settled = newton_terms(r0, eta0, zeta0, dt, X, G1, G2, G3)
            p = _row(g, K_PENDING, lane) > 0.0
            outside = abs(zz) > STUMPFF_SERIES_MAX_Z  # the scalar solve would have used _stumpff_large
            g[K_G1 * LANES + lane] = G1 if p else _row(g, K_G1, lane)
            g[K_G2 * LANES + lane] = G2 if p else _row(g, K_G2, lane)
            g[K_G3 * LANES + lane] = G3 if p else _row(g, K_G3, lane)
            g[K_R * LANES + lane] = r if p else _row(g, K_R, lane)
            g[K_X * LANES + lane] = X + dX if (p and not settled) else X
            g[K_FAST * LANES + lane] = 0.0 if (p and outside) else _row(g, K_FAST, lane)
            still = p and not settled and not outside
            g[K_PENDING * LANES + lane] = 1.0 if still else 0.0
            pending |= still
        if not pending:
            break
    for lane in range(LANES):
        x, y, z = _row(g, JP, lane), _row(g, JP + 1, lane), _row(g, JP + 2, lane)
        vx, vy, vz = _row(g, JV, lane), _row(g, JV + 1, lane), _row(g, JV + 2, lane)
        dx, dy, dz = _row(g, DJP, lane), _row(g, DJP + 1, lane), _row(g, DJP + 2, lane)
        dvx, dvy, dvz = _row(g, DJV, lane), _row(g, DJV + 1, lane), _row(g, DJV + 2, lane)
        r0, eta0, zeta0 = _row(g, K_R0, lane), _row(g, K_ETA0, lane), _row(g, K_ZETA0, lane)
        beta, X, r0i = _row(g, K_BETA, lane), _row(g, K_X, lane), _row(g, K_R0I, lane)
        G1, G2, G3, r = _row(g, K_G1, lane), _row(g, K_G2, lane), _row(g, K_G3, lane), _row(g, K_R, lane)
        ri, f, gl, fd, gd = lagrange_coefficients(mu, dt, r0i, G1, G2, G3, r)
        nx, ny, nz, nvx, nvy, nvz = fg_apply(x, y, z, vx, vy, vz, f, gl, fd, gd)
        Gs0, Gs1, Gs2, Gs3, Gs4, Gs5, z6 = stiefel_g6_short(beta, X)
        ndx, ndy, ndz, ndvx, ndvy, ndvz = drift_derivative(x, y, z, vx, vy, vz, dx, dy, dz, dvx, dvy, dvz, mu, r0, r0i,
                                                           eta0, zeta0, beta, X, ri, f, gl, fd, gd,
                                                           Gs0, Gs1, Gs2, Gs3, Gs4, Gs5)
        ok = _row(g, K_FAST, lane) > 0.0 and _row(g, K_PENDING, lane) == 0.0 and abs(z6) <= 0.1
        ok = ok and _row(g, LIVE, lane) > 0.0
        g[(JP + 0) * LANES + lane] = nx if ok else x
        g[(JP + 1) * LANES + lane] = ny if ok else y
        g[(JP + 2) * LANES + lane] = nz if ok else z
        g[(JV + 0) * LANES + lane] = nvx if ok else vx
        g[(JV + 1) * LANES + lane] = nvy if ok else vy
        g[(JV + 2) * LANES + lane] = nvz if ok else vz
        g[(DJP + 0) * LANES + lane] = ndx if ok else dx
        g[(DJP + 1) * LANES + lane] = ndy if ok else dy
        g[(DJP + 2) * LANES + lane] = ndz if ok else dz
        g[(DJV + 0) * LANES + lane] = ndvx if ok else dvx
        g[(DJV + 1) * LANES + lane] = ndvy if ok else dvy
        g[(DJV + 2) * LANES + lane] = ndvz if ok else dvz
        g[K_DONE * LANES + lane] = 1.0 if ok else 0.0
    failed = 0
    jp, jv, djp, djv = views
    for lane in range(LANES):
        if _row(g, K_DONE, lane) > 0.0 or not _row(g, LIVE, lane) > 0.0:
            continue
        if kepler_drift_tangent(jp, jv, djp, djv, lane, mu, dt) != KEPLER_OK:
            g[LIVE * LANES + lane] = 0.0
            g[STOP_CODE * LANES + lane] = KEPLER_FAILED
            failed += 1
    return failed


@jit
def _tangent_row_lanes(g, pos_row, dpos_row, out_row, rec, s, pos_block, dpos_block, q, m, G, eps2):
    """Row p (the test body) of :func:`orbitsim.physics.tangent.tangent_accelerations` for every lane, against
    the recorded massive positions and (scaled) tangent positions, into rows ``out_row..+2``: the same terms in
    the same order as one pixel's (a sum over the massive bodies, in order)."""
    wide_vectors()
    for c in range(3):
        for lane in range(LANES):
            g[(out_row + c) * LANES + lane] = 0.0
    for j in range(q):
        px, py, pz = (record_value(rec, s, pos_block, q, 0, j), record_value(rec, s, pos_block, q, 1, j),
                      record_value(rec, s, pos_block, q, 2, j))
        qx, qy, qz = (record_value(rec, s, dpos_block, q, 0, j), record_value(rec, s, dpos_block, q, 1, j),
                      record_value(rec, s, dpos_block, q, 2, j))
        gmj = G * m[j]
        for lane in range(LANES):
            scale = _row(g, SCALE, lane)
            dax, day, daz = pair_tangent_acceleration(
                _row(g, pos_row, lane) - px, _row(g, pos_row + 1, lane) - py, _row(g, pos_row + 2, lane) - pz,
                _row(g, dpos_row, lane) - scale * qx, _row(g, dpos_row + 1, lane) - scale * qy,
                _row(g, dpos_row + 2, lane) - scale * qz, eps2)
            g[out_row * LANES + lane] += gmj * dax
            g[(out_row + 1) * LANES + lane] += gmj * day
            g[(out_row + 2) * LANES + lane] += gmj * daz


@jit_inline
def _stop_lanes(g, failed, s):
    """Mark the lanes that :func:`drift_lanes` just stopped with the block's step count ``s + 1``."""
    if failed == 0:
        return
    for lane in range(LANES):
        if _row(g, LIVE, lane) == 0.0 and _row(g, STOP_STEP, lane) == 0.0:
            g[STOP_STEP * LANES + lane] = s + 1.0


@jit_llvm_inline
def _kick_lanes(g, rec, s, q, m, G, eps2, dt, mu_t):
    """The interaction kick of every lane's test body and of its tangent vector (interaction_kick, then
    interaction_kick_tangent's part for the last body), against step ``s`` of the record."""
    wide_vectors()
    for c in range(3):
        com = rec[s, R_HALF_COM + c]
        for lane in range(LANES):
            g[(IPOS + c) * LANES + lane] = _row(g, JP + c, lane) + com
            g[(ACC + c) * LANES + lane] = 0.0
    for i in range(q):
        px, py, pz = (record_value(rec, s, V_KICK_POS, q, 0, i), record_value(rec, s, V_KICK_POS, q, 1, i),
                      record_value(rec, s, V_KICK_POS, q, 2, i))
        mass = m[i]
        for lane in range(LANES):
            dx = _row(g, IPOS, lane) - px
            dy = _row(g, IPOS + 1, lane) - py
            dz = _row(g, IPOS + 2, lane) - pz
            r2 = dx * dx + dy * dy + dz * dz + eps2
            g_r3 = G / (r2 * math.sqrt(r2))
            mi = mass * g_r3
            g[ACC * LANES + lane] -= mi * dx
            g[(ACC + 1) * LANES + lane] -= mi * dy
            g[(ACC + 2) * LANES + lane] -= mi * dz
    acc_com_x, acc_com_y, acc_com_z = rec[s, R_ACC_COM], rec[s, R_ACC_COM + 1], rec[s, R_ACC_COM + 2]
    for lane in range(LANES):
        ax = _row(g, ACC, lane) + 0.0  # the test body's own row of the pair loop adds its (empty) sum
        ay = _row(g, ACC + 1, lane) + 0.0
        az = _row(g, ACC + 2, lane) + 0.0
        x, y, z = _row(g, JP, lane), _row(g, JP + 1, lane), _row(g, JP + 2, lane)
        ax = ax - acc_com_x
        ay = ay - acc_com_y
        az = az - acc_com_z
        r2 = x * x + y * y + z * z
        k = mu_t / (r2 * math.sqrt(r2))
        ax += k * x
        ay += k * y
        az += k * z
        g[JV * LANES + lane] += dt * ax
        g[(JV + 1) * LANES + lane] += dt * ay
        g[(JV + 2) * LANES + lane] += dt * az
    for c in range(3):
        com = rec[s, R_HALF_DCOM + c]
        for lane in range(LANES):
            g[(DIPOS + c) * LANES + lane] = _row(g, DJP + c, lane) + _row(g, SCALE, lane) * com
    _tangent_row_lanes(g, IPOS, DIPOS, DACC, rec, s, V_KICK_POS, V_KICK_DPOS, q, m, G, eps2)
    dacc_com_x, dacc_com_y, dacc_com_z = rec[s, R_DACC_COM], rec[s, R_DACC_COM + 1], rec[s, R_DACC_COM + 2]
    for lane in range(LANES):
        scale = _row(g, SCALE, lane)
        dax = _row(g, DACC, lane) - scale * dacc_com_x
        day = _row(g, DACC + 1, lane) - scale * dacc_com_y
        daz = _row(g, DACC + 2, lane) - scale * dacc_com_z
        x, y, z = _row(g, JP, lane), _row(g, JP + 1, lane), _row(g, JP + 2, lane)
        dx, dy, dz = _row(g, DJP, lane), _row(g, DJP + 1, lane), _row(g, DJP + 2, lane)
        rj2i = 1.0 / (x * x + y * y + z * z)
        rj3iM = math.sqrt(rj2i) * rj2i * mu_t
        prefac1 = dt * rj3iM
        rdr = dx * x + dy * y + dz * z
        prefac2 = -dt * 3.0 * rdr * (rj3iM * rj2i)
        dvx = _row(g, DJV, lane) + (prefac1 * dx + prefac2 * x)
        dvy = _row(g, DJV + 1, lane) + (prefac1 * dy + prefac2 * y)
        dvz = _row(g, DJV + 2, lane) + (prefac1 * dz + prefac2 * z)
        g[DJV * LANES + lane] = dvx + dt * dax
        g[(DJV + 1) * LANES + lane] = dvy + dt * day
        g[(DJV + 2) * LANES + lane] = dvz + dt * daz


@jit
def pixel_block_lanes(g, whole, q, m, G, eps2, dt, mu_t, rec, n_rec, step0, t_start, radius, radii, escape_r2,
                      check_collisions):
    """Steps ``step0 .. step0 + n_rec - 1`` of a group's live lanes against the record ``rec`` (one pixel's
    step: :mod:`orbitsim.ensemble.restricted`). ``whole`` (LANES, 3, 3, q + 1) is scratch for a rescaled
    lane's whole tangent state. A lane that stops is left with LIVE 0, its STOP_CODE (COMPLETE never; a
    status, or KEPLER_FAILED with its state as before the failed step) and STOP_STEP (steps of this block
    it took, the stop's included). Returns the number of lanes still live."""
    wide_vectors()
    half = 0.5 * dt
    views = (g[JP * LANES:(JP + 3) * LANES].reshape((3, LANES)), g[JV * LANES:(JV + 3) * LANES].reshape((3, LANES)),
             g[DJP * LANES:(DJP + 3) * LANES].reshape((3, LANES)), g[DJV * LANES:(DJV + 3) * LANES].reshape((3, LANES)))
    live_lanes = 0
    for lane in range(LANES):
        live_lanes += _row(g, LIVE, lane) > 0.0
    for s in range(n_rec):
        if live_lanes == 0:
            break
        # to Jacobi coordinates: the test body is last, relative to the massive bodies' centre of mass
        for c in range(3):
            com_pos, com_vel = rec[s, R_COM_POS + c], rec[s, R_COM_VEL + c]
            com_dpos, com_dvel = rec[s, R_COM_DPOS + c], rec[s, R_COM_DVEL + c]
            for lane in range(LANES):
                scale = _row(g, SCALE, lane)
                g[(JP + c) * LANES + lane] = _row(g, TP + c, lane) - com_pos
                g[(JV + c) * LANES + lane] = _row(g, TV + c, lane) - com_vel
                g[(DJP + c) * LANES + lane] = _row(g, TDP + c, lane) - scale * com_dpos
                g[(DJV + c) * LANES + lane] = _row(g, TDV + c, lane) - scale * com_dvel
        if rec[s, R_STATUS] == KEPLER_FAILED:
            for lane in range(LANES):
                if _row(g, LIVE, lane) > 0.0:
                    g[LIVE * LANES + lane] = 0.0
                    g[STOP_CODE * LANES + lane] = KEPLER_FAILED
                    g[STOP_STEP * LANES + lane] = s + 1.0
            return 0
        # drift, kick, drift; the two drifts are one call site, so drift_lanes (the kernel's longest code) is
        # inlined, and compiled, once
        for phase in range(2):
            failed = drift_lanes(g, views, mu_t, half)
            _stop_lanes(g, failed, s)
            live_lanes -= failed
            if phase == 1:
                break
            _kick_lanes(g, rec, s, q, m, G, eps2, dt, mu_t)
        # the end of the step, for the live lanes: back to inertial coordinates
        for c in range(3):
            com, vcom = rec[s, R_END_COM + c], rec[s, R_END_VCOM + c]
            dcom, dvcom = rec[s, R_END_DCOM + c], rec[s, R_END_DVCOM + c]
            for lane in range(LANES):
                live = _row(g, LIVE, lane) > 0.0
                scale = _row(g, SCALE, lane)
                g[(TP + c) * LANES + lane] = _row(g, JP + c, lane) + com if live else _row(g, TP + c, lane)
                g[(TV + c) * LANES + lane] = _row(g, JV + c, lane) + vcom if live else _row(g, TV + c, lane)
                g[(TDP + c) * LANES + lane] = _row(g, DJP + c, lane) + scale * dcom if live else _row(g, TDP + c, lane)
                g[(TDV + c) * LANES + lane] = _row(g, DJV + c, lane) + scale * dvcom if live else _row(g, TDV + c, lane)
        # MEGNO's read (megno_after_step): the tangent row at the end, deltad_delta body by body
        t = t_start + (step0 + s + 1) * dt
        _tangent_row_lanes(g, TP, TDP, DACC, rec, s, V_POS, V_DPOS, q, m, G, eps2)
        deltad_m, delta2_m, norm2_m = rec[s, R_DELTAD_M], rec[s, R_DELTA2_M], rec[s, R_NORM2_M]
        for lane in range(LANES):
            g[K_DELTAD * LANES + lane] = deltad_m
            g[K_DELTA2 * LANES + lane] = delta2_m
            if _row(g, SCALE, lane) != 1.0:  # a rescaled pixel: the massive part of the sums from its scaled copy
                g[K_DELTAD * LANES + lane], g[K_DELTA2 * LANES + lane] = _scaled_massive_sums(g, whole[lane], rec, s,
                                                                                             q, lane)
        n_before = step0 + s
        rescale = False
        for lane in range(LANES):
            scale = _row(g, SCALE, lane)
            dpx, dpy, dpz = _row(g, TDP, lane), _row(g, TDP + 1, lane), _row(g, TDP + 2, lane)
            dvx, dvy, dvz = _row(g, TDV, lane), _row(g, TDV + 1, lane), _row(g, TDV + 2, lane)
            dax, day, daz = _row(g, DACC, lane), _row(g, DACC + 1, lane), _row(g, DACC + 2, lane)
            deltad, delta2 = _row(g, K_DELTAD, lane), _row(g, K_DELTA2, lane)
            deltad, delta2 = deltad_delta_body(deltad, delta2, dpx, dpy, dpz, dvx, dvy, dvz, dax, day, daz)
            dY = dt * 2.0 * (t - t_start) * (deltad / delta2)
            before = MegnoState(_row(g, M_YS, lane), _row(g, M_YSS, lane), _row(g, M_COV_YT, lane),
                                _row(g, M_VAR_T, lane), _row(g, M_MEAN_T, lane), _row(g, M_MEAN_Y, lane), t_start,
                                n_before)
            after = megno_update(before, t, dY, dt)
            live = _row(g, LIVE, lane) > 0.0
            g[M_YS * LANES + lane] = after.ys if live else before.ys
            g[M_YSS * LANES + lane] = after.yss if live else before.yss
            g[M_COV_YT * LANES + lane] = after.cov_yt if live else before.cov_yt
            g[M_VAR_T * LANES + lane] = after.var_t if live else before.var_t
            g[M_MEAN_T * LANES + lane] = after.mean_t if live else before.mean_t
            g[M_MEAN_Y * LANES + lane] = after.mean_y if live else before.mean_y
            # |delta|^2 in another order is within 1e-14 of rescale_power_of_two's sum: only a vector near the
            # bar needs that exact sum (a nan skips both, as it skips the exact test)
            norm2 = 0.0
            norm2 += dpx * dpx + dvx * dvx
            norm2 += dpy * dpy + dvy * dvy
            norm2 += dpz * dpz + dvz * dvz
            near = live and norm2_m * (scale * scale) + norm2 > RESCALE_ABOVE * (1.0 - 1e-9)
            g[K_RESCALE * LANES + lane] = 1.0 if near else 0.0
            rescale |= near
        if rescale:
            for lane in range(LANES):
                if _row(g, K_RESCALE, lane) > 0.0:
                    _rescale(g, whole[lane], rec, s, q, lane)
        # track_orbit reads the test body's Jacobi state at the end of the step; then the stop test
        massive = rec[s, R_STATUS]
        sun_x, sun_y, sun_z = record_value(rec, s, V_POS, q, 0, 0), record_value(rec, s, V_POS, q, 1, 0), \
            record_value(rec, s, V_POS, q, 2, 0)
        for lane in range(LANES):
            a, e = elements_ae(_row(g, JP, lane), _row(g, JP + 1, lane), _row(g, JP + 2, lane), _row(g, JV, lane),
                               _row(g, JV + 1, lane), _row(g, JV + 2, lane), mu_t)
            spread = abs(a - _row(g, TRACK_A0, lane)) / abs(_row(g, TRACK_A0, lane))
            live = _row(g, LIVE, lane) > 0.0
            max_e, delta_a = _row(g, TRACK_MAX_E, lane), _row(g, TRACK_DELTA_A, lane)
            g[TRACK_MAX_E * LANES + lane] = e if (live and e > max_e) else max_e
            g[TRACK_DELTA_A * LANES + lane] = spread if (live and spread > delta_a) else delta_a
            x, y, z = _row(g, TP, lane), _row(g, TP + 1, lane), _row(g, TP + 2, lane)
            dx, dy, dz = x - sun_x, y - sun_y, z - sun_z
            finite = math.isfinite(x) and math.isfinite(y) and math.isfinite(z)
            code = COMPLETE
            if not finite or massive == DIVERGED:
                code = DIVERGED
            elif massive == ESCAPED or dx * dx + dy * dy + dz * dz > escape_r2:
                code = ESCAPED
            elif massive == COLLIDED:
                code = COLLIDED
            g[STOP_CODE * LANES + lane] = code if live else _row(g, STOP_CODE, lane)
        if check_collisions:
            for i in range(q):
                reach = radii[i] + radius
                if reach <= 0.0:
                    continue
                px, py, pz = (record_value(rec, s, V_POS, q, 0, i), record_value(rec, s, V_POS, q, 1, i),
                              record_value(rec, s, V_POS, q, 2, i))
                for lane in range(LANES):
                    dx = _row(g, TP, lane) - px
                    dy = _row(g, TP + 1, lane) - py
                    dz = _row(g, TP + 2, lane) - pz
                    hit = _row(g, LIVE, lane) > 0.0 and _row(g, STOP_CODE, lane) == COMPLETE
                    hit = hit and dx * dx + dy * dy + dz * dz < reach * reach
                    g[STOP_CODE * LANES + lane] = COLLIDED if hit else _row(g, STOP_CODE, lane)
        for lane in range(LANES):
            if _row(g, LIVE, lane) > 0.0 and _row(g, STOP_CODE, lane) != COMPLETE:
                g[LIVE * LANES + lane] = 0.0
                g[STOP_STEP * LANES + lane] = s + 1.0
                live_lanes -= 1
    return live_lanes


@jit_inline
def _whole_test_body(g, whole, q, lane):
    """The lane's test body (column q) of ``whole``: its tangent position, velocity and acceleration rows."""
    for c in range(3):
        whole[0, c, q] = _row(g, TDP + c, lane)
        whole[1, c, q] = _row(g, TDV + c, lane)
        whole[2, c, q] = _row(g, DACC + c, lane)


@jit
def _scaled_massive_sums(g, whole, rec, s, q, lane):
    """deltad_delta's sums over a rescaled lane's massive bodies (their shared tangent state times its scale)."""
    scaled_massive_tangent(rec, s, q, _row(g, SCALE, lane), whole)
    return deltad_delta_sums(whole[0, :, :q], whole[1, :, :q], whole[2, :, :q], 0.0, 0.0)


@jit
def _rescale(g, whole, rec, s, q, lane):
    """rescale_power_of_two of a lane's whole tangent vector (the massive part scaled from the record), as one
    pixel's step does it; the test body's part and the lane's HALVINGS and SCALE follow."""
    scaled_massive_tangent(rec, s, q, _row(g, SCALE, lane), whole)
    _whole_test_body(g, whole, q, lane)
    count = rescale_power_of_two(whole[0], whole[1])
    if count > 0:
        for c in range(3):
            g[(TDP + c) * LANES + lane] = whole[0, c, q]
            g[(TDV + c) * LANES + lane] = whole[1, c, q]
        halvings = int(_row(g, HALVINGS, lane)) + count
        g[HALVINGS * LANES + lane] = halvings
        g[SCALE * LANES + lane] = 2.0 ** (-200 * halvings)
