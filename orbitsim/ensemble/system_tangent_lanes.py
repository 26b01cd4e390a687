"""Whole Wisdom-Holman systems with their variational equations in SIMD lanes: MEGNO for LANES systems at once.

:func:`orbitsim.ensemble.kernels.run_ensemble_variational` steps one system and its tangent vector per
``prange`` iteration (:func:`~orbitsim.ensemble.kernels.run_system_variational`). Here LANES systems (a group)
take each step together, in the block layout of :mod:`orbitsim.ensemble.system_lanes` (read its docstring:
one block of LANES-wide rows per body, unsigned offsets, what one block needs from another copied by
``_copy_row``): each lane performs the scalar step's operations in the same order, with no fastmath, so each
system keeps its bits (tests/ensemble/test_system_tangent_lanes.py compares every output bit for bit):

* :func:`orbitsim.integrators.wisdom_holman.tangent.tangent_step` (WHFast's safe mode): the inertial state
  and tangent vector to Jacobi coordinates, K(dt/2) with the drift's derivative, the interaction kick of the
  bodies and of the tangent vector (the tangent gravity without the (0, 1) pair, its Jacobi transform, the
  Jacobi term's derivative), K(dt/2), back to inertial coordinates;
* :func:`orbitsim.chaos.step.megno_after_step`: the tangent gravity of every pair at the new state, the
  sums of ``deltad_delta`` body by body, :func:`orbitsim.chaos.megno.megno_update`;
* ``track_orbit`` and ``_stop_reason`` of :mod:`orbitsim.ensemble.kernels` on the inertial state.

A pair loop (:func:`_tangent_gravity_lanes`, the kick's pair accelerations) computes pair (i, j) in one of
the two bodies' blocks with the other's numbers copied there, and carries a row's running sum from block to
block, so every sum is added in the scalar loop's order.

Where the scalar step would branch, the lanes take the common case and a lane outside it is done by the scalar
code: a body's drift that is not a short step, leaves the Stumpff series, does not settle in
:data:`~orbitsim.physics.kepler_solver.NEWTON_FAST_ITERATIONS` or needs a quartered G6 is drifted by
:func:`orbitsim.integrators.wisdom_holman.tangent.kepler_drift_tangent` (as :mod:`orbitsim.ensemble.lanes`
does for a map's test body); a lane whose |delta|^2 nears the rescaling bar is tested and rescaled by
:func:`orbitsim.chaos.megno.rescale_power_of_two` itself on a copy of its tangent vector.

A lane stops alone, at the step the scalar kernel stops (a failed drift: its inertial state stays as before
that step, as the scalar step leaves it; or the stop test after MEGNO's read); its inertial and MEGNO rows are
then no longer written. The Jacobi, kick and drift rows are scratch recomputed every step, so they are written
for every lane. The indicator row and energy error at the end are the scalar kernel's code, once per system.

The kernel takes ``G`` and ``eps2``, not a force context: it has no forces beyond gravity, so
:func:`orbitsim.ensemble.run.run_ensemble` calls it only for a force-free context.

Why one module (over ~400 lines): the block layout (the row constants) and the lane loops that index it are one
piece, the scalar step written lane-wise part for part, as in :mod:`orbitsim.ensemble.system_lanes`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import prange

from orbitsim._jit import jit, jit_inline, jit_parallel_exact, stop_requested
from orbitsim.chaos.megno import RESCALE_ABOVE, MegnoState, megno_update, rescale_power_of_two
from orbitsim.ensemble.kernels import _energy, elements_ae, jacobi_elements_ae, record_chaos_indicators
from orbitsim.ensemble.lanes import LANES
from orbitsim.ensemble.status import COMPLETE, DIVERGED, ENERGY_ERROR
from orbitsim.ensemble.system_lanes import _copy_row, _copy_rows, _rank_code, _row
from orbitsim.integrators.wisdom_holman.tangent import drift_derivative, kepler_drift_tangent, stiefel_g6_short
from orbitsim.physics.coordinates import inertial_to_jacobi
from orbitsim.physics.kepler import KEPLER_OK, fg_apply, lagrange_coefficients
from orbitsim.physics.kepler_solver import (
    NEWTON_FAST_ITERATIONS,
    STUMPFF_SERIES_MAX_Z,
    newton_terms,
    setup_short,
    stiefel_short,
)
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
#: |delta|^2 summed in the lanes' order is within a few ulps of rescale_power_of_two's sum; a lane above the bar
#: less this margin takes the exact test (a margin far above those ulps, far below any growth in a step).
_NEAR_MARGIN = 1.0 - 1e-9


@jit_inline
def _block(b):
    """The element offset of body ``b``'s block."""
    return _U(b * (BLOCK_ROWS * LANES))


