"""Explicit (forward) Euler: drift with the old velocity, kick with the old acceleration.

    x_{n+1} = x_n + dt v_n
    v_{n+1} = v_n + dt a(x_n)

First order and not symplectic: on a Kepler orbit the energy climbs secularly and the orbit
spirals outwards. It is here as the lesson's negative control, not for production runs.
"""

from __future__ import annotations

from orbitsim._jit import jit, jit_inline
from orbitsim.integrators.base import IntegratorSpec, record_sample
from orbitsim.physics.gravity import update_accelerations

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
def step(pos, vel, acc, m, force, dt, work):
    """One explicit Euler step; ``acc`` holds a(x_n) on entry and a(x_{n+1}) on exit."""
    for c in range(3):
        for i in range(pos.shape[1]):
            v_old = vel[c, i]
            vel[c, i] = v_old + dt * acc[c, i]
            pos[c, i] += dt * v_old
    update_accelerations(pos, m, force, acc)


@jit
def run(state, force, dt, work, t0, n_done, targets, record, out):
    """Fixed-dt loop of :func:`step` (contract in :mod:`orbitsim.integrators.base`)."""
    pos, vel, acc, m = state
    written = 0
    for k in range(targets.shape[0]):
        while n_done < targets[k]:
            step(pos, vel, acc, m, force, dt, work)
            n_done += 1
        if record[k]:
            if not record_sample(written, n_done, t0, dt, pos, vel, m, force, out):
                return written, n_done, False
            written += 1
    return written, n_done, True
