"""The WHFast tangent step's operators for whole systems in SIMD lanes (the kernel: :mod:`.system_tangent_lanes`).

The parts of :func:`orbitsim.integrators.wisdom_holman.tangent.tangent_step` written lane-wise for LANES
systems in :mod:`orbitsim.ensemble.system_lanes`'s block layout (one block of rows per body, unsigned offsets,
rows moved between blocks by ``_copy_row``): Jacobi transforms, the drift with its derivative, the tangent
gravity, the kick of the bodies and of the tangent vector; each lane does the scalar operator's operations in
its order (no fastmath). A pair loop computes pair (i, j) in one body's block with the other's numbers copied
there and carries a row's running sum from block to block: every sum keeps the scalar order. Every lane loop's
rows are constants (LLVM vectorises a loop over rows a known distance apart).

The operators a step calls once (the Jacobi transforms, the kick, and MEGNO's read in
:mod:`.system_tangent_lanes`) are compiled functions of their own, not inlined by Numba into
:func:`~orbitsim.ensemble.system_tangent_lanes.run_tangent_group`: Numba copies an inlined function's IR
into its call site and types it there again, and that work grows faster than the code, so one function
holding every operator took 61 of a first map's 82 compile CPU-s; now the map's kernels take 43. A call a
step for LANES systems costs nothing measurable (250-259 ns a system-step either way, one thread, measured
side by side). The drift, called once per body and half step, stays inlined.
"""

from __future__ import annotations

import math

import numpy as np

from orbitsim._jit import jit, jit_inline, wide_vectors
from orbitsim.ensemble.system_lanes import (
    LANES,
    _copy_row,
    _copy_rows,
    _row,
    jacobi_down_lanes,
    jacobi_up_lanes,
    kepler_solve_lanes,
    pair_accelerations_lanes,
    start_row_sums,
)
from orbitsim.integrators.wisdom_holman.tangent import drift_derivative, kepler_drift_tangent, stiefel_g6_short
from orbitsim.physics.kepler import KEPLER_OK, fg_apply, lagrange_coefficients
from orbitsim.physics.tangent import pair_tangent_acceleration

_U = np.uint64
# Rows of a body's block (each LANES numbers):
P, V, DP, DV = 0, 3, 6, 9  # the inertial state and tangent vector between steps (3 rows each, in this order)
JP, JV, DJP, DJV = 12, 15, 18, 21  # the same in Jacobi coordinates during a step (rows 12..23 mirror 0..11)
IPOS, ACC, DIPOS, DACC = 24, 27, 30, 33  # the kick's inertial positions and accelerations, and their tangents
MASS, WEIGHT, MU, RADIUS = 36, 37, 38, 39  # m_b, the Jacobi weight m_b / M_b, G M_b, the radius
LIVE = 40  # 1: stepping; 0: stopped (STOP_CODE, STOP_STEP in block 0); -1: padding. Kept in every block.
K_R0, K_ETA0, K_ZETA0, K_BETA, K_X, K_R0I, K_PENDING, K_FAST, K_G1, K_G2, K_G3, K_R = range(41, 53)  # the drift
CARRY = 53  # 12 rows: sums carried from block to block (centres of mass, a pair row's sum, MEGNO's sums)
OTHER, OTHER_S = 65, 71  # 6 rows and 1: another body's position and tangent position, and its mass or radius
RANK, HIT = 72, 73  # the stop test's running verdict (3 diverged, 2 escaped, 1 collided, 0 none); a collision seen
A0, MAX_E, DELTA_A = 74, 75, 76  # track_orbit's start a, largest e, largest |a - a0| / |a0| (the watched block)
STOP_CODE, STOP_STEP = 77, 78  # a stopped lane's status and step count (block 0)
M_YS, M_YSS, M_COV_YT, M_VAR_T, M_MEAN_T, M_MEAN_Y = range(79, 85)  # MegnoState's sums (block 0)
NEAR = 85  # 1: the lane's |delta|^2 is near the rescaling bar (block 0)
BLOCK_ROWS = 86


@jit_inline
def block(b):
    """The element offset of body ``b``'s block."""
    return _U(b * (BLOCK_ROWS * LANES))


@jit
def to_jacobi_lanes(g, n, width):
    """inertial_to_jacobi of P, V, DP, DV into JP, JV, DJP, DJV for every lane: the centre of mass (12 rows)
    carried from body 0 up the chain, left in block 0's Jacobi rows."""
    wide_vectors()
    _copy_rows(g, block(1), CARRY, block(0), P, 12)
    for i in range(1, n):
        base = block(i)
        jacobi_up_lanes(g, base, P, JP, CARRY, width, WEIGHT)
        jacobi_up_lanes(g, base, V, JV, CARRY + 3, width, WEIGHT)
        jacobi_up_lanes(g, base, DP, DJP, CARRY + 6, width, WEIGHT)
        jacobi_up_lanes(g, base, DV, DJV, CARRY + 9, width, WEIGHT)
        if i + 1 < n:
            _copy_rows(g, block(i + 1), CARRY, base, CARRY, 12)
        else:
            _copy_rows(g, block(0), JP, base, CARRY, 12)