@jit_inline
def _jacobi_up(g, base, src, dst, carry, width):
    """One body's step of inertial_to_jacobi on the three rows at ``src``: ``dst`` = src - the interior centre
    of mass (the ``carry`` rows), which then moves by weight times that. Rows are constants at every call, so
    LLVM sees the loop's rows a known distance apart and vectorises it."""
    w = _row(base, WEIGHT)
    sx, sy, sz = _row(base, src), _row(base, src + 1), _row(base, src + 2)
    dx, dy, dz = _row(base, dst), _row(base, dst + 1), _row(base, dst + 2)
    cx, cy, cz = _row(base, carry), _row(base, carry + 1), _row(base, carry + 2)
    for lane in range(width):
        weight = g[w + lane]
        com_x, com_y, com_z = g[cx + lane], g[cy + lane], g[cz + lane]
        rel_x, rel_y, rel_z = g[sx + lane] - com_x, g[sy + lane] - com_y, g[sz + lane] - com_z
        g[dx + lane], g[dy + lane], g[dz + lane] = rel_x, rel_y, rel_z
        g[cx + lane] = com_x + weight * rel_x
        g[cy + lane] = com_y + weight * rel_y
        g[cz + lane] = com_z + weight * rel_z


@jit_inline
def _jacobi_down(g, base, src, dst, carry, masked, width):
    """One body's step of jacobi_to_inertial on the three rows at ``src``: the centre of mass (``carry``) moves
    back by weight times the Jacobi vector, and ``dst`` = the vector plus it (where ``masked``, live lanes only)."""
    w, liver = _row(base, WEIGHT), _row(base, LIVE)
    sx, sy, sz = _row(base, src), _row(base, src + 1), _row(base, src + 2)
    dx, dy, dz = _row(base, dst), _row(base, dst + 1), _row(base, dst + 2)
    cx, cy, cz = _row(base, carry), _row(base, carry + 1), _row(base, carry + 2)
    for lane in range(width):
        weight, keep = g[w + lane], masked and not g[liver + lane] > 0.0
        rel_x, rel_y, rel_z = g[sx + lane], g[sy + lane], g[sz + lane]
        com_x = g[cx + lane] - weight * rel_x
        com_y = g[cy + lane] - weight * rel_y
        com_z = g[cz + lane] - weight * rel_z
        g[cx + lane], g[cy + lane], g[cz + lane] = com_x, com_y, com_z
        ox, oy, oz = g[dx + lane], g[dy + lane], g[dz + lane]
        g[dx + lane] = ox if keep else rel_x + com_x
        g[dy + lane] = oy if keep else rel_y + com_y
        g[dz + lane] = oz if keep else rel_z + com_z


@jit_inline
def _to_jacobi_lanes(g, n, width):
    """inertial_to_jacobi of P, V, DP, DV into JP, JV, DJP, DJV for every lane: the centre of mass (12 rows)
    carried from body 0 up the chain, left in block 0's Jacobi rows."""
    _copy_rows(g, _block(1), CARRY, _block(0), P, 12)
    for i in range(1, n):
        base = _block(i)
        _jacobi_up(g, base, P, JP, CARRY, width)
        _jacobi_up(g, base, V, JV, CARRY + 3, width)
        _jacobi_up(g, base, DP, DJP, CARRY + 6, width)
        _jacobi_up(g, base, DV, DJV, CARRY + 9, width)
        if i + 1 < n:
            _copy_rows(g, _block(i + 1), CARRY, base, CARRY, 12)
        else:
            _copy_rows(g, _block(0), JP, base, CARRY, 12)


@jit_inline
def _to_inertial_lanes(g, n, width):
    """jacobi_to_inertial of JP, JV, DJP, DJV into P, V, DP, DV for the live lanes: the centre of mass carried
    from body n-1 down to body 1, then into block 0."""
    _copy_rows(g, _block(n - 1), CARRY, _block(0), JP, 12)
    for i in range(n - 1, 0, -1):
        base = _block(i)
        _jacobi_down(g, base, JP, P, CARRY, True, width)
        _jacobi_down(g, base, JV, V, CARRY + 3, True, width)
        _jacobi_down(g, base, DJP, DP, CARRY + 6, True, width)
        _jacobi_down(g, base, DJV, DV, CARRY + 9, True, width)
        _copy_rows(g, _block(i - 1), CARRY, base, CARRY, 12)
    b0 = _block(0)
    liver = _row(b0, LIVE)
    for r in range(12):
        dst, src = _row(b0, P + r), _row(b0, CARRY + r)
        for lane in range(width):
            live, old = g[liver + lane] > 0.0, g[dst + lane]
            g[dst + lane] = g[src + lane] if live else old


