"""Whole Wisdom-Holman systems in SIMD lanes: LANES systems of the same N stepped side by side, each with its bits.

:func:`orbitsim.ensemble.kernels.run_ensemble_wh` steps one system per ``prange`` iteration with the scalar
operators. Here LANES systems (a group) take each step together, as :mod:`orbitsim.ensemble.lanes` steps a
map's test bodies: the step's every part is a loop over the lanes with no branch LLVM cannot turn into a
select, so it compiles to vector instructions, and each lane performs :func:`~orbitsim.ensemble.kernels.run_system`'s
operations in the same order (no fastmath: a vector add or multiply rounds as the scalar one), so each system
keeps its bits (tests/ensemble/test_system_lanes.py compares them bit for bit).

Layout. A group is one flat array of N blocks, block b holding body b of every lane: :data:`BLOCK_ROWS` rows
of LANES numbers (its Jacobi and inertial state, accelerations, mass, weight, Kepler parameter, radius, and
per-lane scratch). Every lane loop reads and writes one block only, at distances LLVM knows, with unsigned
offsets (a signed index keeps Numba's negative-index select, which LLVM cannot see through); a loop touching
two blocks at a distance known only at run time stays scalar, because Numba's array accesses give LLVM no
way to check the overlap at run time. What one body's block needs from another's (the centre of mass carried
down the Jacobi chain, the other body of a pair, a row's pair sum, the stop test's running verdict) is copied
between blocks by :func:`_copy_row`, straight-line code that LLVM's SLP vectoriser turns into vector moves.

Where the scalar step would branch, the lanes take the common case and a lane outside it is redone by the
scalar code, as in :mod:`orbitsim.ensemble.lanes`: a body's Kepler drift (:func:`drift_body_lanes`) iterates
Newton from the series start with the Stumpff series in every lane, and a lane that is not a short step,
leaves the series range or does not settle in :data:`~orbitsim.physics.kepler_solver.NEWTON_FAST_ITERATIONS`
is drifted by :func:`orbitsim.physics.kepler.kepler_drift` (the bits of ``kepler_drift_bodies``).

A lane stops alone, at the step the scalar kernel stops (a failed drift, or the stop test after the kick:
non-finite, escaped, collided, with the scalar test's precedence); its state rows are no longer written. The
synchronisation and energy error at the end are the scalar kernel's own code
(:func:`~orbitsim.ensemble.kernels.finish_system`), once per system.

Why one module: the block layout (the row constants) and the loops that index it are one piece, the scalar
step written lane-wise part for part (drift, kick, elements, stop test), and read best beside each other;
split, every part would import the layout and none could be read alone. The drift and the kick are called
from one place each, so that their long code is inlined, and compiled, once; the kick and the row copies are
inlined by LLVM (:func:`orbitsim._jit.jit_llvm_inline`), the rest by Numba (inlined by Numba, the kick and its
copies took 9 of a first run's 34 compile CPU-s, 2.5 now; the step's time is the same). The Kepler solve
(:func:`kepler_solve_lanes`), the Jacobi chain's steps (:func:`jacobi_up_lanes`, :func:`jacobi_down_lanes`),
the pair accelerations (:func:`pair_accelerations_lanes`, their row sums started or carried by
:func:`start_row_sums`), the orbit tracking, the stop test and a lane's stop (:func:`stop_lane`) take their rows
as arguments: the variational ensemble (:mod:`orbitsim.ensemble.system_tangent_lanes`), whose blocks hold a
tangent vector too, calls them with its own layout's rows.
"""

from __future__ import annotations

import math

import numpy as np

from orbitsim._jit import jit, jit_inline, jit_llvm_inline, stop_requested, wide_vectors
from orbitsim.ensemble.kernels import _energy, elements_ae, finish_system, jacobi_elements_ae
from orbitsim.ensemble.parallel import aligned_zeros, over_threads
from orbitsim.ensemble.status import COLLIDED, COMPLETE, DIVERGED, ESCAPED
from orbitsim.physics.coordinates import inertial_to_jacobi
from orbitsim.physics.kepler import KEPLER_OK, fg_apply, kepler_drift, lagrange_coefficients
from orbitsim.physics.kepler_solver import (
    NEWTON_FAST_ITERATIONS,
    STUMPFF_SERIES_MAX_Z,
    newton_terms,
    setup_short,
    stiefel_short,
)

_U = np.uint64

