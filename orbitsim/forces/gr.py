"""General relativity about one dominant mass: REBOUNDx ``gr``, jitted (``gr_potential``, the
position-only approximation, is :mod:`orbitsim.forces.gr_potential`).

``gr`` (Anderson et al. 1975, ApJ 200, 221; REBOUNDx ``gr.c``): the first post-Newtonian force of
a single mass, applied to every body's Jacobi coordinate, with mu = G M:

    a_PN = B (1 - A) r - A a_N - D v~,
    A = (v~^2 / 2 + 3 mu / r) / c^2,   B = (mu / r - 3/2 v~^2) mu / (r^3 c^2),
    D = (v~ . (a_N + B r) - 3 mu / r^3 (r . v)) / c^2,

where v~ = v / (1 - A) is solved by fixed-point iteration (A depends on v~), and a_N is the
Newtonian acceleration of the Jacobi coordinate. Its conserved Hamiltonian (REBOUNDx
``rebx_gr_hamiltonian``) is the Newtonian energy with v~ in the Jacobi kinetic energy plus

    V_PN = sum_i m'_i [mu^2 / (2 r^2) - v~^4 / 8 - 3/2 mu v~^2 / r] / c^2   (m'_i: Jacobi masses).

REBOUNDx always takes particle 0 as the source. Here the source may be any body: the Jacobi chain
is built with the source first and the other bodies after it in index order, which for source 0
is REBOUNDx's chain, operation for operation.
"""
from __future__ import annotations

import math

import numpy as np

from orbitsim._jit import jit, jit_inline, jit_llvm_inline

#: Fixed-point iterations for v~ (REBOUNDx's default ``max_iterations``).
MAX_ITERATIONS = 10
#: Rows of ``gr``'s work: Newtonian accelerations (0-2), Jacobi x, v, a (3-11), Jacobi 1PN
#: accelerations (12-14), per Jacobi coordinate r, mu / r, 3 mu / r, r^3, 3 mu / r^3 (15-19), and
#: v~ (20-22), |v~|^2, A and a converged flag (23-25) when solved for every coordinate at once
#: (:func:`_solve_vtilde_all`).
GR_WORK_ROWS = 26
_W, _W2, _A, _DONE = 20, 23, 24, 25
_EPS = np.finfo(np.float64).eps
#: Rows of ``gr``'s operator cache (:func:`gr_prepare_once`): a work block of GR_WORK_ROWS that
#: :func:`gr_prepare` filled, then the positions (3 rows) and masses (1 row) it was filled for, and a
#: key row: the source + 1 (0: empty) and G.
GR_CACHE_ROWS = GR_WORK_ROWS + 5


@jit_inline
def chain(k, src):
    """The body at place k of the Jacobi chain: the source first, then the others in index order."""
    if k == 0:
        return src
    if k - 1 < src:
        return k - 1
    return k


@jit_inline
def _newtonian_in_chain(pos, m, G, src, an):
    """an (3, N) = Newtonian accelerations, indexed by chain place, pairs summed in chain order."""
    n = pos.shape[1]
    for c in range(3):  # explicit loops: a slice assignment costs more than the 9-body sum it clears for
        for a in range(n):
            an[c, a] = 0.0
    for a in range(n):
        i = chain(a, src)
        # body a's sums in registers over its pairs (the same operations in the same order): in memory,
        # every pair's update waited on the last one's store
        ax, ay, az = an[0, a], an[1, a], an[2, a]
        xi, yi, zi = pos[0, i], pos[1, i], pos[2, i]
        for b in range(a + 1, n):
            j = chain(b, src)
            dx = xi - pos[0, j]
            dy = yi - pos[1, j]
            dz = zi - pos[2, j]
            r2 = dx * dx + dy * dy + dz * dz
            r = np.sqrt(r2)
            prefac = G / (r2 * r)
            ax -= prefac * m[j] * dx
            ay -= prefac * m[j] * dy
            az -= prefac * m[j] * dz
            an[0, b] += prefac * m[i] * dx
            an[1, b] += prefac * m[i] * dy
            an[2, b] += prefac * m[i] * dz
        an[0, a] = ax
        an[1, a] = ay
        an[2, a] = az


