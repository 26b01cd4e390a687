"""Eighth-order symmetric composition of the DKD leapfrog (17 stages, Blanes & Casas 2016, p. 91).

Symplectic and time-reversible; seventeen force evaluations per step. Same coefficients as
REBOUND's ``leapfrog`` with ``order = 8``.
"""

from __future__ import annotations

from orbitsim._jit import jit
from orbitsim.events.kernels import watched_run
from orbitsim.integrators.base import IntegratorSpec
from orbitsim.integrators.composition import LEAPFROG8_WEIGHTS, compose_dkd, drift_coefficients, run_dkd

SPEC = IntegratorSpec(
    name="leapfrog8",
    aliases=(),
    order=8,
    symplectic=True,
    reversible=True,
    force_evals=17,
    work_slots=0,
    fsal=False,
    summary="8th-order 17-stage symmetric composition of the DKD leapfrog",
    reference="S. Blanes & F. Casas (2016), A Concise Introduction to Geometric Numerical Integration, "
    "CRC Press, p. 91; REBOUND leapfrog order 8",
    module=__name__,
)

KICKS = LEAPFROG8_WEIGHTS
DRIFTS = drift_coefficients(KICKS)


@jit
def step(pos, vel, acc, m, force, dt, work):
    """One leapfrog8 step of size ``dt`` (17 force evaluations), in place."""
    compose_dkd(pos, vel, acc, m, force, dt, DRIFTS, KICKS)


@jit
def run(state, force, dt, work, t0, n_done, targets, record, out):
    """Fixed-dt loop of :func:`step` (contract in :mod:`orbitsim.integrators.base`)."""
    return run_dkd(state, force, dt, work, t0, n_done, targets, record, out, DRIFTS, KICKS)

@jit
def run_watched(state, force, dt, work, t0, n_done, targets, record, out, watch):
    """:func:`run` one :func:`step` at a time with the events watch after each (:mod:`orbitsim.events`)."""
    return watched_run(step, state, force, dt, work, t0, n_done, targets, record, out, watch)
