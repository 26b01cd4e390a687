"""Velocity Verlet (kick-drift-kick): the old and new accelerations averaged into the velocity.

    v_{n+1/2} = v_n + (dt/2) a(x_n)
    x_{n+1}   = x_n + dt v_{n+1/2}
    v_{n+1}   = v_{n+1/2} + (dt/2) a(x_{n+1})

Second order, symplectic and time-reversible. The closing kick's a(x_{n+1}) is the next step's
opening kick (first-same-as-last), so a step costs one force evaluation.
"""

from __future__ import annotations

import numpy as np

from orbitsim._jit import jit, jit_inline
from orbitsim.chaos.step import megno_after_step
from orbitsim.events.kernels import watched_run
from orbitsim.forces.hooks import (
    ByVelocityForces,
    add_kick_forces,
    no_velocity_operator,
    refresh_accelerations,
    velocity_operator,
)
from orbitsim.forces.tangent import add_tangent_kick_forces
from orbitsim.integrators.base import Integrator, IntegratorSpec, chaos_sample_loop, drift, grid_time, kick, sample_loop
from orbitsim.physics.force_context import newtonian_accelerations
from orbitsim.physics.tangent import ALL_PAIRS, tangent_accelerations

SPEC = IntegratorSpec(
    name="verlet",
    aliases=("velocity_verlet", "kdk"),
    order=2,
    symplectic=True,
    reversible=True,
    force_evals=1,
    work_slots=0,
    fsal=True,
    summary="velocity Verlet (kick-drift-kick), averages old and new accelerations",
    reference="L. Verlet (1967), Phys. Rev. 159, 98; Swope, Andersen, Berens & Wilson (1982), "
    "J. Chem. Phys. 76, 637",
    module=__name__,
)


@jit_inline
def _kick_kick_drift(pos, vel, acc, half_dt, dt):
    """The closing kick of one step, the opening kick of the next, and its drift, in one pass.

    The same operations in the same order as kick, kick, drift (each element's update is
    independent), so the same bits as two single steps, with one pass over the state instead of
    three.
    """
    for c in range(3):
        for i in range(pos.shape[1]):
            v_half = (vel[c, i] + half_dt * acc[c, i]) + half_dt * acc[c, i]
            vel[c, i] = v_half
            pos[c, i] += dt * v_half


@jit_inline
def advance(pos, vel, acc, m, force, dt, work, t0, n_done, n_to):
    """KDK steps from ``n_done`` to ``n_to``; ``acc`` holds the accelerations at ``pos`` on entry
    and exit (gravity and the position-only forces). For a context without velocity-dependent forces
    (:func:`advance_split` is the other loop; :data:`run` picks).

    The steps run back to back, so each closing kick is fused with the next step's opening kick
    and drift (:func:`_kick_kick_drift`); the state at the end is bit-identical to separate steps.
    """
    no_velocity_operator(force)
    steps = n_to - n_done
    if steps < 1:
        return n_done, True
    half_dt = 0.5 * dt
    kick(vel, acc, half_dt)
    drift(pos, vel, dt)
    for s in range(steps):
        if s > 0:
            _kick_kick_drift(pos, vel, acc, half_dt, dt)
        newtonian_accelerations(force, pos, m, acc)
        add_kick_forces(force, pos, m, acc)
    kick(vel, acc, half_dt)
    return n_to, True


@jit_inline
def advance_split(pos, vel, acc, m, force, dt, work, t0, n_done, n_to):
    """:func:`advance` with velocity-dependent forces: each step is ``V(dt/2) KDK V(dt/2)``
    (:func:`orbitsim.forces.hooks.velocity_operator`), and nothing is fused across the operator."""
    half_dt = 0.5 * dt
    while n_done < n_to:
        velocity_operator(force, pos, vel, m, half_dt)
        kick(vel, acc, half_dt)
        drift(pos, vel, dt)
        newtonian_accelerations(force, pos, m, acc)
        add_kick_forces(force, pos, m, acc)
        kick(vel, acc, half_dt)
        velocity_operator(force, pos, vel, m, half_dt)
        n_done += 1
    return n_done, True


@jit_inline
def step(pos, vel, acc, m, force, dt, work):
    """One KDK step; ``acc`` holds a(x_n) on entry and a(x_{n+1}) on exit (no velocity-dependent forces)."""
    advance(pos, vel, acc, m, force, dt, work, 0.0, 0, 1)