@jit_inline
def _to_jacobi_positions(pos, an, m, src, jac):
    """jac rows 0-2 and 6-8 = Jacobi x and a of chain places 1..N-1 (REBOUND's posvelacc
    transformation, the rows that depend on positions only). Column 0 (no Jacobi coordinate)
    holds the running mass-weighted sums; each row's sums are its own, so the rows can be
    transformed apart with the same bits."""
    n = pos.shape[1]
    i0 = chain(0, src)
    eta = m[i0]
    for c in range(3):
        jac[c, 0] = eta * pos[c, i0]
        jac[6 + c, 0] = eta * an[c, 0]
    for k in range(1, n):
        i = chain(k, src)
        ei = 1.0 / eta
        eta += m[i]
        pme = eta * ei
        for c in range(3):
            jac[c, k] = pos[c, i] - jac[c, 0] * ei
            jac[6 + c, k] = an[c, k] - jac[6 + c, 0] * ei
        for c in range(3):
            jac[c, 0] = jac[c, 0] * pme + m[i] * jac[c, k]
            jac[6 + c, 0] = jac[6 + c, 0] * pme + m[i] * jac[6 + c, k]


@jit_inline
def _to_jacobi_velocities(vel, m, src, jac):
    """jac rows 3-5 = Jacobi v of chain places 1..N-1 (as :func:`_to_jacobi_positions`); returns
    the total mass."""
    n = vel.shape[1]
    i0 = chain(0, src)
    eta = m[i0]
    # the running sums in registers (row 0 written at the end): the same operations in the same order
    sx = eta * vel[0, i0]
    sy = eta * vel[1, i0]
    sz = eta * vel[2, i0]
    for k in range(1, n):
        i = chain(k, src)
        ei = 1.0 / eta
        eta += m[i]
        pme = eta * ei
        vx = vel[0, i] - sx * ei
        vy = vel[1, i] - sy * ei
        vz = vel[2, i] - sz * ei
        jac[3, k] = vx
        jac[4, k] = vy
        jac[5, k] = vz
        sx = sx * pme + m[i] * vx
        sy = sy * pme + m[i] * vy
        sz = sz * pme + m[i] * vz
    jac[3, 0] = sx
    jac[4, 0] = sy
    jac[5, 0] = sz
    return eta


@jit_inline
def _vtilde_iteration(vx, vy, vz, A, three_mu_r, C2):
    """One step of the fixed point v~ = v / (1 - A(v~)): v~ from the last A, then |v~|^2 and A(v~)
    (``three_mu_r``: 3 mu / r, computed as ``3.0 * mu / r``)."""
    wx = vx / (1.0 - A)
    wy = vy / (1.0 - A)
    wz = vz / (1.0 - A)
    w2 = wx * wx + wy * wy + wz * wz
    return wx, wy, wz, w2, (0.5 * w2 + three_mu_r) / C2


@jit_inline
def _vtilde_converged(wx, wy, wz, ox, oy, oz, w2):
    """REBOUNDx's stopping rule for v~: |v~ - v~_previous|^2 / |v~|^2 < eps^2."""
    dx, dy, dz = wx - ox, wy - oy, wz - oz
    return (dx * dx + dy * dy + dz * dz) / w2 < _EPS * _EPS


@jit_inline
def _solve_vtilde(vx, vy, vz, three_mu_r, C2):
    """v~ of one Jacobi coordinate by fixed-point iteration, REBOUNDx's stopping rule; returns v~,
    |v~|^2, A."""
    wx, wy, wz = vx, vy, vz
    w2 = wx * wx + wy * wy + wz * wz
    A = (0.5 * w2 + three_mu_r) / C2
    for _ in range(MAX_ITERATIONS):
        ox, oy, oz = wx, wy, wz
        wx, wy, wz, w2, A = _vtilde_iteration(vx, vy, vz, A, three_mu_r, C2)
        if _vtilde_converged(wx, wy, wz, ox, oy, oz, w2):
            break
    return wx, wy, wz, w2, A