#: Systems per group: 16 doubles, two AVX-512 registers (four AVX2 ones). :func:`_copy_row` is written out
#: for 16 (a map's pixels, :mod:`orbitsim.ensemble.lanes`, have a width of their own).
LANES = 16

# Rows of a body's block (each LANES numbers):
JP, JV, IPOS, ACC = 0, 3, 6, 9  # Jacobi position and velocity, inertial position, accelerations (3 rows each)
MASS, WEIGHT, MU, RADIUS = 12, 13, 14, 15  # m_b, the Jacobi weight m_b / M_b, G M_b, the radius
LIVE = 16  # 1: stepping; 0: stopped (STOP_CODE, STOP_STEP in block 0); -1: padding. Kept in every block.
K_R0, K_ETA0, K_ZETA0, K_BETA, K_X, K_R0I, K_PENDING, K_FAST, K_G1, K_G2, K_G3, K_R = range(17, 29)  # the drift
CARRY = 29  # 3 rows: a sum carried from block to block (a centre of mass, a pair-loop row's sum)
OTHER, OTHER_S = 32, 35  # 3 rows and 1: another body's inertial position and its mass (or radius), copied here
RANK, HIT = 36, 37  # the stop test's running verdict (3 diverged, 2 escaped, 1 collided, 0 none); a collision seen
A0, MAX_E, DELTA_A = 38, 39, 40  # track_orbit's start a, largest e, largest |a - a0| / |a0| (the watched body's block)
STOP_CODE, STOP_STEP = 41, 42  # a stopped lane's status and step count (block 0)
BLOCK_ROWS = 43


@jit_inline
def _row(base, row):
    """The element offset of ``row`` of the block at ``base`` (unsigned)."""
    return base + _U(row * LANES)


@jit_inline
def _block(b):
    """The element offset of body ``b``'s block."""
    return _U(b * (BLOCK_ROWS * LANES))


@jit_inline
def _block_of(block_rows, b):
    """The element offset of body ``b``'s block in a layout of ``block_rows`` rows a block."""
    return _U(b * (block_rows * LANES))


@jit_llvm_inline
def _copy_row(g, dst, src):
    """Copy the LANES numbers at ``src`` to ``dst``: every load before any store, so that LLVM's SLP vectoriser
    makes vector moves of them (it may not reorder a load past a store that could overlap it)."""
    wide_vectors()
    a0, a1, a2, a3 = g[src], g[src + _U(1)], g[src + _U(2)], g[src + _U(3)]
    a4, a5, a6, a7 = g[src + _U(4)], g[src + _U(5)], g[src + _U(6)], g[src + _U(7)]
    a8, a9, a10, a11 = g[src + _U(8)], g[src + _U(9)], g[src + _U(10)], g[src + _U(11)]
    a12, a13, a14, a15 = g[src + _U(12)], g[src + _U(13)], g[src + _U(14)], g[src + _U(15)]
    g[dst], g[dst + _U(1)], g[dst + _U(2)], g[dst + _U(3)] = a0, a1, a2, a3
    g[dst + _U(4)], g[dst + _U(5)], g[dst + _U(6)], g[dst + _U(7)] = a4, a5, a6, a7
    g[dst + _U(8)], g[dst + _U(9)], g[dst + _U(10)], g[dst + _U(11)] = a8, a9, a10, a11
    g[dst + _U(12)], g[dst + _U(13)], g[dst + _U(14)], g[dst + _U(15)] = a12, a13, a14, a15


@jit_llvm_inline
def _copy_rows(g, dst_base, dst_row, src_base, src_row, count):
    wide_vectors()
    for c in range(count):
        _copy_row(g, _row(dst_base, dst_row + c), _row(src_base, src_row + c))


