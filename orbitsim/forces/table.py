"""The forces of a run as arrays the jitted kernels read: one row per force, dispatched by id.

A scenario's ``forces:`` list (:mod:`orbitsim.scenario.forces`) becomes a :class:`ForceSet`. The
kernels never see names or dictionaries: they loop over the rows of ``ids`` and branch on each id,
so one compiled kernel serves every combination of forces, and nothing about forces is compiled
for a run that has none (the stepping loops of such runs never reference this package).

Layout (F forces, N bodies):

* ``ids`` (F,) int64: :data:`GR_POTENTIAL`, :data:`GR`, :data:`GR_FULL`, :data:`HARMONICS` or
  :data:`MIGRATION`;
* ``source`` (F,) int64: the body the force is about (``gr``, ``gr_potential``: the dominant
  mass; ``harmonics``: the oblate body), -1 where the force names none (``gr_full``,
  ``migration``);
* ``params`` (F, :data:`N_PARAMS`) float64: the scalars, at the ``P_*`` columns;
* ``per_body`` (F, 3, N) float64: ``migration``'s tau_a, tau_e, tau_inc of every body (inf: not
  damped), zeros for the other forces.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = ["FORCE_IDS", "GR", "GR_FULL", "GR_POTENTIAL", "HARMONICS", "MIGRATION", "N_PARAMS", "POSITION_ONLY", "P_C",
           "P_J2", "P_J4", "P_R_EQ", "P_SPIN", "ForceSet", "empty_force_set"]

GR_POTENTIAL, GR, GR_FULL, HARMONICS, MIGRATION = 1, 2, 3, 4, 5
#: Scenario names of the forces, by id.
FORCE_IDS: dict[str, int] = {"gr_potential": GR_POTENTIAL, "gr": GR, "gr_full": GR_FULL, "harmonics": HARMONICS,
                             "migration": MIGRATION}
#: Forces that depend on positions only: they are kicked with gravity inside every symplectic scheme.
POSITION_ONLY = frozenset({GR_POTENTIAL, HARMONICS})

#: Columns of ``params``: the speed of light (gr, gr_potential, gr_full); J2, J4, the equatorial
#: radius and the unit spin axis (x, y, z at P_SPIN .. P_SPIN + 2) of an oblate body (harmonics).
P_C = 0
P_J2, P_J4, P_R_EQ, P_SPIN = 1, 2, 3, 4
N_PARAMS = 8


@dataclass(frozen=True)
class ForceSet:
    """The forces of one run: the arrays the kernels read, and what the scenario said.

    ``entries`` keeps each force as the scenario gave it, resolved (names of bodies, numbers in
    the scenario's units), for provenance and messages.
    """

    ids: np.ndarray
    source: np.ndarray
    params: np.ndarray
    per_body: np.ndarray
    entries: tuple[dict[str, Any], ...] = field(default=())

    def __post_init__(self) -> None:
        f = self.ids.shape[0]
        if self.source.shape != (f,) or self.params.shape != (f, N_PARAMS) or self.per_body.shape[:2] != (f, 3):
            raise ValueError("ForceSet arrays disagree on the number of forces")

    @property
    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(ids, source, params, per_body)``, the tuple every forced kernel takes."""
        return (self.ids, self.source, self.params, self.per_body)

    @property
    def names(self) -> tuple[str, ...]:
        """The scenario names of the forces, in order."""
        by_id = {v: k for k, v in FORCE_IDS.items()}
        return tuple(by_id[int(i)] for i in self.ids)

    @property
    def velocity_dependent(self) -> bool:
        """True if any force depends on velocities (``gr``, ``gr_full``, ``migration``)."""
        return any(int(i) not in POSITION_ONLY for i in self.ids)

    @property
    def dissipative(self) -> bool:
        """True if a force removes energy on purpose (``migration``): energy error measures nothing."""
        return bool(np.any(self.ids == MIGRATION))

    def without_bodies(self, keep: np.ndarray) -> ForceSet:
        """The same forces after bodies were removed: ``keep`` (N,) bool of the bodies left.
        Sources are renumbered; a force whose source left is dropped."""
        new_index = np.cumsum(keep) - 1
        rows = [k for k in range(self.ids.shape[0]) if self.source[k] < 0 or keep[self.source[k]]]
        source = np.array([new_index[s] if s >= 0 else -1 for s in self.source[rows]], dtype=np.int64)
        return ForceSet(self.ids[rows].copy(), source, self.params[rows].copy(),
                        np.ascontiguousarray(self.per_body[rows][:, :, keep]), tuple(self.entries[k] for k in rows))


def empty_force_set(n: int) -> ForceSet:
    """No forces, for N bodies."""
    return ForceSet(np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64), np.zeros((0, N_PARAMS)),
                    np.zeros((0, 3, n)))
