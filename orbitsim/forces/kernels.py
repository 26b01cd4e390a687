"""What the forces of a run do, per force record: the entry points the stepping code calls.

Each entry point takes the run's ``terms`` (:func:`orbitsim.forces.terms.terms_of`: one record per
force, in the scenario's order, each record its own Numba type) and applies them one after another.
The walk over the tuple is unrolled when a caller is compiled (each step takes the tuple's head
and a static slice of its tail), and each record
resolves to its own kernel, so a run compiles the kernels of its own forces and no others. Nothing
here allocates (the ``gr_full`` energy excepted, at sample times): the velocity-dependent forces
work in the rows of :func:`make_force_scratch`.

* :func:`add_position_forces`: ``gr_potential`` and ``harmonics``, kicked with gravity.
* :func:`add_velocity_forces`: ``gr``, ``gr_full`` and ``migration`` at a (pos, vel), for the
  integrators that put them in the derivative (euler, rk4, ias15).
* :func:`velocity_operator`: the same forces as an operator on the velocities over h with the
  positions fixed, for the symplectic schemes (Tamayo, Rein, Shi & Hernandez 2020, MNRAS 491,
  2885): REBOUNDx ``integrate_force`` with its implicit midpoint integrator, one operator per
  force in order (as REBOUNDx runs one operator per force added).
* :func:`force_energy`: what each force adds to the Newtonian energy to give its conserved
  quantity.

The ``*_of`` functions are the same walks for jitted callers, inlined at Numba's IR level (the
hooks of :mod:`orbitsim.forces.hooks` call them from inside a step); the entry points wrap them
for Python callers and tests.
"""

from __future__ import annotations

import numpy as np
from numba import types

from orbitsim._jit import jit, overload_inline
from orbitsim.forces.gr import (
    GR_CACHE_ROWS,
    GR_WORK_ROWS,
    MAX_ITERATIONS,
    gr_accelerations,
    gr_energy,
    gr_operator_accelerations,
    gr_prepare_once,
)
from orbitsim.forces.gr_full import WORK_ROWS, gr_full_accelerations, gr_full_energy
from orbitsim.forces.gr_potential import gr_potential_accelerations, gr_potential_energy
from orbitsim.forces.harmonics import harmonics_accelerations, harmonics_potential
from orbitsim.forces.migration import centre_of_mass, migration_accelerations
from orbitsim.forces.terms import VELOCITY_TERMS, GRFullTerm, GRPotentialTerm, GRTerm, HarmonicsTerm, MigrationTerm

__all__ = ["SCRATCH_ROWS", "add_position_forces", "add_velocity_forces", "force_energy", "has_velocity_terms",
           "make_force_scratch", "velocity_operator"]

#: Rows of the operator's own state: the latest estimate of v at the end, the midpoint v, the
#: acceleration there (3 rows each).
_OP_ROWS = 9
#: First row of gr's operator cache (:func:`~orbitsim.forces.gr.gr_prepare_once`), after the operator's rows
#: and the forces' work rows (gr needs GR_WORK_ROWS, gr_full WORK_ROWS).
_GR_CACHE = _OP_ROWS + max(GR_WORK_ROWS, WORK_ROWS)
#: Rows of the scratch: the operator's, the forces' work rows, gr's operator cache.
SCRATCH_ROWS = _GR_CACHE + GR_CACHE_ROWS
#: Implicit-midpoint iterations, and its test |dv|^2 / |v|^2 < eps^2 (REBOUNDx's).
_MIDPOINT_ITERATIONS = MAX_ITERATIONS
_EPS = np.finfo(np.float64).eps


def make_force_scratch(n: int) -> np.ndarray:
    """The work array (SCRATCH_ROWS, N) that :func:`add_velocity_forces` and
    :func:`velocity_operator` take, for N bodies."""
    return np.zeros((SCRATCH_ROWS, n))


def _record(term: types.Type) -> type | None:
    """The record class of a term's Numba type (None for another type)."""
    return getattr(term, "instance_class", None) if isinstance(term, types.BaseNamedTuple) else None


def has_velocity_terms(terms: types.Type) -> bool:
    """True when a terms tuple's Numba type holds a velocity-dependent force (typing time)."""
    return any(_record(t) in VELOCITY_TERMS for t in terms)


