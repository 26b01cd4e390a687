"""What a trace says about its run's events, read with h5py alone (``orbitsim info``, ``orbitsim batch``).

A run with an ``events:`` section leaves in its trace (docs/trace.md): the ``events`` table, one row
per event; in ``bodies`` each body's fate (``removed_step``, ``removed_time``, ``merged_into``, ...);
and with ``output.elements`` the ``elements`` group. These readers take an open :class:`h5py.File`
and never touch the per-sample arrays beyond their shapes, so ``info`` on a trace of millions of
samples stays instant, and nothing here imports numba: ``info`` and the batch summary must stay light.

A trace written before events existed, or by a run without them, has none of these: the readers
return None (or zero counts), never an error. A group that is there but lacks a column is a damaged
trace, reported as :class:`~orbitsim.io.schema.TraceError` naming the dataset, as the trace reader does.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np

from orbitsim.events.log import EVENT_KINDS
from orbitsim.io.schema import ELEMENTS, TraceError

__all__ = ["COUNTED_KINDS", "EVENTS_BLOCK", "BodyExit", "ElementsInfo", "EventRow", "bodies_left", "elements_info",
           "event_counts", "event_times", "first_events", "format_time", "iter_events"]

#: The kinds the batch summary counts, one column each; ``lost`` (an overflow of the event buffer,
#: never expected) is listed by ``info`` but not a summary column.
COUNTED_KINDS = ("encounter", "collision", "escape", "unresolved")
#: Rows of the ``events`` table read at a time by :func:`iter_events`: memory stays flat for a run
#: that logged millions of encounters.
EVENTS_BLOCK = 65536


@dataclass(frozen=True)
class EventRow:
    """One row of the ``events`` table, as ``info`` lists it."""

    time: float
    kind: str
    details: str


@dataclass(frozen=True)
class BodyExit:
    """A body that left the run: at ``step`` / ``time``, merged into ``into`` (a name) or removed (``into`` "")."""

    name: str
    step: int
    time: float
    into: str


@dataclass(frozen=True)
class ElementsInfo:
    """The ``elements`` group: its primary, its datasets (in the stored order) and their shape."""

    primary: str
    names: tuple[str, ...]
    shape: tuple[int, ...]


def _column(f: Any, name: str) -> Any:
    """Dataset ``name`` of the trace, or a TraceError naming it."""
    if name not in f:
        raise TraceError(f"{f.filename}: damaged trace: dataset '{name}' is missing")
    return f[name]


def _text(f: Any, name: str, rows: slice = slice(None)) -> list[str]:
    """A UTF-8 text column (or a slice of it) as str."""
    return [str(v) for v in _column(f, name).asstr()[rows]]


def event_counts(f: Any) -> dict[str, int] | None:
    """Events by kind (every kind of :data:`~orbitsim.events.log.EVENT_KINDS`, 0 when none), or None
    when the trace has no ``events`` table (a run without ``events:``)."""
    if "events" not in f:
        return None
    kinds = _text(f, "events/kind")
    counts = dict.fromkeys(EVENT_KINDS, 0)
    for kind in kinds:
        counts[kind] = counts.get(kind, 0) + 1  # a kind this version does not know is still counted
    return counts


def first_events(f: Any, limit: int) -> list[EventRow]:
    """The first ``limit`` rows of the ``events`` table (in the order they happened); [] without one."""
    if "events" not in f:
        return []
    rows = slice(0, limit)
    times = np.asarray(_column(f, "events/time")[rows], dtype=np.float64)
    kinds, details = _text(f, "events/kind", rows), _text(f, "events/details", rows)
    return [EventRow(float(t), k, d) for t, k, d in zip(times, kinds, details, strict=True)]


def iter_events(f: Any, kind: str | None = None, block: int = EVENTS_BLOCK) -> Iterator[EventRow]:
    """Every row of the ``events`` table (only those of ``kind`` when given), in the order they
    happened, read ``block`` rows at a time; nothing without a table."""
    if "events" not in f:
        return
    count = int(_column(f, "events/kind").shape[0])
    for start in range(0, count, block):
        rows = slice(start, min(count, start + block))
        times = np.asarray(_column(f, "events/time")[rows], dtype=np.float64)
        kinds, details = _text(f, "events/kind", rows), _text(f, "events/details", rows)
        for t, k, d in zip(times, kinds, details, strict=True):
            if kind is None or k == kind:
                yield EventRow(float(t), k, d)


def event_times(f: Any) -> dict[str, np.ndarray] | None:
    """Each kind's event times (kinds in :data:`~orbitsim.events.log.EVENT_KINDS` order, only
    those that happened; a ``lost`` row has no time and is left out), or None without a table."""
    if "events" not in f:
        return None
    kinds = np.array(_text(f, "events/kind"), dtype=object)
    times = np.asarray(_column(f, "events/time")[()], dtype=np.float64)
    order = [k for k in EVENT_KINDS if k in set(kinds)] + sorted(set(kinds) - set(EVENT_KINDS))
    out = {kind: times[(kinds == kind) & np.isfinite(times)] for kind in order}
    return {kind: t for kind, t in out.items() if t.size}


def bodies_left(f: Any) -> list[BodyExit] | None:
    """The bodies that left the run (merged or removed), in the order they left; None when the
    trace does not record it (no ``bodies/removed_step``: a run without ``events:``)."""
    if "bodies/removed_step" not in f:
        return None
    names = _text(f, "bodies/names")
    step = np.asarray(f["bodies/removed_step"][()], dtype=np.int64)
    time = np.asarray(_column(f, "bodies/removed_time")[()], dtype=np.float64)
    into = np.asarray(_column(f, "bodies/merged_into")[()], dtype=np.int64)
    gone = np.flatnonzero(step >= 0)
    order = gone[np.argsort(step[gone], kind="stable")]
    return [BodyExit(names[k], int(step[k]), float(time[k]), names[into[k]] if 0 <= into[k] < len(names) else "")
            for k in order]


def elements_info(f: Any) -> ElementsInfo | None:
    """The ``elements`` group's primary, datasets and shape, or None when the trace has none."""
    if "elements" not in f:
        return None
    group = f["elements"]
    present = [name for name in group if hasattr(group[name], "shape")]
    # The format's order (a, e, inc, ...), not HDF5's alphabetical one; unknown names after.
    names = tuple(sorted(present, key=lambda n: (ELEMENTS.index(n) if n in ELEMENTS else len(ELEMENTS), n)))
    if not names:
        raise TraceError(f"{f.filename}: damaged trace: group 'elements' holds no dataset")
    primary = group.attrs.get("primary", "")
    primary = primary.decode() if isinstance(primary, bytes) else str(primary)
    return ElementsInfo(primary, names, tuple(int(n) for n in group[names[0]].shape))


def format_time(value: float) -> str:
    """A time as ``info`` shows it (``-`` when there is none: a ``lost`` event has no time)."""
    return f"{value:.10g}" if math.isfinite(value) else "-"
