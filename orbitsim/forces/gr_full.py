"""The full first post-Newtonian force of all bodies (REBOUNDx ``gr_full``), jitted.

The Einstein-Infeld-Hoffmann equations in the form of Newhall, Standish & Williams (1983, A&A
125, 150), eq. 1, in barycentric coordinates (G = gravitational constant, c light speed):

    a_i = sum_{j != i} G m_j (x_j - x_i) / r_ij^3 [1 - 4/c^2 sum_{k != i} G m_k / r_ik
          - 1/c^2 sum_{l != j} G m_l / r_jl + v_i^2/c^2 + 2 v_j^2/c^2 - 4 (v_i . v_j)/c^2
          - 3/(2 c^2) ((x_i - x_j) . v_j / r_ij)^2 + (x_j - x_i) . a_j / (2 c^2)]
        + 1/c^2 sum_{j != i} G m_j / r_ij^3 [(x_i - x_j) . (4 v_i - 3 v_j)] (v_i - v_j)
        + 7/(2 c^2) sum_{j != i} G m_j a_j / r_ij,

less the Newtonian term (which orbitsim's gravity already gives). The a_j on the right are first
the Newtonian accelerations, then the post-Newtonian ones themselves: REBOUNDx solves for them by
substitution, updating each body's in place (Gauss-Seidel) for up to 10 sweeps, until no
component changes by a relative DBL_EPSILON. This port follows REBOUNDx's order of operations;
the sums over k and l, which do not depend on the other index, are computed once per body
(the same numbers REBOUNDx computes again in its inner loop).

The conserved quantity (REBOUNDx ``rebx_gr_full_hamiltonian``) is the Newtonian energy with the
canonical velocities v~ (found from the momenta by 10 fixed-point sweeps) in the kinetic term,
plus the 1PN Hamiltonian of the same module.
"""

from __future__ import annotations

import numpy as np

from orbitsim._jit import jit

#: Substitution sweeps (REBOUNDx's fixed count).
SWEEPS = 10
_EPS = np.finfo(np.float64).eps
#: Rows of ``work`` used: barycentric x, v (6), Newtonian a (3), the constant part (3), the
#: current 1PN acceleration (3), the previous sweep's (3), the potentials a1 and a2 (2).
WORK_ROWS = 20


@jit
def _potentials(pb, m, G, C2, i, scale):
    """scale * sum_{k != i} G m_k / r_ik, summed in REBOUNDx's order."""
    s = 0.0
    for k in range(pb.shape[1]):
        if k != i:
            dx = pb[0, i] - pb[0, k]
            dy = pb[1, i] - pb[1, k]
            dz = pb[2, i] - pb[2, k]
            s += (scale / C2) * G * m[k] / np.sqrt(dx * dx + dy * dy + dz * dz)
    return s


@jit
def _constant_part(pb, an, m, G, C2, pot, aconst):
    """aconst (3, N) = the terms that do not involve the 1PN accelerations."""
    n = pb.shape[1]
    for i in range(n):
        cx = cy = cz = 0.0
        vi2 = pb[3, i] * pb[3, i] + pb[4, i] * pb[4, i] + pb[5, i] * pb[5, i]
        for j in range(n):
            if j == i:
                continue
            dx = pb[0, i] - pb[0, j]
            dy = pb[1, i] - pb[1, j]
            dz = pb[2, i] - pb[2, j]
            rij2 = dx * dx + dy * dy + dz * dz
            rij = np.sqrt(rij2)
            rij3 = rij2 * rij
            vj2 = pb[3, j] * pb[3, j] + pb[4, j] * pb[4, j] + pb[5, j] * pb[5, j]
            a5 = (4.0 / C2) * (pb[3, i] * pb[3, j] + pb[4, i] * pb[4, j] + pb[5, i] * pb[5, j])
            a6_0 = dx * pb[3, j] + dy * pb[4, j] + dz * pb[5, j]
            a6 = (3.0 / (2.0 * C2)) * a6_0 * a6_0 / rij2
            a7 = (dx * an[0, j] + dy * an[1, j] + dz * an[2, j]) / (2.0 * C2)
            factor1 = pot[0, i] + pot[1, j] + -vi2 / C2 + -2.0 * vj2 / C2 + a5 + a6 + a7
            gm = G * m[j]
            cx += gm * dx * factor1 / rij3
            cy += gm * dy * factor1 / rij3
            cz += gm * dz * factor1 / rij3
            dvx = pb[3, i] - pb[3, j]
            dvy = pb[4, i] - pb[4, j]
            dvz = pb[5, i] - pb[5, j]
            factor2 = (dx * (4.0 * pb[3, i] - 3.0 * pb[3, j]) + dy * (4.0 * pb[4, i] - 3.0 * pb[4, j])
                       + dz * (4.0 * pb[5, i] - 3.0 * pb[5, j]))
            cx += gm / C2 * (factor2 * dvx / rij3 + 3.5 * an[0, j] / rij)
            cy += gm / C2 * (factor2 * dvy / rij3 + 3.5 * an[1, j] / rij)
            cz += gm / C2 * (factor2 * dvz / rij3 + 3.5 * an[2, j] / rij)
        aconst[0, i] = cx
        aconst[1, i] = cy
        aconst[2, i] = cz


