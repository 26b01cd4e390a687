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
from orbitsim.integrators.base import Integrator, IntegratorSpec, kick_drift, record_sample
from orbitsim.physics.gravity import SMALL_N_MAX, accelerations, all_pairs_accelerations

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
def advance(pos, vel, acc, m, force, dt, work, steps):
    """``steps`` kick-then-drift steps; ``acc`` holds the accelerations at ``pos`` on entry and exit.

    The force kernels are called from this loop, not through an inlined helper: see
    :mod:`orbitsim.physics.gravity`.
    """
    G, eps2, slabs, bounds = force
    small = pos.shape[1] <= SMALL_N_MAX
    for _ in range(steps):
        kick_drift(pos, vel, acc, dt, dt)
        if small:
            all_pairs_accelerations(pos, m, G, eps2, acc)
        else:
            accelerations(pos, m, G, eps2, acc, slabs, bounds)


@jit_inline
def step(pos, vel, acc, m, force, dt, work):
    """One kick-then-drift step; ``acc`` holds a(x_n) on entry and a(x_{n+1}) on exit."""
    advance(pos, vel, acc, m, force, dt, work, 1)


@jit
def run(state, force, dt, work, t0, n_done, targets, record, out):
    """Fixed-dt loop of :func:`advance` (contract in :mod:`orbitsim.integrators.base`)."""
    pos, vel, acc, m = state
    written = 0
    for k in range(targets.shape[0]):
        if n_done < targets[k]:
            advance(pos, vel, acc, m, force, dt, work, targets[k] - n_done)
            n_done = targets[k]
        if record[k]:
            if not record_sample(written, n_done, t0, dt, pos, vel, m, force, out):
                return written, n_done, False
            written += 1
    return written, n_done, True


@jit
def run_watched(state, force, dt, work, t0, n_done, targets, record, out, watch):
    """:func:`run` one :func:`step` at a time with the events watch after each (:mod:`orbitsim.events`)."""
    return watched_run(step, state, force, dt, work, t0, n_done, targets, record, out, watch)


SEMI_IMPLICIT_EULER = Integrator(spec=SPEC, step=step, run=run, run_watched=run_watched)