@jit_inline
def drift_tangent_lanes(g, base, h):
    """kepler_drift_tangent by ``h`` of the body whose block is at ``base`` (its JP, JV, DJP, DJV rows about MU)
    for every lane, each live lane with the scalar drift's bits (module docstring). Returns the number of live
    lanes whose drift failed (their LIVE in this block set to 0; the caller stops them)."""
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
        r0 = math.sqrt(x * x + y * y + z * z)
        eta0 = x * vx + y * vy + z * vz
        mu = g[mur + lane]
        r0i, zeta0, beta, X, short = setup_short(r0, vx * vx + vy * vy + vz * vz, eta0, mu, h)
        short = short & (mu != 0.0)  # the scalar drift moves a body about mu = 0 in a straight line
        live = g[liver + lane] > 0.0
        g[r0r + lane] = r0
        g[etar + lane] = eta0
        g[zetar + lane] = zeta0
        g[betar + lane] = beta
        g[xr + lane] = X
        g[r0ir + lane] = r0i
        g[pendr + lane] = 1.0 if (short and live) else 0.0
        g[fastr + lane] = 1.0 if short else 0.0
    for _ in range(NEWTON_FAST_ITERATIONS):
        pending = 0
        for lane in range(_U(LANES)):
            r0, eta0, zeta0 = g[r0r + lane], g[etar + lane], g[zetar + lane]
            beta, X = g[betar + lane], g[xr + lane]
            _, G1, G2, G3, zz = stiefel_short(beta, X)
            dX, r, settled = newton_terms(r0, eta0, zeta0, h, X, G1, G2, G3)
            p = g[pendr + lane] > 0.0
            outside = abs(zz) > STUMPFF_SERIES_MAX_Z  # the scalar solve would have used _stumpff_large
            g[g1r + lane] = G1 if p else g[g1r + lane]
            g[g2r + lane] = G2 if p else g[g2r + lane]
            g[g3r + lane] = G3 if p else g[g3r + lane]
            g[rr + lane] = r if p else g[rr + lane]
            g[xr + lane] = X + dX if (p and not settled) else X
            g[fastr + lane] = 0.0 if (p and outside) else g[fastr + lane]
            still = p and not settled and not outside
            g[pendr + lane] = 1.0 if still else 0.0
            pending |= still
        if not pending:
            break
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
def _stop_lane(g, n, lane, code, step):
    """Lane ``lane`` stops with status ``code`` after ``step`` steps: LIVE 0 in every block."""
    for b in range(n):
        g[_row(_block(b), LIVE) + _U(lane)] = 0.0
    g[_row(_U(0), STOP_CODE) + _U(lane)] = code
    g[_row(_U(0), STOP_STEP) + _U(lane)] = step


@jit
def _stop_failed_drifts(g, n, b, step):
    """Stop the live lanes whose drift of body ``b`` failed (their LIVE 0 in b's block only); returns how many."""
    stopped = 0
    for lane in range(LANES):
        if g[_row(_U(0), LIVE) + _U(lane)] > 0.0 and not g[_row(_block(b), LIVE) + _U(lane)] > 0.0:
            _stop_lane(g, n, lane, np.int64(DIVERGED), step)
            stopped += 1
    return stopped


@jit
def _tangent_gravity_lanes(g, n, G, eps2, first_i, width):
    """:func:`orbitsim.physics.tangent.tangent_accelerations` of every lane into the DACC rows, at the positions
    IPOS and tangent positions DIPOS (fixed rows: a loop's rows a known distance apart vectorise), rows i from
    ``first_i`` (1: every pair; 2: without (0, 1)). Pair (i, j < i) in j's block with i's numbers copied
    there; row i's sum carried from j to j + 1 and then set in i's block, where it is the scalar's sum from
    zero (nothing was taken from row i before)."""
    for b in range(n):
        for c in range(3):
            dacc = _row(_block(b), DACC + c)
            for lane in range(width):
                g[dacc + lane] = 0.0
    for i in range(first_i, n):
        bi = _block(i)
        for j in range(i):
            bj = _block(j)
            _copy_rows(g, bj, OTHER, bi, IPOS, 3)
            _copy_rows(g, bj, OTHER + 3, bi, DIPOS, 3)
            _copy_row(g, _row(bj, OTHER_S), _row(bi, MASS))
            if j == 0:
                for c in range(3):
                    carry = _row(bj, CARRY + c)
                    for lane in range(width):
                        g[carry + lane] = 0.0
            else:
                _copy_rows(g, bj, CARRY, _block(j - 1), CARRY, 3)
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
        _copy_rows(g, bi, DACC, _block(i - 1), CARRY, 3)