@jit
def _sweep(pb, m, G, C2, aconst, a):
    """One Gauss-Seidel substitution of the 1PN accelerations ``a`` into the right-hand side."""
    n = pb.shape[1]
    for i in range(n):
        nx = ny = nz = 0.0
        for j in range(n):
            if j == i:
                continue
            dx = pb[0, i] - pb[0, j]
            dy = pb[1, i] - pb[1, j]
            dz = pb[2, i] - pb[2, j]
            rij = np.sqrt(dx * dx + dy * dy + dz * dz)
            rij3 = rij * rij * rij
            dot = dx * a[0, j] + dy * a[1, j] + dz * a[2, j]
            gm = G * m[j]
            nx += (gm * dx / rij3) * dot / (2.0 * C2) + (7.0 / (2.0 * C2)) * G * m[j] * a[0, j] / rij
            ny += (gm * dy / rij3) * dot / (2.0 * C2) + (7.0 / (2.0 * C2)) * G * m[j] * a[1, j] / rij
            nz += (gm * dz / rij3) * dot / (2.0 * C2) + (7.0 / (2.0 * C2)) * G * m[j] * a[2, j] / rij
        a[0, i] = aconst[0, i] + nx
        a[1, i] = aconst[1, i] + ny
        a[2, i] = aconst[2, i] + nz


@jit
def _newtonian(pos, m, G, an):
    """an (3, N) = Newtonian accelerations, pairs in REBOUNDx's order."""
    n = pos.shape[1]
    an[:, :] = 0.0
    for i in range(n):
        for j in range(i + 1, n):
            dx = pos[0, i] - pos[0, j]
            dy = pos[1, i] - pos[1, j]
            dz = pos[2, i] - pos[2, j]
            r2 = dx * dx + dy * dy + dz * dz
            prefac = G / (r2 * np.sqrt(r2))
            an[0, i] -= prefac * m[j] * dx
            an[1, i] -= prefac * m[j] * dy
            an[2, i] -= prefac * m[j] * dz
            an[0, j] += prefac * m[i] * dx
            an[1, j] += prefac * m[i] * dy
            an[2, j] += prefac * m[i] * dz


@jit
def gr_full_accelerations(pos, vel, m, G, c, com, acc, work):
    """acc (3, N) += the 1PN accelerations of the module docstring; ``com``: the centre of mass
    (x, y, z, vx, vy, vz, M) REBOUNDx would subtract; ``work``: at least (WORK_ROWS, N)."""
    n = pos.shape[1]
    C2 = c * c
    pb, an, aconst, a, aold, pot = work[0:6], work[6:9], work[9:12], work[12:15], work[15:18], work[18:20]
    _newtonian(pos, m, G, an)
    for i in range(n):
        for k in range(3):
            pb[k, i] = pos[k, i] - com[k]
            pb[3 + k, i] = vel[k, i] - com[3 + k]
    for i in range(n):
        pot[0, i] = _potentials(pb, m, G, C2, i, 4.0)
        pot[1, i] = _potentials(pb, m, G, C2, i, 1.0)
    _constant_part(pb, an, m, G, C2, pot, aconst)
    a[:, :] = aconst
    for _ in range(SWEEPS):
        aold[:, :] = a
        _sweep(pb, m, G, C2, aconst, a)
        maxdev = 0.0
        for i in range(n):
            for k in range(3):
                dev = 0.0 if abs(a[k, i]) < _EPS else abs((a[k, i] - aold[k, i]) / a[k, i])
                maxdev = max(maxdev, dev)
        if maxdev < _EPS:
            break
    for k in range(3):
        for i in range(n):
            acc[k, i] += a[k, i]


