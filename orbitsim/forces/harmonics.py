"""Zonal harmonics J2 and J4 of one oblate body (REBOUNDx ``gravitational_harmonics``), jitted.

In the body-fixed frame (u, v, w), w along the unit spin axis s, a body j at separation
d = x_j - x_s from the oblate body (mass M, radius R), r = |d|, c = cos(theta) = d_w / r, feels
(REBOUNDx implementation by M. Broz; Tamayo et al. 2020, MNRAS 491, 2885)

    a_u = [K2 (5 c^2 - 1) + K4 (63 c^4 - 42 c^2 + 3)] d_u,           a_v likewise,
    a_w = [K2 (5 c^2 - 3) + K4 (63 c^4 - 70 c^2 + 15)] d_w,
    K2 = 3/2 G M J2 R^2 / r^5,   K4 = 5/8 G M J4 R^4 / r^7,

which is minus the gradient (per unit mass) of the pair's potential energy

    U_j = G M m_j [J2 R^2 / r^3 (3 c^2 - 1) / 2 + J4 R^4 / r^5 (35 c^4 - 30 c^2 + 3) / 8],

with the body's equal and opposite reaction, -(m_j / M) a_j, so the total momentum is kept. The
oblate body's spin is fixed (no torque back on it), as in REBOUNDx.

The arithmetic follows ``gravitational_harmonics.c`` operation by operation (the rotation into and
out of the body frame included), so the accelerations agree with REBOUNDx to the last bits. One
difference, on purpose: REBOUNDx skips a body whose J2 is 0 even if its J4 is not; here J4 then
acts alone.
"""

from __future__ import annotations

import numpy as np

from orbitsim._jit import jit, jit_inline, jit_llvm_inline


@jit_inline
def spin_basis(sx, sy, sz):
    """The body frame (u, v, w) of a spin axis, as REBOUNDx's ``uvw``: w = s / |s|, u = z x w
    normalised (x when s is along z), v = w x u. Returns the nine components, u then v then w."""
    omega = np.sqrt(sx * sx + sy * sy + sz * sz)
    wx = sx / omega
    wy = sy / omega
    wz = sz / omega
    fac = np.sqrt(wx * wx + wy * wy)
    if fac != 0.0:
        ux = -wy / fac
        uy = wx / fac
        uz = 0.0
    else:
        ux = 1.0
        uy = 0.0
        uz = 0.0
    vx = -(uy * wz - uz * wy)
    vy = -(uz * wx - ux * wz)
    vz = -(ux * wy - uy * wx)
    return ux, uy, uz, vx, vy, vz, wx, wy, wz


@jit_inline
def add_with_reaction(out, j, src, fac, au, av, aw, ux, uy, uz, vx, vy, vz, wx, wy, wz):
    """out[:, j] += the body-frame vector (au, av, aw) back in the inertial frame (the transpose of the
    (u, v, w) rotation), and out[:, src] -= ``fac`` times it: the oblate body's reaction, ``fac`` = m_j / M.
    One place for :func:`harmonics_accelerations` and :func:`harmonics_tangent` (the same operations)."""
    ax = ux * au + vx * av + wx * aw
    ay = uy * au + vy * av + wy * aw
    az = uz * au + vz * av + wz * aw
    out[0, j] += ax
    out[1, j] += ay
    out[2, j] += az
    out[0, src] -= fac * ax
    out[1, src] -= fac * ay
    out[2, src] -= fac * az


@jit
def harmonics_accelerations(pos, m, G, src, J2, J4, R_eq, sx, sy, sz, acc):
    """acc (3, N) += the J2/J4 accelerations of every body about body ``src``, and its reaction.

    Called, not inlined by Numba: the force hooks reach it through four levels of overloads
    (:mod:`orbitsim.forces.kernels`), and when Numba inlined those it typed an inlined body again at
    every look-up, so this one was copied and typed 74 times in a first ``j2_satellite`` run (CPU 40 s,
    18 s called); a warm step runs at the same speed (6 us an IAS15 step, within noise)."""
    ux, uy, uz, vx, vy, vz, wx, wy, wz = spin_basis(sx, sy, sz)
    n = pos.shape[1]
    ms = m[src]
    for j in range(n):
        if j == src:
            continue
        dx = pos[0, j] - pos[0, src]
        dy = pos[1, j] - pos[1, src]
        dz = pos[2, j] - pos[2, src]
        r2 = dx * dx + dy * dy + dz * dz
        r = np.sqrt(r2)
        du = ux * dx + uy * dy + uz * dz
        dv = vx * dx + vy * dy + vz * dz
        dw = wx * dx + wy * dy + wz * dz
        costheta = dw / r
        c2 = costheta * costheta
        au = 0.0
        av = 0.0
        aw = 0.0
        if J2 != 0.0:
            f1 = 1.5 * G * ms * J2 * R_eq * R_eq / r2 / r2 / r
            f2 = 5.0 * c2 - 1.0
            f3 = f2 - 2.0
            au += f1 * f2 * du
            av += f1 * f2 * dv
            aw += f1 * f3 * dw
        if J4 != 0.0:
            f1 = 0.625 * G * ms * J4 * R_eq * R_eq * R_eq * R_eq / r2 / r2 / r2 / r
            f2 = 63.0 * c2 * c2 - 42.0 * c2 + 3.0
            f3 = f2 - 28.0 * c2 + 12.0
            au += f1 * f2 * du
            av += f1 * f2 * dv
            aw += f1 * f3 * dw
        add_with_reaction(acc, j, src, m[j] / ms, au, av, aw, ux, uy, uz, vx, vy, vz, wx, wy, wz)


