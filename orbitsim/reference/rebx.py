"""A :class:`~orbitsim.forces.table.ForceSet` as REBOUNDx 5.1 forces on a REBOUND simulation.

The partner of :mod:`orbitsim.reference.bridge` for runs with a ``forces:`` list: given the
``rebound.Simulation`` the bridge built (same bodies, same order) and the run's ``ForceSet``,
:func:`attach_forces` loads the REBOUNDx effect of every force with the same parameters, and
:func:`rebx_energy` returns the quantity REBOUNDx says each conserves. The names map as

=============== =========================== ==================================================
orbitsim        REBOUNDx 5.1                parameters
=============== =========================== ==================================================
gr_potential    ``gr_potential``            force ``c``; the source must be particle 0
gr              ``gr``                      force ``c``; the source must be particle 0
gr_full         ``gr_full``                 force ``c``
harmonics       ``gravitational_harmonics`` particle ``J2``, ``J4``, ``R_eq``, ``Omega``
migration       ``modify_orbits_forces``    particle ``tau_a``, ``tau_e``, ``tau_inc``; force
                                            ``coordinates`` (Jacobi, REBOUNDx's default)
=============== =========================== ==================================================

Checked on REBOUNDx 5.1.0 (source: src/gr.c, gr_potential.c, gravitational_harmonics.c,
modify_orbits_forces.c, integrate_force.c):

* ``gr`` and ``gr_potential`` take ``particles[0]`` as the dominant mass whatever the
  ``gr_source`` flag says (the flag is registered but not read: a run with the Sun at index 1 and
  the flag on it precesses at a different rate), so :func:`attach_forces` refuses another source
  rather than compare two different problems.
* ``gravitational_harmonics`` reads the spin axis from the particle's ``Omega`` vector (only its
  direction is used; default z-hat), which is orbitsim's unit spin axis.
* Velocity-dependent forces added with ``add_force`` are kicked like gravity by REBOUND's
  symplectic schemes. With ``split=True`` they are instead applied by ``integrate_force``
  operators over half a step before and half after each step (implicit midpoint), the splitting
  of Tamayo, Rein, Shi & Hernandez (2020, MNRAS 491, 2885) that orbitsim's symplectic loops use.

REBOUND and REBOUNDx are imported inside the functions: importing this module costs nothing.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from orbitsim.forces.table import (
    GR,
    GR_FULL,
    GR_POTENTIAL,
    HARMONICS,
    MIGRATION,
    P_C,
    P_J2,
    P_J4,
    P_R_EQ,
    P_SPIN,
    POSITION_ONLY,
    ForceSet,
)

__all__ = ["REBX_NAMES", "AttachedForces", "attach_forces", "rebx_energy", "rebx_force_energy"]

#: orbitsim force id -> REBOUNDx effect name.
REBX_NAMES: dict[int, str] = {GR_POTENTIAL: "gr_potential", GR: "gr", GR_FULL: "gr_full",
                              HARMONICS: "gravitational_harmonics", MIGRATION: "modify_orbits_forces"}
#: ``modify_orbits_forces``' ``coordinates`` values (REBOUNDx's REBX_COORDINATES enum).
REBX_COORDINATES = {"jacobi": 0, "barycentric": 1, "particle": 2}


@dataclass
class AttachedForces:
    """The REBOUNDx objects of one simulation; keep it alive as long as the simulation runs.

    ``extras`` is the ``reboundx.Extras`` (dropping it detaches the forces); ``forces`` lists
    ``(orbitsim id, reboundx.Force)`` once per REBOUNDx effect loaded (one
    ``gravitational_harmonics`` serves every oblate body).
    """

    extras: Any
    forces: list[tuple[int, Any]]
    operators: list[Any]


def _check_source(forces: ForceSet, row: int) -> None:
    if int(forces.source[row]) != 0:
        name = REBX_NAMES[int(forces.ids[row])]
        raise ValueError(f"REBOUNDx 5.1 {name} takes particle 0 as the dominant mass (gr_source is not read); "
                         f"this force's source is body {int(forces.source[row])}")


def _set_harmonics(sim: Any, forces: ForceSet, row: int) -> None:
    """J2, J4, R_eq and the spin axis of the oblate body, as REBOUNDx particle parameters."""
    p = forces.params[row]
    body = sim.particles[int(forces.source[row])]
    body.params["J2"] = float(p[P_J2])
    body.params["J4"] = float(p[P_J4])
    body.params["R_eq"] = float(p[P_R_EQ])
    body.params["Omega"] = [float(s) for s in p[P_SPIN:P_SPIN + 3]]


def _set_migration(sim: Any, forces: ForceSet, row: int) -> None:
    """tau_a, tau_e, tau_inc of every body where finite (REBOUNDx skips a parameter left unset)."""
    for k, key in enumerate(("tau_a", "tau_e", "tau_inc")):
        for i, tau in enumerate(forces.per_body[row, k]):
            if np.isfinite(tau):
                sim.particles[i].params[key] = float(tau)


def attach_forces(sim: Any, forces: ForceSet, *, split: bool = False, coordinates: str = "jacobi") -> AttachedForces:
    """Load every force of ``forces`` into REBOUNDx on ``sim``.

    Parameters
    ----------
    sim : rebound.Simulation
        Built by :func:`orbitsim.reference.bridge.rebound_simulation` from the same bodies.
    forces : ForceSet
        The run's forces (body indices are particle indices).
    split : bool
        False: every force is an additional force (evaluated with gravity; right for IAS15 and
        for position-only forces in any scheme). True: the velocity-dependent ones (``gr``,
        ``gr_full``, ``migration``) are applied instead by ``integrate_force`` operators over
        dt/2 before and after each step, implicit midpoint (Tamayo et al. 2020).
    coordinates : {"jacobi", "barycentric", "particle"}
        ``modify_orbits_forces``' coordinates (about what each body's orbit is damped).

    Returns
    -------
    AttachedForces
    """
    import reboundx  # noqa: PLC0415 -- lazy: loads reboundx

    rebx = reboundx.Extras(sim)
    attached = AttachedForces(rebx, [], [])
    oblate: set[int] = set()
    for row, fid in enumerate(int(i) for i in forces.ids):
        if fid == HARMONICS:
            if int(forces.source[row]) in oblate:  # REBOUNDx holds one set of harmonics per particle
                raise ValueError(f"two harmonics forces on body {int(forces.source[row])}")
            if not oblate:  # one gravitational_harmonics effect serves every oblate body
                _load(rebx, attached, fid, split)
            oblate.add(int(forces.source[row]))
            _set_harmonics(sim, forces, row)
            continue
        if fid in (GR, GR_POTENTIAL):
            _check_source(forces, row)
        force = _load(rebx, attached, fid, split)
        if fid == MIGRATION:
            force.params["coordinates"] = REBX_COORDINATES[coordinates]
            _set_migration(sim, forces, row)
        else:
            force.params["c"] = float(forces.params[row, P_C])
    return attached


def _load(rebx: Any, attached: AttachedForces, fid: int, split: bool) -> Any:
    """Load one REBOUNDx effect; add it as a force, or wrap it in two half-step operators."""
    import reboundx  # noqa: PLC0415 -- lazy: loads reboundx

    force = rebx.load_force(REBX_NAMES[fid])
    attached.forces.append((fid, force))
    if split and fid not in POSITION_ONLY:
        for timing in ("pre", "post"):
            op = rebx.load_operator("integrate_force")
            op.params["force"] = force
            op.params["integrator"] = reboundx.integrators["implicit_midpoint"]
            rebx.add_operator(op, dtfraction=0.5, timing=timing)
            attached.operators.append(op)
    else:
        rebx.add_force(force)
    return force


def rebx_force_energy(sim: Any, attached: AttachedForces) -> float:
    """What REBOUNDx adds to ``sim.energy()`` to get the quantity its forces conserve.

    ``gr_potential``: ``rebx_gr_potential_potential``, -3 (G M)^2 m / (c^2 r^2) summed over the
    bodies (Nobili & Roxburgh 1986); ``gravitational_harmonics``: its potential; ``gr`` and
    ``gr_full``: the Hamiltonian REBOUNDx returns (Newtonian part included, in canonical
    momenta) minus ``sim.energy()``; ``modify_orbits_forces``: nothing (it dissipates).
    Call ``sim.synchronize()`` first under WHFast.
    """
    rebx = attached.extras
    newton = None
    extra = 0.0
    for fid, force in attached.forces:
        if fid == GR_POTENTIAL:
            extra += rebx.gr_potential_potential(force)
        elif fid == HARMONICS:
            extra += rebx.gravitational_harmonics_potential()
        elif fid in (GR, GR_FULL):
            newton = sim.energy() if newton is None else newton
            hamiltonian = rebx.gr_hamiltonian(force) if fid == GR else rebx.gr_full_hamiltonian(force)
            extra += hamiltonian - newton
    return float(extra)


def rebx_energy(sim: Any, attached: AttachedForces) -> float:
    """``sim.energy()`` plus :func:`rebx_force_energy`: REBOUNDx's conserved quantity."""
    return float(sim.energy()) + rebx_force_energy(sim, attached)
