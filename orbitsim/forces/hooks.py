"""Where every integrator meets a run's forces: hooks that compile to nothing without forces.

A step receives the force context of :func:`orbitsim.physics.force_context.make_force`; in a run with
forces its ``forces`` field holds a :class:`Forces` (:func:`forced_context` puts it there), and
None otherwise. The hooks below are Numba ``overload`` s resolved when a step is typed: for a
context whose ``forces`` is None they are empty functions, inlined at Numba's IR level and so
removed before LLVM sees the step, which compiles to the same code as a step that never heard of
forces (benchmarks/forces_overhead.py measures it); with forces they walk the run's force records
(:mod:`orbitsim.forces.kernels`, imported only then), each resolved to its own kernel. That is how
every scheme serves forced runs with its own loop and no second copy of it, and how a run without
forces compiles, imports and pays nothing for them.

* :func:`add_forces`: ``acc +=`` every force at (pos, vel), for the schemes that integrate the
  equations of motion (euler, rk4, ias15);
* :func:`add_kick_forces`: ``acc +=`` the position-only forces (``gr_potential``, ``harmonics``):
  they derive from a potential, so they join gravity in every kick of a symplectic scheme (in
  Wisdom-Holman's interaction kick before the Jacobi transform, as REBOUND's WHFast adds
  ``additional_forces``), which stays symplectic;
* :func:`velocity_operator`: the velocity-dependent forces
  (``gr``, ``migration``) as their own operator ``V(h)`` around a symplectic step,
  ``V(dt/2) S(dt) V(dt/2)`` (REBOUNDx's ``integrate_force``, implicit midpoint): naive
  velocity-dependent kicks give qualitatively wrong long-term answers (Tamayo, Rein, Shi &
  Hernandez 2020, MNRAS 491, 2885);
* :func:`add_node_forces`: :func:`add_forces` at an IAS15 node, the node's velocities predicted from
  the polynomial first when a force needs them, in the operation order of REBOUND's
  ``integrator_ias15.c`` (its ``force_is_velocity_dependent`` branch);
* :func:`refresh_accelerations`: a forced run's accelerations afresh at the start of every call,
  with the arithmetic of the end of a step, so however a run is cut into calls the bits are the
  same (a run without forces keeps the ones its last step left);
* :func:`record_force_energy`: a sample's potential gets the forces' energy added, so every
  energy a trace reports is the quantity the forces conserve;
* :func:`gravity_only`: the context for a kick by gravity alone (Wisdom-Holman's correctors);
* :class:`ByVelocityForces`: a scheme's entry point as two kernels, the one a call runs chosen in Python
  by the context (:func:`velocity_forces_in`), where the loop with the operator ``V(h)`` and the loop
  without it differ (Wisdom-Holman, verlet). One kernel with a branch on a constant of the context's type
  would type, lower and optimise both loops: Numba prunes a branch before typing only, and an overload's
  constant is known only once the call is typed (2 s of a 16-18 s first Wisdom-Holman run);
  :func:`no_velocity_operator` makes the plain loop refuse, while it is typed, a context that needs V.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
from numba import types
from numba.core.errors import TypingError

from orbitsim._jit import overload_inline
from orbitsim.physics.force_context import newtonian_accelerations

if TYPE_CHECKING:
    from orbitsim.forces.table import ForceSet
    from orbitsim.physics.force_context import ForceContext

__all__ = ["ByVelocityForces", "Forces", "add_forces", "add_kick_forces", "add_node_forces", "forced_context",
           "gravity_only", "no_velocity_operator", "record_force_energy",
           "refresh_accelerations", "velocity_forces_in", "velocity_operator"]


class Forces(NamedTuple):
    """A run's forces as the steps read them: the force records in order
    (:func:`orbitsim.forces.terms.terms_of`), the velocity-dependent forces' scratch
    (:func:`orbitsim.forces.kernels.make_force_scratch`) and IAS15's node velocities (3, N)."""

    terms: tuple
    scratch: np.ndarray
    v_node: np.ndarray


def forced_context(force: ForceContext, forces: ForceSet, n: int) -> ForceContext:
    """``force`` (a context of :func:`~orbitsim.physics.force_context.make_force` for N bodies) with the
    ForceSet's forces in its ``forces`` field."""
    from orbitsim.forces.kernels import make_force_scratch  # noqa: PLC0415 -- lazy: off `orbitsim run`/`validate`
    from orbitsim.forces.terms import terms_of  # noqa: PLC0415 -- lazy: off `orbitsim run`/`validate`

    return force._replace(forces=Forces(terms_of(*forces.arrays), make_force_scratch(n), np.zeros((3, n))))


