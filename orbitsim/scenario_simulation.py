"""A :class:`~orbitsim.simulation.Simulation` set up from a :class:`~orbitsim.scenario.Scenario`.

One place turns a scenario into the engine that steps it (its scheme and settings, ``grid_dt``,
G, softening, the clock from ``t_start``, events, radii and forces), so that a run, a replay to a
sample (:mod:`orbitsim.scenario.integrator_state`) and an animation of the scenario step the same
bits. A new run from the scenario's own bodies also takes the scheme's own coordinates when the
scenario carries them (``integrator_state``), and resolves bodies that overlap at its start as
``events.collisions`` says; a continuation passes the state it goes on from.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import numpy as np

    from orbitsim.scenario import Scenario
    from orbitsim.simulation import Simulation

__all__ = ["scenario_forces", "scenario_simulation"]


def scenario_forces(scenario: Any) -> Any:
    """A scenario's ForceSet (:func:`orbitsim.forces.schema.force_set`), or None without forces;
    the forces package is imported only when there are some."""
    if not getattr(scenario, "forces", ()):
        return None
    from orbitsim.forces.schema import force_set

    return force_set(scenario)


def scenario_simulation(scenario: Scenario, threads: int | None = None, *, elements: str | int | None = None,
                        start: tuple[np.ndarray, np.ndarray, np.ndarray, Any, float] | None = None) -> Simulation:
    """The engine for ``scenario``, from its bodies at ``t_start``, or from ``start`` = (masses,
    positions, velocities (N, 3), radii, t0) for a run that continues elsewhere (its work is then
    the caller's to restore). ``elements``: the primary of recorded orbital elements, if any."""
    from orbitsim.simulation import Simulation

    sc = scenario
    masses, positions, velocities, radii, t0 = start or (sc.masses, sc.positions, sc.velocities, sc.radii, sc.t_start)
    sim = Simulation(masses, positions, velocities, sc.integrator, sc.grid_dt, sc.G, sc.softening, t0, threads,
                     sc.run_settings, events=sc.events, radii=radii, elements=elements, forces=scenario_forces(sc))
    if start is None and sc.integrator_state is not None:
        from orbitsim.scenario.integrator_state import install

        install(sim, sc)
    if start is None and sim.watcher is not None:
        sim.watcher.contacts_at_start(sim)  # bodies that overlap at t_start: a collision at step 0
    return sim
