"""The Python side of the events watch: build its arrays, drain its events, shrink it with the system.

The jitted checks (:mod:`orbitsim.events.kernels`) only read and write the arrays of the ``watch``
:class:`~orbitsim.events.layout.Watch`. This module makes them from an
:class:`~orbitsim.events.config.EventsConfig`, turns the logged rows into :class:`Event` objects
with the scenario's body indices, drops the bodies a merge or a removal took out, and exports
every array for a checkpoint (so a resumed run continues its open encounters bit for bit).
"""

from __future__ import annotations

import numpy as np

from orbitsim.events import layout as wl
from orbitsim.events.config import EventsConfig
from orbitsim.events.log import EVENT_KINDS, Event

__all__ = ["build_watch", "drain", "open_encounters", "shrink_watch", "watch_arrays", "watch_from_arrays"]

#: Rows of the event buffer per body (and at least :data:`MIN_EVENTS`): after every step that
#: fills it past three quarters the run returns to Python to drain it, so only a single step with
#: more events than a quarter of it could overflow, which is reported (a ``lost`` event) and
#: doubles the buffer.
EVENTS_PER_BODY = 8
MIN_EVENTS = 1024
#: Open episodes (encounters, contacts) per body, and at least this many.
PAIRS_PER_BODY = 4
MIN_PAIRS = 256

_DETECT = {None: wl.DETECT_NONE, "direct": wl.DETECT_DIRECT, "line": wl.DETECT_LINE}
_RESOLVE = {"log": wl.RESOLVE_LOG, "halt": wl.RESOLVE_HALT, "merge": wl.RESOLVE_MERGE}
_ESCAPE = {None: wl.ESC_NONE, "log": wl.ESC_LOG, "halt": wl.ESC_HALT, "remove": wl.ESC_REMOVE}


def build_watch(config: EventsConfig, masses: np.ndarray, radii: np.ndarray, G: float) -> wl.Watch:
    """The :class:`~orbitsim.events.layout.Watch` for a system of ``len(masses)`` bodies."""
    n = int(masses.shape[0])
    iconf = np.zeros(wl.ICONF_SIZE, dtype=np.int64)
    fconf = np.zeros(wl.FCONF_SIZE)
    col, enc, esc = config.collisions, config.encounters, config.escape
    iconf[wl.C_DETECT] = _DETECT[col.detect if col is not None else None]
    iconf[wl.C_RESOLVE] = _RESOLVE[col.resolve] if col is not None else wl.RESOLVE_LOG
    if enc is not None:
        iconf[wl.C_ENC] = wl.ENC_DISTANCE if enc.distance is not None else wl.ENC_HILL
        iconf[wl.C_ENC_HALT] = int(enc.halt)
        fconf[wl.F_ENC] = enc.distance if enc.distance is not None else enc.hill
    iconf[wl.C_ESCAPE] = _ESCAPE[esc.action if esc is not None else None]
    fconf[wl.F_ESC_R] = esc.distance if esc is not None else np.inf
    iconf[wl.C_UNRES] = int(config.unresolved is not None)
    fconf[wl.F_ETA] = config.unresolved.eta if config.unresolved is not None else 0.0
    iconf[wl.C_CENTRAL] = int(np.argmax(masses)) if n else 0
    fconf[wl.F_G] = G
    pairs, events = max(MIN_PAIRS, PAIRS_PER_BODY * n), max(MIN_EVENTS, EVENTS_PER_BODY * n)
    return wl.Watch(iconf=iconf, fconf=fconf, radii=np.array(radii, dtype=np.float64), prev=np.zeros((2, 3, n)),
                    body=np.zeros(n, dtype=np.int64), pair_i=np.zeros((pairs, wl.PAIR_I_COLS), dtype=np.int64),
                    pair_f=np.zeros((pairs, wl.PAIR_F_COLS)), ev_i=np.zeros((events, wl.EV_I_COLS), dtype=np.int64),
                    ev_f=np.zeros((events, wl.EV_F_COLS)), counts=np.zeros(4, dtype=np.int64), best=np.zeros(n),
                    attractor=np.zeros(n, dtype=np.int64), hill=np.zeros((2, n)))


def drain(watch: wl.Watch, alive: np.ndarray) -> tuple[list[Event], wl.Watch]:
    """The events logged since the last drain (body indices mapped through ``alive`` to the
    scenario's), and the watch to go on with: the same one emptied, or, after a loss, one with
    buffers twice the size (the loss is reported as a ``lost`` event)."""
    ev_i, ev_f, counts = watch.ev_i, watch.ev_f, watch.counts
    used = int(counts[wl.N_EVENTS])
    events = [_event(ev_i[k], ev_f[k], alive) for k in range(used)]
    # Cleared, not just forgotten: a checkpoint saves the buffer, and a resumed run's must hold the
    # same bits as an uninterrupted one's, whatever was drained before.
    ev_i[:used] = 0
    ev_f[:used] = 0.0
    lost = int(counts[wl.N_LOST])
    counts[wl.N_EVENTS] = 0
    counts[wl.N_LOST] = 0
    if lost:
        step = events[-1].step if events else -1
        events.append(Event("lost", step, step, float("nan"), -1, -1, float("nan"), float("nan"), float(lost)))
        watch = _grown(watch)
    return events, watch