def _terms(force: Any) -> Any:
    """The Numba type of a force context's force records, or None for a context without forces."""
    if not isinstance(force, types.BaseNamedTuple) or "forces" not in getattr(force, "fields", ()):
        return None
    forces = force.types[force.fields.index("forces")]
    if not isinstance(forces, types.BaseNamedTuple):
        return None
    return forces.types[forces.fields.index("terms")]


def _velocity_dependent(force: Any) -> bool:
    """True when the context's type holds a velocity-dependent force (typing time)."""
    terms = _terms(force)
    if terms is None:
        return False
    from orbitsim.forces.kernels import has_velocity_terms  # noqa: PLC0415 -- lazy: off `orbitsim run`/`validate`

    return has_velocity_terms(terms)


# The Python stand-ins: never run (every caller is jitted); the overloads below give their meaning.
def add_forces(force, pos, vel, m, acc):
    """acc += every force at (pos, vel) (module docstring)."""
    raise NotImplementedError("called from jitted code only")


def add_kick_forces(force, pos, m, acc):
    """acc += the position-only forces at pos."""
    raise NotImplementedError("called from jitted code only")


def velocity_operator(force, pos, vel, m, h):
    """vel advanced over h by the velocity-dependent forces, positions fixed."""
    raise NotImplementedError("called from jitted code only")


def no_velocity_operator(force):
    """Nothing; a typing error where the context holds velocity-dependent forces (a loop without V)."""
    raise NotImplementedError("called from jitted code only")


def velocity_forces_in(force: Any) -> bool:
    """Whether the force context ``force`` holds a velocity-dependent force (a run that needs the operator
    V(h)), from the records' classes, as the overloads ask it of their Numba types; in microseconds: it
    runs at every kernel call."""
    forces = getattr(force, "forces", None)
    if forces is None:
        return False
    from orbitsim.forces.terms import VELOCITY_TERMS  # noqa: PLC0415 -- lazy: off `orbitsim run`/`validate`

    return any(isinstance(term, VELOCITY_TERMS) for term in forces.terms)


@dataclass(frozen=True)
class ByVelocityForces:
    """A scheme's entry point as two cached kernels: ``split`` (each step wrapped in the velocity operator)
    for a context with velocity-dependent forces, ``plain`` for any other; called as the kernel it picks,
    with the context as its second argument (module docstring)."""

    plain: Callable[..., Any]
    split: Callable[..., Any]

    def __call__(self, state: Any, force: Any, *args: Any) -> Any:
        kernel = self.split if velocity_forces_in(force) else self.plain
        return kernel(state, force, *args)


def add_node_forces(force, pos, m, at, b, csv, v0, a0, dt, hn):
    """at += the forces at IAS15's node hn."""
    raise NotImplementedError("called from jitted code only")


def refresh_accelerations(force, pos, vel, m, acc, derivative):
    """A forced run's acc afresh: gravity and the position-only forces, the velocity-dependent ones
    too when ``derivative``; nothing without forces."""
    raise NotImplementedError("called from jitted code only")


def record_force_energy(force, pos, vel, m, scalars, r):
    """scalars[r, 1] += the forces' energy (forced runs)."""
    raise NotImplementedError("called from jitted code only")


def gravity_only(force):
    """A context whose hooks add no forces: ``force`` itself when it holds none, else None.

    Passing the run's own context where it has no forces gives a callee the same argument types as
    the run's other calls, so Numba compiles it once rather than once more for None (Wisdom-Holman's
    interaction kick: 0.6-0.9 s of a first run's compilation).
    """
    raise NotImplementedError("called from jitted code only")


@overload_inline(add_forces)
def _add_forces(force, pos, vel, m, acc):
    if _terms(force) is None:
        return lambda force, pos, vel, m, acc: None
    from orbitsim.forces.kernels import add_position_forces_of, add_velocity_forces_of  # noqa: PLC0415 -- lazy: off `orbitsim run`/`validate`

    def impl(force, pos, vel, m, acc):
        forces = force.forces
        add_position_forces_of(forces.terms, pos, m, force.G, acc)
        add_velocity_forces_of(forces.terms, pos, vel, m, force.G, acc, forces.scratch)
    return impl


