"""The forces' part of the variational equations: how a position force's acceleration changes.

A force that acts on positions changes the tangent accelerations da = J dr by its own Jacobian
times dr; leaving it out (REBOUND's MEGNO ignores REBOUNDx forces, its issue #800) integrates the
variations of a different system than the bodies'. :func:`add_tangent_kick_forces` is the hook
every scheme's variational kick and MEGNO's read call beside
:func:`orbitsim.physics.tangent.tangent_accelerations`; like :mod:`orbitsim.forces.hooks` it
compiles to nothing for a force context without forces. With forces it walks the run's records
(:mod:`orbitsim.forces.terms`) as the force kernels do, each resolved to its own derivative:

* ``gr_potential``: :func:`orbitsim.forces.gr_potential.gr_potential_tangent`;
* ``harmonics``: :func:`orbitsim.forces.harmonics.harmonics_tangent`.

Each is the exact Jacobian of the acceleration the kick applies (the reaction on the source
included), applied to the tangent positions: a matrix-vector product, no 3N x 3N matrix. The
velocity-dependent forces (``gr``, ``gr_full``, ``migration``) enter the symplectic schemes as an
operator on the velocities, whose derivative is not built: the front door refuses them in one
line before a kernel is compiled (:func:`orbitsim.forces.compat.check_chaos_forces`), and the
overload raises a typing error naming the force for anything that slipped past it, so a
variational run never silently uses Newtonian variations.
"""

from __future__ import annotations

from numba import errors

from orbitsim._jit import jit, overload_inline
from orbitsim.forces.hooks import _terms

__all__ = ["add_tangent_forces", "add_tangent_forces_of", "add_tangent_kick_forces"]


# The Python stand-ins: never run (every caller is jitted); the overloads below give their meaning.
def add_tangent_kick_forces(force, pos, m, dpos, dacc):
    """dacc += the position forces' Jacobian at ``pos`` times ``dpos`` (each (3, N))."""
    raise NotImplementedError("called from jitted code only")


def add_tangent_forces_of(terms, pos, m, G, dpos, dacc):
    """dacc (3, N) += every force record's Jacobian at ``pos`` times ``dpos``, in order."""
    raise NotImplementedError("called from jitted code only")


def _tangent_term(term, pos, m, G, dpos, dacc):
    """dacc += one force's Jacobian times dpos (a typing error for a force without one)."""
    raise NotImplementedError("called from jitted code only")


@overload_inline(_tangent_term)
def _ol_tangent_term(term, pos, m, G, dpos, dacc):
    # lazy: the force modules load only when a forced variational step is typed
    from orbitsim.forces.gr_potential import gr_potential_tangent  # noqa: PLC0415 -- lazy: off runs without forces
    from orbitsim.forces.harmonics import harmonics_tangent  # noqa: PLC0415 -- lazy: off runs without forces
    from orbitsim.forces.kernels import _record  # noqa: PLC0415 -- lazy: off runs without forces
    from orbitsim.forces.terms import (  # noqa: PLC0415 -- lazy: off runs without forces
        GRFullTerm,
        GRPotentialTerm,
        GRTerm,
        HarmonicsTerm,
        MigrationTerm,
    )

    kind = _record(term)
    if kind is GRPotentialTerm:
        return lambda term, pos, m, G, dpos, dacc: gr_potential_tangent(pos, m, G, term.source, term.c, dpos, dacc)
    if kind is HarmonicsTerm:
        return lambda term, pos, m, G, dpos, dacc: harmonics_tangent(
            pos, m, G, term.source, term.J2, term.J4, term.R_eq, term.spin_x, term.spin_y, term.spin_z, dpos, dacc)
    name = {GRTerm: "gr", GRFullTerm: "gr_full", MigrationTerm: "migration"}.get(kind, str(term))
    raise errors.TypingError(f"orbitsim: the variational equations of force {name} are not built")


@overload_inline(add_tangent_forces_of)
def _ol_add_tangent_forces_of(terms, pos, m, G, dpos, dacc):
    if len(terms) == 0:
        return lambda terms, pos, m, G, dpos, dacc: None

    def impl(terms, pos, m, G, dpos, dacc):
        _tangent_term(terms[0], pos, m, G, dpos, dacc)
        add_tangent_forces_of(terms[1:], pos, m, G, dpos, dacc)
    return impl


@overload_inline(add_tangent_kick_forces)
def _add_tangent_kick_forces(force, pos, m, dpos, dacc):
    if _terms(force) is None:
        return lambda force, pos, m, dpos, dacc: None
    return lambda force, pos, m, dpos, dacc: add_tangent_forces_of(force.forces.terms, pos, m, force.G, dpos, dacc)


@jit
def add_tangent_forces(pos, m, G, terms, dpos, dacc):
    """dacc (3, N) += the Jacobian of the position-only forces ``terms`` at ``pos`` times ``dpos``
    (the entry point for Python callers and tests)."""
    add_tangent_forces_of(terms, pos, m, G, dpos, dacc)
