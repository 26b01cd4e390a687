"""The few places where IAS15, Wisdom-Holman and the sample recorder meet a run's forces.

A run with forces passes a *forced force context* instead of the plain one of
:func:`orbitsim.physics.gravity.make_force`:

    (G, eps2, slabs, bounds, (ids, source, params, per_body, scratch, v_node, velocity_in_derivative))

(:func:`forced_context` builds it). The hooks below are Numba ``overload`` s resolved when a caller
is typed: for the plain 4-tuple they are empty functions, inlined at Numba's IR level and so
removed before LLVM sees the caller, which therefore compiles to the same code as before the
hooks existed (benchmarks/forces_overhead.py measures it); for the forced context they call the
force kernels of :mod:`orbitsim.forces.kernels`, which is imported only then. That is how IAS15's
predictor-corrector and Wisdom-Holman's map serve forced runs without a second copy of either,
and how a run without forces compiles, imports and pays nothing for forces.

* :func:`add_forces`: ``acc += `` the forces at (pos, vel): position-only ones always, the
  velocity-dependent ones too when ``velocity_in_derivative`` (IAS15; the symplectic schemes
  apply those as an operator instead, Tamayo et al. 2020, MNRAS 491, 2885).
* :func:`add_node_forces`: the same at an IAS15 node; when velocity-dependent forces are in the
  derivative, the node's velocities are first predicted from the polynomial, in the operation
  order of REBOUND's ``integrator_ias15.c`` (its ``force_is_velocity_dependent`` branch).
* :func:`add_interaction_forces`: Wisdom-Holman's interaction kick, with the position-only forces
  added to the inertial accelerations before their Jacobi transform, as REBOUND's WHFast does
  with ``additional_forces``.
* :func:`record_force_energy`: a sample's potential gets ``force_energy`` added, so every
  energy a trace reports is the quantity the forces conserve.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numba import types
from numba.extending import overload

#: Length of a forced force context, and of the tuple of force arrays in its last slot.
FORCED_LEN = 5
EXTRA_LEN = 7


def is_forced(force: Any) -> bool:
    """True for the Numba type of a forced force context (see the module docstring)."""
    return (isinstance(force, types.BaseTuple) and len(force) == FORCED_LEN
            and isinstance(force[FORCED_LEN - 1], types.BaseTuple) and len(force[FORCED_LEN - 1]) == EXTRA_LEN)


def forced_context(force: tuple[Any, ...], arrays: tuple[np.ndarray, ...], n: int,
                   velocity_in_derivative: bool) -> tuple[Any, ...]:
    """The forced context for the plain ``force`` of N bodies and a ForceSet's ``arrays``."""
    from orbitsim.forces.kernels import make_force_scratch

    ids, source, params, per_body = (np.ascontiguousarray(a) for a in arrays)
    extra = (ids, source, params, per_body, make_force_scratch(n), np.zeros((3, n)), bool(velocity_in_derivative))
    return (*force, extra)


# The Python stand-ins: never run (every caller is jitted); the overloads below give their meaning.
def force_arrays(force):
    """The force arrays of a forced context, None for a plain one."""
    raise NotImplementedError


def add_forces(extra, G, pos, vel, m, acc):
    """acc += the forces at (pos, vel) (module docstring)."""
    raise NotImplementedError


def add_node_forces(extra, G, pos, m, at, b, csv, v0, a0, dt, hn):
    """at += the forces at IAS15's node hn."""
    raise NotImplementedError


def add_interaction_forces(extra, G, ipos, m, acc):
    """acc += the position-only forces at inertial ipos."""
    raise NotImplementedError


def record_force_energy(force, pos, vel, m, scalars, r):
    """scalars[r, 1] += force_energy (forced runs)."""
    raise NotImplementedError


def _none(extra: Any) -> bool:
    return isinstance(extra, (types.NoneType, types.Omitted))


@overload(force_arrays, inline="always")
def _force_arrays(force):
    if is_forced(force):
        return lambda force: force[4]
    return lambda force: None


@overload(add_forces, inline="always")
def _add_forces(extra, G, pos, vel, m, acc):
    if _none(extra):
        return lambda extra, G, pos, vel, m, acc: None
    from orbitsim.forces.kernels import add_position_forces, add_velocity_forces

    def impl(extra, G, pos, vel, m, acc):
        ids, source, params, per_body, scratch, _, in_derivative = extra
        add_position_forces(pos, m, G, ids, source, params, per_body, acc)
        if in_derivative:
            add_velocity_forces(pos, vel, m, G, ids, source, params, per_body, acc, scratch)
    return impl


@overload(add_node_forces, inline="always")
def _add_node_forces(extra, G, pos, m, at, b, csv, v0, a0, dt, hn):
    if _none(extra):
        return lambda extra, G, pos, m, at, b, csv, v0, a0, dt, hn: None
    from orbitsim.forces.kernels import add_position_forces, add_velocity_forces

    def impl(extra, G, pos, m, at, b, csv, v0, a0, dt, hn):
        ids, source, params, per_body, scratch, v_node, in_derivative = extra
        add_position_forces(pos, m, G, ids, source, params, per_body, at)
        if in_derivative:
            vf = v_node.reshape(v_node.size)
            for k in range(vf.shape[0]):
                # REBOUND's Horner form of v(h) = v0 + h dt (a0 + h/2 (b0 + 2h/3 (b1 + ...))).
                vk = -csv[k] + (((((((b[6, k] * 7.0 * hn / 8.0 + b[5, k]) * 6.0 * hn / 7.0 + b[4, k])
                                    * 5.0 * hn / 6.0 + b[3, k]) * 4.0 * hn / 5.0 + b[2, k]) * 3.0 * hn / 4.0
                                  + b[1, k]) * 2.0 * hn / 3.0 + b[0, k]) * hn / 2.0 + a0[k]) * dt * hn
                vf[k] = vk + v0[k]
            add_velocity_forces(pos, v_node, m, G, ids, source, params, per_body, at, scratch)
    return impl


@overload(add_interaction_forces, inline="always")
def _add_interaction_forces(extra, G, ipos, m, acc):
    if _none(extra):
        return lambda extra, G, ipos, m, acc: None
    from orbitsim.forces.kernels import add_position_forces

    def impl(extra, G, ipos, m, acc):
        add_position_forces(ipos, m, G, extra[0], extra[1], extra[2], extra[3], acc)
    return impl


@overload(record_force_energy, inline="always")
def _record_force_energy(force, pos, vel, m, scalars, r):
    if not is_forced(force):
        return lambda force, pos, vel, m, scalars, r: None
    from orbitsim.forces.kernels import force_energy

    def impl(force, pos, vel, m, scalars, r):
        extra = force[4]
        scalars[r, 1] += force_energy(pos, vel, m, force[0], extra[0], extra[1], extra[2], extra[3])
    return impl
