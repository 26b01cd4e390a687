"""Drift-kick-drift (DKD) leapfrog, the scheme REBOUND calls ``leapfrog``.

    x_{n+1/2} = x_n + (dt/2) v_n
    v_{n+1}   = v_n + dt a(x_{n+1/2})
    x_{n+1}   = x_{n+1/2} + (dt/2) v_{n+1}

Second order, symplectic, time-reversible; one force evaluation per step, at the midpoint.
It is the position-Verlet twin of :mod:`orbitsim.integrators.verlet` and the order-2 member of
the composition family in :mod:`orbitsim.integrators.composition`.
"""

from __future__ import annotations

from orbitsim._jit import jit
from orbitsim.events.kernels import watched_run
from orbitsim.integrators.base import IntegratorSpec
from orbitsim.integrators.composition import LEAPFROG2_WEIGHTS, compose_dkd, drift_coefficients, run_dkd

SPEC = IntegratorSpec(
    name="leapfrog",
    aliases=("dkd",),
    order=2,
    symplectic=True,
    reversible=True,
    force_evals=1,
    work_slots=0,
    fsal=False,
    summary="drift-kick-drift leapfrog, the scheme REBOUND calls leapfrog",
    reference="Hairer, Lubich & Wanner (2003), Acta Numerica 12, 399 (Stoermer-Verlet); REBOUND leapfrog order 2",
    module=__name__,
)

KICKS = LEAPFROG2_WEIGHTS
DRIFTS = drift_coefficients(KICKS)


@jit
def step(pos, vel, acc, m, force, dt, work):
    """One leapfrog step of size ``dt`` (1 force evaluation), in place."""
    compose_dkd(pos, vel, acc, m, force, dt, DRIFTS, KICKS)


@jit
def run(state, force, dt, work, t0, n_done, targets, record, out):
    """Fixed-dt loop of :func:`step` (contract in :mod:`orbitsim.integrators.base`)."""
    return run_dkd(state, force, dt, work, t0, n_done, targets, record, out, DRIFTS, KICKS)

@jit
def run_watched(state, force, dt, work, t0, n_done, targets, record, out, watch):
    """:func:`run` one :func:`step` at a time with the events watch after each (:mod:`orbitsim.events`)."""
    return watched_run(step, state, force, dt, work, t0, n_done, targets, record, out, watch)