@jit
def to_inertial_lanes(g, n, width):
    """jacobi_to_inertial of JP, JV, DJP, DJV into P, V, DP, DV for the live lanes: the centre of mass carried
    from body n-1 down to body 1, then into block 0."""
    wide_vectors()
    _copy_rows(g, block(n - 1), CARRY, block(0), JP, 12)
    for i in range(n - 1, 0, -1):
        base = block(i)
        jacobi_down_lanes(g, base, JP, P, CARRY, True, width, WEIGHT, LIVE)
        jacobi_down_lanes(g, base, JV, V, CARRY + 3, True, width, WEIGHT, LIVE)
        jacobi_down_lanes(g, base, DJP, DP, CARRY + 6, True, width, WEIGHT, LIVE)
        jacobi_down_lanes(g, base, DJV, DV, CARRY + 9, True, width, WEIGHT, LIVE)
        _copy_rows(g, block(i - 1), CARRY, base, CARRY, 12)
    b0 = block(0)
    liver = _row(b0, LIVE)
    for r in range(12):
        dst, src = _row(b0, P + r), _row(b0, CARRY + r)
        for lane in range(width):
            live, old = g[liver + lane] > 0.0, g[dst + lane]
            g[dst + lane] = g[src + lane] if live else old


@jit_inline
def drift_tangent_lanes(g, base, h):
    """kepler_drift_tangent by ``h`` of the body whose block is at ``base`` (its JP, JV, DJP, DJV rows about MU)
    for every lane, each live lane with the scalar drift's bits (module docstring): the solve
    (:func:`orbitsim.ensemble.system_lanes.kepler_solve_lanes`), then the f and g functions and their derivative.
    Returns the number of live lanes whose drift failed (their LIVE in this block set to 0; the caller stops
    them)."""
    kepler_solve_lanes(g, base, h, JP, JV, MU, LIVE, K_R0)
    jx, jy, jz = _row(base, JP), _row(base, JP + 1), _row(base, JP + 2)
    vxr, vyr, vzr = _row(base, JV), _row(base, JV + 1), _row(base, JV + 2)
    dxr, dyr, dzr = _row(base, DJP), _row(base, DJP + 1), _row(base, DJP + 2)
    dvxr, dvyr, dvzr = _row(base, DJV), _row(base, DJV + 1), _row(base, DJV + 2)
    mur, liver = _row(base, MU), _row(base, LIVE)
    r0r, etar, zetar, betar, xr, r0ir = (_row(base, K_R0), _row(base, K_ETA0), _row(base, K_ZETA0),
                                         _row(base, K_BETA), _row(base, K_X), _row(base, K_R0I))
    pendr, fastr, g1r, g2r, g3r, rr = (_row(base, K_PENDING), _row(base, K_FAST), _row(base, K_G1),
                                       _row(base, K_G2), _row(base, K_G3), _row(base, K_R))
    for lane in range(_U(LANES)):
        x, y, z = g[jx + lane], g[jy + lane], g[jz + lane]
        vx, vy, vz = g[vxr + lane], g[vyr + lane], g[vzr + lane]
        dx, dy, dz = g[dxr + lane], g[dyr + lane], g[dzr + lane]
        dvx, dvy, dvz = g[dvxr + lane], g[dvyr + lane], g[dvzr + lane]
        mu, r0, eta0, zeta0 = g[mur + lane], g[r0r + lane], g[etar + lane], g[zetar + lane]
        beta, X, r0i = g[betar + lane], g[xr + lane], g[r0ir + lane]
        ri, f, gl, fd, gd = lagrange_coefficients(mu, h, r0i, g[g1r + lane], g[g2r + lane], g[g3r + lane],
                                                  g[rr + lane])
        nx, ny, nz, nvx, nvy, nvz = fg_apply(x, y, z, vx, vy, vz, f, gl, fd, gd)
        Gs0, Gs1, Gs2, Gs3, Gs4, Gs5, z6 = stiefel_g6_short(beta, X)
        ndx, ndy, ndz, ndvx, ndvy, ndvz = drift_derivative(x, y, z, vx, vy, vz, dx, dy, dz, dvx, dvy, dvz, mu, r0, r0i,
                                                           eta0, zeta0, beta, X, ri, f, gl, fd, gd,
                                                           Gs0, Gs1, Gs2, Gs3, Gs4, Gs5)
        fast, settled, live = g[fastr + lane] > 0.0, g[pendr + lane] == 0.0, g[liver + lane] > 0.0
        ok = fast and settled and live and abs(z6) <= 0.1  # stiefel_g6 would have quartered above 0.1
        g[jx + lane] = nx if ok else x
        g[jy + lane] = ny if ok else y
        g[jz + lane] = nz if ok else z
        g[vxr + lane] = nvx if ok else vx
        g[vyr + lane] = nvy if ok else vy
        g[vzr + lane] = nvz if ok else vz
        g[dxr + lane] = ndx if ok else dx
        g[dyr + lane] = ndy if ok else dy
        g[dzr + lane] = ndz if ok else dz
        g[dvxr + lane] = ndvx if ok else dvx
        g[dvyr + lane] = ndvy if ok else dvy
        g[dvzr + lane] = ndvz if ok else dvz
        g[fastr + lane] = 1.0 if ok else 0.0  # from here: done by the lanes
    failed = 0
    for lane in range(LANES):
        ulane = _U(lane)
        if g[fastr + ulane] > 0.0 or not g[liver + ulane] > 0.0:
            continue
        jpos = g[jx:jx + _U(3 * LANES)].reshape((3, LANES))
        jvel = g[vxr:vxr + _U(3 * LANES)].reshape((3, LANES))
        djpos = g[dxr:dxr + _U(3 * LANES)].reshape((3, LANES))
        djvel = g[dvxr:dvxr + _U(3 * LANES)].reshape((3, LANES))
        if kepler_drift_tangent(jpos, jvel, djpos, djvel, lane, g[mur + ulane], h) != KEPLER_OK:
            g[liver + ulane] = 0.0
            failed += 1
    return failed