@jit_inline
def kepler_solve_lanes(g, base, h, jp, jv, mu_row, live_row, k0):
    """The solve of a Kepler drift by ``h`` for every lane of the body whose block is at ``base`` (position and
    velocity rows ``jp``, ``jv``, its G M and LIVE rows ``mu_row``, ``live_row``; every caller gives its layout's
    constant rows): each lane Newton-iterates from the series start with the Stumpff series, stopping when its
    residual settles. Leaves in the 12 rows from ``k0`` (the K_R0 .. K_R order) r0, eta0, zeta0, beta, X, 1/r0,
    pending (1: not settled in NEWTON_FAST_ITERATIONS), fast (1: a short step of a live lane that stayed in the
    series range, which the caller may finish; a lane about mu = 0, which the scalar drift moves in a straight
    line, is not), G1, G2, G3 and r. Shared by :func:`drift_body_lanes` and the variational ensemble's drift."""
    jx, jy, jz = _row(base, jp), _row(base, jp + 1), _row(base, jp + 2)
    vxr, vyr, vzr = _row(base, jv), _row(base, jv + 1), _row(base, jv + 2)
    mur, liver = _row(base, mu_row), _row(base, live_row)
    r0r, etar, zetar, betar, xr, r0ir = (_row(base, k0), _row(base, k0 + 1), _row(base, k0 + 2),
                                         _row(base, k0 + 3), _row(base, k0 + 4), _row(base, k0 + 5))
    pendr, fastr, g1r, g2r, g3r, rr = (_row(base, k0 + 6), _row(base, k0 + 7), _row(base, k0 + 8),
                                       _row(base, k0 + 9), _row(base, k0 + 10), _row(base, k0 + 11))
    for lane in range(_U(LANES)):
        x, y, z = g[jx + lane], g[jy + lane], g[jz + lane]
        vx, vy, vz = g[vxr + lane], g[vyr + lane], g[vzr + lane]
        r0 = math.sqrt(x * x + y * y + z * z)
        eta0 = x * vx + y * vy + z * vz
        mu = g[mur + lane]
        r0i, zeta0, beta, X, short = setup_short(r0, vx * vx + vy * vy + vz * vz, eta0, mu, h)
        short = short & (mu != 0.0)  # the scalar drift moves a body about mu = 0 in a straight line
        live = g[liver + lane] > 0.0  # loaded before the ``and``: a load inside it is a branch, and no vector
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


@jit_inline
def drift_body_lanes(g, base, h):
    """Kepler drift by ``h`` of the live lanes of the body whose block is at ``base`` (its JP, JV rows about
    MU), each lane with the bits of :func:`orbitsim.physics.kepler.kepler_drift`: the solve
    (:func:`kepler_solve_lanes`), then the f and g functions, or the scalar drift for a lane the lanes did not
    finish. Returns the number of live lanes whose drift failed (their LIVE in this block set to 0; the caller
    stops them)."""
    kepler_solve_lanes(g, base, h, JP, JV, MU, LIVE, K_R0)
    jx, jy, jz = _row(base, JP), _row(base, JP + 1), _row(base, JP + 2)
    vxr, vyr, vzr = _row(base, JV), _row(base, JV + 1), _row(base, JV + 2)
    mur, liver = _row(base, MU), _row(base, LIVE)
    r0ir, pendr, fastr = _row(base, K_R0I), _row(base, K_PENDING), _row(base, K_FAST)
    g1r, g2r, g3r, rr = _row(base, K_G1), _row(base, K_G2), _row(base, K_G3), _row(base, K_R)
    for lane in range(_U(LANES)):
        x, y, z = g[jx + lane], g[jy + lane], g[jz + lane]
        vx, vy, vz = g[vxr + lane], g[vyr + lane], g[vzr + lane]
        _, f, gl, fd, gd = lagrange_coefficients(g[mur + lane], h, g[r0ir + lane], g[g1r + lane], g[g2r + lane],
                                                 g[g3r + lane], g[rr + lane])
        nx, ny, nz, nvx, nvy, nvz = fg_apply(x, y, z, vx, vy, vz, f, gl, fd, gd)
        fast, settled, live = g[fastr + lane] > 0.0, g[pendr + lane] == 0.0, g[liver + lane] > 0.0
        ok = fast and settled and live
        g[jx + lane] = nx if ok else x
        g[jy + lane] = ny if ok else y
        g[jz + lane] = nz if ok else z
        g[vxr + lane] = nvx if ok else vx
        g[vyr + lane] = nvy if ok else vy
        g[vzr + lane] = nvz if ok else vz
        g[fastr + lane] = 1.0 if ok else 0.0  # from here: done by the lanes
    failed = 0
    for lane in range(LANES):
        ulane = _U(lane)
        if g[fastr + ulane] > 0.0 or not g[liver + ulane] > 0.0:
            continue
        jpos = g[jx:jx + _U(3 * LANES)].reshape((3, LANES))
        jvel = g[vxr:vxr + _U(3 * LANES)].reshape((3, LANES))
        if kepler_drift(jpos, jvel, lane, g[mur + ulane], h) != KEPLER_OK:
            g[liver + ulane] = 0.0
            failed += 1
    return failed


