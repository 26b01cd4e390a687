"""The four entry points the forced stepping loops call, dispatching on the rows of a ForceSet.

Each takes the arrays of :attr:`orbitsim.forces.table.ForceSet.arrays` unpacked after its fixed
arguments, loops over the force rows and branches on the id, so one compiled kernel serves every
combination of forces. Nothing here allocates (the ``gr_full`` energy excepted, at sample times):
the velocity-dependent forces work in the rows of :func:`make_force_scratch`.

* :func:`add_position_forces`: ``gr_potential`` and ``harmonics``, kicked with gravity.
* :func:`add_velocity_forces`: ``gr``, ``gr_full`` and ``migration`` at a (pos, vel), for the
  integrators that put them in the derivative (euler, rk4, ias15).
* :func:`velocity_operator`: the same forces as an operator on the velocities over h with the
  positions fixed, for the symplectic schemes (Tamayo, Rein, Shi & Hernandez 2020, MNRAS 491,
  2885): REBOUNDx ``integrate_force`` with its implicit midpoint integrator, one operator per
  force in row order (as REBOUNDx runs one operator per force added).
* :func:`force_energy`: what each force adds to the Newtonian energy to give its conserved
  quantity.
"""

from __future__ import annotations

import numpy as np

from orbitsim._jit import jit
from orbitsim.forces.gr import (
    MAX_ITERATIONS,
    gr_accelerations,
    gr_energy,
    gr_potential_accelerations,
    gr_potential_energy,
)
from orbitsim.forces.gr_full import WORK_ROWS, gr_full_accelerations, gr_full_energy
from orbitsim.forces.harmonics import harmonics_accelerations, harmonics_potential
from orbitsim.forces.migration import centre_of_mass, migration_accelerations
from orbitsim.forces.table import GR, GR_FULL, GR_POTENTIAL, HARMONICS, MIGRATION, P_C, P_J2, P_J4, P_R_EQ, P_SPIN

__all__ = ["SCRATCH_ROWS", "add_position_forces", "add_velocity_forces", "force_energy", "make_force_scratch",
           "velocity_operator"]

#: Rows of the operator's own state: v at the start, the latest and the previous estimate of v at
#: the end, the midpoint v, the acceleration there (3 rows each).
_OP_ROWS = 15
#: Rows of the scratch: the operator's, then the force's work rows (gr needs 15, gr_full 20).
SCRATCH_ROWS = _OP_ROWS + max(15, WORK_ROWS)
#: Implicit-midpoint iterations, and its test |dv|^2 / |v|^2 < eps^2 (REBOUNDx's).
_MIDPOINT_ITERATIONS = MAX_ITERATIONS
_EPS = np.finfo(np.float64).eps


def make_force_scratch(n: int) -> np.ndarray:
    """The work array (SCRATCH_ROWS, N) that :func:`add_velocity_forces` and
    :func:`velocity_operator` take, for N bodies."""
    return np.zeros((SCRATCH_ROWS, n))


@jit
def add_position_forces(pos, m, G, ids, source, params, per_body, acc):
    """acc (3, N) += the accelerations of the position-only forces (gr_potential, harmonics)."""
    for k in range(ids.shape[0]):
        fid = ids[k]
        if fid == GR_POTENTIAL:
            gr_potential_accelerations(pos, m, G, source[k], params[k, P_C], acc)
        elif fid == HARMONICS:
            harmonics_accelerations(pos, m, G, source[k], params[k, P_J2], params[k, P_J4], params[k, P_R_EQ],
                                    params[k, P_SPIN], params[k, P_SPIN + 1], params[k, P_SPIN + 2], acc)


@jit
def _velocity_force(pos, vel, m, G, fid, src, c, taus, com, acc, work):
    """acc += one velocity-dependent force at (pos, vel); ``com`` as the force reads it."""
    if fid == GR:
        gr_accelerations(pos, vel, m, G, src, c, acc, work)
    elif fid == GR_FULL:
        gr_full_accelerations(pos, vel, m, G, c, com, acc, work)
    elif fid == MIGRATION:
        migration_accelerations(pos, vel, m, taus, com, acc)