@jit
def tangent_gravity_lanes(g, n, G, eps2, first_i, width):
    """:func:`orbitsim.physics.tangent.tangent_accelerations` of every lane at IPOS, DIPOS into DACC, rows i from
    ``first_i`` (1: every pair; 2: without (0, 1)). Pair (i, j < i) in j's block, row i's sum carried from j to
    j + 1, then set in i's block: the scalar's sum from zero (nothing was taken from row i before).
    ``first_i`` comes as an int64, never a literal: one compilation serves both callers (2-4 CPU-s each)."""
    wide_vectors()
    for b in range(n):
        for c in range(3):
            dacc = _row(block(b), DACC + c)
            for lane in range(width):
                g[dacc + lane] = 0.0
    for i in range(first_i, n):
        bi = block(i)
        for j in range(i):
            bj = block(j)
            _copy_rows(g, bj, OTHER, bi, IPOS, 3)
            _copy_rows(g, bj, OTHER + 3, bi, DIPOS, 3)
            _copy_row(g, _row(bj, OTHER_S), _row(bi, MASS))
            start_row_sums(g, BLOCK_ROWS, j, 0, CARRY, width)
            xj, yj, zj = _row(bj, IPOS), _row(bj, IPOS + 1), _row(bj, IPOS + 2)
            qx, qy, qz = _row(bj, DIPOS), _row(bj, DIPOS + 1), _row(bj, DIPOS + 2)
            xi, yi, zi = _row(bj, OTHER), _row(bj, OTHER + 1), _row(bj, OTHER + 2)
            pxi, pyi, pzi = _row(bj, OTHER + 3), _row(bj, OTHER + 4), _row(bj, OTHER + 5)
            sx, sy, sz = _row(bj, CARRY), _row(bj, CARRY + 1), _row(bj, CARRY + 2)
            ax, ay, az = _row(bj, DACC), _row(bj, DACC + 1), _row(bj, DACC + 2)
            mj_r, mi_r = _row(bj, MASS), _row(bj, OTHER_S)
            for lane in range(_U(LANES)):
                dax, day, daz = pair_tangent_acceleration(
                    g[xi + lane] - g[xj + lane], g[yi + lane] - g[yj + lane], g[zi + lane] - g[zj + lane],
                    g[pxi + lane] - g[qx + lane], g[pyi + lane] - g[qy + lane], g[pzi + lane] - g[qz + lane], eps2)
                gmi = G * g[mi_r + lane]
                gmj = G * g[mj_r + lane]
                g[sx + lane] += gmj * dax
                g[sy + lane] += gmj * day
                g[sz + lane] += gmj * daz
                g[ax + lane] -= gmi * dax
                g[ay + lane] -= gmi * day
                g[az + lane] -= gmi * daz
        _copy_rows(g, bi, DACC, block(i - 1), CARRY, 3)