@overload_inline(add_kick_forces)
def _add_kick_forces(force, pos, m, acc):
    if _terms(force) is None:
        return lambda force, pos, m, acc: None
    from orbitsim.forces.kernels import add_position_forces_of  # noqa: PLC0415 -- lazy: off `orbitsim run`/`validate`

    return lambda force, pos, m, acc: add_position_forces_of(force.forces.terms, pos, m, force.G, acc)


@overload_inline(velocity_operator)
def _velocity_operator(force, pos, vel, m, h):
    if not _velocity_dependent(force):
        return lambda force, pos, vel, m, h: None
    from orbitsim.forces.kernels import velocity_operator_of  # noqa: PLC0415 -- lazy: off `orbitsim run`/`validate`

    return lambda force, pos, vel, m, h: velocity_operator_of(force.forces.terms, pos, vel, m, force.G, h,
                                                               force.forces.scratch)


@overload_inline(no_velocity_operator)
def _no_velocity_operator(force):
    if _velocity_dependent(force):
        raise TypingError("a loop without the velocity operator was given velocity-dependent forces: "
                          "call the scheme's entry point (ByVelocityForces), which picks the split loop")
    return lambda force: None


@overload_inline(add_node_forces)
def _add_node_forces(force, pos, m, at, b, csv, v0, a0, dt, hn):
    if _terms(force) is None:
        return lambda force, pos, m, at, b, csv, v0, a0, dt, hn: None
    from orbitsim.forces.kernels import add_position_forces_of, add_velocity_forces_of  # noqa: PLC0415 -- lazy: off `orbitsim run`/`validate`

    if not _velocity_dependent(force):
        return lambda force, pos, m, at, b, csv, v0, a0, dt, hn: add_position_forces_of(force.forces.terms, pos, m,
                                                                                          force.G, at)

    def impl(force, pos, m, at, b, csv, v0, a0, dt, hn):
        forces = force.forces
        add_position_forces_of(forces.terms, pos, m, force.G, at)
        v_node = forces.v_node
        vf = v_node.reshape(v_node.size)
        for k in range(vf.shape[0]):
            # REBOUND's Horner form of v(h) = v0 + h dt (a0 + h/2 (b0 + 2h/3 (b1 + ...))).
            vk = -csv[k] + (((((((b[6, k] * 7.0 * hn / 8.0 + b[5, k]) * 6.0 * hn / 7.0 + b[4, k])
                                * 5.0 * hn / 6.0 + b[3, k]) * 4.0 * hn / 5.0 + b[2, k]) * 3.0 * hn / 4.0
                              + b[1, k]) * 2.0 * hn / 3.0 + b[0, k]) * hn / 2.0 + a0[k]) * dt * hn
            vf[k] = vk + v0[k]
        add_velocity_forces_of(forces.terms, pos, v_node, m, force.G, at, forces.scratch)
    return impl


@overload_inline(refresh_accelerations)
def _refresh_accelerations(force, pos, vel, m, acc, derivative):
    if _terms(force) is None:
        return lambda force, pos, vel, m, acc, derivative: None
    from orbitsim.forces.kernels import add_position_forces_of, add_velocity_forces_of  # noqa: PLC0415 -- lazy: off `orbitsim run`/`validate`

    def impl(force, pos, vel, m, acc, derivative):
        forces = force.forces
        newtonian_accelerations(force, pos, m, acc)
        add_position_forces_of(forces.terms, pos, m, force.G, acc)
        if derivative:
            add_velocity_forces_of(forces.terms, pos, vel, m, force.G, acc, forces.scratch)
    return impl


@overload_inline(record_force_energy)
def _record_force_energy(force, pos, vel, m, scalars, r):
    if _terms(force) is None:
        return lambda force, pos, vel, m, scalars, r: None
    from orbitsim.forces.kernels import force_energy  # noqa: PLC0415 -- lazy: off `orbitsim run`/`validate`

    def impl(force, pos, vel, m, scalars, r):
        scalars[r, 1] += force_energy(pos, vel, m, force.G, force.forces.terms)
    return impl


@overload_inline(gravity_only)
def _gravity_only(force):
    if _terms(force) is None:
        return lambda force: force
    return lambda force: None