@jit_inline
def jacobi_up_lanes(g, base, src, dst, carry, width, weight_row):
    """One body's step of inertial_to_jacobi on the rows at ``src``: ``dst`` = src - the interior centre of mass
    (the ``carry`` rows), which then moves by weight (row ``weight_row``) times that. Every caller gives constant
    rows (the plain kick, :func:`kick_lanes`, and the variational step, in their layouts)."""
    w = _row(base, weight_row)
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
def jacobi_down_lanes(g, base, src, dst, carry, masked, width, weight_row, live_row):
    """One body's step of jacobi_to_inertial on the three rows at ``src``: the centre of mass (``carry``) moves
    back by weight (row ``weight_row``) times the Jacobi vector, and ``dst`` = the vector plus it (where ``masked``,
    live lanes only: LIVE in row ``live_row``). Every caller gives constant rows (as :func:`jacobi_up_lanes`)."""
    w, liver = _row(base, weight_row), _row(base, live_row)
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
def _rank_code(verdict):
    """The stop test's verdict (a rank: the larger wins) as a status of :mod:`orbitsim.ensemble.status`."""
    if verdict == 1.0:
        return COLLIDED
    return ESCAPED if verdict == 2.0 else DIVERGED


@jit
def stop_lane(g, n, lane, code, step, block_rows, live_row, code_row, step_row):
    """Lane ``lane`` stops with status ``code`` after ``step`` steps: LIVE (row ``live_row``) 0 in every block,
    the code and step in block 0's rows ``code_row``, ``step_row``. Blocks of ``block_rows`` rows: each caller
    gives its layout's constants (shared with the variational ensemble)."""
    for b in range(n):
        g[_row(_block_of(block_rows, b), live_row) + _U(lane)] = 0.0
    g[_row(_U(0), code_row) + _U(lane)] = code
    g[_row(_U(0), step_row) + _U(lane)] = step


@jit
def stop_failed_drifts(g, n, b, step, block_rows, live_row, code_row, step_row):
    """Stop the live lanes whose drift of body ``b`` failed (their LIVE 0 in b's block only); returns how many.
    The layout's constants as :func:`stop_lane`'s."""
    stopped, live0, liveb = 0, _row(_U(0), live_row), _row(_block_of(block_rows, b), live_row)
    for lane in range(LANES):
        if g[live0 + _U(lane)] > 0.0 and not g[liveb + _U(lane)] > 0.0:
            stop_lane(g, n, lane, np.int64(DIVERGED), step, block_rows, live_row, code_row, step_row)
            stopped += 1
    return stopped


@jit_inline
def start_row_sums(g, block_rows, j, first, carry, width):
    """Start or carry a pair loop's running row sums (the 3 rows at ``carry``) in block ``j``: zero where ``j``
    is the row's first pair (``first``), else the sums so far carried from block j - 1 (blocks of
    ``block_rows`` rows, the caller's layout)."""
    bj = _block_of(block_rows, j)
    if j == first:
        for c in range(3):
            sums = _row(bj, carry + c)
            for lane in range(width):
                g[sums + lane] = 0.0
    else:
        _copy_rows(g, bj, carry, _block_of(block_rows, j - 1), carry, 3)


