"""Velocity Verlet (kick-drift-kick): the old and new accelerations averaged into the velocity.

    v_{n+1/2} = v_n + (dt/2) a(x_n)
    x_{n+1}   = x_n + dt v_{n+1/2}
    v_{n+1}   = v_{n+1/2} + (dt/2) a(x_{n+1})

Second order, symplectic and time-reversible. The closing kick's a(x_{n+1}) is the next step's
opening kick (first-same-as-last), so a step costs one force evaluation.
"""

from __future__ import annotations

from orbitsim._jit import jit
from orbitsim.integrators.base import IntegratorSpec, drift, kick, record_sample
from orbitsim.physics.gravity import update_accelerations

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


@jit
def step(pos, vel, acc, m, force, dt, work):
    """One KDK step; ``acc`` holds a(x_n) on entry and a(x_{n+1}) on exit."""
    half_dt = 0.5 * dt
    kick(vel, acc, half_dt)
    drift(pos, vel, dt)
    update_accelerations(pos, m, force, acc)
    kick(vel, acc, half_dt)


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