@jit
def _run_plain(state, force, dt, work, t0, n_done, targets, record, out):
    """:func:`~orbitsim.integrators.base.sample_loop` of :func:`advance`; a forced run's ``acc``
    afresh first (:func:`~orbitsim.forces.hooks.refresh_accelerations`)."""
    pos, vel, acc, m = state
    refresh_accelerations(force, pos, vel, m, acc, False)
    return sample_loop(advance, grid_time, state, force, dt, work, t0, n_done, targets, record, out)


@jit
def _run_split(state, force, dt, work, t0, n_done, targets, record, out):
    """:func:`_run_plain` of :func:`advance_split`."""
    pos, vel, acc, m = state
    refresh_accelerations(force, pos, vel, m, acc, False)
    return sample_loop(advance_split, grid_time, state, force, dt, work, t0, n_done, targets, record, out)


@jit
def _run_watched_plain(state, force, dt, work, t0, n_done, targets, record, out, watch):
    """:func:`_run_plain` one step at a time with the events watch after each (:mod:`orbitsim.events`)."""
    return watched_run(advance, state, force, dt, work, t0, n_done, targets, record, out, watch)


@jit
def _run_watched_split(state, force, dt, work, t0, n_done, targets, record, out, watch):
    """:func:`_run_split` one step at a time with the events watch after each."""
    return watched_run(advance_split, state, force, dt, work, t0, n_done, targets, record, out, watch)


#: The sampled run and the watched run, each the kernel of the call's forces (:class:`ByVelocityForces`).
run = ByVelocityForces(_run_plain, _run_split)
run_watched = ByVelocityForces(_run_watched_plain, _run_watched_split)


@jit_inline
def advance_chaos(pos, vel, acc, m, force, dt, work, t0, n_done, n_to, tangent, megno):
    """KDK steps of the bodies and their tangent vector (the tangent of a kick is a kick with the
    tangent accelerations, of a drift a drift), with MEGNO's read after each step. ``acc`` and
    ``tangent.dacc`` hold the accelerations at the current state between steps; ``dacc`` is made
    afresh on entry (a function of the state alone, so however the run is cut, the same bits). The
    bodies take the operations of separate :func:`advance` steps, so the same bits. Returns
    ``(n_done, True, megno)``."""
    dpos, dvel, dacc = tangent.dpos, tangent.dvel, tangent.dacc
    G = force.G
    eps2 = force.eps2
    half_dt = 0.5 * dt
    tangent_accelerations(pos, m, G, eps2, dpos, dacc, np.int64(ALL_PAIRS))
    add_tangent_kick_forces(force, pos, m, dpos, dacc)
    while n_done < n_to:
        kick(vel, acc, half_dt)
        kick(dvel, dacc, half_dt)
        drift(pos, vel, dt)
        drift(dpos, dvel, dt)
        newtonian_accelerations(force, pos, m, acc)
        add_kick_forces(force, pos, m, acc)
        tangent_accelerations(pos, m, G, eps2, dpos, dacc, np.int64(ALL_PAIRS))
        add_tangent_kick_forces(force, pos, m, dpos, dacc)
        kick(vel, acc, half_dt)
        kick(dvel, dacc, half_dt)
        n_done += 1
        # MEGNO's read recomputes dacc at the synchronised state: the next opening kick's.
        megno, halvings = megno_after_step(megno, pos, m, force, dpos, dvel, dacc, t0 + n_done * dt, dt)
        tangent.halvings[0] += halvings
    return n_done, True, megno


@jit
def run_chaos(state, tangent, force, dt, work, t0, n_done, targets, record, out, indicators, megno):
    """:func:`~orbitsim.integrators.base.chaos_sample_loop` of :func:`advance_chaos`; a forced run's
    ``acc`` afresh first."""
    pos, vel, acc, m = state
    refresh_accelerations(force, pos, vel, m, acc, False)
    return chaos_sample_loop(advance_chaos, grid_time, state, tangent, force, dt, work, t0, n_done, targets, record,
                             out, indicators, megno)


VERLET = Integrator(spec=SPEC, step=step, run=run, run_watched=run_watched, run_chaos=run_chaos)