@jit
def kick_tangent_lanes(g, n, G, eps2, dt, width):
    """interaction_kick_tangent of every lane: the bodies' kick (interaction_kick, Jacobi), then the tangent
    vector's (the tangent gravity without the (0, 1) pair, its Jacobi transform, jacobi_term_tangent_kick)."""
    wide_vectors()
    b0 = block(0)
    # inertial positions and tangent positions: the centre of mass carried from body n-1 down to body 1
    _copy_rows(g, block(n - 1), CARRY, b0, JP, 3)
    _copy_rows(g, block(n - 1), CARRY + 3, b0, DJP, 3)
    for i in range(n - 1, 0, -1):
        base = block(i)
        jacobi_down_lanes(g, base, JP, IPOS, CARRY, False, _U(LANES), WEIGHT, LIVE)
        jacobi_down_lanes(g, base, DJP, DIPOS, CARRY + 3, False, _U(LANES), WEIGHT, LIVE)
        if i > 1:
            _copy_rows(g, block(i - 1), CARRY, base, CARRY, 6)
        else:
            _copy_rows(g, b0, IPOS, base, CARRY, 3)
            _copy_rows(g, b0, DIPOS, base, CARRY + 3, 3)
    # the pair accelerations (interaction_accelerations, Jacobi: the (0, 1) pair left out)
    pair_accelerations_lanes(g, n, G, eps2, width, width, BLOCK_ROWS, IPOS, ACC, MASS, CARRY, OTHER, OTHER_S)
    # the tangent gravity without the (0, 1) pair, at the kick's inertial positions
    tangent_gravity_lanes(g, n, G, eps2, np.int64(2), width)
    # both to Jacobi (inertial_to_jacobi, in place): the interior centre of mass carried from body 1 up
    _copy_rows(g, block(1), CARRY, b0, ACC, 3)
    _copy_rows(g, block(1), CARRY + 3, b0, DACC, 3)
    for i in range(1, n):
        base = block(i)
        jacobi_up_lanes(g, base, ACC, ACC, CARRY, _U(LANES), WEIGHT)
        jacobi_up_lanes(g, base, DACC, DACC, CARRY + 3, _U(LANES), WEIGHT)
        if i + 1 < n:
            _copy_rows(g, block(i + 1), CARRY, base, CARRY, 6)
    # the kicks: body 1's Kepler term cancels the (0, 1) pair; bodies i >= 2 add G M_i r'_i / |r'_i|^3 and, to
    # the tangent vector, its derivative (added first, as jacobi_term_tangent_kick)
    for i in range(1, n):
        base = block(i)
        accx, accy, accz = _row(base, ACC), _row(base, ACC + 1), _row(base, ACC + 2)
        daccx, daccy, daccz = _row(base, DACC), _row(base, DACC + 1), _row(base, DACC + 2)
        vx, vy, vz = _row(base, JV), _row(base, JV + 1), _row(base, JV + 2)
        jx, jy, jz = _row(base, JP), _row(base, JP + 1), _row(base, JP + 2)
        dxr, dyr, dzr = _row(base, DJP), _row(base, DJP + 1), _row(base, DJP + 2)
        dvx, dvy, dvz = _row(base, DJV), _row(base, DJV + 1), _row(base, DJV + 2)
        mur = _row(base, MU)
        if i > 1:
            for lane in range(_U(LANES)):
                ax, ay, az = g[accx + lane], g[accy + lane], g[accz + lane]
                x, y, z = g[jx + lane], g[jy + lane], g[jz + lane]
                mu = g[mur + lane]
                r2 = x * x + y * y + z * z
                k = mu / (r2 * math.sqrt(r2))
                ax += k * x
                ay += k * y
                az += k * z
                g[vx + lane] += dt * ax
                g[vy + lane] += dt * ay
                g[vz + lane] += dt * az
                rj2i = 1.0 / (x * x + y * y + z * z)
                rj3iM = math.sqrt(rj2i) * rj2i * mu
                prefac1 = dt * rj3iM
                ddx, ddy, ddz = g[dxr + lane], g[dyr + lane], g[dzr + lane]
                rdr = ddx * x + ddy * y + ddz * z
                prefac2 = -dt * 3.0 * rdr * (rj3iM * rj2i)
                ux = g[dvx + lane] + (prefac1 * ddx + prefac2 * x)
                uy = g[dvy + lane] + (prefac1 * ddy + prefac2 * y)
                uz = g[dvz + lane] + (prefac1 * ddz + prefac2 * z)
                g[dvx + lane] = ux + dt * g[daccx + lane]
                g[dvy + lane] = uy + dt * g[daccy + lane]
                g[dvz + lane] = uz + dt * g[daccz + lane]
        else:
            for lane in range(_U(LANES)):
                g[vx + lane] += dt * g[accx + lane]
                g[vy + lane] += dt * g[accy + lane]
                g[vz + lane] += dt * g[accz + lane]
                g[dvx + lane] += dt * g[daccx + lane]
                g[dvy + lane] += dt * g[daccy + lane]
                g[dvz + lane] += dt * g[daccz + lane]