@jit_inline
def _solve_vtilde_all(jac, work, C2):
    """:func:`_solve_vtilde` for every Jacobi coordinate (v from ``jac`` rows 3-5, 3 mu / r from ``work``
    row 17) into ``work`` rows :data:`_W` .. :data:`_A`. Each coordinate's operations are those of
    solving it alone, in the same order (the same bits); the coordinates advance together, one
    iteration of each in turn, so that their divisions overlap: solved one after another, each
    iteration's two divisions waited on the last, and that wait was most of an evaluation."""
    n = jac.shape[1]
    for k in range(1, n):
        vx, vy, vz = jac[3, k], jac[4, k], jac[5, k]
        w2 = vx * vx + vy * vy + vz * vz
        work[_W, k], work[_W + 1, k], work[_W + 2, k], work[_W2, k] = vx, vy, vz, w2
        work[_A, k] = (0.5 * w2 + work[17, k]) / C2
        work[_DONE, k] = 0.0
    for _ in range(MAX_ITERATIONS):
        active = False
        for k in range(1, n):
            if work[_DONE, k] != 0.0:
                continue
            ox, oy, oz = work[_W, k], work[_W + 1, k], work[_W + 2, k]
            wx, wy, wz, w2, A = _vtilde_iteration(jac[3, k], jac[4, k], jac[5, k], work[_A, k], work[17, k], C2)
            work[_W, k], work[_W + 1, k], work[_W + 2, k], work[_W2, k], work[_A, k] = wx, wy, wz, w2, A
            if _vtilde_converged(wx, wy, wz, ox, oy, oz, w2):
                work[_DONE, k] = 1.0
            else:
                active = True
        if not active:
            break


@jit
def gr_prepare(pos, m, G, src, work):
    """The part of :func:`gr_accelerations` that depends on positions only, into ``work``: the
    Newtonian accelerations (rows 0-2) and the Jacobi positions and accelerations (rows 3-5,
    9-11). An operator that evaluates the force at fixed positions and several velocities
    (the implicit midpoint) prepares once and calls :func:`gr_operator_accelerations` per
    velocity: the same bits as :func:`gr_accelerations` each time, without the N^2 sum. Rows
    15-19 get each Jacobi coordinate's r, mu / r, 3 mu / r, r^3 and 3 mu / r^3, each written as
    the expressions of REBOUNDx's ``gr.c`` evaluate it (left to right), so the bits are theirs."""
    _newtonian_in_chain(pos, m, G, src, work[0:3])
    jac = work[3:12]
    _to_jacobi_positions(pos, work[0:3], m, src, jac)
    mu = G * m[src]
    for k in range(1, pos.shape[1]):
        x, y, z = jac[0, k], jac[1, k], jac[2, k]
        ri = np.sqrt(x * x + y * y + z * z)
        work[15, k] = ri
        work[16, k] = mu / ri
        work[17, k] = 3.0 * mu / ri
        ri3 = ri * ri * ri
        work[18, k] = ri3
        work[19, k] = 3.0 * mu / ri3


@jit_llvm_inline
def _same_bits(a, b):
    """a and b are the same float64, -0.0 and 0.0 apart (``==`` alone takes them for equal)."""
    return a == b and (a != 0.0 or math.copysign(1.0, a) == math.copysign(1.0, b))


