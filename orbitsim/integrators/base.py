"""The contract every integrator implements, and the jitted pieces they share.

An integrator module provides, beside the math:

1. ``SPEC``: an :class:`IntegratorSpec` (name, aliases, order, symplecticity, reversibility, force
   evaluations per step, scratch slots, citation).
2. ``step(pos, vel, acc, m, force, dt, work)``: one whole step of size ``dt``, in place.
   ``pos``, ``vel``, ``acc`` are ``(3, N)``; ``m`` is ``(N,)``; ``force`` is the context from
   :func:`orbitsim.physics.gravity.make_force`; ``work`` is ``(SPEC.work_slots, 3, N)`` scratch.
   On entry ``acc`` holds the accelerations at ``pos``; on exit it holds those at the new ``pos``
   when ``SPEC.fsal`` is true (first-same-as-last: kick-drift-kick schemes reuse the last force
   evaluation), otherwise whatever the scheme last evaluated. Steps call gravity as a module
   global, never as an argument, so they hit Numba's on-disk cache.
3. ``run(state, force, dt, work, t0, n_done, targets, record, out)``: the fixed-dt loop. For each
   ``k`` it takes whole steps until the step count reaches ``targets[k]`` and, when ``record[k]``,
   writes a sample with :func:`record_sample`. Returns ``(samples_written, n_done, finite)``; it
   stops early, with ``finite`` false, at the first sample whose state is not finite. A step is
   never shortened: sample times fall on whole steps.

``run`` lives in each scheme's module (it is a few lines) rather than in one dispatcher because a
jitted function that receives another as an argument never hits the on-disk cache, and a single
switch over every scheme would compile all of them on a user's first run.

The steps between two samples are written once per scheme, as an inlined
``advance(..., steps)`` that both ``step`` (one step) and ``run`` (the steps up to the next
sample) use. It unpacks the force context once and calls the force kernels from its own loop.
An inlined helper that made the call would take and release a reference to each array it is
given on every step (:mod:`orbitsim.physics.gravity` says why).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from orbitsim._jit import jit, jit_inline
from orbitsim.forces.hooks import record_force_energy
from orbitsim.physics.diagnostics import (
    angular_momentum_into,
    kinetic_energy,
    momentum_into,
    potential_energy,
)

#: Columns of the ``scalars`` sample buffer.
SCALAR_COLUMNS = ("kinetic", "potential", "px", "py", "pz", "lx", "ly", "lz")


@dataclass(frozen=True)
class IntegratorSpec:
    """Metadata of one fixed-step scheme; the registry holds one per integrator module."""

    name: str
    aliases: tuple[str, ...]
    order: int
    symplectic: bool
    reversible: bool
    force_evals: int
    work_slots: int
    fsal: bool
    summary: str
    reference: str
    module: str
    adaptive: bool = False  # chooses its own steps: ``dt`` is then the output grid (see ias15)

    @property
    def names(self) -> tuple[str, ...]:
        """The name followed by its aliases."""
        return (self.name, *self.aliases)


@jit_inline
def drift(pos, vel, h):
    """x <- x + h v, in place."""
    for c in range(3):
        for i in range(pos.shape[1]):
            pos[c, i] += h * vel[c, i]


@jit_inline
def kick(vel, acc, h):
    """v <- v + h a, in place."""
    for c in range(3):
        for i in range(vel.shape[1]):
            vel[c, i] += h * acc[c, i]


@jit_inline
def kick_drift(pos, vel, acc, h_kick, h_drift):
    """v <- v + h_kick a, then x <- x + h_drift v with the new v: :func:`kick` then :func:`drift`
    in one pass, with the same arithmetic (each element's update is independent), so the same
    bits, and one loop's loads and stores fewer (6% of a 5-body step)."""
    for c in range(3):
        for i in range(pos.shape[1]):
            v_new = vel[c, i] + h_kick * acc[c, i]
            vel[c, i] = v_new
            pos[c, i] += h_drift * v_new


@jit
def is_finite_state(pos, vel):
    """True when every coordinate and velocity component is finite."""
    for c in range(3):
        for i in range(pos.shape[1]):
            if not (np.isfinite(pos[c, i]) and np.isfinite(vel[c, i])):
                return False
    return True


@jit
def record_sample(r, n_done, t0, dt, pos, vel, m, force, out):
    """Write sample ``r`` (time, step, energies, momenta, optionally the state) into ``out``.

    ``out`` is ``(times, steps, scalars, snapshots, rows)``: ``scalars`` (S, 8) in the order of
    :data:`SCALAR_COLUMNS`, ``snapshots`` (S, 2, 3, N) or empty when the state is not recorded,
    ``rows`` scratch for the potential. Returns False, writing nothing, if the state is not finite.
    """
    if not is_finite_state(pos, vel):
        return False
    times, steps, scalars, snapshots, rows = out
    times[r] = t0 + n_done * dt
    steps[r] = n_done
    scalars[r, 0] = kinetic_energy(vel, m)
    scalars[r, 1] = potential_energy(pos, m, force[0], force[1], rows)
    record_force_energy(force, pos, vel, m, scalars, r)  # a forced run's potential includes the forces'
    momentum_into(vel, m, scalars[r, 2:5])
    angular_momentum_into(pos, vel, m, scalars[r, 5:8])
    if snapshots.shape[0] > 0:
        # Element loops, not ``snapshots[r, 0] = pos``: Numba's slice assignment builds views and
        # checks broadcasting, ~1 us a sample at N = 9, a third of a 100-step stretch's overhead.
        for c in range(3):
            for i in range(pos.shape[1]):
                snapshots[r, 0, c, i] = pos[c, i]
                snapshots[r, 1, c, i] = vel[c, i]
    return True
