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
from orbitsim.integrators.base import Integrator, IntegratorSpec, drift, kick, record_sample
from orbitsim.physics.gravity import SMALL_N_MAX, accelerations, all_pairs_accelerations

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
def advance(pos, vel, acc, m, force, dt, work, steps):
    """``steps`` KDK steps; ``acc`` holds the accelerations at ``pos`` on entry and exit.

    The steps run back to back, so each closing kick is fused with the next step's opening kick
    and drift (:func:`_kick_kick_drift`); the state at the end is bit-identical to ``steps``
    separate steps. The force kernels are called from this loop, not through an inlined helper:
    see :mod:`orbitsim.physics.gravity`.
    """
    if steps < 1:
        return
    G, eps2, slabs, bounds = force
    small = pos.shape[1] <= SMALL_N_MAX
    half_dt = 0.5 * dt
    kick(vel, acc, half_dt)
    drift(pos, vel, dt)
    for s in range(steps):
        if s > 0:
            _kick_kick_drift(pos, vel, acc, half_dt, dt)
        if small:
            all_pairs_accelerations(pos, m, G, eps2, acc)
        else:
            accelerations(pos, m, G, eps2, acc, slabs, bounds)
    kick(vel, acc, half_dt)


@jit_inline
def step(pos, vel, acc, m, force, dt, work):
    """One KDK step; ``acc`` holds a(x_n) on entry and a(x_{n+1}) on exit."""
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


VERLET = Integrator(spec=SPEC, step=step, run=run, run_watched=run_watched)
