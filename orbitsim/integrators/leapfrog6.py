"""Sixth-order symmetric composition of the DKD leapfrog (9 stages, Blanes & Casas 2016).

Symplectic and time-reversible; nine force evaluations per step. Same coefficients as REBOUND's
``leapfrog`` with ``order = 6``.
"""

from __future__ import annotations

from orbitsim._jit import jit
from orbitsim.events.kernels import watched_run
from orbitsim.integrators.base import IntegratorSpec
from orbitsim.integrators.composition import LEAPFROG6_WEIGHTS, compose_dkd, drift_coefficients, run_dkd

SPEC = IntegratorSpec(
    name="leapfrog6",
    aliases=(),
    order=6,
    symplectic=True,
    reversible=True,
    force_evals=9,
    work_slots=0,
    fsal=False,
    summary="6th-order 9-stage symmetric composition of the DKD leapfrog",
    reference="S. Blanes & F. Casas (2016), A Concise Introduction to Geometric Numerical Integration, "
    "CRC Press; REBOUND leapfrog order 6",
    module=__name__,
)

KICKS = LEAPFROG6_WEIGHTS
DRIFTS = drift_coefficients(KICKS)


@jit
def step(pos, vel, acc, m, force, dt, work):
    """One leapfrog6 step of size ``dt`` (9 force evaluations), in place."""
    compose_dkd(pos, vel, acc, m, force, dt, DRIFTS, KICKS)


@jit
def run(state, force, dt, work, t0, n_done, targets, record, out):
    """Fixed-dt loop of :func:`step` (contract in :mod:`orbitsim.integrators.base`)."""
    return run_dkd(state, force, dt, work, t0, n_done, targets, record, out, DRIFTS, KICKS)

@jit
def run_watched(state, force, dt, work, t0, n_done, targets, record, out, watch):
    """:func:`run` one :func:`step` at a time with the events watch after each (:mod:`orbitsim.events`)."""
    return watched_run(step, state, force, dt, work, t0, n_done, targets, record, out, watch)