@jit_llvm_inline
def harmonics_tangent(pos, m, G, src, J2, J4, R_eq, sx, sy, sz, dpos, dacc):
    """dacc (3, N) += the derivative of :func:`harmonics_accelerations` at ``pos`` along ``dpos``.

    In the body frame a = (F d_u, F d_v, H d_w) with F = K2 (5 c^2 - 1) + K4 (63 c^4 - 42 c^2 + 3),
    H = K2 (5 c^2 - 3) + K4 (63 c^4 - 70 c^2 + 15). For a displacement dd of the separation
    (dd_u, dd_v, dd_w in the body frame), with q = (d . dd) / r^2 (so dr = q r),
    dK2 = -5 K2 q, dK4 = -7 K4 q and dc = dd_w / r - c q:

        dF = -5 K2 q (5 c^2 - 1) + 10 K2 c dc - 7 K4 q (63 c^4 - 42 c^2 + 3) + K4 (252 c^3 - 84 c) dc,
        dH = -5 K2 q (5 c^2 - 3) + 10 K2 c dc - 7 K4 q (63 c^4 - 70 c^2 + 15) + K4 (252 c^3 - 140 c) dc,
        da_u = dF d_u + F dd_u,   da_v = dF d_v + F dd_v,   da_w = dH d_w + H dd_w,

    rotated back to the inertial frame (the rotation is fixed: the spin axis does not move); the
    oblate body takes -(m_j / M) da_j.
    """
    ux, uy, uz, vx, vy, vz, wx, wy, wz = spin_basis(sx, sy, sz)
    n = pos.shape[1]
    ms = m[src]
    for j in range(n):
        if j == src:
            continue
        dx = pos[0, j] - pos[0, src]
        dy = pos[1, j] - pos[1, src]
        dz = pos[2, j] - pos[2, src]
        ddx = dpos[0, j] - dpos[0, src]
        ddy = dpos[1, j] - dpos[1, src]
        ddz = dpos[2, j] - dpos[2, src]
        r2 = dx * dx + dy * dy + dz * dz
        r = np.sqrt(r2)
        du = ux * dx + uy * dy + uz * dz
        dv = vx * dx + vy * dy + vz * dz
        dw = wx * dx + wy * dy + wz * dz
        ddu = ux * ddx + uy * ddy + uz * ddz
        ddv = vx * ddx + vy * ddy + vz * ddz
        ddw = wx * ddx + wy * ddy + wz * ddz
        c = dw / r
        c2 = c * c
        q = (dx * ddx + dy * ddy + dz * ddz) / r2
        dc = ddw / r - c * q
        F = 0.0
        H = 0.0
        dF = 0.0
        dH = 0.0
        if J2 != 0.0:
            K2 = 1.5 * G * ms * J2 * R_eq * R_eq / r2 / r2 / r
            F += K2 * (5.0 * c2 - 1.0)
            H += K2 * (5.0 * c2 - 3.0)
            dF += -5.0 * K2 * q * (5.0 * c2 - 1.0) + 10.0 * K2 * c * dc
            dH += -5.0 * K2 * q * (5.0 * c2 - 3.0) + 10.0 * K2 * c * dc
        if J4 != 0.0:
            K4 = 0.625 * G * ms * J4 * R_eq * R_eq * R_eq * R_eq / r2 / r2 / r2 / r
            F += K4 * (63.0 * c2 * c2 - 42.0 * c2 + 3.0)
            H += K4 * (63.0 * c2 * c2 - 70.0 * c2 + 15.0)
            dF += -7.0 * K4 * q * (63.0 * c2 * c2 - 42.0 * c2 + 3.0) + K4 * (252.0 * c2 * c - 84.0 * c) * dc
            dH += -7.0 * K4 * q * (63.0 * c2 * c2 - 70.0 * c2 + 15.0) + K4 * (252.0 * c2 * c - 140.0 * c) * dc
        dau = dF * du + F * ddu
        dav = dF * dv + F * ddv
        daw = dH * dw + H * ddw
        add_with_reaction(dacc, j, src, m[j] / ms, dau, dav, daw, ux, uy, uz, vx, vy, vz, wx, wy, wz)


@jit
def harmonics_potential(pos, m, G, src, J2, J4, R_eq, sx, sy, sz):
    """The potential energy sum_j U_j of the module docstring (REBOUNDx
    ``rebx_gravitational_harmonics_potential``)."""
    wx, wy, wz = spin_basis(sx, sy, sz)[6:]
    n = pos.shape[1]
    ms = m[src]
    H = 0.0
    for j in range(n):
        if j == src:
            continue
        dx = pos[0, j] - pos[0, src]
        dy = pos[1, j] - pos[1, src]
        dz = pos[2, j] - pos[2, src]
        r2 = dx * dx + dy * dy + dz * dz
        r = np.sqrt(r2)
        dw = wx * dx + wy * dy + wz * dz
        costheta = dw / r
        c2 = costheta * costheta
        if J2 != 0.0:
            f1 = G * ms * m[j] * J2 * R_eq * R_eq / r2 / r
            H += f1 * (0.5 * (3.0 * c2 - 1.0))
        if J4 != 0.0:
            f1 = G * ms * m[j] * J4 * R_eq * R_eq * R_eq * R_eq / r2 / r2 / r
            H += f1 * (0.125 * (35.0 * c2 * c2 - 30.0 * c2 + 3.0))
    return H