@jit
def _canonical_velocities(pos, vel, m, G, C2, vt):
    """vt (3, N) = the velocities v~ of the 1PN Hamiltonian, 10 in-place sweeps as REBOUNDx."""
    n = pos.shape[1]
    vt[:, :] = vel
    for _ in range(SWEEPS):
        for i in range(n):
            vti2 = vt[0, i] * vt[0, i] + vt[1, i] * vt[1, i] + vt[2, i] * vt[2, i]
            A = 1.0 - 0.5 * vti2 / C2
            dx = dy = dz = 0.0
            for j in range(n):
                if j == i:
                    continue
                xij = pos[0, j] - pos[0, i]
                yij = pos[1, j] - pos[1, i]
                zij = pos[2, j] - pos[2, i]
                rij2 = xij * xij + yij * yij + zij * zij
                rij = np.sqrt(rij2)
                rv = vt[0, j] * xij + vt[1, j] * yij + vt[2, j] * zij
                pfac = m[j] / rij
                dx += pfac * (6.0 * vt[0, i] - 7.0 * vt[0, j] - rv * xij / rij2)
                dy += pfac * (6.0 * vt[1, i] - 7.0 * vt[1, j] - rv * yij / rij2)
                dz += pfac * (6.0 * vt[2, i] - 7.0 * vt[2, j] - rv * zij / rij2)
            f = G / (2.0 * C2)
            vt[0, i] = (vel[0, i] + dx * f) / A
            vt[1, i] = (vel[1, i] + dy * f) / A
            vt[2, i] = (vel[2, i] + dz * f) / A


@jit
def gr_full_energy(pos, vel, m, G, c):
    """What the 1PN Hamiltonian adds to the Newtonian energy: sum_i m_i (v~_i^2 - v_i^2) / 2 plus
    the post-Newtonian terms of ``rebx_gr_full_hamiltonian``. Allocates v~ (3, N): it runs at
    sample times only, and the contract's energy entry point takes no scratch."""
    n = pos.shape[1]
    C2 = c * c
    vt = np.empty((3, n))
    _canonical_velocities(pos, vel, m, G, C2, vt)
    dkin = 0.0
    e_pn = 0.0
    for i in range(n):
        vti2 = vt[0, i] * vt[0, i] + vt[1, i] * vt[1, i] + vt[2, i] * vt[2, i]
        vi2 = vel[0, i] * vel[0, i] + vel[1, i] * vel[1, i] + vel[2, i] * vel[2, i]
        dkin += 0.5 * m[i] * (vti2 - vi2)
        sumk = 0.0
        for k in range(n):
            if k != i:
                dx = pos[0, k] - pos[0, i]
                dy = pos[1, k] - pos[1, i]
                dz = pos[2, k] - pos[2, i]
                sumk -= 2.0 * G * m[k] / np.sqrt(dx * dx + dy * dy + dz * dz)
        for j in range(n):
            if j == i:
                continue
            xij = pos[0, j] - pos[0, i]
            yij = pos[1, j] - pos[1, i]
            zij = pos[2, j] - pos[2, i]
            rij2 = xij * xij + yij * yij + zij * zij
            rij = np.sqrt(rij2)
            rvj = vt[0, j] * xij + vt[1, j] * yij + vt[2, j] * zij
            rvi = vt[0, i] * xij + vt[1, i] * yij + vt[2, i] * zij
            vivj = vt[0, i] * vt[0, j] + vt[1, i] * vt[1, j] + vt[2, i] * vt[2, j]
            e_pn -= G / (4.0 * C2) * m[i] * m[j] / rij * (6.0 * vti2 - 7.0 * vivj - rvi * rvj / rij2 + sumk)
        e_pn -= m[i] / (8.0 * C2) * vti2 * vti2
    return dkin + e_pn
