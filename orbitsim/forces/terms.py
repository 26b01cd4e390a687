"""The forces of a run as the kernels read them: one small record per force, each its own type.

A :class:`~orbitsim.forces.table.ForceSet` (rows of arrays, what a scenario resolved to) becomes a
tuple of the records below, in the scenario's order (:func:`terms_of`). Each record class is its
own Numba type, so the kernels (:mod:`orbitsim.forces.kernels`) are resolved per force when a
run's loop is compiled: a run with ``gr`` compiles ``gr``'s kernel and its operator, and none of
``gr_full``, ``harmonics`` or ``migration`` (a loop over rows that branched on an id compiled
every force's kernels for every run: 45 s before a first Wisdom-Holman + ``gr`` step). The
numbers are the rows' own float64 values, so the kernels see the same bits either way.

Plain Python (numpy and typing only): the Python side builds the records without importing Numba.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from orbitsim.forces.table import GR, GR_FULL, GR_POTENTIAL, HARMONICS, MIGRATION, P_C, P_J2, P_J4, P_R_EQ, P_SPIN

__all__ = ["POSITION_TERMS", "VELOCITY_TERMS", "GRFullTerm", "GRPotentialTerm", "GRTerm", "HarmonicsTerm",
           "MigrationTerm", "terms_of"]


class GRPotentialTerm(NamedTuple):
    """``gr_potential`` about body ``source`` (:func:`orbitsim.forces.gr_potential.gr_potential_accelerations`)."""

    source: int
    c: float


class GRTerm(NamedTuple):
    """``gr`` about body ``source`` (:func:`orbitsim.forces.gr.gr_accelerations`)."""

    source: int
    c: float


class GRFullTerm(NamedTuple):
    """``gr_full`` of every body (:func:`orbitsim.forces.gr_full.gr_full_accelerations`)."""

    c: float


class HarmonicsTerm(NamedTuple):
    """``harmonics`` of body ``source``: J2, J4, its equatorial radius and unit spin axis
    (:func:`orbitsim.forces.harmonics.harmonics_accelerations`)."""

    source: int
    J2: float
    J4: float
    R_eq: float
    spin_x: float
    spin_y: float
    spin_z: float


class MigrationTerm(NamedTuple):
    """``migration``: tau_a, tau_e, tau_inc (3, N) of every body, inf where not damped
    (:func:`orbitsim.forces.migration.migration_accelerations`)."""

    taus: np.ndarray


#: Forces that depend on positions only (kicked with gravity), and those that depend on velocities.
POSITION_TERMS = (GRPotentialTerm, HarmonicsTerm)
VELOCITY_TERMS = (GRTerm, GRFullTerm, MigrationTerm)


def terms_of(ids: np.ndarray, source: np.ndarray, params: np.ndarray, per_body: np.ndarray) -> tuple[NamedTuple, ...]:
    """The records of a ForceSet's rows (:attr:`~orbitsim.forces.table.ForceSet.arrays`), in row order."""
    terms: list[NamedTuple] = []
    for k in range(ids.shape[0]):
        fid, src, p = int(ids[k]), int(source[k]), params[k]
        if fid == GR_POTENTIAL:
            terms.append(GRPotentialTerm(src, float(p[P_C])))
        elif fid == GR:
            terms.append(GRTerm(src, float(p[P_C])))
        elif fid == GR_FULL:
            terms.append(GRFullTerm(float(p[P_C])))
        elif fid == HARMONICS:
            terms.append(HarmonicsTerm(src, float(p[P_J2]), float(p[P_J4]), float(p[P_R_EQ]), float(p[P_SPIN]),
                                       float(p[P_SPIN + 1]), float(p[P_SPIN + 2])))
        elif fid == MIGRATION:
            terms.append(MigrationTerm(np.ascontiguousarray(per_body[k])))
        else:
            raise ValueError(f"unknown force id {fid}")
    return tuple(terms)
