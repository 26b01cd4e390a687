"""The jitted events watch: what happened during each step, checked right after it.

A run with an ``events:`` section calls its scheme's ``run_watched``, which steps one step at a time
through :func:`watched_run` and calls :func:`after_step` after every step. A run without one calls
the scheme's plain ``run``: none of this is compiled or executed, and its bits and speed are today's.

What is checked (each only when the scenario asks for it), in one pass over the pairs:

* **collisions**: ``direct``, the separation at the end of the step is below r_i + r_j; ``line``,
  the straight segment from the start-of-step to the end-of-step separation comes that close
  (REBOUND's ``line`` mode draws the segment back from the end with the end velocity; the start
  of the step is known here, so it is used).
* **close encounters**: the minimum separation *within* the step, from a cubic Hermite fit of the
  squared separation over the step to its values and time derivatives at both ends (the
  prediction REBOUND's MERCURIUS makes, Rein et al. 2019), below a distance D or k mutual Hill
  radii ((m_i + m_j) / 3 M_c)^(1/3) (r_i + r_j) / 2 about the heaviest body c. So a pair that
  passes within D between two steps is still caught. An encounter is one episode: logged once,
  when it ends, with its closest approach.
* **unresolved steps**: each body's local timescale tau about its dominant attractor (the body
  pulling it hardest), from the two-body derivatives of the acceleration:
  tau^2 = 2 |a|^2 / (|a'|^2 + |a| |a''|) (Pham, Rein & Spiegel 2024, eq. 16, as REBOUND TRACE
  evaluates it about the star), flagged when dt > eta tau. When the pair passed its closest point
  inside the step, tau is also taken at the pericentre of the osculating orbit, so a step that
  jumps over a pericentre is caught too. Logged once per episode, naming the lighter body. A
  hybrid scheme (TRACE) passes what it integrated with adaptive sub-steps this step, which is not
  judged: only what it stepped with the fixed dt can be unresolved.
* **escapes**: farther than R from the centre of mass, with positive two-body energy relative to
  the rest of the system (specific energy, so a massless body counts); a body bound to another is
  judged with it, as a pair. Once per escape: escaped until bound again.

Events go into a buffer the Python side drains after every call (:mod:`orbitsim.events.watch`);
``after_step`` returns True when Python must act now: a merge or a removal to make, a halt, or a
buffer three-quarters full. The layout of the ``watch`` tuple is :data:`WATCH_LAYOUT`.
"""

from __future__ import annotations

import numpy as np

from orbitsim._jit import jit_inline
from orbitsim.events.bodies import check_escapes, check_unresolved
from orbitsim.events.layout import (
    C_DETECT,
    C_ENC,
    C_ESCAPE,
    C_UNRES,
    DETECT_NONE,
    ENC_NONE,
    ESC_NONE,
    N_EVENTS,
    N_LOST,
    STOP,
    STOP_DRAIN,
    STOP_NONE,
)
from orbitsim.events.pairs import close_episodes, scan_pairs
from orbitsim.integrators.base import grid_time, record_sample

__all__ = ["after_step", "watched_run"]


@jit_inline
def remember_start(watch, pos, vel):
    """Copy the start-of-step state into ``prev`` (the segment and Hermite fits need both ends)."""
    prev = watch.prev
    for c in range(3):
        for i in range(pos.shape[1]):
            prev[0, c, i] = pos[c, i]
            prev[1, c, i] = vel[c, i]


@jit_inline
def watched_run(advance, state, force, dt, work, t0, n_done, targets, record, out, watch):
    """A scheme's ``run`` one step at a time, with :func:`after_step` after each: the one watched
    loop, inlined into each scheme's cached ``run_watched`` with its ``advance``
    (:mod:`orbitsim.integrators.base`).

    Same contract as ``run`` plus a fourth result, True when the call stopped early for the
    Python side (``watch.counts[STOP]`` says why). Taking whole steps one by one gives the same bits
    as the scheme's own loop (its fused loops are bit-identical to single steps). A planned sample
    at the step where Python must act is left to the next call, so it shows the state after the
    merge or removal.
    """
    pos, vel, acc, m = state
    written = np.int64(0)  # not the literal 0: record_sample would compile twice (for Literal[int](0) and int64)
    for k in range(targets.shape[0]):
        while n_done < targets[k]:
            remember_start(watch, pos, vel)
            n_done, ok = advance(pos, vel, acc, m, force, dt, work, t0, n_done, n_done + 1)
            if not ok:
                return written, n_done, False, False
            if after_step(watch, pos, vel, m, n_done, t0, dt, None):
                return written, n_done, True, True
        if record[k]:
            if not record_sample(written, n_done, grid_time(work, t0, n_done, dt), pos, vel, m, force, out):
                return written, n_done, False, False
            written += 1
    return written, n_done, True, False


@jit_inline
def after_step(watch, pos, vel, m, n_done, t0, dt, handoff):
    """Check the step that just ended (``n_done``); True when Python must act before the next.

    ``handoff``: None, or what a hybrid scheme integrated with its own adaptive sub-steps this
    step (:func:`orbitsim.events.bodies.handed_over`), which the unresolved-step check leaves out.
    """
    iconf, counts = watch.iconf, watch.counts
    stop = STOP_NONE
    if iconf[C_DETECT] != DETECT_NONE or iconf[C_ENC] != ENC_NONE or iconf[C_UNRES] != 0:
        stop = max(stop, scan_pairs(watch, pos, vel, m, n_done, t0, dt))
    if iconf[C_ENC] != ENC_NONE or iconf[C_DETECT] != DETECT_NONE:
        close_episodes(watch, n_done)
    if iconf[C_UNRES] != 0:
        check_unresolved(watch, pos, vel, m, n_done, t0, dt, handoff)
    if iconf[C_ESCAPE] != ESC_NONE:
        stop = max(stop, check_escapes(watch, pos, vel, m, n_done, t0, dt))
    if counts[N_EVENTS] * 4 >= watch.ev_i.shape[0] * 3 or counts[N_LOST] > 0:
        stop = max(stop, STOP_DRAIN)
    counts[STOP] = stop
    return stop != STOP_NONE