@jit_inline
def _kick_tangent_lanes(g, n, G, eps2, dt, width):
    """interaction_kick_tangent of every lane: the bodies' kick (interaction_kick, Jacobi), then the tangent
    vector's (the tangent gravity without the (0, 1) pair, its Jacobi transform, jacobi_term_tangent_kick)."""
    b0 = _block(0)
    # inertial positions and tangent positions: the centre of mass carried from body n-1 down to body 1
    _copy_rows(g, _block(n - 1), CARRY, b0, JP, 3)
    _copy_rows(g, _block(n - 1), CARRY + 3, b0, DJP, 3)
    for i in range(n - 1, 0, -1):
        base = _block(i)
        _jacobi_down(g, base, JP, IPOS, CARRY, False, _U(LANES))
        _jacobi_down(g, base, DJP, DIPOS, CARRY + 3, False, _U(LANES))
        if i > 1:
            _copy_rows(g, _block(i - 1), CARRY, base, CARRY, 6)
        else:
            _copy_rows(g, b0, IPOS, base, CARRY, 3)
            _copy_rows(g, b0, DIPOS, base, CARRY + 3, 3)
    # the pair accelerations (interaction_accelerations, Jacobi: the (0, 1) pair left out): pair (i, j > i) in
    # j's block, with i's position and mass copied there, and row i's sum carried from j to j + 1
    for b in range(n):
        for c in range(3):
            acc = _row(_block(b), ACC + c)
            for lane in range(width):
                g[acc + lane] = 0.0
    for i in range(n):
        bi = _block(i)
        start = 2 if i == 0 else i + 1
        for j in range(start, n):
            bj = _block(j)
            _copy_rows(g, bj, OTHER, bi, IPOS, 3)
            _copy_row(g, _row(bj, OTHER_S), _row(bi, MASS))
            if j == start:
                for c in range(3):
                    carry = _row(bj, CARRY + c)
                    for lane in range(width):
                        g[carry + lane] = 0.0
            else:
                _copy_rows(g, bj, CARRY, _block(j - 1), CARRY, 3)
            xj, yj, zj = _row(bj, IPOS), _row(bj, IPOS + 1), _row(bj, IPOS + 2)
            xi, yi, zi = _row(bj, OTHER), _row(bj, OTHER + 1), _row(bj, OTHER + 2)
            ax, ay, az = _row(bj, CARRY), _row(bj, CARRY + 1), _row(bj, CARRY + 2)
            accx, accy, accz = _row(bj, ACC), _row(bj, ACC + 1), _row(bj, ACC + 2)
            mj_r, mi_r = _row(bj, MASS), _row(bj, OTHER_S)
            for lane in range(_U(LANES)):
                dx = g[xj + lane] - g[xi + lane]
                dy = g[yj + lane] - g[yi + lane]
                dz = g[zj + lane] - g[zi + lane]
                r2 = dx * dx + dy * dy + dz * dz + eps2
                g_r3 = G / (r2 * math.sqrt(r2))
                mj = g[mj_r + lane] * g_r3
                mi = g[mi_r + lane] * g_r3
                g[ax + lane] += mj * dx
                g[ay + lane] += mj * dy
                g[az + lane] += mj * dz
                g[accx + lane] -= mi * dx
                g[accy + lane] -= mi * dy
                g[accz + lane] -= mi * dz
        if start < n:
            _copy_rows(g, bi, CARRY, _block(n - 1), CARRY, 3)
        else:  # a row without pairs adds its empty sum
            for c in range(3):
                carry = _row(bi, CARRY + c)
                for lane in range(width):
                    g[carry + lane] = 0.0
        accx, accy, accz = _row(bi, ACC), _row(bi, ACC + 1), _row(bi, ACC + 2)
        cx, cy, cz = _row(bi, CARRY), _row(bi, CARRY + 1), _row(bi, CARRY + 2)
        for lane in range(width):
            g[accx + lane] += g[cx + lane]
            g[accy + lane] += g[cy + lane]
            g[accz + lane] += g[cz + lane]
    # the tangent gravity without the (0, 1) pair, at the kick's inertial positions
    _tangent_gravity_lanes(g, n, G, eps2, 2, width)
    # both to Jacobi (inertial_to_jacobi, in place): the interior centre of mass carried from body 1 up
    _copy_rows(g, _block(1), CARRY, b0, ACC, 3)
    _copy_rows(g, _block(1), CARRY + 3, b0, DACC, 3)
    for i in range(1, n):
        base = _block(i)
        _jacobi_up(g, base, ACC, ACC, CARRY, _U(LANES))
        _jacobi_up(g, base, DACC, DACC, CARRY + 3, _U(LANES))
        if i + 1 < n:
            _copy_rows(g, _block(i + 1), CARRY, base, CARRY, 6)
    # the kicks: body 1's Kepler term cancels the (0, 1) pair; bodies i >= 2 add G M_i r'_i / |r'_i|^3 and, to
    # the tangent vector, its derivative (added first, as jacobi_term_tangent_kick)
    for i in range(1, n):
        base = _block(i)
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


