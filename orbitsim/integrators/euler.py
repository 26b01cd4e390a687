"""Explicit (forward) Euler: drift with the old velocity, kick with the old acceleration.

    x_{n+1} = x_n + dt v_n
    v_{n+1} = v_n + dt a(x_n)

First order and not symplectic: on a Kepler orbit the energy climbs secularly and the orbit
spirals outwards. It is here as the lesson's negative control, not for production runs.
"""

from __future__ import annotations

from orbitsim._jit import jit, jit_inline
from orbitsim.events.kernels import watched_run
from orbitsim.integrators.base import Integrator, IntegratorSpec, record_sample
from orbitsim.physics.gravity import SMALL_N_MAX, accelerations, all_pairs_accelerations

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
def advance(pos, vel, acc, m, force, dt, work, steps):
    """``steps`` explicit Euler steps; ``acc`` holds the accelerations at ``pos`` on entry and exit.

    The force kernels are called from this loop, not through an inlined helper: see
    :mod:`orbitsim.physics.gravity`.
    """
    G, eps2, slabs, bounds = force
    small = pos.shape[1] <= SMALL_N_MAX
    for _ in range(steps):
        for c in range(3):
            for i in range(pos.shape[1]):
                v_old = vel[c, i]
                vel[c, i] = v_old + dt * acc[c, i]
                pos[c, i] += dt * v_old
        if small:
            all_pairs_accelerations(pos, m, G, eps2, acc)
        else:
            accelerations(pos, m, G, eps2, acc, slabs, bounds)


@jit_inline
def step(pos, vel, acc, m, force, dt, work):
    """One explicit Euler step; ``acc`` holds a(x_n) on entry and a(x_{n+1}) on exit."""
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


EULER = Integrator(spec=SPEC, step=step, run=run, run_watched=run_watched)
