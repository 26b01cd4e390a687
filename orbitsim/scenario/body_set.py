"""The bodies a scenario's reader has collected so far: :class:`BodySet`.

Kept below both readers of bodies, :mod:`orbitsim.scenario.bodies` (explicit lists, the ephemeris,
generators) and :mod:`orbitsim.scenario.element_input` (a body given by orbital elements, whose
primary is looked up here), so that neither imports the other to know what it is filling.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from orbitsim.scenario.errors import ScenarioError
from orbitsim.scenario.quantities import QuantityReader

__all__ = ["BodySet"]


@dataclass
class BodySet:
    """Bodies collected so far, each with the key path it came from."""

    names: list[str] = field(default_factory=list)
    masses: list[np.ndarray] = field(default_factory=list)
    positions: list[np.ndarray] = field(default_factory=list)
    velocities: list[np.ndarray] = field(default_factory=list)
    origins: list[str] = field(default_factory=list)
    radii: dict[int, float] = field(default_factory=dict)
    #: Reads numbers with units and angles in the scenario's ``angles`` unit.
    reader: QuantityReader = field(default_factory=lambda: QuantityReader("nbody"))
    #: The plane of the scenario's x-y axes: the ephemeris's ``frame``, else the ecliptic.
    axes: str = "ecliptic"
    #: What the input meant, one line each, for ``orbitsim validate`` (angle unit, frames).
    notes: list[str] = field(default_factory=list)
    #: Bodies given by elements without an anomaly (``bodies[1] (b)``): they start at f = 0.
    no_anomaly: list[str] = field(default_factory=list)
    _index: dict[str, int] = field(default_factory=dict)

    def add(self, names: list[str], m: Any, x: Any, v: Any, origins: list[str], name_keys: list[str]) -> None:
        """Append a block of bodies; a name used before is an error at its ``name_keys`` entry."""
        for name, key in zip(names, name_keys, strict=True):
            if name in self._index:
                first = self.origins[self._index[name]]
                raise ScenarioError(f"duplicate body name {name!r} (already used by {first}); names must be "
                                    "unique", key=key)
            self._index[name] = len(self.names)
            self.names.append(name)
        self.origins.extend(origins)
        self.masses.append(np.asarray(m, dtype=np.float64).reshape(-1))
        self.positions.append(np.asarray(x, dtype=np.float64).reshape(-1, 3))
        self.velocities.append(np.asarray(v, dtype=np.float64).reshape(-1, 3))

    def copy(self) -> BodySet:
        """A copy to read more bodies into; the bodies' arrays are shared (nothing writes into them)."""
        return dataclasses.replace(self, names=list(self.names), masses=list(self.masses),
                                   positions=list(self.positions), velocities=list(self.velocities),
                                   origins=list(self.origins), radii=dict(self.radii), notes=list(self.notes),
                                   no_anomaly=list(self.no_anomaly), _index=dict(self._index))

    def find(self, name: str) -> tuple[float, np.ndarray, np.ndarray] | None:
        """Mass, position and velocity of an earlier body, or None."""
        i = self._index.get(name)
        if i is None:
            return None
        m, x, v = self.arrays()
        return float(m[i]), x[i], v[i]

    def radii_array(self) -> np.ndarray | None:
        """(N,) radii, 0 for bodies without ``r``; None when no body gave one."""
        if not self.radii:
            return None
        r = np.zeros(len(self.names))
        for i, value in self.radii.items():
            r[i] = value
        return r

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Masses (N,), positions (N, 3), velocities (N, 3) of every body so far."""
        if len(self.masses) > 1:  # keep one block, so repeated lookups stay cheap
            self.masses = [np.concatenate(self.masses)]
            self.positions = [np.concatenate(self.positions)]
            self.velocities = [np.concatenate(self.velocities)]
        if not self.masses:
            return np.zeros(0), np.zeros((0, 3)), np.zeros((0, 3))
        return self.masses[0], self.positions[0], self.velocities[0]
