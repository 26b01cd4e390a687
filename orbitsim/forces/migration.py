"""Migration and eccentricity/inclination damping: REBOUNDx ``modify_orbits_forces``, jitted.

Each body i > 0 feels, relative to the centre of mass of the bodies before it (Jacobi
coordinates, REBOUNDx's default; Papaloizou & Larwood 2000, MNRAS 315, 823; Kostov et al. 2016),
with d, u its position and velocity relative to that centre of mass,

    a_i = u / (2 tau_a) + 2 (d . u) / (|d|^2 tau_e) d + 2 u_z / tau_inc z^,

whose orbit averages give exponential change of a, e and i on the timescales tau_a, tau_e, tau_inc
(REBOUNDx's signs: a negative tau damps). The term in tau_e keeps the angular momentum; the
eccentricity and inclination terms act only when one of the two timescales is finite. The
reaction is spread over the bodies 0 .. i (weight m_i / (M_<i + m_i) each, the body itself
included), so the total momentum is kept. Body 0 has no Jacobi coordinate and is never forced.
A timescale of inf switches its term off (1/inf = 0, exactly as an unset REBOUNDx parameter).

The centre of mass enters as an argument: REBOUNDx takes it from the simulation's particles, which
inside its ``integrate_force`` operator keep the velocities from before the step while the force
is evaluated at the midpoint velocities; the operator reproduces that.
"""

from __future__ import annotations

import numpy as np

from orbitsim._jit import jit


@jit
def centre_of_mass(pos, vel, m):
    """(x, y, z, vx, vy, vz, M) of all bodies, accumulated pair by pair as REBOUND's
    ``reb_simulation_com`` (its rounding is what the Jacobi chain below starts from)."""
    x = y = z = vx = vy = vz = M = 0.0
    for i in range(pos.shape[1]):
        mi = m[i]
        x = x * M + pos[0, i] * mi
        y = y * M + pos[1, i] * mi
        z = z * M + pos[2, i] * mi
        vx = vx * M + vel[0, i] * mi
        vy = vy * M + vel[1, i] * mi
        vz = vz * M + vel[2, i] * mi
        M += mi
        if M > 0.0:
            x /= M
            y /= M
            z /= M
            vx /= M
            vy /= M
            vz /= M
    return x, y, z, vx, vy, vz, M


@jit
def _damping(dx, dy, dz, dvx, dvy, dvz, tau_a, tau_e, tau_inc):
    """The acceleration of the module docstring for one body (REBOUNDx's order of operations)."""
    invtau_a = 1.0 / tau_a
    ax = dvx * invtau_a / 2.0
    ay = dvy * invtau_a / 2.0
    az = dvz * invtau_a / 2.0
    if tau_e < np.inf or tau_inc < np.inf:
        r2 = dx * dx + dy * dy + dz * dz
        vdotr = dx * dvx + dy * dvy + dz * dvz
        prefac = 2.0 * vdotr / r2 / tau_e
        ax += prefac * dx
        ay += prefac * dy
        az += prefac * dz + 2.0 * dvz / tau_inc
    return ax, ay, az


@jit
def migration_accelerations(pos, vel, m, taus, com, acc):
    """acc (3, N) += the damping forces of ``taus`` (3, N: tau_a, tau_e, tau_inc) in Jacobi
    coordinates; ``com``: :func:`centre_of_mass` of the state REBOUNDx would take it from."""
    cx, cy, cz, cvx, cvy, cvz, cm = com
    for i in range(pos.shape[1] - 1, 0, -1):
        mi = m[i]
        # The centre of mass of bodies 0 .. i-1 (REBOUNDx's rebx_get_com_without_particle).
        cx = cx * cm - pos[0, i] * mi
        cy = cy * cm - pos[1, i] * mi
        cz = cz * cm - pos[2, i] * mi
        cvx = cvx * cm - vel[0, i] * mi
        cvy = cvy * cm - vel[1, i] * mi
        cvz = cvz * cm - vel[2, i] * mi
        cm -= mi
        if cm > 0.0:
            cx /= cm
            cy /= cm
            cz /= cm
            cvx /= cm
            cvy /= cm
            cvz /= cm
        tau_a, tau_e, tau_inc = taus[0, i], taus[1, i], taus[2, i]
        if tau_a == np.inf and tau_e == np.inf and tau_inc == np.inf:
            continue  # an undamped body: REBOUNDx adds zeros here
        ax, ay, az = _damping(pos[0, i] - cx, pos[1, i] - cy, pos[2, i] - cz,
                              vel[0, i] - cvx, vel[1, i] - cvy, vel[2, i] - cvz, tau_a, tau_e, tau_inc)
        acc[0, i] += ax
        acc[1, i] += ay
        acc[2, i] += az
        massratio = mi / (cm + mi)
        for j in range(i + 1):
            acc[0, j] -= massratio * ax
            acc[1, j] -= massratio * ay
            acc[2, j] -= massratio * az