@jit_llvm_inline
def gr_prepare_once(pos, m, G, src, cache):
    """The :func:`gr_prepare`'d work block at ``pos`` (``cache[:GR_WORK_ROWS]``; ``cache`` has
    :data:`GR_CACHE_ROWS` rows), prepared only if the block does not already hold these positions',
    masses', G's and source's: the same bits as preparing it. An operator at the end of one step and the
    next step's first operator see the same positions, so a step prepares once, not twice."""
    n = pos.shape[1]
    work = cache[:GR_WORK_ROWS]
    key = GR_WORK_ROWS + 4
    same = cache[key, 0] == src + 1.0 and cache[key, 1] == G
    if same:
        for i in range(n):
            if not (_same_bits(cache[GR_WORK_ROWS + 3, i], m[i]) and _same_bits(cache[GR_WORK_ROWS, i], pos[0, i])
                    and _same_bits(cache[GR_WORK_ROWS + 1, i], pos[1, i])
                    and _same_bits(cache[GR_WORK_ROWS + 2, i], pos[2, i])):
                same = False
                break
    if not same:
        gr_prepare(pos, m, G, src, work)
        for i in range(n):
            for c in range(3):
                cache[GR_WORK_ROWS + c, i] = pos[c, i]
            cache[GR_WORK_ROWS + 3, i] = m[i]
        cache[key, 0] = src + 1.0
        cache[key, 1] = G
    return work


@jit_inline
def _pn_acceleration(k, wx, wy, wz, w2, A, mu, C2, jac, work, apn):
    """apn[:, k] = the 1PN acceleration of Jacobi coordinate k (module docstring), given its v~, |v~|^2, A."""
    x, y, z = jac[0, k], jac[1, k], jac[2, k]
    B = (work[16, k] - 1.5 * w2) * mu / work[18, k] / C2
    rdotrdot = x * jac[3, k] + y * jac[4, k] + z * jac[5, k]
    vdx = jac[6, k] + B * x
    vdy = jac[7, k] + B * y
    vdz = jac[8, k] + B * z
    vdotvdot = wx * vdx + wy * vdy + wz * vdz
    D = (vdotvdot - work[19, k] * rdotrdot) / C2
    apn[0, k] = B * (1.0 - A) * x - A * jac[6, k] - D * wx
    apn[1, k] = B * (1.0 - A) * y - A * jac[7, k] - D * wy
    apn[2, k] = B * (1.0 - A) * z - A * jac[8, k] - D * wz


@jit_inline
def _add_inertial(apn, m, src, eta, acc):
    """acc += the inertial accelerations of the Jacobi 1PN accelerations ``apn`` (REBOUND's
    jacobi_to_inertial_acc; the centre of mass's is 0); ``eta``: the total mass."""
    n = apn.shape[1]
    sx = 0.0 * eta
    sy = 0.0 * eta
    sz = 0.0 * eta
    for k in range(n - 1, 0, -1):
        i = chain(k, src)
        ei = 1.0 / eta
        sx = (sx - m[i] * apn[0, k]) * ei
        sy = (sy - m[i] * apn[1, k]) * ei
        sz = (sz - m[i] * apn[2, k]) * ei
        acc[0, i] += apn[0, k] + sx
        acc[1, i] += apn[1, k] + sy
        acc[2, i] += apn[2, k] + sz
        eta -= m[i]
        sx *= eta
        sy *= eta
        sz *= eta
    i0 = chain(0, src)
    mi = 1.0 / eta
    acc[0, i0] += sx * mi
    acc[1, i0] += sy * mi
    acc[2, i0] += sz * mi


@jit
def gr_accelerations_prepared(vel, m, G, src, c, acc, work):
    """acc (3, N) += the 1PN acceleration at velocities ``vel``, the positions' part taken from
    ``work`` as :func:`gr_prepare` left it; v~ solved one Jacobi coordinate after another."""
    C2 = c * c
    mu = G * m[src]
    jac = work[3:12]
    apn = work[12:15]
    eta = _to_jacobi_velocities(vel, m, src, jac)
    for k in range(1, vel.shape[1]):
        wx, wy, wz, w2, A = _solve_vtilde(jac[3, k], jac[4, k], jac[5, k], work[17, k], C2)
        _pn_acceleration(k, wx, wy, wz, w2, A, mu, C2, jac, work, apn)
    _add_inertial(apn, m, src, eta, acc)


