"""What a scenario's ``events:`` section asks for, as frozen values (the schema is in docs/scenarios.md).

Each part is optional; ``None`` means that kind of event is not watched. A scenario without an
``events:`` section has no :class:`EventsConfig` at all, and its run is the plain fixed-dt loop,
bit for bit and at full speed. With a section, ``unresolved`` is on (at REBOUND TRACE's default
``eta = 1``) unless it is turned off, because a step too long for the orbit it is on is the
failure a user of a fixed-dt code can least see.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

__all__ = ["COLLISION_DETECT", "COLLISION_RESOLVE", "ESCAPE_ACTIONS", "Collisions", "Encounters", "Escape",
           "EventsConfig", "Unresolved"]

#: ``direct``: the bodies overlap at the end of a step; ``line``: they come within r_i + r_j at
#: some point of the straight segment from their start-of-step to their end-of-step separation.
COLLISION_DETECT = ("direct", "line")
#: ``log`` records the contact (once per contact), ``halt`` ends the run there, ``merge`` joins the
#: two bodies into one, conserving mass and momentum.
COLLISION_RESOLVE = ("log", "halt", "merge")
#: ``log`` records the escape (once per escape), ``halt`` ends the run, ``remove`` takes the body out.
ESCAPE_ACTIONS = ("log", "halt", "remove")


@dataclass(frozen=True)
class Collisions:
    """``events.collisions``: bodies with radii ``r`` that touch."""

    detect: str = "direct"
    resolve: str = "log"


@dataclass(frozen=True)
class Encounters:
    """``events.encounters``: pairs closer than ``distance``, or than ``hill`` mutual Hill radii."""

    distance: float | None = None
    hill: float | None = None
    halt: bool = False


@dataclass(frozen=True)
class Escape:
    """``events.escape``: a body farther than ``distance`` from the centre of mass, on an unbound
    orbit relative to the rest of the system."""

    distance: float
    action: str = "log"


@dataclass(frozen=True)
class Unresolved:
    """``events.unresolved``: a body whose local timescale tau (Pham, Rein & Spiegel 2024) is
    shorter than ``dt / eta``."""

    eta: float = 1.0


@dataclass(frozen=True)
class EventsConfig:
    """Every kind of event a run watches for."""

    collisions: Collisions | None = None
    encounters: Encounters | None = None
    escape: Escape | None = None
    unresolved: Unresolved | None = field(default_factory=Unresolved)

    def to_dict(self) -> dict[str, Any]:
        """The section as the resolved scenario writes it (every key explicit, so it reloads the same)."""
        out: dict[str, Any] = {}
        if self.collisions is not None:
            out["collisions"] = {"detect": self.collisions.detect, "resolve": self.collisions.resolve}
        if self.encounters is not None:
            enc = self.encounters
            out["encounters"] = ({"distance": enc.distance} if enc.distance is not None else {"hill": enc.hill})
            out["encounters"]["halt"] = enc.halt
        if self.escape is not None:
            out["escape"] = {"distance": self.escape.distance, "action": self.escape.action}
        out["unresolved"] = {"eta": self.unresolved.eta} if self.unresolved is not None else False
        return out

    @property
    def changes_bodies(self) -> bool:
        """Whether an event can take bodies out of the run (a merge, a removal)."""
        return bool((self.collisions is not None and self.collisions.resolve == "merge")
                    or (self.escape is not None and self.escape.action == "remove"))