# -- one record ---------------------------------------------------------------------------------
# The Python stand-ins are never run: jitted callers only; the overloads give their meaning.

def _position_term(term, pos, m, G, acc):
    """acc += one position-only force (nothing for a velocity-dependent one)."""
    raise NotImplementedError("called from jitted code only")


def _velocity_term(term, pos, vel, m, G, com, acc, work):
    """acc += one velocity-dependent force at (pos, vel); ``com`` as the force reads it."""
    raise NotImplementedError("called from jitted code only")


def _operator_work(term, pos, m, G, scratch):
    """The work rows one velocity-dependent force's operator evaluates it with at positions ``pos``, holding
    what the force computes from the positions alone (gr: :func:`~orbitsim.forces.gr.gr_prepare_once`'s
    block of its own rows, prepared only for new positions; the shared work rows for the others)."""
    raise NotImplementedError("called from jitted code only")


def _prepared_velocity_term(term, pos, vel, m, G, com, acc, work):
    """:func:`_velocity_term` with ``work`` from :func:`_operator_work` at the same positions: the same bits."""
    raise NotImplementedError("called from jitted code only")


def _com_for(term, pos, vel, m):
    """The centre of mass a velocity-dependent force reads (None for gr, which reads none)."""
    raise NotImplementedError("called from jitted code only")


def _derivative_term(term, pos, vel, m, G, acc, scratch):
    """acc += one velocity-dependent force at (pos, vel) in an equation of motion (nothing for a
    position-only one)."""
    raise NotImplementedError("called from jitted code only")


def _term_energy(term, pos, vel, m, G, e):
    """e + what one force adds to the energy (e itself for migration, which dissipates)."""
    raise NotImplementedError("called from jitted code only")


@overload_inline(_position_term)
def _ol_position_term(term, pos, m, G, acc):
    kind = _record(term)
    if kind is GRPotentialTerm:
        return lambda term, pos, m, G, acc: gr_potential_accelerations(pos, m, G, term.source, term.c, acc)
    if kind is HarmonicsTerm:
        return lambda term, pos, m, G, acc: harmonics_accelerations(
            pos, m, G, term.source, term.J2, term.J4, term.R_eq, term.spin_x, term.spin_y, term.spin_z, acc)
    return lambda term, pos, m, G, acc: None


@overload_inline(_velocity_term)
def _ol_velocity_term(term, pos, vel, m, G, com, acc, work):
    kind = _record(term)
    if kind is GRTerm:
        return lambda term, pos, vel, m, G, com, acc, work: gr_accelerations(pos, vel, m, G, term.source, term.c, acc,
                                                                             work)
    if kind is GRFullTerm:
        return lambda term, pos, vel, m, G, com, acc, work: gr_full_accelerations(pos, vel, m, G, term.c, com, acc,
                                                                                  work)
    if kind is MigrationTerm:
        return lambda term, pos, vel, m, G, com, acc, work: migration_accelerations(pos, vel, m, term.taus, com, acc)
    return lambda term, pos, vel, m, G, com, acc, work: None


@overload_inline(_operator_work)
def _ol_operator_work(term, pos, m, G, scratch):
    if _record(term) is GRTerm:
        return lambda term, pos, m, G, scratch: gr_prepare_once(pos, m, G, term.source, scratch[_GR_CACHE:])
    return lambda term, pos, m, G, scratch: scratch[_OP_ROWS:_GR_CACHE]


@overload_inline(_prepared_velocity_term)
def _ol_prepared_velocity_term(term, pos, vel, m, G, com, acc, work):
    if _record(term) is GRTerm:
        return lambda term, pos, vel, m, G, com, acc, work: gr_operator_accelerations(vel, m, G, term.source, term.c,
                                                                                      acc, work)
    return lambda term, pos, vel, m, G, com, acc, work: _velocity_term(term, pos, vel, m, G, com, acc, work)


@overload_inline(_com_for)
def _ol_com_for(term, pos, vel, m):
    if _record(term) in (GRFullTerm, MigrationTerm):
        return lambda term, pos, vel, m: centre_of_mass(pos, vel, m)
    return lambda term, pos, vel, m: None


