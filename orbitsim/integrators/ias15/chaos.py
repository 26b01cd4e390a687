"""IAS15's variational run behind the run contract: ``run_chaos``, ``check_chaos``, ``make_tangent``.

The kernel is :mod:`.tangent` (REBOUND's IAS15 with first-order variational particles and MEGNO);
this module puts it behind items 17-19 of :mod:`orbitsim.integrators.base`, on the same output grid
as the plain run (:mod:`orbitsim.integrators.ias15`):

* ``dt`` is the output grid, and between two grid points IAS15 takes steps of its own choosing, the
  last one shortened to land exactly on the grid time (:func:`~.tangent.integrate_to_tangent`, the
  plain ``integrate_to`` line for line); with ``adaptive: false``, one constant step per grid point;
* the tangent record is an :class:`~.tangent.IAS15Tangent` (its ``dpos``, ``dvel`` and ``halvings``
  are what the contract reads of every tangent; the rest is the tangent polynomial and its
  compensations), and the bodies' adaptive state (the clock, the step to try next, b, e and their
  compensations) stays in the plain run's :class:`~.core.IAS15Work`: a run resumed from copies of
  the two records continues bit for bit;
* the MEGNO sums the contract carries as a :class:`~orbitsim.chaos.megno.MegnoState` are written
  into the record's ``megno`` array on entry and read back on exit (the kernel updates them there,
  after each accepted step, with the step's Radau quadrature of the MEGNO integrand).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from orbitsim._jit import jit, jit_inline
from orbitsim.forces.hooks import refresh_accelerations
from orbitsim.integrators.base import chaos_sample_loop
from orbitsim.integrators.ias15.core import CLOCK_DT, CLOCK_T
from orbitsim.integrators.ias15.grid import grid_target, sample_time, start_clock
from orbitsim.integrators.ias15.tangent import (
    REACHED,
    IAS15Tangent,
    _read_megno,
    _take_step_tangent,
    _write_megno,
    integrate_to_tangent,
    make_tangent,
    refresh_tangent,
)

__all__ = ["advance_chaos", "check_chaos", "make_chaos_tangent", "run_chaos"]


def make_chaos_tangent(dpos: np.ndarray, dvel: np.ndarray, halvings: int = 0) -> IAS15Tangent:
    """The contract's ``make_tangent``: an :class:`~.tangent.IAS15Tangent` holding copies of the (3, N)
    tangent vector, its polynomial zero (as the bodies' is at the start of a run), ``halvings``
    rescalings counted. Its MEGNO sums are the run's, written in by :func:`advance_chaos`."""
    return make_tangent(dpos, dvel, 0.0, halvings)


@jit_inline
def advance_chaos(pos, vel, acc, m, force, dt, work, t0, n_done, n_to, tangent, megno):
    """Grid points ``n_done`` to ``n_to`` of the bodies and their tangent vector (the plain
    :func:`~orbitsim.integrators.ias15.advance_grid` with the tangent step), MEGNO's sums updated
    after every accepted step. Returns ``(n_done, ok, megno)``; on a failure the status is in
    ``work`` (:func:`~orbitsim.integrators.ias15.failure_message`) and ``n_done`` the last grid
    point reached."""
    start_clock(work, grid_target(work, t0, dt, n_done), dt)
    _write_megno(tangent.megno, megno)
    clock = work.clock
    reached = n_to
    ok = True
    for n in range(n_done + 1, n_to + 1):
        if work.adaptive:
            ok = integrate_to_tangent(pos, vel, acc, m, force, work, tangent, grid_target(work, t0, dt, n)) == REACHED
        else:
            clock[CLOCK_DT] = dt
            ok = _take_step_tangent(pos, vel, acc, m, force, work, tangent)
            clock[CLOCK_T] = t0 + n * dt  # whole steps: the grid time, not a running sum (as the plain run)
        if not ok:
            reached = n - 1
            break
    return reached, ok, _read_megno(tangent.megno)


@jit
def run_chaos(state, tangent, force, dt, work, t0, n_done, targets, record, out, indicators, megno):
    """:func:`~orbitsim.integrators.base.chaos_sample_loop` of :func:`advance_chaos` (``dt`` is the
    output grid; each sample at the exact time IAS15's clock reached). ``acc`` (a forced run's) and
    the tangent accelerations are evaluated afresh first: functions of the state alone, so however
    a run is cut into calls, the same bits."""
    pos, vel, acc, m = state
    refresh_accelerations(force, pos, vel, m, acc, True)
    refresh_tangent(pos, m, force, tangent)
    return chaos_sample_loop(advance_chaos, sample_time, state, tangent, force, dt, work, t0, n_done, targets, record,
                             out, indicators, megno)


def check_chaos(settings: Mapping[str, Any]) -> str | None:
    """Every IAS15 setting has variational equations: adaptive or constant steps (``adaptive``,
    ``epsilon`` 0), any ``epsilon``, ``min_dt`` or ``first_dt``; the tangent never chooses a step.
    (Forces are refused or admitted by :func:`orbitsim.integrators.registry.chaos_refusal` with the
    forces' own table; the step passes them to the bodies and to the tangent as the plain step and
    every other variational kernel do.)"""
    return None