@jit_inline
def _megno_lanes(g, n, G, eps2, dt, t, t_start, n_before, width):
    """megno_after_step of the live lanes: the tangent gravity of every pair at the new state, deltad_delta's
    sums carried body by body, megno_update; marks in NEAR the lanes to test for a rescaling. Returns
    whether any lane is marked."""
    for b in range(n):  # the new state into the rows the tangent gravity reads (scratch until the next kick)
        _copy_rows(g, _block(b), IPOS, _block(b), P, 3)
        _copy_rows(g, _block(b), DIPOS, _block(b), DP, 3)
    _tangent_gravity_lanes(g, n, G, eps2, 1, width)
    b0 = _block(0)
    for r in range(3):
        carry = _row(b0, CARRY + r)
        for lane in range(width):
            g[carry + lane] = 0.0
    for b in range(n):
        base = _block(b)
        if b > 0:
            _copy_rows(g, base, CARRY, _block(b - 1), CARRY, 3)
        pxr, vxr, axr = _row(base, DP), _row(base, DV), _row(base, DACC)
        sd, s2, sn = _row(base, CARRY), _row(base, CARRY + 1), _row(base, CARRY + 2)
        for lane in range(_U(LANES)):
            dpx, dpy, dpz = g[pxr + lane], g[pxr + _U(LANES) + lane], g[pxr + _U(2 * LANES) + lane]
            dvx, dvy, dvz = g[vxr + lane], g[vxr + _U(LANES) + lane], g[vxr + _U(2 * LANES) + lane]
            dax, day, daz = g[axr + lane], g[axr + _U(LANES) + lane], g[axr + _U(2 * LANES) + lane]
            deltad, delta2 = g[sd + lane], g[s2 + lane]
            deltad += dvx * dpx
            deltad += dvy * dpy
            deltad += dvz * dpz
            deltad += dax * dvx
            deltad += day * dvy
            deltad += daz * dvz
            delta2 += dpx * dpx
            delta2 += dpy * dpy
            delta2 += dpz * dpz
            delta2 += dvx * dvx
            delta2 += dvy * dvy
            delta2 += dvz * dvz
            g[sd + lane], g[s2 + lane] = deltad, delta2
            g[sn + lane] += (dpx * dpx + dvx * dvx) + (dpy * dpy + dvy * dvy) + (dpz * dpz + dvz * dvz)
    _copy_rows(g, b0, CARRY, _block(n - 1), CARRY, 3)
    liver, sd, s2, sn, near_r = _row(b0, LIVE), _row(b0, CARRY), _row(b0, CARRY + 1), _row(b0, CARRY + 2), \
        _row(b0, NEAR)
    ys, yss, cov, var = _row(b0, M_YS), _row(b0, M_YSS), _row(b0, M_COV_YT), _row(b0, M_VAR_T)
    mean_t, mean_y = _row(b0, M_MEAN_T), _row(b0, M_MEAN_Y)
    rescale = False
    for lane in range(LANES):
        ulane = _U(lane)
        dY = dt * 2.0 * (t - t_start) * (g[sd + ulane] / g[s2 + ulane])
        before = MegnoState(g[ys + ulane], g[yss + ulane], g[cov + ulane], g[var + ulane], g[mean_t + ulane],
                            g[mean_y + ulane], t_start, n_before)
        after = megno_update(before, t, dY, dt)
        live = g[liver + ulane] > 0.0
        g[ys + ulane] = after.ys if live else before.ys
        g[yss + ulane] = after.yss if live else before.yss
        g[cov + ulane] = after.cov_yt if live else before.cov_yt
        g[var + ulane] = after.var_t if live else before.var_t
        g[mean_t + ulane] = after.mean_t if live else before.mean_t
        g[mean_y + ulane] = after.mean_y if live else before.mean_y
        near = live and g[sn + ulane] > RESCALE_ABOVE * _NEAR_MARGIN
        g[near_r + ulane] = 1.0 if near else 0.0
        rescale |= near
    return rescale