@jit
def gr_operator_accelerations(vel, m, G, src, c, acc, work):
    """:func:`gr_accelerations_prepared` with v~ solved for every Jacobi coordinate at once
    (:func:`_solve_vtilde_all`): the same bits, a quarter less time; the implicit midpoint's
    evaluation. (Kept apart from the other: its interleaved loop costs each kernel that links it
    compile time, and IAS15 evaluates ``gr`` through :func:`gr_accelerations`.)"""
    C2 = c * c
    mu = G * m[src]
    jac = work[3:12]
    apn = work[12:15]
    eta = _to_jacobi_velocities(vel, m, src, jac)
    _solve_vtilde_all(jac, work, C2)
    for k in range(1, vel.shape[1]):
        _pn_acceleration(k, work[_W, k], work[_W + 1, k], work[_W + 2, k], work[_W2, k], work[_A, k], mu, C2, jac,
                         work, apn)
    _add_inertial(apn, m, src, eta, acc)


@jit
def gr_accelerations(pos, vel, m, G, src, c, acc, work):
    """acc (3, N) += the single-mass 1PN acceleration (module docstring) about ``src``.

    ``work``: at least (:data:`GR_WORK_ROWS`, N) scratch.
    """
    gr_prepare(pos, m, G, src, work)
    gr_accelerations_prepared(vel, m, G, src, c, acc, work)


@jit
def gr_energy(pos, vel, m, G, src, c):
    """What ``gr``'s Hamiltonian adds to the Newtonian energy (REBOUNDx ``rebx_gr_hamiltonian``):
    sum_i m'_i (v~_i^2 - v_i^2) / 2 over Jacobi coordinates, plus V_PN. The Jacobi chain is built
    on the fly (no storage)."""
    n = pos.shape[1]
    C2 = c * c
    mu = G * m[src]
    i0 = chain(0, src)
    eta = m[i0]
    sx, sy, sz = eta * pos[0, i0], eta * pos[1, i0], eta * pos[2, i0]
    svx, svy, svz = eta * vel[0, i0], eta * vel[1, i0], eta * vel[2, i0]
    dT = 0.0
    V_PN = 0.0
    for k in range(1, n):
        i = chain(k, src)
        ei = 1.0 / eta
        mj = m[i] * eta  # the Jacobi mass m_i eta_{k-1} / eta_k, divided below as REBOUNDx does
        eta += m[i]
        mj /= eta
        pme = eta * ei
        x, y, z = pos[0, i] - sx * ei, pos[1, i] - sy * ei, pos[2, i] - sz * ei
        vx, vy, vz = vel[0, i] - svx * ei, vel[1, i] - svy * ei, vel[2, i] - svz * ei
        sx, sy, sz = sx * pme + m[i] * x, sy * pme + m[i] * y, sz * pme + m[i] * z
        svx, svy, svz = svx * pme + m[i] * vx, svy * pme + m[i] * vy, svz * pme + m[i] * vz
        rdoti2 = vx * vx + vy * vy + vz * vz
        vt2 = rdoti2
        ri = np.sqrt(x * x + y * y + z * z)
        vscale2 = mu / ri
        for _ in range(MAX_ITERATIONS):
            old = vt2
            A = (0.5 * vt2 + 3.0 * vscale2) / C2
            vt2 = rdoti2 / ((1.0 - A) * (1.0 - A))
            if (vt2 - old) / vt2 < _EPS:  # signed, as REBOUNDx's test
                break
        V_PN += mj * (0.5 * mu * mu / (ri * ri) - 0.125 * vt2 * vt2 - 1.5 * mu * vt2 / ri)
        dT += 0.5 * mj * (vt2 - rdoti2)
    return dT + V_PN / C2
