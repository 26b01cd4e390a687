"""Classical fourth-order Runge-Kutta on the first-order system (x, v)' = (v, a(x)).

    k1 = (v_n,                 a(x_n))
    k2 = (v_n + dt/2 k1_v,     a(x_n + dt/2 k1_x))
    k3 = (v_n + dt/2 k2_v,     a(x_n + dt/2 k2_x))
    k4 = (v_n + dt   k3_v,     a(x_n + dt   k3_x))
    (x, v)_{n+1} = (x, v)_n + dt/6 (k1 + 2 k2 + 2 k3 + k4)

Butcher tableau: c = (0, 1/2, 1/2, 1), b = (1/6, 1/3, 1/3, 1/6). Fourth order, neither symplectic
nor time-reversible: its energy error drifts, slowly. a(x_{n+1}) is evaluated at the end of the
step and reused as the next step's k1, so a step costs four force evaluations.

Written with explicit loops over (3, N) slots: the same scheme in whole-array expressions took
6 s to compile, the loops 0.6 s.
"""

from __future__ import annotations

from orbitsim._jit import jit, jit_inline
from orbitsim.events.kernels import watched_run
from orbitsim.forces.hooks import add_forces, refresh_accelerations
from orbitsim.integrators.base import Integrator, IntegratorSpec, grid_time, sample_loop
from orbitsim.physics.force_context import newtonian_accelerations

SPEC = IntegratorSpec(
    name="rk4",
    aliases=("runge_kutta4",),
    order=4,
    symplectic=False,
    reversible=False,
    force_evals=4,
    work_slots=5,
    fsal=True,
    summary="classical Runge-Kutta on (x, v)",
    reference="W. Kutta (1901), Z. Math. Phys. 46, 435; Hairer, Norsett & Wanner (1993), "
    "Solving ODEs I, Table II.1.2",
    module=__name__,
)

#: Stage weights b_i of the classical tableau, and the node c_i at which each next stage is taken.
B_WEIGHTS = (1.0 / 6.0, 1.0 / 3.0, 1.0 / 3.0, 1.0 / 6.0)
C_NODES = (0.5, 0.5, 1.0)


@jit_inline
def _stage(pos, x0, v0, k_x, acc, h, weight, sum_x, sum_v):
    """Accumulate the current stage (k_x, acc) with ``weight``, move pos to x0 + h k_x and
    k_x to the next stage's v0 + h k_v."""
    for c in range(3):
        for i in range(pos.shape[1]):
            kx = k_x[c, i]
            kv = acc[c, i]
            sum_x[c, i] += weight * kx
            sum_v[c, i] += weight * kv
            pos[c, i] = x0[c, i] + h * kx
            k_x[c, i] = v0[c, i] + h * kv


@jit_inline
def advance(pos, vel, acc, m, force, dt, work, t0, n_done, n_to):
    """RK4 steps from ``n_done`` to ``n_to``; ``acc`` holds the accelerations at (pos, vel) on entry
    and exit (gravity and every force: they are the equations of motion, evaluated at each stage's
    positions and velocities).

    ``work`` slots: x0, v0, sum of weighted k_x, sum of weighted k_v, current k_x (the stage's
    velocities).
    """
    x0 = work[0]
    v0 = work[1]
    sum_x = work[2]
    sum_v = work[3]
    k_x = work[4]
    last = B_WEIGHTS[3]
    for _ in range(n_to - n_done):
        x0[:, :] = pos
        v0[:, :] = vel
        k_x[:, :] = vel
        sum_x[:, :] = 0.0
        sum_v[:, :] = 0.0
        for s in range(3):
            _stage(pos, x0, v0, k_x, acc, C_NODES[s] * dt, B_WEIGHTS[s], sum_x, sum_v)
            newtonian_accelerations(force, pos, m, acc)
            add_forces(force, pos, k_x, m, acc)
        for c in range(3):
            for i in range(pos.shape[1]):
                pos[c, i] = x0[c, i] + dt * (sum_x[c, i] + last * k_x[c, i])
                vel[c, i] = v0[c, i] + dt * (sum_v[c, i] + last * acc[c, i])
        newtonian_accelerations(force, pos, m, acc)
        add_forces(force, pos, vel, m, acc)
    return n_to, True


@jit_inline
def step(pos, vel, acc, m, force, dt, work):
    """One RK4 step; ``acc`` holds a(x_n) on entry and a(x_{n+1}) on exit."""
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


RK4 = Integrator(spec=SPEC, step=step, run=run, run_watched=run_watched)
