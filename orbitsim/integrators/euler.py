"""Explicit (forward) Euler: drift with the old velocity, kick with the old acceleration.

    x_{n+1} = x_n + dt v_n
    v_{n+1} = v_n + dt a(x_n)

First order and not symplectic: on a Kepler orbit the energy climbs secularly and the orbit
spirals outwards. It is here as the lesson's negative control, not for production runs.
"""

from __future__ import annotations

from orbitsim._jit import jit, jit_inline
from orbitsim.events.kernels import watched_run
from orbitsim.forces.hooks import add_forces, refresh_accelerations
from orbitsim.integrators.base import Integrator, IntegratorSpec, grid_time, sample_loop
from orbitsim.physics.force_context import newtonian_accelerations

SPEC = IntegratorSpec(
    name="euler",
    aliases=("explicit_euler", "forward_euler"),
    order=1,
    symplectic=False,
    reversible=False,
    force_evals=1,
    work_slots=0,
    fsal=True,
    summary="explicit Euler: drift with the old velocity, kick with the old acceleration",
    reference="L. Euler (1768), Institutionum calculi integralis; e.g. Hairer, Lubich & Wanner (2006), "
    "Geometric Numerical Integration, sec. I.1",
    module=__name__,
)


@jit_inline
def advance(pos, vel, acc, m, force, dt, work, t0, n_done, n_to):
    """Explicit Euler steps from ``n_done`` to ``n_to``; ``acc`` holds the accelerations at (pos,
    vel) on entry and exit (gravity and every force: they are the equations of motion)."""
    for _ in range(n_to - n_done):
        for c in range(3):
            for i in range(pos.shape[1]):
                v_old = vel[c, i]
                vel[c, i] = v_old + dt * acc[c, i]
                pos[c, i] += dt * v_old
        newtonian_accelerations(force, pos, m, acc)
        add_forces(force, pos, vel, m, acc)
    return n_to, True


@jit_inline
def step(pos, vel, acc, m, force, dt, work):
    """One explicit Euler step; ``acc`` holds a(x_n) on entry and a(x_{n+1}) on exit."""
    advance(pos, vel, acc, m, force, dt, work, 0.0, 0, 1)


@jit
def run(state, force, dt, work, t0, n_done, targets, record, out):
    """:func:`~orbitsim.integrators.base.sample_loop` of :func:`advance`; a forced run's ``acc``
    afresh first (:func:`~orbitsim.forces.hooks.refresh_accelerations`)."""
    pos, vel, acc, m = state
    refresh_accelerations(force, pos, vel, m, acc, True)
    return sample_loop(advance, grid_time, state, force, dt, work, t0, n_done, targets, record, out)


@jit
def run_watched(state, force, dt, work, t0, n_done, targets, record, out, watch):
    """:func:`run` one step at a time with the events watch after each (:mod:`orbitsim.events`)."""
    return watched_run(advance, state, force, dt, work, t0, n_done, targets, record, out, watch)


EULER = Integrator(spec=SPEC, step=step, run=run, run_watched=run_watched)
