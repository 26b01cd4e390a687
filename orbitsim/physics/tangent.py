"""The tangent (first-order variational) gravity: how the accelerations change with the positions.

For a small displacement of the state, delta = (dr_i, dv_i), Newtonian gravity's accelerations change by

    da_i = sum_{j != i} G m_j [ (dr_i - dr_j) / s^3 - 3 (d_ij . (dr_i - dr_j)) d_ij / s^5 ],

with d_ij = r_i - r_j and s^2 = |d_ij|^2 + eps^2 (the Jacobian of the Plummer-softened pull, so a
softened run's variations are those of the force it actually integrates). This is the matrix-vector
product of the acceleration's Jacobian with dr, never the 3N x 3N matrix itself: O(N^2) work and no
storage. Every integrator's variational equations kick with it (the tangent map of a kick
v += a(r) dt is dv += da(r; dr) dt), and MEGNO's <delta', delta> reads it.

It is REBOUND's ``reb_gravity_basic_calculate_acceleration_var`` (``src/gravity.c``) for one set of
first-order variations with fixed masses, ported as orbitsim's own loop: the same pair terms in the same
pair order (i from ``first_i``, j < i), so for the same state the two agree to round-off. The pair
skips mirror REBOUND's ``gravity_ignore_terms``, which WHFast sets for its Jacobi (the 0-1 pair is in
the Kepler part) and democratic heliocentric (every pair with the star is) splittings.
"""

from __future__ import annotations

import math

from orbitsim._jit import jit, jit_inline

#: Pair selection, as REBOUND's ``gravity_ignore_terms``: every pair ...
ALL_PAIRS = 0
#: ... every pair but (0, 1): the Jacobi splitting's Kepler part holds it ...
SKIP_PAIR_0_1 = 1
#: ... no pair with body 0: the democratic heliocentric splitting's Kepler part holds them.
SKIP_BODY_0 = 2
# Jitted callers pass these as ``np.int64(ALL_PAIRS)``: Numba compiles a callee once per literal, and a
# Wisdom-Holman chaos run (the kick skips the (0, 1) pair, MEGNO's step takes every pair) compiled
# tangent_accelerations twice (0.4-0.5 CPU-s each); as int64 both share one compilation, same speed.


@jit_inline
def pair_tangent_acceleration(dx, dy, dz, ddx, ddy, ddz, eps2):
    """The Jacobian of the pair acceleration ``-r / |r|^3`` (softened by ``eps2``) at ``r = (dx, dy, dz)``
    applied to the relative tangent vector ``(ddx, ddy, ddz)``, before the factor G m."""
    r2 = dx * dx + dy * dy + dz * dz + eps2
    r = math.sqrt(r2)  # math.sqrt: numba-cuda lacks the numpy sqrt ufunc (the GPU ensemble calls this)
    r3inv = 1.0 / (r2 * r)
    r5inv = 3.0 * r3inv / r2
    dxdx = dx * dx * r5inv - r3inv
    dydy = dy * dy * r5inv - r3inv
    dzdz = dz * dz * r5inv - r3inv
    dxdy = dx * dy * r5inv
    dxdz = dx * dz * r5inv
    dydz = dy * dz * r5inv
    return (ddx * dxdx + ddy * dxdy + ddz * dxdz,
            ddx * dxdy + ddy * dydy + ddz * dydz,
            ddx * dxdz + ddy * dydz + ddz * dzdz)


@jit
def tangent_accelerations(pos, m, G, eps2, dpos, dacc, skip):
    """Write da = J(pos) dpos into ``dacc`` (3, N), for masses ``m`` and gravitational constant ``G``.

    ``skip`` is :data:`ALL_PAIRS`, :data:`SKIP_PAIR_0_1` or :data:`SKIP_BODY_0`. Massless bodies pull
    nothing (m_j = 0) and are pulled as any other body, so a test particle's variation is exact.
    """
    n = pos.shape[1]
    for c in range(3):
        for i in range(n):
            dacc[c, i] = 0.0
    first_i = 1 if skip == ALL_PAIRS else 2
    first_j = 1 if skip == SKIP_BODY_0 else 0
    for i in range(first_i, n):
        for j in range(first_j, i):
            dx = pos[0, i] - pos[0, j]
            dy = pos[1, i] - pos[1, j]
            dz = pos[2, i] - pos[2, j]
            dax, day, daz = pair_tangent_acceleration(dx, dy, dz, dpos[0, i] - dpos[0, j], dpos[1, i] - dpos[1, j],
                                                      dpos[2, i] - dpos[2, j], eps2)
            gmi = G * m[i]
            gmj = G * m[j]
            dacc[0, i] += gmj * dax
            dacc[1, i] += gmj * day
            dacc[2, i] += gmj * daz
            dacc[0, j] -= gmi * dax
            dacc[1, j] -= gmi * day
            dacc[2, j] -= gmi * daz