@jit
def _rescale_lane(g, n, lane, whole):
    """rescale_power_of_two of lane ``lane``'s tangent vector (a copy in ``whole`` (2, 3, N)), written back."""
    ulane = _U(lane)
    for b in range(n):
        for c in range(3):
            whole[0, c, b] = g[_row(_block(b), DP + c) + ulane]
            whole[1, c, b] = g[_row(_block(b), DV + c) + ulane]
    if rescale_power_of_two(whole[0], whole[1]) > 0:
        for b in range(n):
            for c in range(3):
                g[_row(_block(b), DP + c) + ulane] = whole[0, c, b]
                g[_row(_block(b), DV + c) + ulane] = whole[1, c, b]


@jit_inline
def _track_orbit_lanes(g, base):
    """track_orbit for the live lanes: the watched body's (block ``base``) Jacobi a and e after the step."""
    jx, jy, jz = _row(base, JP), _row(base, JP + 1), _row(base, JP + 2)
    vx, vy, vz = _row(base, JV), _row(base, JV + 1), _row(base, JV + 2)
    mur, liver, a0r, max_er, delta_ar = (_row(base, MU), _row(base, LIVE), _row(base, A0), _row(base, MAX_E),
                                         _row(base, DELTA_A))
    for lane in range(_U(LANES)):
        a, e = elements_ae(g[jx + lane], g[jy + lane], g[jz + lane], g[vx + lane], g[vy + lane], g[vz + lane],
                           g[mur + lane])
        spread = abs(a - g[a0r + lane]) / abs(g[a0r + lane])
        live = g[liver + lane] > 0.0
        max_e, delta_a = g[max_er + lane], g[delta_ar + lane]
        g[max_er + lane] = e if (live and e > max_e) else max_e
        g[delta_ar + lane] = spread if (live and spread > delta_a) else delta_a


@jit_inline
def _stop_test_lanes(g, n, escape_r2, check_collisions, width):
    """_stop_reason of every lane's inertial positions (P) as a rank carried from block 0 to block n - 1 (the
    scalar test's precedence, as :mod:`orbitsim.ensemble.system_lanes`); left in block 0's RANK row."""
    b0 = _block(0)
    if check_collisions:  # pair (i, j) in j's block, with i's position and radius copied there
        for j in range(n):
            hit = _row(_block(j), HIT)
            for lane in range(width):
                g[hit + lane] = 0.0
        for i in range(n):
            bi = _block(i)
            for j in range(i + 1, n):
                bj = _block(j)
                _copy_rows(g, bj, OTHER, bi, P, 3)
                _copy_row(g, _row(bj, OTHER_S), _row(bi, RADIUS))
                xj, yj, zj = _row(bj, P), _row(bj, P + 1), _row(bj, P + 2)
                xi, yi, zi = _row(bj, OTHER), _row(bj, OTHER + 1), _row(bj, OTHER + 2)
                ri, rj, hit = _row(bj, OTHER_S), _row(bj, RADIUS), _row(bj, HIT)
                for lane in range(width):
                    reach = g[ri + lane] + g[rj + lane]
                    dx = g[xj + lane] - g[xi + lane]
                    dy = g[yj + lane] - g[yi + lane]
                    dz = g[zj + lane] - g[zi + lane]
                    met = (reach > 0.0) & (dx * dx + dy * dy + dz * dz < reach * reach)
                    g[hit + lane] = 1.0 if met else g[hit + lane]
    x0, y0, z0, rank = _row(b0, P), _row(b0, P + 1), _row(b0, P + 2), _row(b0, RANK)
    for lane in range(width):
        x, y, z = g[x0 + lane], g[y0 + lane], g[z0 + lane]
        g[rank + lane] = 0.0 if (math.isfinite(x) & math.isfinite(y) & math.isfinite(z)) else 3.0
    for b in range(1, n):
        base = _block(b)
        _copy_rows(g, base, OTHER, b0, P, 3)
        _copy_row(g, _row(base, RANK), _row(_block(b - 1), RANK))
        x, y, z = _row(base, P), _row(base, P + 1), _row(base, P + 2)
        xs, ys, zs = _row(base, OTHER), _row(base, OTHER + 1), _row(base, OTHER + 2)
        rank, hit = _row(base, RANK), _row(base, HIT)
        for lane in range(width):
            xb, yb, zb = g[x + lane], g[y + lane], g[z + lane]
            dx, dy, dz = xb - g[xs + lane], yb - g[ys + lane], zb - g[zs + lane]
            verdict, met = g[rank + lane], g[hit + lane] > 0.0
            verdict = 1.0 if (check_collisions & met & (verdict < 1.0)) else verdict
            verdict = 2.0 if ((dx * dx + dy * dy + dz * dz > escape_r2) & (verdict < 2.0)) else verdict
            finite = math.isfinite(xb) & math.isfinite(yb) & math.isfinite(zb)
            g[rank + lane] = verdict if finite else 3.0
    _copy_row(g, _row(b0, RANK), _row(_block(n - 1), RANK))


