"""The layout of the events watch: the :class:`Watch` of arrays, their columns and codes.

Shared by the jitted checks (:mod:`orbitsim.events.kernels` and the modules it calls) and by the
Python side that builds, drains and resizes the watch (:mod:`orbitsim.events.watch`).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from orbitsim._jit import jit_inline


class Watch(NamedTuple):
    """The arrays the jitted checks read and write (:func:`orbitsim.events.watch.build_watch`)."""

    iconf: np.ndarray  #: (ICONF_SIZE,) int64 configuration (C_* below)
    fconf: np.ndarray  #: (FCONF_SIZE,) float64 configuration (F_* below)
    radii: np.ndarray  #: (N,) collision radii
    prev: np.ndarray  #: (2, 3, N) positions and velocities at the start of the step
    body: np.ndarray  #: (N,) int64 body flags (B_* below)
    pair_i: np.ndarray  #: (P, PAIR_I_COLS) int64 open episodes (an encounter, or a logged contact)
    pair_f: np.ndarray  #: (P, PAIR_F_COLS) their closest approach so far, and the distance limit then
    ev_i: np.ndarray  #: (E, EV_I_COLS) int64 event buffer
    ev_f: np.ndarray  #: (E, EV_F_COLS) its float64 columns
    counts: np.ndarray  #: (4,) int64: events, open pairs, events lost, why the call stopped (N_EVENTS ...)
    best: np.ndarray  #: (N,) each body's strongest pull this step
    attractor: np.ndarray  #: (N,) int64 its source
    hill: np.ndarray  #: (2, N) each body's distance to the heaviest body and an upper bound of its Hill factor


#: The names of the watch's arrays, in order (a checkpoint saves them by name).
WATCH_LAYOUT = Watch._fields

# iconf: int64 configuration
C_DETECT, C_RESOLVE, C_ENC, C_ENC_HALT, C_ESCAPE, C_UNRES, C_CENTRAL = range(7)
ICONF_SIZE = 8
# fconf: float64 configuration
F_ENC, F_ESC_R, F_ETA, F_G = range(4)
FCONF_SIZE = 4
# detect / resolve / encounter / escape codes
DETECT_NONE, DETECT_DIRECT, DETECT_LINE = 0, 1, 2
RESOLVE_LOG, RESOLVE_HALT, RESOLVE_MERGE = 0, 1, 2
ENC_NONE, ENC_DISTANCE, ENC_HILL = 0, 1, 2
ESC_NONE, ESC_LOG, ESC_HALT, ESC_REMOVE = 0, 1, 2, 3
# body flag bits
B_UNRESOLVED, B_ESCAPED = 1, 2
# pair_i columns (an open episode: an encounter, or a logged contact)
P_I, P_J, P_START, P_LAST, P_KIND = range(5)
PAIR_I_COLS = 5
PAIR_ENCOUNTER, PAIR_CONTACT = 0, 1
# pair_f columns: closest approach so far, and the distance limit then
PF_DMIN, PF_TMIN, PF_VMIN, PF_LIMIT = range(4)
PAIR_F_COLS = 4
# ev_i / ev_f columns of the event buffer
E_KIND, E_STEP, E_I, E_J, E_START = range(5)
EV_I_COLS = 5
EF_TIME, EF_DIST, EF_SPEED, EF_EXTRA = range(4)
EV_F_COLS = 4
EV_ENCOUNTER, EV_COLLISION, EV_ESCAPE, EV_UNRESOLVED = 1, 2, 3, 4
# counts
N_EVENTS, N_PAIRS, N_LOST, STOP = range(4)
STOP_NONE, STOP_DRAIN, STOP_RESOLVE, STOP_HALT = 0, 1, 2, 3



@jit_inline
def log_event(watch, kind, step, start, i, j, time, dist, speed, extra):
    """Append an event to the buffer; a full buffer counts it as lost (Python reports that loudly)."""
    ev_i, ev_f, counts = watch.ev_i, watch.ev_f, watch.counts
    k = counts[N_EVENTS]
    if k >= ev_i.shape[0]:
        counts[N_LOST] += 1
        return
    ev_i[k, E_KIND] = kind
    ev_i[k, E_STEP] = step
    ev_i[k, E_I] = i
    ev_i[k, E_J] = j
    ev_i[k, E_START] = start
    ev_f[k, EF_TIME] = time
    ev_f[k, EF_DIST] = dist
    ev_f[k, EF_SPEED] = speed
    ev_f[k, EF_EXTRA] = extra
    counts[N_EVENTS] = k + 1


@jit_inline
def find_pair(watch, i, j, kind):
    """Row of the open episode of ``kind`` between i and j, or -1."""
    pair_i, counts = watch.pair_i, watch.counts
    for p in range(counts[N_PAIRS]):
        if pair_i[p, P_I] == i and pair_i[p, P_J] == j and pair_i[p, P_KIND] == kind:
            return p
    return -1


@jit_inline
def open_pair(watch, i, j, kind, n_done):
    """A new open episode; -1 (and a lost event) when the table is full."""
    pair_i, pair_f, counts = watch.pair_i, watch.pair_f, watch.counts
    p = counts[N_PAIRS]
    if p >= pair_i.shape[0]:
        counts[N_LOST] += 1
        return -1
    pair_i[p, P_I] = i
    pair_i[p, P_J] = j
    pair_i[p, P_START] = n_done
    pair_i[p, P_LAST] = n_done
    pair_i[p, P_KIND] = kind
    pair_f[p, PF_DMIN] = np.inf
    pair_f[p, PF_TMIN] = np.nan
    pair_f[p, PF_VMIN] = np.nan
    pair_f[p, PF_LIMIT] = np.nan
    counts[N_PAIRS] = p + 1
    return p
