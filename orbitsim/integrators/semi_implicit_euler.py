"""Semi-implicit (symplectic) Euler: kick first, then drift with the new velocity.

    v_{n+1} = v_n + dt a(x_n)
    x_{n+1} = x_n + dt v_{n+1}

First order, but symplectic: the map preserves phase-space volume and a nearby "shadow"
Hamiltonian, so the energy error oscillates within a bound instead of drifting. It is the
adjoint of explicit Euler's update order and the lesson's centre panel.
"""

from __future__ import annotations

from orbitsim._jit import jit, jit_inline
from orbitsim.events.kernels import watched_run
from orbitsim.forces.hooks import add_kick_forces, refresh_accelerations, velocity_operator
from orbitsim.integrators.base import Integrator, IntegratorSpec, grid_time, kick_drift, sample_loop
from orbitsim.physics.force_context import newtonian_accelerations

SPEC = IntegratorSpec(
    name="semi_implicit_euler",
    aliases=("symplectic_euler",),
    order=1,
    symplectic=True,
    reversible=False,
    force_evals=1,
    work_slots=0,
    fsal=True,
    summary="semi-implicit Euler: kick first, then drift with the new velocity",
    reference="Hairer, Lubich & Wanner (2006), Geometric Numerical Integration, Thm. VI.3.3",
    module=__name__,
)


@jit_inline
def advance(pos, vel, acc, m, force, dt, work, t0, n_done, n_to):
    """Kick-then-drift steps from ``n_done`` to ``n_to``; ``acc`` holds the accelerations at ``pos``
    on entry and exit (gravity and the position-only forces). Velocity-dependent forces are an
    operator around each step, ``V(dt/2) S(dt) V(dt/2)`` (nothing without them)."""
    half_dt = 0.5 * dt
    for _ in range(n_to - n_done):
        velocity_operator(force, pos, vel, m, half_dt)
        kick_drift(pos, vel, acc, dt, dt)
        newtonian_accelerations(force, pos, m, acc)
        add_kick_forces(force, pos, m, acc)
        velocity_operator(force, pos, vel, m, half_dt)
    return n_to, True


@jit_inline
def step(pos, vel, acc, m, force, dt, work):
    """One kick-then-drift step; ``acc`` holds a(x_n) on entry and a(x_{n+1}) on exit."""
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


SEMI_IMPLICIT_EULER = Integrator(spec=SPEC, step=step, run=run, run_watched=run_watched)
