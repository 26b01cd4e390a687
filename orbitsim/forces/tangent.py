"""The forces' part of the variational equations: how a position force's acceleration changes.

A force that acts on positions changes the tangent accelerations da = J dr by its own Jacobian
times dr; leaving it out (REBOUND's MEGNO ignores REBOUNDx forces, its issue #800) integrates the
variations of a different system than the bodies'. :func:`add_tangent_kick_forces` is the hook
every scheme's variational kick and MEGNO's read call beside
:func:`orbitsim.physics.tangent.tangent_accelerations`; like :mod:`orbitsim.forces.hooks` it
compiles to nothing for a force context without forces.

A forced context is typed only when every force it holds has its derivative here: the front door
refuses the rest in one line before a kernel is compiled, and the overload raises a typing error
for anything that slipped past it.
"""

from __future__ import annotations

from numba import errors
from numba.extending import overload

from orbitsim.forces.hooks import _terms

__all__ = ["add_tangent_kick_forces"]


# The Python stand-in: never run (every caller is jitted); the overload below gives its meaning.
def add_tangent_kick_forces(force, pos, m, dpos, dacc):
    """dacc += the position forces' Jacobian at ``pos`` times ``dpos`` (each (3, N))."""
    raise NotImplementedError("called from jitted code only")


@overload(add_tangent_kick_forces, inline="always")
def _add_tangent_kick_forces(force, pos, m, dpos, dacc):
    if _terms(force) is None:
        return lambda force, pos, m, dpos, dacc: None
    raise errors.TypingError("orbitsim: the variational equations of this run's forces are not built")