@overload_inline(_derivative_term)
def _ol_derivative_term(term, pos, vel, m, G, acc, scratch):
    if _record(term) not in (GRTerm, GRFullTerm, MigrationTerm):
        return lambda term, pos, vel, m, G, acc, scratch: None

    def impl(term, pos, vel, m, G, acc, scratch):
        # The centre of mass is that of the state the forces are evaluated at (REBOUND's IAS15 and RK
        # steps call REBOUNDx with the simulation's particles at that state).
        _velocity_term(term, pos, vel, m, G, _com_for(term, pos, vel, m), acc, scratch[_OP_ROWS:])
    return impl


@overload_inline(_term_energy)
def _ol_term_energy(term, pos, vel, m, G, e):
    kind = _record(term)
    if kind is GRPotentialTerm:
        return lambda term, pos, vel, m, G, e: e + gr_potential_energy(pos, m, G, term.source, term.c)
    if kind is HarmonicsTerm:
        return lambda term, pos, vel, m, G, e: e + harmonics_potential(
            pos, m, G, term.source, term.J2, term.J4, term.R_eq, term.spin_x, term.spin_y, term.spin_z)
    if kind is GRTerm:
        return lambda term, pos, vel, m, G, e: e + gr_energy(pos, vel, m, G, term.source, term.c)
    if kind is GRFullTerm:
        return lambda term, pos, vel, m, G, e: e + gr_full_energy(pos, vel, m, G, term.c)
    return lambda term, pos, vel, m, G, e: e


# -- the walks over a run's records ------------------------------------------------------------

def add_position_forces_of(terms, pos, m, G, acc):
    """acc (3, N) += the position-only forces (gr_potential, harmonics), in order."""
    raise NotImplementedError("called from jitted code only")


def add_velocity_forces_of(terms, pos, vel, m, G, acc, scratch):
    """acc (3, N) += the velocity-dependent forces (gr, gr_full, migration) at (pos, vel), in order."""
    raise NotImplementedError("called from jitted code only")


def velocity_operator_of(terms, pos, vel, m, G, h, scratch):
    """``vel`` advanced over h under the velocity-dependent forces, positions fixed, in order."""
    raise NotImplementedError("called from jitted code only")


def force_energy_of(terms, pos, vel, m, G, e):
    """e + the forces' energy, in order."""
    raise NotImplementedError("called from jitted code only")


@overload_inline(add_position_forces_of)
def _ol_add_position_forces_of(terms, pos, m, G, acc):
    if len(terms) == 0:
        return lambda terms, pos, m, G, acc: None

    def impl(terms, pos, m, G, acc):
        _position_term(terms[0], pos, m, G, acc)
        add_position_forces_of(terms[1:], pos, m, G, acc)
    return impl


@overload_inline(add_velocity_forces_of)
def _ol_add_velocity_forces_of(terms, pos, vel, m, G, acc, scratch):
    if len(terms) == 0:
        return lambda terms, pos, vel, m, G, acc, scratch: None

    def impl(terms, pos, vel, m, G, acc, scratch):
        _derivative_term(terms[0], pos, vel, m, G, acc, scratch)
        add_velocity_forces_of(terms[1:], pos, vel, m, G, acc, scratch)
    return impl


@overload_inline(velocity_operator_of)
def _ol_velocity_operator_of(terms, pos, vel, m, G, h, scratch):
    if len(terms) == 0:
        return lambda terms, pos, vel, m, G, h, scratch: None

    # The first record's operator is chosen here, not by an overload of its own: Numba compiles every
    # overload's implementation once apart (to type it), and a layer that only called _implicit_midpoint
    # optimised and compiled it once more (0.5 s of a first Wisdom-Holman + gr run).
    if _record(terms[0]) not in VELOCITY_TERMS:  # a position-only force: not in the operator
        return lambda terms, pos, vel, m, G, h, scratch: velocity_operator_of(terms[1:], pos, vel, m, G, h, scratch)

    def impl(terms, pos, vel, m, G, h, scratch):
        _implicit_midpoint(terms[0], pos, vel, m, G, h, scratch)
        velocity_operator_of(terms[1:], pos, vel, m, G, h, scratch)
    return impl


