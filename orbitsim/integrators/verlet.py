"""Velocity Verlet (kick-drift-kick): the old and new accelerations averaged into the velocity.

    v_{n+1/2} = v_n + (dt/2) a(x_n)
    x_{n+1}   = x_n + dt v_{n+1/2}
    v_{n+1}   = v_{n+1/2} + (dt/2) a(x_{n+1})

Second order, symplectic and time-reversible. The closing kick's a(x_{n+1}) is the next step's
opening kick (first-same-as-last), so a step costs one force evaluation.
"""

from __future__ import annotations

from orbitsim._jit import jit, jit_inline
from orbitsim.events.kernels import watched_run
from orbitsim.forces.hooks import add_kick_forces, has_velocity_operator, refresh_accelerations, velocity_operator
from orbitsim.integrators.base import Integrator, IntegratorSpec, drift, grid_time, kick, sample_loop
from orbitsim.physics.force_context import newtonian_accelerations

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
    and exit (gravity and the position-only forces).

    The steps run back to back, so each closing kick is fused with the next step's opening kick
    and drift (:func:`_kick_kick_drift`); the state at the end is bit-identical to separate steps.
    With velocity-dependent forces each step is ``V(dt/2) KDK V(dt/2)``
    (:func:`orbitsim.forces.hooks.velocity_operator`), and nothing is fused across the operator.
    """
    steps = n_to - n_done
    if steps < 1:
        return n_done, True
    half_dt = 0.5 * dt
    if has_velocity_operator(force):
        for _ in range(steps):
            velocity_operator(force, pos, vel, m, half_dt)
            kick(vel, acc, half_dt)
            drift(pos, vel, dt)
            newtonian_accelerations(force, pos, m, acc)
            add_kick_forces(force, pos, m, acc)
            kick(vel, acc, half_dt)
            velocity_operator(force, pos, vel, m, half_dt)
        return n_to, True
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
def step(pos, vel, acc, m, force, dt, work):
    """One KDK step; ``acc`` holds a(x_n) on entry and a(x_{n+1}) on exit."""
    advance(pos, vel, acc, m, force, dt, work, 0.0, 0, 1)


@jit
def run(state, force, dt, work, t0, n_done, targets, record, out):
    """:func:`~orbitsim.integrators.base.sample_loop` of :func:`advance`; a forced run's ``acc``
    afresh first (:func:`~orbitsim.forces.hooks.refresh_accelerations`)."""
    pos, vel, acc, m = state
    refresh_accelerations(force, pos, vel, m, acc, False)
    return sample_loop(advance, grid_time, state, force, dt, work, t0, n_done, targets, record, out)


@jit
def run_watched(state, force, dt, work, t0, n_done, targets, record, out, watch):
    """:func:`run` one step at a time with the events watch after each (:mod:`orbitsim.events`)."""
    return watched_run(advance, state, force, dt, work, t0, n_done, targets, record, out, watch)


VERLET = Integrator(spec=SPEC, step=step, run=run, run_watched=run_watched)
