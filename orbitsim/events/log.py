"""The events of a run: one :class:`Event` per thing that happened, in the order it happened.

Events are plain numbers (body indices are the scenario's, whatever merges or removals happened
since), so a checkpoint stores them exactly (:func:`log_arrays`, :func:`log_from_arrays`) and the
trace's ``events`` table is the same columns plus a human-readable ``details`` text made from them
(:func:`describe`). :func:`summary_line` is what ``orbitsim run`` prints about them.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = ["EVENT_KINDS", "OUTCOMES", "Event", "RunEvents", "describe", "log_arrays", "log_from_arrays",
           "summary_line", "unresolved_fix"]

#: Event kinds; the index + 1 is the code the jitted watch logs (orbitsim.events.layout.EV_*).
EVENT_KINDS = ("encounter", "collision", "escape", "unresolved", "lost")
#: What became of the bodies: nothing (logged only), merged, removed, the run halted there, or (an
#: encounter) the run ended during it.
OUTCOMES = ("", "merged", "removed", "halted", "open")
#: Integer and float columns of the stored log, in order.
_INT_COLUMNS = ("code", "step", "step_start", "i", "j", "outcome_code", "into")
_FLOAT_COLUMNS = ("time", "distance", "speed", "extra")


@dataclass(frozen=True)
class Event:
    """One event. ``i``, ``j`` are scenario body indices (``j = -1`` when there is no second body).

    ``step`` is the step after which it was seen (for an encounter, its last step within the
    distance) and ``step_start`` its first step; ``time`` is the time of closest approach for an
    encounter, else the time of ``step``. ``distance`` and ``speed`` are the separation and
    relative speed then (the distance from the centre of mass for an escape). ``extra`` depends on
    the kind: an escape's specific energy, an unresolved step's suggested dt (eta tau), a
    collision's r_i + r_j, an encounter's distance limit at its closest approach, the number of
    events a full buffer lost (kind ``lost``, never expected: the buffer grows). ``outcome``
    is one of :data:`OUTCOMES`; ``into`` the body a merged one joined.
    """

    kind: str
    step: int
    step_start: int
    time: float
    i: int
    j: int
    distance: float
    speed: float
    extra: float = float("nan")
    outcome: str = ""
    into: int = -1


def unresolved_fix(event: Event, scheme: str = "", settings: Mapping[str, Any] | None = None) -> str:
    """What to change for an ``unresolved`` event, in the terms of the scheme that took the step.

    A fixed-dt scheme: ``use dt <= eta tau``. ``trace`` judges only what it stepped with its fixed
    dt (:func:`orbitsim.events.bodies.handed_over`), so the pair or the pericentre passage was one
    its switch left to the Wisdom-Holman map: its own knobs hand it to Bulirsch-Stoer
    (``r_crit_hill`` for two bodies, neither of them the star, body 0; ``peri_crit_eta`` for an
    orbit about the star), or a shorter dt. An adaptive ``ias15`` chooses its own steps: its
    ``epsilon`` does, not dt.
    """
    config = dict(settings or {})
    dt_fix = f"dt <= {event.extra:.3g}"
    if scheme == "trace":
        if event.i == 0 or event.j == 0:
            eta = config.get("peri_crit_eta", 1.0)
            return (f"trace stepped this pericentre passage with the fixed dt (its switch, peri_crit_eta = {eta:g}, "
                    f"did not hand it to Bulirsch-Stoer): lower peri_crit_eta, or use {dt_fix}")
        hill = config.get("r_crit_hill", 3.0)
        return (f"trace stepped this pair with the fixed dt (it stayed outside r_crit_hill = {hill:g} Hill radii, so "
                f"was not handed to Bulirsch-Stoer): raise r_crit_hill, or use {dt_fix}")
    if scheme == "ias15" and config.get("adaptive", True):
        return (f"ias15 chose a step longer than {event.extra:.3g} here: lower its epsilon (now "
                f"{config.get('epsilon', 1e-9):g})")
    return f"use {dt_fix}"


def describe(event: Event, names: Sequence[str], scheme: str = "", settings: Mapping[str, Any] | None = None) -> str:
    """One line about ``event`` for the trace's ``details`` column and ``orbitsim info``;
    ``scheme`` and its ``settings`` (the run's) word the fix for an unresolved step
    (:func:`unresolved_fix`)."""
    a = names[event.i] if 0 <= event.i < len(names) else f"body {event.i}"
    b = names[event.j] if 0 <= event.j < len(names) else ""
    if event.kind == "encounter":
        text = (f"{a} and {b}: closest {event.distance:.6g} (within {event.extra:.6g}) at t = {event.time:.10g}, "
                f"relative speed {event.speed:.6g} (steps {event.step_start}-{event.step})")
    elif event.kind == "collision":
        text = (f"{a} and {b} touch: separation {event.distance:.6g} < r_i + r_j = {event.extra:.6g}, relative speed "
                f"{event.speed:.6g}")
    elif event.kind == "escape":
        text = (f"{a} escapes: {event.distance:.6g} from the centre of mass, specific energy {event.extra:+.6g} "
                f"relative to the rest")
    elif event.kind == "unresolved":
        text = (f"{a}: the step is longer than its orbit about {b} can take here (separation "
                f"{event.distance:.6g}); {unresolved_fix(event, scheme, settings)}")
    else:
        text = f"{event.extra:.0f} events could not be logged (the event buffer was full); it has been enlarged"
    if event.outcome == "merged":
        text += f"; merged into {names[event.into] if 0 <= event.into < len(names) else event.into}"
    elif event.outcome == "removed":
        text += "; removed from the run"
    elif event.outcome == "halted":
        text += "; the run halted here"
    elif event.outcome == "open":
        text += "; still in progress when the run ended"
    return text


@dataclass(frozen=True)
class RunEvents:
    """What a run's events amount to, for its trace and its summary: the events, and each body's
    fate (arrays of the scenario's N: initial and final radii, final masses, the step and time
    of its removal or -1 / nan, the body it merged into or -1)."""

    events: tuple[Event, ...]
    fates: dict[str, np.ndarray]
    scheme: str = ""  # the run's integrator and its settings, which word an unresolved step's fix
    settings: Mapping[str, Any] = field(default_factory=dict)

    def summary(self, names: Sequence[str]) -> str:
        """:func:`summary_line` of the events."""
        return summary_line(self.events, names)

    def table(self, names: Sequence[str]) -> dict[str, np.ndarray]:
        """The trace's ``events`` table: one row per event, the columns of :class:`Event` plus
        ``details``; ``kind`` and ``outcome`` as text."""
        ev = self.events
        table = {name: arr for name, arr in log_arrays(ev).items() if name not in ("code", "outcome_code")}
        table["kind"] = np.array([e.kind for e in ev], dtype=object)
        table["outcome"] = np.array([e.outcome for e in ev], dtype=object)
        table["details"] = np.array([describe(e, names, self.scheme, self.settings) for e in ev], dtype=object)
        return table


def log_arrays(events: Sequence[Event]) -> dict[str, np.ndarray]:
    """The log as numeric columns (what a checkpoint stores; nothing is lost)."""
    out = {name: np.array([_int_value(e, name) for e in events], dtype=np.int64) for name in _INT_COLUMNS}
    out.update({name: np.array([getattr(e, name) for e in events], dtype=np.float64) for name in _FLOAT_COLUMNS})
    return out


def _int_value(event: Event, name: str) -> int:
    if name == "code":
        return EVENT_KINDS.index(event.kind) + 1
    if name == "outcome_code":
        return OUTCOMES.index(event.outcome)
    return int(getattr(event, name))


def log_from_arrays(arrays: dict[str, np.ndarray]) -> list[Event]:
    """The inverse of :func:`log_arrays`."""
    n = len(arrays["code"])
    return [Event(kind=EVENT_KINDS[int(arrays["code"][k]) - 1], step=int(arrays["step"][k]),
                  step_start=int(arrays["step_start"][k]), time=float(arrays["time"][k]), i=int(arrays["i"][k]),
                  j=int(arrays["j"][k]), distance=float(arrays["distance"][k]), speed=float(arrays["speed"][k]),
                  extra=float(arrays["extra"][k]), outcome=OUTCOMES[int(arrays["outcome_code"][k])],
                  into=int(arrays["into"][k])) for k in range(n)]


#: How the summary names each kind: (one, many).
_PLURALS = {"encounter": ("close encounter", "close encounters"), "collision": ("collision", "collisions"),
            "escape": ("escape", "escapes"), "unresolved": ("unresolved step", "unresolved steps"),
            "lost": ("overflow of the event buffer", "overflows of the event buffer")}


def summary_line(events: Sequence[Event], names: Sequence[str], limit: int = 3) -> str:
    """``3 close encounters, 1 escape (comet at t = 412.3)``: counts by kind, and for escapes,
    collisions and unresolved steps the first few bodies and times; "" without events."""
    counts = Counter(e.kind for e in events)
    parts = []
    for kind in EVENT_KINDS:
        if not counts[kind]:
            continue
        one, many = _PLURALS[kind]
        text = f"{counts[kind]} {one if counts[kind] == 1 else many}"
        if kind != "encounter":
            shown = [e for e in events if e.kind == kind][:limit]
            who = ", ".join(f"{_who(e, names)} at t = {e.time:.6g}" for e in shown)
            more = ", ..." if counts[kind] > limit else ""
            text += f" ({who}{more})"
        parts.append(text)
    return ", ".join(parts)


def _who(event: Event, names: Sequence[str]) -> str:
    a = names[event.i] if 0 <= event.i < len(names) else str(event.i)
    if event.kind == "collision" and 0 <= event.j < len(names):
        a = f"{a} and {names[event.j]}"
    if event.outcome:
        a = f"{a}, {event.outcome}"
    return a
