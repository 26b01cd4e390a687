"""Inertial <-> Jacobi and inertial <-> democratic heliocentric coordinates (jitted, no allocation).

Arrays are ``(3, N)`` as everywhere in orbitsim; body 0 is the central body. Every kernel writes
into an output array given by the caller, and may be called with the output the same array as
the input (in place).

Jacobi coordinates (Jacobi 1843; Plummer 1918, ch. 13; Wisdom & Holman 1991, section 3). With
``M_i = m_0 + ... + m_i`` and ``R_i`` the centre of mass of bodies 0..i,

    r'_i = x_i - R_{i-1}   (i >= 1),        r'_0 = R_{N-1}  (the centre of mass),

computed with the recurrence ``R_0 = x_0``, ``R_i = R_{i-1} + (m_i / M_i) r'_i``; the inverse runs
it backwards, ``R_{i-1} = R_i - (m_i / M_i) r'_i``, ``x_i = r'_i + R_{i-1}``, ``x_0 = R_0``. The
map is linear, so the same kernel transforms positions, velocities and accelerations. The
weights ``m_i / M_i`` come from :func:`jacobi_weights`; a zero-mass body has weight 0 and does
not move the interior centre of mass.

Democratic heliocentric coordinates (Duncan, Levison & Lee 1998, eq. 3; Hernandez & Dehnen 2017):
heliocentric positions and barycentric velocities,

    Q_i = x_i - x_0,   V_i = v_i - V_com   (i >= 1),     Q_0 = X_com,   V_0 = V_com,

with inverse ``x_0 = X_com - sum_{i>=1} m_i Q_i / M``, ``x_i = Q_i + x_0`` and
``v_i = V_i + V_com``, ``v_0 = V_com - sum_{i>=1} m_i V_i / m_0`` (total momentum is M V_com).

References
----------
.. [1] Wisdom, J. & Holman, M. (1991), "Symplectic maps for the N-body problem", AJ 102, 1528.
.. [2] Duncan, M. J., Levison, H. F. & Lee, M. H. (1998), "A multiple time step symplectic
       algorithm for integrating close encounters", AJ 116, 2067.
.. [3] Hernandez, D. M. & Dehnen, W. (2017), "A study of symplectic integrators for planetary
       system problems", MNRAS 468, 2614.
.. [4] Rein, H. & Tamayo, D. (2019), "Higher order symplectic integrators for planetary dynamics"
       (REBOUND's ``transformations.c``: the same coordinates), MNRAS 489, 4632.
"""

from __future__ import annotations

import numpy as np

from orbitsim._jit import jit


def jacobi_weights(m: np.ndarray) -> np.ndarray:
    """Weights ``w_i = m_i / M_i`` (``w_0 = 1``) of the Jacobi recurrence, ``M_i = m_0 + ... + m_i``.

    ``M_i`` is summed left to right, as the Kepler parameters ``G M_i`` of the Jacobi splitting.
    Requires ``m_0 > 0``.
    """
    m = np.asarray(m, dtype=np.float64)
    if m.shape[0] < 1 or not m[0] > 0.0:
        raise ValueError("Jacobi coordinates need a central body with mass m[0] > 0")
    interior = np.cumsum(m)
    weights = m / interior
    weights[0] = 1.0
    return weights


@jit
def inertial_to_jacobi(src, weights, dst):
    """Jacobi vectors of the inertial vectors ``src`` into ``dst`` (both (3, N); may alias)."""
    n = src.shape[1]
    for c in range(3):
        com = src[c, 0]
        for i in range(1, n):
            rel = src[c, i] - com
            dst[c, i] = rel
            com = com + weights[i] * rel
        dst[c, 0] = com


@jit
def jacobi_to_inertial(src, weights, dst):
    """Inertial vectors of the Jacobi vectors ``src`` into ``dst`` (both (3, N); may alias)."""
    n = src.shape[1]
    for c in range(3):
        com = src[c, 0]
        for i in range(n - 1, 0, -1):
            rel = src[c, i]
            com = com - weights[i] * rel
            dst[c, i] = rel + com
        dst[c, 0] = com


@jit
def inertial_to_democratic_heliocentric(pos, vel, m, hpos, hvel):
    """Heliocentric positions and barycentric velocities of ``pos``, ``vel`` into ``hpos``, ``hvel``.

    Column 0 receives the centre-of-mass position and velocity. Outputs may alias the inputs.
    """
    n = pos.shape[1]
    total = 0.0
    for i in range(n):
        total += m[i]
    for c in range(3):
        sx = 0.0
        sv = 0.0
        for i in range(n):
            sx += m[i] * pos[c, i]
            sv += m[i] * vel[c, i]
        com = sx / total
        vcom = sv / total
        centre = pos[c, 0]
        for i in range(1, n):
            hpos[c, i] = pos[c, i] - centre
            hvel[c, i] = vel[c, i] - vcom
        hpos[c, 0] = com
        hvel[c, 0] = vcom


@jit
def democratic_heliocentric_to_inertial_pos(hpos, m, dst):
    """Inertial positions of democratic heliocentric ``hpos`` into ``dst`` (may alias)."""
    n = hpos.shape[1]
    total = 0.0
    for i in range(n):
        total += m[i]
    for c in range(3):
        s = 0.0
        for i in range(1, n):
            s += m[i] * hpos[c, i]
        centre = hpos[c, 0] - s / total
        for i in range(1, n):
            dst[c, i] = hpos[c, i] + centre
        dst[c, 0] = centre


@jit
def democratic_heliocentric_to_inertial_vel(hvel, m, dst):
    """Inertial velocities of democratic heliocentric (barycentric) ``hvel`` into ``dst`` (may alias)."""
    n = hvel.shape[1]
    for c in range(3):
        p = 0.0
        for i in range(1, n):
            p += m[i] * hvel[c, i]
        vcom = hvel[c, 0]
        for i in range(1, n):
            dst[c, i] = hvel[c, i] + vcom
        dst[c, 0] = vcom - p / m[0]