@jit_inline
def pair_accelerations_lanes(g, n, G, eps2, width, zero_width, block_rows, pos, acc, mass, carry, other, other_s):
    """interaction_accelerations (Jacobi: the (0, 1) pair left out) of every lane at the inertial positions
    (rows ``pos``) into the 3 rows at ``acc``: pair (i, j > i) in j's block, with i's position and mass (row
    ``mass``) copied to the rows ``other``, ``other_s`` there, and row i's sum carried from j to j + 1 in the
    rows ``carry``, then added to i's: the scalar sum's order. Blocks of ``block_rows`` rows; every caller
    gives its layout's constants (the plain kick, :func:`kick_lanes`, and the variational one). The rows are
    zeroed in loops of ``zero_width`` lanes, the sums added in loops of ``width`` (both LANES: each kick passes
    the counts its own loops had, a constant or one counted at run time, see :func:`run_group`)."""
    for b in range(n):
        for c in range(3):
            row = _row(_block_of(block_rows, b), acc + c)
            for lane in range(zero_width):
                g[row + lane] = 0.0
    for i in range(n):
        bi = _block_of(block_rows, i)
        start = 2 if i == 0 else i + 1
        for j in range(start, n):
            bj = _block_of(block_rows, j)
            _copy_rows(g, bj, other, bi, pos, 3)
            _copy_row(g, _row(bj, other_s), _row(bi, mass))
            start_row_sums(g, block_rows, j, start, carry, zero_width)
            xj, yj, zj = _row(bj, pos), _row(bj, pos + 1), _row(bj, pos + 2)
            xi, yi, zi = _row(bj, other), _row(bj, other + 1), _row(bj, other + 2)
            ax, ay, az = _row(bj, carry), _row(bj, carry + 1), _row(bj, carry + 2)
            accx, accy, accz = _row(bj, acc), _row(bj, acc + 1), _row(bj, acc + 2)
            mj_r, mi_r = _row(bj, mass), _row(bj, other_s)
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
            _copy_rows(g, bi, carry, _block_of(block_rows, n - 1), carry, 3)
        else:  # a row without pairs adds its empty sum
            for c in range(3):
                sums = _row(bi, carry + c)
                for lane in range(zero_width):
                    g[sums + lane] = 0.0
        accx, accy, accz = _row(bi, acc), _row(bi, acc + 1), _row(bi, acc + 2)
        cx, cy, cz = _row(bi, carry), _row(bi, carry + 1), _row(bi, carry + 2)
        for lane in range(width):
            g[accx + lane] += g[cx + lane]
            g[accy + lane] += g[cy + lane]
            g[accz + lane] += g[cz + lane]


@jit_llvm_inline
def kick_lanes(g, n, G, eps2, dt, width):
    """:func:`orbitsim.integrators.wisdom_holman.operators.interaction_kick` (Jacobi) of every lane: the
    inertial positions, the pair accelerations, their Jacobi transform and the kick of the live lanes'
    velocities, each the scalar kick's operations in its order. ``width`` is LANES (see :func:`run_group`)."""
    wide_vectors()
    b0 = _block(0)
    # inertial positions: the centre of mass carried from body n-1 down to body 1 (jacobi_to_inertial)
    _copy_rows(g, _block(n - 1), CARRY, b0, JP, 3)
    for i in range(n - 1, 0, -1):
        base = _block(i)
        jacobi_down_lanes(g, base, JP, IPOS, CARRY, False, _U(LANES), WEIGHT, LIVE)
        if i > 1:
            _copy_rows(g, _block(i - 1), CARRY, base, CARRY, 3)
        else:
            _copy_rows(g, b0, IPOS, base, CARRY, 3)
    # the pair accelerations (interaction_accelerations, Jacobi: the (0, 1) pair left out)
    pair_accelerations_lanes(g, n, G, eps2, width, _U(LANES), BLOCK_ROWS, IPOS, ACC, MASS, CARRY, OTHER, OTHER_S)
    # their Jacobi transform (inertial_to_jacobi): the interior centre of mass carried from body 1 up
    _copy_rows(g, _block(1), CARRY, b0, ACC, 3)
    for i in range(1, n):
        base = _block(i)
        jacobi_up_lanes(g, base, ACC, ACC, CARRY, _U(LANES), WEIGHT)
        if i + 1 < n:
            _copy_rows(g, _block(i + 1), CARRY, base, CARRY, 3)
    # the kick: body 1's Kepler term cancels the (0, 1) pair; bodies i >= 2 add G M_i r'_i / |r'_i|^3
    for i in range(1, n):
        base = _block(i)
        accx, accy, accz = _row(base, ACC), _row(base, ACC + 1), _row(base, ACC + 2)
        vx, vy, vz = _row(base, JV), _row(base, JV + 1), _row(base, JV + 2)
        jx, jy, jz = _row(base, JP), _row(base, JP + 1), _row(base, JP + 2)
        mur, liver = _row(base, MU), _row(base, LIVE)
        if i > 1:
            for lane in range(_U(LANES)):
                ax, ay, az = g[accx + lane], g[accy + lane], g[accz + lane]
                x, y, z = g[jx + lane], g[jy + lane], g[jz + lane]
                r2 = x * x + y * y + z * z
                k = g[mur + lane] / (r2 * math.sqrt(r2))
                ax += k * x
                ay += k * y
                az += k * z
                live, ux, uy, uz = g[liver + lane] > 0.0, g[vx + lane], g[vy + lane], g[vz + lane]
                g[vx + lane] = ux + dt * ax if live else ux  # loaded before the select: no masked loads
                g[vy + lane] = uy + dt * ay if live else uy
                g[vz + lane] = uz + dt * az if live else uz
        else:
            for lane in range(_U(LANES)):
                live, ux, uy, uz = g[liver + lane] > 0.0, g[vx + lane], g[vy + lane], g[vz + lane]
                ax, ay, az = g[accx + lane], g[accy + lane], g[accz + lane]
                g[vx + lane] = ux + dt * ax if live else ux
                g[vy + lane] = uy + dt * ay if live else uy
                g[vz + lane] = uz + dt * az if live else uz