def _event(row_i: np.ndarray, row_f: np.ndarray, alive: np.ndarray) -> Event:
    j = int(row_i[wl.E_J])
    return Event(kind=EVENT_KINDS[int(row_i[wl.E_KIND]) - 1], step=int(row_i[wl.E_STEP]),
                 step_start=int(row_i[wl.E_START]), time=float(row_f[wl.EF_TIME]), i=int(alive[row_i[wl.E_I]]),
                 j=int(alive[j]) if j >= 0 else -1, distance=float(row_f[wl.EF_DIST]),
                 speed=float(row_f[wl.EF_SPEED]), extra=float(row_f[wl.EF_EXTRA]))


def _grown(watch: wl.Watch) -> wl.Watch:
    parts = list(watch)
    for slot in (wl.WATCH_LAYOUT.index(name) for name in ("pair_i", "pair_f", "ev_i", "ev_f")):
        old = parts[slot]
        parts[slot] = np.zeros((2 * old.shape[0], old.shape[1]), dtype=old.dtype)
        parts[slot][: old.shape[0]] = old
    return wl.Watch(*parts)


def open_encounters(watch: wl.Watch, alive: np.ndarray, involving: np.ndarray | None = None,
                    ) -> list[Event]:
    """The encounters still open (at the end of a run, or of a body: ``involving`` is a boolean
    mask of the current bodies whose encounters end now), as events; they are not removed."""
    pair_i, pair_f, counts = watch.pair_i, watch.pair_f, watch.counts
    events = []
    for p in range(int(counts[wl.N_PAIRS])):
        i, j = int(pair_i[p, wl.P_I]), int(pair_i[p, wl.P_J])
        if pair_i[p, wl.P_KIND] != wl.PAIR_ENCOUNTER or (involving is not None and not (involving[i] or involving[j])):
            continue
        events.append(Event("encounter", int(pair_i[p, wl.P_LAST]), int(pair_i[p, wl.P_START]),
                            float(pair_f[p, wl.PF_TMIN]), int(alive[i]), int(alive[j]), float(pair_f[p, wl.PF_DMIN]),
                            float(pair_f[p, wl.PF_VMIN]), float(pair_f[p, wl.PF_LIMIT])))
    return events


def shrink_watch(watch: wl.Watch, keep: np.ndarray, radii: np.ndarray,
                 masses: np.ndarray) -> wl.Watch:
    """The watch of the bodies ``keep`` (current indices, increasing) with their new ``radii`` and
    ``masses``: episodes of removed bodies are dropped (the caller logs them first), the others
    renumbered; the start-of-step states of the bodies kept are kept."""
    iconf, fconf, _, prev, body, pair_i, pair_f, ev_i, ev_f, counts, _, _, _ = watch
    n_old, n = int(body.shape[0]), int(keep.shape[0])
    new_index = np.full(n_old, -1, dtype=np.int64)
    new_index[keep] = np.arange(n)
    rows = [p for p in range(int(counts[wl.N_PAIRS]))
            if new_index[pair_i[p, wl.P_I]] >= 0 and new_index[pair_i[p, wl.P_J]] >= 0]
    new_pair_i, new_pair_f = np.zeros_like(pair_i), np.zeros_like(pair_f)
    for r, p in enumerate(rows):
        new_pair_i[r] = pair_i[p]
        new_pair_i[r, wl.P_I] = new_index[pair_i[p, wl.P_I]]
        new_pair_i[r, wl.P_J] = new_index[pair_i[p, wl.P_J]]
        new_pair_f[r] = pair_f[p]
    new_counts = counts.copy()
    new_counts[wl.N_PAIRS] = len(rows)
    new_iconf = iconf.copy()
    new_iconf[wl.C_CENTRAL] = int(np.argmax(masses)) if n else 0
    # The start-of-step states go along: checks can then run on the step that just ended.
    return wl.Watch(iconf=new_iconf, fconf=fconf.copy(), radii=np.array(radii, dtype=np.float64),
                    prev=prev[:, :, keep].copy(), body=body[keep].copy(), pair_i=new_pair_i, pair_f=new_pair_f,
                    ev_i=ev_i, ev_f=ev_f, counts=new_counts, best=np.zeros(n), attractor=np.zeros(n, dtype=np.int64),
                    hill=np.zeros((2, n)))


def watch_arrays(watch: wl.Watch) -> dict[str, np.ndarray]:
    """Copies of the watch's arrays by name (for a checkpoint; the scratch ``best``, ``attractor``
    and ``prev`` are rewritten every step, but are saved too so the layout check stays simple)."""
    return {name: np.array(arr) for name, arr in zip(wl.WATCH_LAYOUT, watch, strict=True)}


def watch_from_arrays(arrays: dict[str, np.ndarray]) -> wl.Watch:
    """The inverse of :func:`watch_arrays`."""
    return wl.Watch(*(np.ascontiguousarray(arrays[name]) for name in wl.WATCH_LAYOUT))
