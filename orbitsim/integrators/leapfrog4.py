"""Fourth-order symmetric composition of the DKD leapfrog (Yoshida 1990 triple jump).

Three leapfrog substeps with weights w1, 1 - 2 w1, w1, w1 = 1/(2 - 2^(1/3)); the middle one runs
backwards in time. Symplectic and time-reversible; three force evaluations per step. Same
coefficients as REBOUND's ``leapfrog`` with ``order = 4``.
"""

from __future__ import annotations

from orbitsim._jit import jit
from orbitsim.events.kernels import watched_run
from orbitsim.integrators.base import IntegratorSpec
from orbitsim.integrators.composition import LEAPFROG4_WEIGHTS, compose_dkd, drift_coefficients, run_dkd

SPEC = IntegratorSpec(
    name="leapfrog4",
    aliases=("yoshida4",),
    order=4,
    symplectic=True,
    reversible=True,
    force_evals=3,
    work_slots=0,
    fsal=False,
    summary="Yoshida's 4th-order triple-jump composition of the DKD leapfrog",
    reference="H. Yoshida (1990), Phys. Lett. A 150, 262; REBOUND leapfrog order 4",
    module=__name__,
)

KICKS = LEAPFROG4_WEIGHTS
DRIFTS = drift_coefficients(KICKS)


@jit
def step(pos, vel, acc, m, force, dt, work):
    """One leapfrog4 step of size ``dt`` (3 force evaluations), in place."""
    compose_dkd(pos, vel, acc, m, force, dt, DRIFTS, KICKS)


@jit
def run(state, force, dt, work, t0, n_done, targets, record, out):
    """Fixed-dt loop of :func:`step` (contract in :mod:`orbitsim.integrators.base`)."""
    return run_dkd(state, force, dt, work, t0, n_done, targets, record, out, DRIFTS, KICKS)

@jit
def run_watched(state, force, dt, work, t0, n_done, targets, record, out, watch):
    """:func:`run` one :func:`step` at a time with the events watch after each (:mod:`orbitsim.events`)."""
    return watched_run(step, state, force, dt, work, t0, n_done, targets, record, out, watch)