@jit_inline
def track_orbit_lanes(g, base, jp, jv, mu_row, live_row, a0_row):
    """track_orbit for the live lanes: the watched body's (block ``base``) Jacobi a and e from its rows ``jp``,
    ``jv`` about ``mu_row``, the largest e and |a - a0| / |a0| kept in the two rows after ``a0_row`` (every caller
    gives its layout's constant rows; shared with the variational ensemble)."""
    jx, jy, jz = _row(base, jp), _row(base, jp + 1), _row(base, jp + 2)
    vx, vy, vz = _row(base, jv), _row(base, jv + 1), _row(base, jv + 2)
    mur, liver, a0r, max_er, delta_ar = (_row(base, mu_row), _row(base, live_row), _row(base, a0_row),
                                         _row(base, a0_row + 1), _row(base, a0_row + 2))
    for lane in range(_U(LANES)):
        a, e = elements_ae(g[jx + lane], g[jy + lane], g[jz + lane], g[vx + lane], g[vy + lane], g[vz + lane],
                           g[mur + lane])
        spread = abs(a - g[a0r + lane]) / abs(g[a0r + lane])
        live = g[liver + lane] > 0.0
        max_e, delta_a = g[max_er + lane], g[delta_ar + lane]
        g[max_er + lane] = e if (live and e > max_e) else max_e
        g[delta_ar + lane] = spread if (live and spread > delta_a) else delta_a


@jit_inline
def stop_test_lanes(g, n, escape_r2, check_collisions, width, block_rows, pos, radius, other, other_s,
                    rank_row):
    """:func:`orbitsim.ensemble.kernels._stop_reason` of every lane's inertial positions (rows ``pos``: IPOS,
    from the kick, in this module's layout) as a rank carried from block 0 to block n - 1 (3 non-finite,
    2 escaped, 1 collided, 0 none: the larger wins, the scalar test's precedence); left in block 0's
    ``rank_row`` row (the row after it: a collision seen). Blocks of ``block_rows`` rows, a body's radius in row
    ``radius``, 3 rows from ``other`` and the row ``other_s`` scratch: every caller gives its layout's
    constants (shared with the variational ensemble). ``width`` is LANES (see :func:`run_group`)."""
    b0 = _block_of(block_rows, 0)
    if check_collisions:  # pair (i, j) in j's block, with i's position and radius copied there
        for j in range(n):
            hit = _row(_block_of(block_rows, j), rank_row + 1)
            for lane in range(width):
                g[hit + lane] = 0.0
        for i in range(n):
            bi = _block_of(block_rows, i)
            for j in range(i + 1, n):
                bj = _block_of(block_rows, j)
                _copy_rows(g, bj, other, bi, pos, 3)
                _copy_row(g, _row(bj, other_s), _row(bi, radius))
                xj, yj, zj = _row(bj, pos), _row(bj, pos + 1), _row(bj, pos + 2)
                xi, yi, zi = _row(bj, other), _row(bj, other + 1), _row(bj, other + 2)
                ri, rj, hit = _row(bj, other_s), _row(bj, radius), _row(bj, rank_row + 1)
                for lane in range(width):
                    reach = g[ri + lane] + g[rj + lane]
                    dx = g[xj + lane] - g[xi + lane]
                    dy = g[yj + lane] - g[yi + lane]
                    dz = g[zj + lane] - g[zi + lane]
                    met = (reach > 0.0) & (dx * dx + dy * dy + dz * dz < reach * reach)
                    g[hit + lane] = 1.0 if met else g[hit + lane]
    x0, y0, z0, rank = _row(b0, pos), _row(b0, pos + 1), _row(b0, pos + 2), _row(b0, rank_row)
    for lane in range(width):
        x, y, z = g[x0 + lane], g[y0 + lane], g[z0 + lane]
        g[rank + lane] = 0.0 if (math.isfinite(x) & math.isfinite(y) & math.isfinite(z)) else 3.0
    for b in range(1, n):
        base = _block_of(block_rows, b)
        _copy_rows(g, base, other, b0, pos, 3)
        _copy_row(g, _row(base, rank_row), _row(_block_of(block_rows, b - 1), rank_row))
        x, y, z = _row(base, pos), _row(base, pos + 1), _row(base, pos + 2)
        xs, ys, zs = _row(base, other), _row(base, other + 1), _row(base, other + 2)
        rank, hit = _row(base, rank_row), _row(base, rank_row + 1)
        for lane in range(width):
            xb, yb, zb = g[x + lane], g[y + lane], g[z + lane]
            dx, dy, dz = xb - g[xs + lane], yb - g[ys + lane], zb - g[zs + lane]
            verdict, met = g[rank + lane], g[hit + lane] > 0.0
            verdict = 1.0 if (check_collisions & met & (verdict < 1.0)) else verdict
            verdict = 2.0 if ((dx * dx + dy * dy + dz * dz > escape_r2) & (verdict < 2.0)) else verdict
            finite = math.isfinite(xb) & math.isfinite(yb) & math.isfinite(zb)
            g[rank + lane] = verdict if finite else 3.0
    _copy_row(g, _row(b0, rank_row), _row(_block_of(block_rows, n - 1), rank_row))