@overload_inline(force_energy_of)
def _ol_force_energy_of(terms, pos, vel, m, G, e):
    if len(terms) == 0:
        return lambda terms, pos, vel, m, G, e: e

    def impl(terms, pos, vel, m, G, e):
        return force_energy_of(terms[1:], pos, vel, m, G, _term_energy(terms[0], pos, vel, m, G, e))
    return impl


# -- the implicit midpoint ----------------------------------------------------------------------

@jit
def _implicit_midpoint(term, pos, vel, m, G, h, scratch):
    """v(h) = v(0) + h a(pos, (v(0) + v(h)) / 2) for one velocity-dependent force, solved by
    fixed-point iteration (REBOUNDx's ``integrator_implicit_midpoint``: the first estimate takes a
    at v(0); at most 10 iterations).

    The centre of mass the force reads is that of the state before the step, as in REBOUNDx,
    whose simulation particles keep their velocities until the operator ends. The positions do
    not move, so what the force computes from them alone is computed once (:func:`_operator_work`:
    ``gr``'s Newtonian sum and Jacobi positions), not at every iteration as in REBOUNDx, and for
    ``gr`` not again in the next operator at the same positions (the next step's first).
    """
    n = pos.shape[1]
    vf, va, a = scratch[0:3], scratch[3:6], scratch[6:9]  # vel itself is v(0) until the end
    for k in range(3):  # explicit loops, not slice assignments: they cost more than a few bodies' arithmetic
        for i in range(n):
            vf[k, i] = vel[k, i]
            va[k, i] = vel[k, i]
    com = _com_for(term, pos, vel, m)
    work = _operator_work(term, pos, m, G, scratch)
    for _ in range(_MIDPOINT_ITERATIONS):
        for k in range(3):
            for i in range(n):
                a[k, i] = 0.0
        _prepared_velocity_term(term, pos, va, m, G, com, a, work)
        # the new estimate, and REBOUNDx's test on it in the same pass: sum |v_new - v_prev|^2 / sum |v_new|^2
        # < eps^2, each sum taken body by body as REBOUNDx does
        delta = 0.0
        tot = 0.0
        for i in range(n):
            fx = vel[0, i] + h * a[0, i]
            fy = vel[1, i] + h * a[1, i]
            fz = vel[2, i] + h * a[2, i]
            dx = fx - vf[0, i]
            dy = fy - vf[1, i]
            dz = fz - vf[2, i]
            delta += dx * dx + dy * dy + dz * dz
            tot += fx * fx + fy * fy + fz * fz
            vf[0, i] = fx
            vf[1, i] = fy
            vf[2, i] = fz
        if delta / tot < _EPS * _EPS:
            break
        for k in range(3):
            for i in range(n):
                va[k, i] = 0.5 * (vel[k, i] + vf[k, i])
    for k in range(3):
        for i in range(n):
            vel[k, i] = vf[k, i]


# -- entry points for Python callers and tests --------------------------------------------------

@jit
def add_position_forces(pos, m, G, terms, acc):
    """acc (3, N) += the accelerations of the position-only forces (gr_potential, harmonics)."""
    add_position_forces_of(terms, pos, m, G, acc)


@jit
def add_velocity_forces(pos, vel, m, G, terms, acc, scratch):
    """acc (3, N) += the accelerations of the velocity-dependent forces (gr, gr_full, migration)."""
    add_velocity_forces_of(terms, pos, vel, m, G, acc, scratch)


@jit
def velocity_operator(pos, vel, m, G, terms, h, scratch):
    """Advance ``vel`` in place over h under the velocity-dependent forces, positions fixed: one
    implicit-midpoint operator per force, in order."""
    velocity_operator_of(terms, pos, vel, m, G, h, scratch)


@jit
def force_energy(pos, vel, m, G, terms):
    """What to add to the Newtonian kinetic + potential energy to get the conserved quantity:
    the potentials of gr_potential and harmonics, the 1PN Hamiltonians' corrections of gr and
    gr_full, nothing for migration (dissipative)."""
    return force_energy_of(terms, pos, vel, m, G, 0.0)
