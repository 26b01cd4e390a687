"""The scenario keys of events and orbital elements: body radii ``r``, the ``events:`` section and
``output.elements`` / ``output.primary`` (schema in docs/scenarios.md; the values in
:mod:`orbitsim.events.config`).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from orbitsim.events.config import (
    COLLISION_DETECT,
    COLLISION_RESOLVE,
    ESCAPE_ACTIONS,
    Collisions,
    Encounters,
    Escape,
    EventsConfig,
    Unresolved,
)
from orbitsim.scenario.errors import ScenarioError
from orbitsim.scenario.fields import Fields, describe

__all__ = ["ELEMENT_PRIMARIES", "EVENTS_KEYS", "check_elements_output", "check_events", "check_radii",
           "read_events"]

EVENTS_KEYS = ("collisions", "encounters", "escape", "unresolved")
#: ``output.primary`` besides a body name.
ELEMENT_PRIMARIES = ("heaviest", "jacobi")


def read_events(top: Fields, radii: np.ndarray | None) -> EventsConfig | None:
    """The ``events:`` section of a scenario document, or None when it has none."""
    if not top.has("events"):
        return None
    section = Fields(top.raw("events"), "events", EVENTS_KEYS, "events section")
    collisions = encounters = escape = None
    if section.has("collisions"):
        col = Fields(section.raw("collisions"), "events.collisions", ("detect", "resolve"), "collisions section")
        collisions = Collisions(detect=col.string("detect", "direct", choices=COLLISION_DETECT),
                                resolve=col.string("resolve", "log", choices=COLLISION_RESOLVE))
        if radii is None or not np.any(radii > 0.0):
            raise ScenarioError("no body has a radius r, so no two bodies can ever touch: give the bodies that can "
                                "collide a radius (bodies[k].r)", key="events.collisions")
    if section.has("encounters"):
        enc = Fields(section.raw("encounters"), "events.encounters", ("distance", "hill", "halt"),
                     "encounters section")
        enc.one_of("distance", "hill")
        encounters = Encounters(distance=enc.number("distance", None, positive=True),
                                hill=enc.number("hill", None, positive=True), halt=enc.boolean("halt", False))
    if section.has("escape"):
        esc = Fields(section.raw("escape"), "events.escape", ("distance", "action"), "escape section")
        escape = Escape(distance=esc.number("distance", positive=True),
                        action=esc.string("action", "log", choices=ESCAPE_ACTIONS))
    return EventsConfig(collisions=collisions, encounters=encounters, escape=escape,
                        unresolved=_read_unresolved(section))


def _read_unresolved(section: Fields) -> Unresolved | None:
    """``unresolved: {eta: 0.5}``, ``true`` (eta = 1) or ``false``; on by default."""
    value = section.data.get("unresolved", True)
    if value is True:
        return Unresolved()
    if value is False:
        return None
    if not isinstance(value, dict):
        raise ScenarioError(f"expected true, false or {{eta: <number>}}, got {describe(value)}",
                            key="events.unresolved")
    unres = Fields(value, "events.unresolved", ("eta",), "unresolved section")
    return Unresolved(eta=unres.number("eta", 1.0, positive=True))


def check_radii(radii: Any, n: int) -> np.ndarray | None:
    """Radii as (N,) float64 >= 0, or None."""
    if radii is None:
        return None
    r = np.array(radii, dtype=np.float64).reshape(-1)
    if r.shape != (n,):
        raise ScenarioError(f"need {n} radii, got {r.shape[0]}", key="bodies")
    bad = np.flatnonzero(~(np.isfinite(r) & (r >= 0.0)))
    if bad.size:
        raise ScenarioError(f"a radius must be a finite number >= 0, got {r[bad[0]]}", key=f"bodies[{bad[0]}].r")
    return r


def check_events(events: Any, integrator: str) -> None:
    """``events`` must be an :class:`EventsConfig` (or None); every integrator supports them."""
    if events is not None and not isinstance(events, EventsConfig):
        raise ScenarioError(f"expected an events section, got {describe(events)}", key="events")


def check_elements_output(record: Any, primary: Any, names: Sequence[str]) -> None:
    """``output.elements`` is a bool; ``output.primary`` is heaviest, jacobi or a body's name."""
    if not isinstance(record, bool):
        raise ScenarioError(f"expected true or false, got {describe(record)}", key="output.elements")
    if primary not in ELEMENT_PRIMARIES and primary not in names:
        raise ScenarioError(f"must be heaviest, jacobi or a body name, got {describe(primary)}", key="output.primary")
