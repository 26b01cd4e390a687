"""The coordinate transforms and the jump of TRACE's democratic heliocentric map (jitted, in place).

TRACE uses its own transforms (REBOUND ``reb_integrator_trace_inertial_to_dh`` and
``..._dh_to_inertial``), not :mod:`orbitsim.physics.coordinates` nor REBOUND's
``transformations.c``: their sums run in a different order, and the centre of mass is kept
apart so that it can drift on its own. Democratic heliocentric ("DH") coordinates are
heliocentric positions and barycentric velocities (Duncan, Levison & Lee 1998); the star sits at
the origin with the barycentric velocity it had at the start of the step, which the inverse
transform ignores (the star's velocity follows from the others' momentum).

Sums run in index order, products are written ``m * x`` as REBOUND writes them, and the
positions' centre is divided by the total mass while the momentum is divided by m0, exactly as
REBOUND does; nothing here is compensated.
"""

from __future__ import annotations

from orbitsim._jit import jit_inline


@jit_inline
def inertial_to_dh(pos, vel, m, n_active, com):
    """Inertial -> democratic heliocentric, in place; ``com`` (6,) gets the centre of mass.

    TRACE's own transform (not :mod:`orbitsim.physics.coordinates`): centre of mass of the active
    bodies summed in index order, every position minus the star's (the star lands at 0), every
    velocity minus the centre-of-mass velocity.
    """
    n = pos.shape[1]
    m_total = 0.0
    for i in range(n_active):
        m_total += m[i]
    for c in range(3):
        com_pos = 0.0
        com_vel = 0.0
        for i in range(n_active):
            com_pos += m[i] * pos[c, i]
            com_vel += m[i] * vel[c, i]
        com[c] = com_pos / m_total
        com[3 + c] = com_vel / m_total
    for c in range(3):
        x0 = pos[c, 0]
        for i in range(n):
            pos[c, i] -= x0
            vel[c, i] -= com[3 + c]


@jit_inline
def dh_to_inertial(pos, vel, m, n_active, com):
    """Democratic heliocentric -> inertial, in place, about the centre of mass ``com``.

    The star's position follows from the planets' (``x0 = X_com - sum m_i x_i / M``), its velocity
    from their momentum (``v0 = V_com - sum m_i v_i / m0``); its stored values are ignored.
    """
    n = pos.shape[1]
    m_total = 0.0
    for i in range(1, n_active):
        m_total += m[i]
    m_total += m[0]
    for c in range(3):
        sum_x = 0.0
        sum_v = 0.0
        for i in range(1, n_active):
            sum_x += m[i] * pos[c, i]
            sum_v += m[i] * vel[c, i]
        x0 = com[c] - sum_x / m_total
        pos[c, 0] = x0
        for i in range(1, n):
            pos[c, i] += x0
            vel[c, i] += com[3 + c]
        vel[c, 0] = com[3 + c] - sum_v / m[0]


@jit_inline
def jump(pos, vel, m, n_active, h):
    """The jump ``x_i += h P / m0``, ``P = sum_{1 <= i < n_active} m_i v_i``, for every body i >= 1."""
    n = pos.shape[1]
    h_m0 = h / m[0]
    for c in range(3):
        p = 0.0
        for i in range(1, n_active):
            p += vel[c, i] * m[i]
        p *= h_m0
        for i in range(1, n):
            pos[c, i] += p


@jit_inline
def save_state(pos, vel, frames, plane):
    """Copy the state into ``frames[plane]`` (positions) and ``frames[plane + 1]`` (velocities)."""
    for c in range(3):
        for i in range(pos.shape[1]):
            frames[plane, c, i] = pos[c, i]
            frames[plane + 1, c, i] = vel[c, i]


@jit_inline
def restore_state(pos, vel, frames, plane):
    """Copy ``frames[plane]``, ``frames[plane + 1]`` back into the state."""
    for c in range(3):
        for i in range(pos.shape[1]):
            pos[c, i] = frames[plane, c, i]
            vel[c, i] = frames[plane + 1, c, i]
