"""General relativity as a potential about one dominant mass: REBOUNDx ``gr_potential``, jitted.

``gr_potential`` (Nobili & Roxburgh 1986, IAU Symp. 114, 105): every body i other than the
source s (mass M) feels the position-only acceleration

    a_i = -6 (G M)^2 / (c^2 r^4) d,   d = x_i - x_s,  r = |d|,

from the potential energy U = -3 (G M)^2 m_i / (c^2 r^2); the source takes the reaction
-(m_i / M) a_i. It gets the pericentre precession right and the mean motion wrong by O(GM/(a c^2)).
The velocity-dependent first post-Newtonian force is :mod:`orbitsim.forces.gr`.
"""

from __future__ import annotations

from orbitsim._jit import jit, jit_llvm_inline


@jit_llvm_inline
def gr_potential_accelerations(pos, m, G, src, c, acc):
    """acc (3, N) += the Nobili-Roxburgh acceleration of every body about ``src``, and its reaction."""
    C2 = c * c
    gm = G * m[src]
    prefac1 = 6.0 * gm * gm / C2
    for i in range(pos.shape[1]):
        if i == src:
            continue
        dx = pos[0, i] - pos[0, src]
        dy = pos[1, i] - pos[1, src]
        dz = pos[2, i] - pos[2, src]
        r2 = dx * dx + dy * dy + dz * dz
        prefac = prefac1 / (r2 * r2)
        acc[0, i] -= prefac * dx
        acc[1, i] -= prefac * dy
        acc[2, i] -= prefac * dz
        ratio = m[i] / m[src]
        acc[0, src] += ratio * prefac * dx
        acc[1, src] += ratio * prefac * dy
        acc[2, src] += ratio * prefac * dz


@jit_llvm_inline
def gr_potential_tangent(pos, m, G, src, c, dpos, dacc):
    """dacc (3, N) += the derivative of :func:`gr_potential_accelerations` at ``pos`` along ``dpos``.

    With P = 6 (G M)^2 / c^2, d = x_i - x_s and dd = dx_i - dx_s, the Jacobian of a = -P d / r^4
    applied to dd is

        da_i = -P / r^4 [dd - 4 (d . dd) / r^2 d],

    and the source takes -(m_i / M) da_i, as it takes the reaction of a_i.
    """
    C2 = c * c
    gm = G * m[src]
    prefac1 = 6.0 * gm * gm / C2
    for i in range(pos.shape[1]):
        if i == src:
            continue
        dx = pos[0, i] - pos[0, src]
        dy = pos[1, i] - pos[1, src]
        dz = pos[2, i] - pos[2, src]
        ddx = dpos[0, i] - dpos[0, src]
        ddy = dpos[1, i] - dpos[1, src]
        ddz = dpos[2, i] - dpos[2, src]
        r2 = dx * dx + dy * dy + dz * dz
        prefac = prefac1 / (r2 * r2)
        s = 4.0 * (dx * ddx + dy * ddy + dz * ddz) / r2
        fx = -prefac * (ddx - s * dx)
        fy = -prefac * (ddy - s * dy)
        fz = -prefac * (ddz - s * dz)
        dacc[0, i] += fx
        dacc[1, i] += fy
        dacc[2, i] += fz
        ratio = m[i] / m[src]
        dacc[0, src] -= ratio * fx
        dacc[1, src] -= ratio * fy
        dacc[2, src] -= ratio * fz


@jit
def gr_potential_energy(pos, m, G, src, c):
    """U = -sum_i 3 (G M)^2 m_i / (c^2 r_i^2) (REBOUNDx ``rebx_gr_potential_potential``)."""
    C2 = c * c
    mu = G * m[src]
    prefac = 3.0 * mu * mu / C2
    H = 0.0
    for i in range(pos.shape[1]):
        if i == src:
            continue
        dx = pos[0, i] - pos[0, src]
        dy = pos[1, i] - pos[1, src]
        dz = pos[2, i] - pos[2, src]
        r2 = dx * dx + dy * dy + dz * dz
        H -= prefac * m[i] / r2
    return H