@jit
def run_group(g, n, G, dt, n_steps, escape_r2, check_collisions, watch):
    """Step a group's live lanes ``n_steps`` times, each until it stops (its LIVE 0, STOP_CODE, STOP_STEP in
    block 0). Returns the steps taken by the lanes still live at the end (``n_steps`` unless a stop of the
    kernels was asked for, :func:`orbitsim._jit.stop_requested`: the caller then throws the results away)."""
    wide_vectors()
    half = 0.5 * dt
    eps2 = 0.0
    b0 = _block(0)
    # LANES as a number LLVM cannot see, for the short lane loops: with a known count of 16 LLVM unrolls them
    # first, and their unrolled code (isfinite, selects, sums) was not vectorised; counted at run time they are
    width = _U(g.size // (n * BLOCK_ROWS))
    live_lanes = 0
    for lane in range(LANES):
        live_lanes += g[_row(b0, LIVE) + _U(lane)] > 0.0
    done = 0
    while done < n_steps and live_lanes > 0:
        if stop_requested():
            break
        h = half if done == 0 else dt
        for b in range(1, n):  # bodies 1..n-1 (kepler_drift_bodies); one call site, so inlined and compiled once
            if drift_body_lanes(g, _block(b), h) > 0:
                live_lanes -= stop_failed_drifts(g, n, b, done + 1, BLOCK_ROWS, LIVE, STOP_CODE, STOP_STEP)
        jx, jy, jz, liver = _row(b0, JP), _row(b0, JP + 1), _row(b0, JP + 2), _row(b0, LIVE)
        vx, vy, vz = _row(b0, JV), _row(b0, JV + 1), _row(b0, JV + 2)
        for lane in range(width):  # the centre of mass drifts
            live, x, y, z = g[liver + lane] > 0.0, g[jx + lane], g[jy + lane], g[jz + lane]
            g[jx + lane] = x + h * g[vx + lane] if live else x
            g[jy + lane] = y + h * g[vy + lane] if live else y
            g[jz + lane] = z + h * g[vz + lane] if live else z
        kick_lanes(g, n, G, eps2, dt, width)
        done += 1
        track_orbit_lanes(g, _block(watch), JP, JV, MU, LIVE, A0)
        stop_test_lanes(g, n, escape_r2, check_collisions, width, BLOCK_ROWS, IPOS, RADIUS, OTHER, OTHER_S,
                        RANK)
        for lane in range(LANES):
            verdict = g[_row(b0, RANK) + _U(lane)]
            if verdict > 0.0 and g[_row(b0, LIVE) + _U(lane)] > 0.0:
                stop_lane(g, n, lane, _rank_code(verdict), done, BLOCK_ROWS, LIVE, STOP_CODE, STOP_STEP)
                live_lanes -= 1
    return done


@jit
def _start_group(g, grp, pos, vel, m, G, weights, mu, radii, watch, rows, jpos, jvel, e0):
    """Fill group ``grp``'s blocks from its systems (run_system's start: energy, Jacobi state, the watched
    body's elements); lanes past the last system are padding, a copy of lane 0 that is never live."""
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
        inertial_to_jacobi(pos[k], weights[k], jpos[k])
        inertial_to_jacobi(vel[k], weights[k], jvel[k])
        a0, e_start = jacobi_elements_ae(jpos[k], jvel[k], mu[k], watch)
        for b in range(n):
            base = _block(b)
            for c in range(3):
                g[_row(base, JP + c) + ulane] = jpos[k, c, b]
                g[_row(base, JV + c) + ulane] = jvel[k, c, b]
            g[_row(base, MASS) + ulane] = m[k, b]
            g[_row(base, WEIGHT) + ulane] = weights[k, b]
            g[_row(base, MU) + ulane] = mu[k, b]
            g[_row(base, RADIUS) + ulane] = radii[k, b]
            g[_row(base, LIVE) + ulane] = 1.0
        g[_row(wb, A0) + ulane] = a0
        g[_row(wb, MAX_E) + ulane] = e_start
        g[_row(wb, DELTA_A) + ulane] = 0.0


@jit
def _finish_group(g, grp, done, pos, vel, m, G, dt, t_start, watch, jpos, jvel, ipos, iacc, weights, mu, ks, kstage,
                  rows, e0, status, steps, out):
    """Each system of group ``grp``: its lane's Jacobi state into ``jpos[k]``, ``jvel[k]``, then
    :func:`~orbitsim.ensemble.kernels.finish_system` (synchronisation, energy error, the indicator row)."""
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
                jpos[k, c, b] = g[_row(_block(b), JP + c) + ulane]
                jvel[k, c, b] = g[_row(_block(b), JV + c) + ulane]
        st, n_done = finish_system(pos[k], vel[k], m[k], G, dt, t_start, n_done, code, g[_row(wb, MAX_E) + ulane],
                                   g[_row(wb, DELTA_A) + ulane], e0[k], jpos[k], jvel[k], ipos[k], iacc[k], weights[k],
                                   mu[k], ks[k], kstage[k], rows, out[k])
        status[k] = st
        steps[k] = n_done


@jit
def _run_groups(first, last, groups, e0, pos, vel, m, G, dt, t_start, n_steps, escape_r2, radii, check_collisions,
                watch, jpos, jvel, ipos, iacc, weights, mu, ks, kstage, rows, status, steps, out):
    """Groups ``first .. last - 1`` of :func:`run_ensemble_wh_lanes`, one after another (one thread's range)."""
    n = pos.shape[2]
    for grp in range(first, last):
        g = groups[grp]
        _start_group(g, grp, pos, vel, m, G, weights, mu, radii, watch, rows, jpos, jvel, e0)
        done = run_group(g, np.int64(n), G, dt, n_steps, escape_r2, check_collisions, watch)
        _finish_group(g, grp, np.int64(done), pos, vel, m, G, dt, t_start, watch, jpos, jvel, ipos, iacc, weights,
                      mu, ks, kstage, rows, e0, status, steps, out)


def run_ensemble_wh_lanes(pos: np.ndarray, vel: np.ndarray, m: np.ndarray, G: float, dt: float, t_start: float,
                          n_steps: np.int64, escape_r2: float, radii: np.ndarray, check_collisions: bool,
                          watch: np.int64, jpos: np.ndarray, jvel: np.ndarray, ipos: np.ndarray, iacc: np.ndarray,
                          weights: np.ndarray, mu: np.ndarray, ks: np.ndarray, kstage: np.ndarray, rows: np.ndarray,
                          status: np.ndarray, steps: np.ndarray, out: np.ndarray) -> None:
    """:func:`orbitsim.ensemble.kernels.run_ensemble_wh` with LANES systems per group in SIMD lanes (module
    docstring): the same arguments, the same results bit for bit; the groups over the threads
    (:func:`orbitsim.ensemble.parallel.over_threads`; the last group padded)."""
    n_sys, n = pos.shape[0], pos.shape[2]
    n_groups = (n_sys + LANES - 1) // LANES
    groups = aligned_zeros((n_groups, n * BLOCK_ROWS * LANES))  # rows start cache lines (parallel.py)
    e0 = np.zeros(n_sys)
    over_threads(_run_groups, n_groups, groups, e0, pos, vel, m, G, dt, t_start, n_steps, escape_r2, radii,
                 check_collisions, watch, jpos, jvel, ipos, iacc, weights, mu, ks, kstage, rows, status, steps, out)