@jit
def run_tangent_group(g, n, G, eps2, dt, t_start, n_steps, escape_r2, check_collisions, watch, whole):
    """Step a group's live lanes and their tangent vectors ``n_steps`` times, each until it stops (LIVE 0,
    STOP_CODE, STOP_STEP in block 0), with MEGNO's read after every step. ``whole`` (2, 3, N) is scratch for a
    rescaled lane. Returns the steps taken by the lanes still live at the end (fewer where a stop of the kernels
    was asked for, :func:`orbitsim._jit.stop_requested`: the caller then throws the results away)."""
    half = 0.5 * dt
    b0 = _block(0)
    width = _U(g.size // (n * BLOCK_ROWS))  # LANES, counted at run time (see system_lanes.run_group)
    live_lanes = 0
    for lane in range(LANES):
        live_lanes += g[_row(b0, LIVE) + _U(lane)] > 0.0
    done = 0
    while done < n_steps and live_lanes > 0:
        if stop_requested():
            break
        _to_jacobi_lanes(g, n, width)
        for phase in range(2):  # K(dt/2) I(dt) K(dt/2); one drift call site, so inlined and compiled once
            for b in range(1, n):
                if drift_tangent_lanes(g, _block(b), half) > 0:
                    live_lanes -= _stop_failed_drifts(g, n, b, done + 1)
            jx, vx = _row(b0, JP), _row(b0, JV)
            for r in range(3):  # the centre of mass and its variation drift
                for lane in range(width):
                    g[jx + _U(r * LANES) + lane] += half * g[vx + _U(r * LANES) + lane]
                    g[jx + _U((r + 6) * LANES) + lane] += half * g[vx + _U((r + 6) * LANES) + lane]
            if phase == 1:
                break
            _kick_tangent_lanes(g, n, G, eps2, dt, width)
        done += 1
        _to_inertial_lanes(g, n, width)
        if _megno_lanes(g, n, G, eps2, dt, t_start + done * dt, t_start, done - 1, width):
            for lane in range(LANES):
                if g[_row(b0, NEAR) + _U(lane)] > 0.0:
                    _rescale_lane(g, n, lane, whole)
        _track_orbit_lanes(g, _block(watch))
        _stop_test_lanes(g, n, escape_r2, check_collisions, width)
        for lane in range(LANES):
            verdict = g[_row(b0, RANK) + _U(lane)]
            if verdict > 0.0 and g[_row(b0, LIVE) + _U(lane)] > 0.0:
                _stop_lane(g, n, lane, _rank_code(verdict), done)
                live_lanes -= 1
    return done


@jit
def _start_group(g, grp, pos, vel, dpos, dvel, m, G, weights, mu, radii, watch, rows, scratch, e0):
    """Fill group ``grp``'s blocks from its systems (run_system_variational's start: energy, the watched body's
    Jacobi elements); lanes past the last system are padding, a copy of lane 0 that is never live."""
    n_sys, n = pos.shape[0], pos.shape[2]
    wb = _block(watch)
    for lane in range(LANES):
        k = grp * LANES + lane
        ulane = _U(lane)
        if k >= n_sys:
            for row in range(n * BLOCK_ROWS):
                g[row * LANES + lane] = g[row * LANES]
            for b in range(n):
                g[_row(_block(b), LIVE) + ulane] = -1.0
            continue
        e0[k] = _energy(pos[k], vel[k], m[k], G, rows)
        jpos, jvel = scratch[k, 0], scratch[k, 1]
        inertial_to_jacobi(pos[k], weights[k], jpos)
        inertial_to_jacobi(vel[k], weights[k], jvel)
        a0, e_start = jacobi_elements_ae(jpos, jvel, mu[k], watch)
        for b in range(n):
            base = _block(b)
            for c in range(3):
                g[_row(base, P + c) + ulane] = pos[k, c, b]
                g[_row(base, V + c) + ulane] = vel[k, c, b]
                g[_row(base, DP + c) + ulane] = dpos[k, c, b]
                g[_row(base, DV + c) + ulane] = dvel[k, c, b]
            g[_row(base, MASS) + ulane] = m[k, b]
            g[_row(base, WEIGHT) + ulane] = weights[k, b]
            g[_row(base, MU) + ulane] = mu[k, b]
            g[_row(base, RADIUS) + ulane] = radii[k, b]
            g[_row(base, LIVE) + ulane] = 1.0
        g[_row(wb, A0) + ulane] = a0
        g[_row(wb, MAX_E) + ulane] = e_start
        g[_row(wb, DELTA_A) + ulane] = 0.0


@jit
def _finish_group(g, grp, done, pos, vel, dpos, dvel, m, G, dt, t_start, watch, rows, e0, status, steps, out):
    """Each system of group ``grp``: its inertial state and tangent vector into ``pos[k]``, ``vel[k]``,
    ``dpos[k]``, ``dvel[k]`` (where run_system_variational leaves them) and the end of run_system_variational
    (the indicator row, the energy error)."""
    n_sys, n = pos.shape[0], pos.shape[2]
    b0, wb = _block(0), _block(watch)
    for lane in range(LANES):
        k = grp * LANES + lane
        if k >= n_sys:
            break
        ulane = _U(lane)
        code, n_done = np.int64(COMPLETE), done
        if not g[_row(b0, LIVE) + ulane] > 0.0:
            code, n_done = np.int64(g[_row(b0, STOP_CODE) + ulane]), np.int64(g[_row(b0, STOP_STEP) + ulane])
        for b in range(n):
            for c in range(3):
                pos[k, c, b] = g[_row(_block(b), P + c) + ulane]
                vel[k, c, b] = g[_row(_block(b), V + c) + ulane]
                dpos[k, c, b] = g[_row(_block(b), DP + c) + ulane]
                dvel[k, c, b] = g[_row(_block(b), DV + c) + ulane]
        megno = MegnoState(g[_row(b0, M_YS) + ulane], g[_row(b0, M_YSS) + ulane], g[_row(b0, M_COV_YT) + ulane],
                           g[_row(b0, M_VAR_T) + ulane], g[_row(b0, M_MEAN_T) + ulane],
                           g[_row(b0, M_MEAN_Y) + ulane], t_start, n_done)
        record_chaos_indicators(out[k], t_start + n_done * dt, g[_row(wb, MAX_E) + ulane],
                                g[_row(wb, DELTA_A) + ulane], megno)
        if code == DIVERGED:
            out[k, ENERGY_ERROR] = np.nan
        else:
            out[k, ENERGY_ERROR] = abs((_energy(pos[k], vel[k], m[k], G, rows) - e0[k]) / e0[k])
        status[k] = code
        steps[k] = n_done


@jit_parallel_exact
def run_ensemble_variational_lanes(pos, vel, dpos, dvel, m, G, eps2, dt, t_start, n_steps, escape_r2, radii,
                                   check_collisions, watch, weights, mu, scratch, rows, status, steps, out):
    """:func:`orbitsim.ensemble.kernels.run_ensemble_variational` without forces beyond gravity (``G``,
    ``eps2`` in place of its force context), LANES systems per group in SIMD lanes (module docstring): the same
    results bit for bit, ``dpos`` and ``dvel`` left with each system's last tangent vector as that kernel leaves
    them; the groups in parallel (the last one padded). ``scratch`` (K, >= 2, 3, N)."""
    n_sys, n = pos.shape[0], pos.shape[2]
    n_groups = (n_sys + LANES - 1) // LANES
    groups = np.zeros((n_groups, n * BLOCK_ROWS * LANES))
    whole = np.zeros((n_groups, 2, 3, n))
    e0 = np.zeros(n_sys)
    # np.int64 arguments: a prange index, and a literal, are typed otherwise inside a parfor (system_lanes)
    for grp in prange(n_groups):
        g = groups[grp]
        _start_group(g, np.int64(grp), pos, vel, dpos, dvel, m, G, weights, mu, radii, watch, rows, scratch, e0)
        done = run_tangent_group(g, np.int64(n), G, eps2, dt, t_start, n_steps, escape_r2, check_collisions, watch,
                                 whole[grp])
        _finish_group(g, np.int64(grp), np.int64(done), pos, vel, dpos, dvel, m, G, dt, t_start, watch, rows, e0,
                      status, steps, out)
