"""IAS15's output grid: when its clock starts, the time of grid point n, and a sample's time stamp.

An IAS15 run's ``dt`` is its output grid (:mod:`orbitsim.integrators.ias15`): grid point ``n`` is the
time ``t0 + n dt``, the last one clipped to the run's ``t_end``. The clock in ``work`` starts at the
first grid point a run touches, with the first trial step ``first_dt`` (or the grid interval), and
from then on is IAS15's own. The plain run (:func:`~orbitsim.integrators.ias15.advance_grid`) and the
variational one (:func:`~orbitsim.integrators.ias15.chaos.advance_chaos`) both read these.
"""

from __future__ import annotations

from orbitsim._jit import jit, jit_inline
from orbitsim.integrators.ias15.core import CLOCK_DT, CLOCK_STARTED, CLOCK_T

__all__ = ["grid_target", "sample_time", "start_clock"]


@jit
def start_clock(work, t_now, dt_grid):
    """Start ``work``'s clock at ``t_now`` with the first trial step (once; a started clock is kept)."""
    clock = work.clock
    if clock[CLOCK_STARTED] == 0.0:
        clock[CLOCK_T] = t_now
        first = work.first_dt
        clock[CLOCK_DT] = first if first != 0.0 else dt_grid
        clock[CLOCK_STARTED] = 1.0


@jit
def grid_target(work, t0, dt, n):
    """The time of grid point ``n``, ``t0 + n dt``, clipped to the run's ``t_end``."""
    target = t0 + n * dt
    t_end = work.t_end
    if (dt > 0.0 and target > t_end) or (dt < 0.0 and target < t_end):
        return t_end
    return target


@jit_inline
def sample_time(work, t0, n_done, dt):
    """The time of a sample at grid point ``n_done``: the clock's (started there, if it is not yet)."""
    start_clock(work, grid_target(work, t0, dt, n_done), dt)
    return work.clock[CLOCK_T]
