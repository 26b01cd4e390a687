"""A map's axes: ``BODY.KEY=LO:HI:N`` specs, checked against the scenario document.

KEY is an orbital element of a body given by elements (``a``, ``P``, ``q``, ``e``, ``inc``,
``Omega``, ``omega``, ``pomega``, ``M``, ``f``, ``l``, ``theta``) or its mass ``m``, in the scenario's
units and angle setting (a bare number, read as the scenario reads it). Setting one key of a group
that admits only one (``a``/``P``/``q``; ``omega``/``pomega``; ``M``/``f``/``l``/``theta``) removes the
body's other key of that group, so ``jupiter.P`` on a body given by ``a`` varies its period.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from typing import Any, NamedTuple

import numpy as np

__all__ = ["AXIS_KEYS", "Axis", "MapSpecError", "parse_axis"]

#: Keys an axis may vary: the orbital elements of ``orbitsim.scenario.element_input`` and the mass.
AXIS_KEYS = ("a", "P", "q", "e", "inc", "Omega", "omega", "pomega", "M", "f", "l", "theta", "m")
#: Keys of which a body takes only one.
_GROUPS = (("a", "P", "q"), ("omega", "pomega"), ("M", "f", "l", "theta"))
#: Element keys that make a body an elements body (``orbitsim.scenario.element_input.ELEMENT_ONLY_KEYS``).
_ELEMENT_MARKERS = ("primary", "a", "P", "q")
_SPEC_RE = re.compile(r"^(?P<body>[^=]+)\.(?P<key>[A-Za-z]+)=(?P<lo>[^:]+):(?P<hi>[^:]+):(?P<n>[^:]+)$")
_ANGLE_KEYS = ("inc", "Omega", "omega", "pomega", "M", "f", "l", "theta")


class MapSpecError(ValueError):
    """A bad ``--x``/``--y`` spec or a scenario the map cannot vary; the message is one line."""


class Axis(NamedTuple):
    """One axis of a map."""

    option: str  #: ``--x`` or ``--y``
    body: str  #: body name
    index: int  #: index of the body in the document's ``bodies`` list
    key: str  #: element or ``m``
    values: np.ndarray  #: (N,) the values, in the scenario's units
    log: bool  #: spaced logarithmically
    unit: str  #: the unit words of the values, for labels

    @property
    def label(self) -> str:
        return f"{self.body}.{self.key} [{self.unit}]" if self.unit else f"{self.body}.{self.key}"

    def apply(self, body: dict[str, Any], value: float) -> None:
        """Set this axis's key of the (copied) body mapping ``body`` to ``value``."""
        for group in _GROUPS:
            if self.key in group:
                for other in group:
                    body.pop(other, None)
        body[self.key] = float(value)


def _unit_words(key: str, doc: Mapping[str, Any]) -> str:
    units = str(doc.get("units", "nbody")).lower()
    if key in _ANGLE_KEYS:
        return "rad" if str(doc.get("angles", "deg")).lower() in ("rad", "radian", "radians") else "deg"
    if key == "e":
        return ""
    kind = {"a": "length", "q": "length", "P": "time", "m": "mass"}[key]
    from orbitsim.units import UNIT_SYSTEMS  # noqa: PLC0415 - lazy: a small module, kept off the CLI start-up

    system = UNIT_SYSTEMS.get(units)
    name = getattr(system, kind, None) if system is not None else None
    return name if isinstance(name, str) else f"{units} {kind}"


def parse_axis(option: str, spec: str, doc: Mapping[str, Any], log: bool = False) -> Axis:
    """Parse ``BODY.KEY=LO:HI:N`` against the scenario document ``doc``; raise :class:`MapSpecError`."""
    match = _SPEC_RE.match(spec.strip())
    if match is None:
        raise MapSpecError(f"{option} {spec!r}: expected BODY.KEY=LO:HI:N, e.g. planet.a=5.8:9.0:20")
    name, key = match["body"], match["key"]
    if key not in AXIS_KEYS:
        raise MapSpecError(f"{option} {spec!r}: unknown key {key!r}; a map varies one of {', '.join(AXIS_KEYS)}")
    try:
        lo, hi = float(match["lo"]), float(match["hi"])
    except ValueError:
        raise MapSpecError(f"{option} {spec!r}: LO and HI must be numbers") from None
    try:
        n = int(match["n"])
    except ValueError:
        raise MapSpecError(f"{option} {spec!r}: N must be a whole number") from None
    if not (math.isfinite(lo) and math.isfinite(hi)) or lo >= hi:
        raise MapSpecError(f"{option} {spec!r}: LO must be below HI (got {lo:g} >= {hi:g})")
    if n < 2:
        raise MapSpecError(f"{option} {spec!r}: N must be at least 2, got {n}")
    if log and lo <= 0.0:
        raise MapSpecError(f"{option} {spec!r}: a logarithmic axis ({option}-log) needs LO > 0")
    bodies = doc.get("bodies")
    items = bodies if isinstance(bodies, list) else []
    names = [str(b.get("name")) for b in items if isinstance(b, dict)]
    if name not in names:
        known = ", ".join(names) or "none in its bodies list"
        raise MapSpecError(f"{option} {spec!r}: no body {name!r} in the scenario's bodies (known: {known})")
    index = names.index(name)
    body = items[index]
    if key != "m" and not any(k in body for k in _ELEMENT_MARKERS):
        raise MapSpecError(f"{option} {spec!r}: body {name!r} is given by its Cartesian state (x, v), not by "
                           f"orbital elements, so {key!r} cannot be varied; give it as primary + elements")
    values = np.geomspace(lo, hi, n) if log else np.linspace(lo, hi, n)
    return Axis(option, name, index, key, values, log, _unit_words(key, doc))
