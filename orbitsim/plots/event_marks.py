"""``orbitsim plot --events``: a run's events as vertical lines on the time axes of its figures.

Each kind of event (:data:`~orbitsim.events.log.EVENT_KINDS`) is one
:class:`~matplotlib.collections.LineCollection` of vertical lines spanning the panel at the events'
times, in the kind's colour, labelled ``collision (2)``, so thousands of encounters cost one artist
and the legend says how many of each there were. The lines are added without autoscaling
(``autolim=False``): an event lies within the run, so it changes no axis range, and a log axis never
sees the 0 and 1 of the lines' panel-relative ends.

matplotlib and h5py are imported inside the functions: the CLI imports this module only when
``--events`` is given.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from orbitsim.io.schema import TraceError
from orbitsim.io.trace_events import event_times

__all__ = ["EVENT_COLOURS", "EVENT_GID", "mark_events", "read_event_times"]

#: Each kind's colour, apart from the C0-C9 cycle the bodies' lines use (so a mark is never read as
#: a body's line).
EVENT_COLOURS = {"encounter": "0.55", "collision": "crimson", "escape": "darkorange", "unresolved": "teal"}
#: Every mark's matplotlib group id, ``events:<kind>``; tests find the marks by it.
EVENT_GID = "events:{kind}"


def read_event_times(path: str) -> dict[str, np.ndarray]:
    """Each kind's event times in the trace at ``path`` (only kinds that happened).

    Raises
    ------
    TraceError
        When the trace has no ``events`` table (a run without ``events:``), or it is damaged.
    """
    import h5py  # noqa: PLC0415 -- lazy: loads h5py

    with h5py.File(path, "r") as f:
        times = event_times(f)
    if times is None:
        raise TraceError(f"{path}: has no events to mark: the run had no events: section")
    return times


def mark_events(ax: Any, times: dict[str, np.ndarray], legend: bool = True) -> list[Any]:
    """Vertical lines at ``times`` (kind -> times) on ``ax``; returns the collections drawn.

    With ``legend`` the axes get a legend of the kinds (and their counts) in its upper left corner;
    without, the marks carry no legend label, so a figure legend made from these axes' lines (the
    bodies') does not repeat them.
    """
    from matplotlib.collections import LineCollection  # noqa: PLC0415 -- lazy: loads matplotlib

    drawn = []
    for kind, t in times.items():
        segments = np.stack([np.column_stack([t, np.zeros_like(t)]), np.column_stack([t, np.ones_like(t)])], axis=1)
        lines = LineCollection(segments, transform=ax.get_xaxis_transform(), colors=EVENT_COLOURS.get(kind, "k"),
                               linewidths=0.8, linestyles="--", alpha=0.7, zorder=0.5,
                               label=f"{'' if legend else '_'}{kind} ({t.size})")  # "_": no legend entry
        lines.set_gid(EVENT_GID.format(kind=kind))
        ax.add_collection(lines, autolim=False)
        drawn.append(lines)
    if legend and drawn:
        ax.legend(handles=drawn, loc="upper left", fontsize="small", title="events", title_fontsize="small")
    return drawn
