"""A :class:`~orbitsim.simulation.Simulation` set up from a :class:`~orbitsim.scenario.Scenario`.

One place turns a scenario into the engine that steps it (its scheme and settings, ``grid_dt``,
G, softening, the clock from ``t_start``, events, radii, forces and ``output.chaos``'s initial
variation), so that a run, a replay to a sample (:mod:`orbitsim.scenario.integrator_state`) and an
animation of the scenario step the same bits. A new run from the scenario's own bodies also takes
the scheme's own coordinates when the scenario carries them (``integrator_state``), and resolves
bodies that overlap at its start as ``events.collisions`` says; a continuation passes the state it
goes on from.

Those coordinates (:mod:`orbitsim.scenario.integrator_state`) meet the engine here: :func:`install`
puts them into a new run's work, and :func:`state_from_checkpoint` and :func:`state_by_replay`
recover them at a sample of a trace, for ``orbitsim export --format scenario``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from orbitsim.scenario.integrator_state import PHASES, STATEFUL, applies

if TYPE_CHECKING:
    from orbitsim.io.checkpoint import Checkpoint
    from orbitsim.scenario import Scenario
    from orbitsim.simulation import Simulation

__all__ = ["install", "scenario_forces", "scenario_simulation", "state_by_replay", "state_from_checkpoint"]


def scenario_forces(scenario: Any) -> Any:
    """A scenario's ForceSet (:func:`orbitsim.scenario.forces.force_set`), or None without forces;
    the forces package is imported only when there are some."""
    if not getattr(scenario, "forces", ()):
        return None
    from orbitsim.scenario.forces import force_set  # noqa: PLC0415 -- lazy: off `orbitsim run`

    return force_set(scenario)


def scenario_simulation(scenario: Scenario, threads: int | None = None, *, elements: str | int | None = None,
                        start: tuple[np.ndarray, np.ndarray, np.ndarray, Any, float] | None = None) -> Simulation:
    """The engine for ``scenario``, from its bodies at ``t_start``, or from ``start`` = (masses,
    positions, velocities (N, 3), radii, t0) for a run that continues elsewhere (its work is then
    the caller's to restore). ``elements``: the primary of recorded orbital elements, if any."""
    from orbitsim.simulation import Simulation  # noqa: PLC0415 -- lazy: loads numba

    sc = scenario
    masses, positions, velocities, radii, t0 = start or (sc.masses, sc.positions, sc.velocities, sc.radii, sc.t_start)
    sim = Simulation(masses, positions, velocities, sc.integrator, sc.grid_dt, sc.G, sc.softening, t0, threads,
                     sc.run_settings, events=sc.events, radii=radii, elements=elements, forces=scenario_forces(sc),
                     chaos=_chaos_rows(sc))
    if start is None and sc.integrator_state is not None:
        install(sim, sc)
    if start is None and sim.watcher is not None:
        sim.watcher.contacts_at_start(sim)  # bodies that overlap at t_start: a collision at step 0
    return sim


def _chaos_rows(scenario: Scenario) -> np.ndarray | None:
    """The initial tangent vector of ``output.chaos`` as (N, 6) rows, or None without it (a continuation
    restores its own from the checkpoint)."""
    config = getattr(scenario, "chaos", None)
    if config is None:
        return None
    dpos, dvel = config.initial_tangent(scenario.n_bodies)
    return np.concatenate([dpos.T, dvel.T], axis=1)


def install(sim: Simulation, s: Scenario) -> None:
    """Put ``s``'s integrator state into ``sim``'s work (a new run), when it applies."""
    if not applies(s):
        return
    from orbitsim.integrators.wisdom_holman import restore_internal_state  # noqa: PLC0415 -- lazy: loads numba

    state = s.integrator_state
    restore_internal_state(sim.work, {
        "mapping_positions": state["mapping_positions"].T, "mapping_velocities": state["mapping_velocities"].T,
        "synced_positions": sim.pos, "synced_velocities": sim.vel, "phase": np.array([state["phase"]])})


def state_from_checkpoint(s: Scenario, checkpoint: Checkpoint, step: int, positions: np.ndarray,
                          velocities: np.ndarray) -> dict[str, Any] | None:
    """The integrator state at sample ``step`` with state ``positions``, ``velocities`` (N, 3), from
    the checkpoint of the run ``s`` describes; None when the checkpoint holds another step's state."""
    if s.integrator not in STATEFUL or checkpoint.state.steps_done != step:
        return None
    from orbitsim.checkpoint.state import restore_work  # noqa: PLC0415 -- lazy: loads h5py
    from orbitsim.integrators.wisdom_holman import make_work  # noqa: PLC0415 -- lazy: loads numba

    work = make_work(s.masses, s.G, s.integrator_settings)
    if not restore_work(work, checkpoint.state):
        return None
    return _state_at(work, positions, velocities)


def state_by_replay(s: Scenario, step: int, positions: np.ndarray, velocities: np.ndarray) -> dict[str, Any] | None:
    """The integrator state at sample ``step`` of the run ``s`` describes, by running ``s`` again from
    its start to that step: same input, same bits, and where outputs fall does not change the map's
    state (:mod:`orbitsim.integrators.wisdom_holman`). None unless the replay lands on the sample's
    exact bits (a trace that was not one run of ``s``)."""
    if s.integrator not in STATEFUL or not 0 <= step <= s.steps:
        return None
    sim = scenario_simulation(s)  # the run that wrote the trace, from s's own integrator state if it has one
    for _ in sim.chunks(np.array([step], dtype=np.int64), record_positions=False):
        pass
    if sim.steps_done != step or sim.n != positions.shape[0]:
        return None
    return _state_at(sim.work, positions, velocities)


def _state_at(work: tuple[Any, ...], positions: np.ndarray, velocities: np.ndarray) -> dict[str, Any] | None:
    """The map's state in ``work`` if it was synchronised to exactly ``positions``, ``velocities``."""
    from orbitsim.integrators.wisdom_holman import internal_state  # noqa: PLC0415 -- lazy: loads numba

    arrays = internal_state(work)
    phase = int(arrays["phase"][0])
    synced = (np.array_equal(arrays["synced_positions"], positions.T)
              and np.array_equal(arrays["synced_velocities"], velocities.T))
    if phase not in PHASES or not synced:
        return None
    return {"phase": phase, "mapping_positions": arrays["mapping_positions"].T.copy(),
            "mapping_velocities": arrays["mapping_velocities"].T.copy()}