@jit
def add_velocity_forces(pos, vel, m, G, ids, source, params, per_body, acc, scratch):
    """acc (3, N) += the accelerations of the velocity-dependent forces (gr, gr_full, migration)."""
    work = scratch[_OP_ROWS:]
    for k in range(ids.shape[0]):
        fid = ids[k]
        if fid == GR:
            gr_accelerations(pos, vel, m, G, source[k], params[k, P_C], acc, work)
        elif fid == GR_FULL or fid == MIGRATION:
            # Their centre of mass is that of the state they are evaluated at (REBOUND's IAS15 and
            # RK steps call REBOUNDx with the simulation's particles at that state).
            com = centre_of_mass(pos, vel, m)
            _velocity_force(pos, vel, m, G, fid, source[k], params[k, P_C], per_body[k], com, acc, work)


@jit
def _converged(vf, vp):
    """REBOUNDx's implicit-midpoint test: sum |v_new - v_prev|^2 / sum |v_new|^2 < eps^2."""
    delta = 0.0
    tot = 0.0
    for i in range(vf.shape[1]):
        dx = vf[0, i] - vp[0, i]
        dy = vf[1, i] - vp[1, i]
        dz = vf[2, i] - vp[2, i]
        delta += dx * dx + dy * dy + dz * dz
        tot += vf[0, i] * vf[0, i] + vf[1, i] * vf[1, i] + vf[2, i] * vf[2, i]
    return delta / tot < _EPS * _EPS


@jit
def _implicit_midpoint(pos, vel, m, G, fid, src, c, taus, h, scratch):
    """v(h) = v(0) + h a(pos, (v(0) + v(h)) / 2), solved by fixed-point iteration (REBOUNDx's
    ``integrator_implicit_midpoint``: the first estimate takes a at v(0); at most 10 iterations).

    The centre of mass the force reads is that of the state before the step, as in REBOUNDx,
    whose simulation particles keep their velocities until the operator ends.
    """
    n = pos.shape[1]
    v0, vf, vp, va, a = scratch[0:3], scratch[3:6], scratch[6:9], scratch[9:12], scratch[12:15]
    work = scratch[_OP_ROWS:]
    v0[:, :] = vel
    vf[:, :] = vel
    va[:, :] = vel
    com = centre_of_mass(pos, vel, m)
    for _ in range(_MIDPOINT_ITERATIONS):
        vp[:, :] = vf
        a[:, :] = 0.0
        _velocity_force(pos, va, m, G, fid, src, c, taus, com, a, work)
        for k in range(3):
            for i in range(n):
                vf[k, i] = v0[k, i] + h * a[k, i]
        if _converged(vf, vp):
            break
        for k in range(3):
            for i in range(n):
                va[k, i] = 0.5 * (v0[k, i] + vf[k, i])
    vel[:, :] = vf


@jit
def velocity_operator(pos, vel, m, G, ids, source, params, per_body, h, scratch):
    """Advance ``vel`` in place over h under the velocity-dependent forces, positions fixed: one
    implicit-midpoint operator per force, in row order."""
    for k in range(ids.shape[0]):
        fid = ids[k]
        if fid == GR or fid == GR_FULL or fid == MIGRATION:
            _implicit_midpoint(pos, vel, m, G, fid, source[k], params[k, P_C], per_body[k], h, scratch)


@jit
def force_energy(pos, vel, m, G, ids, source, params, per_body):
    """What to add to the Newtonian kinetic + potential energy to get the conserved quantity:
    the potentials of gr_potential and harmonics, the 1PN Hamiltonians' corrections of gr and
    gr_full, nothing for migration (dissipative)."""
    e = 0.0
    for k in range(ids.shape[0]):
        fid = ids[k]
        if fid == GR_POTENTIAL:
            e += gr_potential_energy(pos, m, G, source[k], params[k, P_C])
        elif fid == HARMONICS:
            e += harmonics_potential(pos, m, G, source[k], params[k, P_J2], params[k, P_J4], params[k, P_R_EQ],
                                     params[k, P_SPIN], params[k, P_SPIN + 1], params[k, P_SPIN + 2])
        elif fid == GR:
            e += gr_energy(pos, vel, m, G, source[k], params[k, P_C])
        elif fid == GR_FULL:
            e += gr_full_energy(pos, vel, m, G, params[k, P_C])
    return e
