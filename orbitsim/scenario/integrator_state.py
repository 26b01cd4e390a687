"""``integrator_state``: a scheme's own coordinates, so an exported scenario continues a run bit for bit.

``wisdom_holman`` keeps its state between steps in Jacobi (or democratic heliocentric)
coordinates, corrected and owing half a Kepler drift (:mod:`orbitsim.integrators.wisdom_holman`);
a sample's Cartesian state is converted from them. A run started from that Cartesian state
converts back, and the round trip changes the last bits, so it would continue the original only
to round-off (a REBOUND WHFast restart from Cartesian coordinates does the same). So
``orbitsim export --format scenario`` writes the map's own state beside the bodies when the trace
holds it (its checkpoint, for the sample at the run's end) or can recover it (any other sample, by
running the stored scenario again to that step: same input, same bits)::

    integrator_state:
      of: 3f1c...            # SHA-256 of the exact bits the state belongs to
      phase: 2
      mapping_positions: [[X, Y, Z], ...]   # one row per body; row 0 is the centre of mass
      mapping_velocities: [[VX, VY, VZ], ...]

It belongs to exact bits (:func:`state_fingerprint`): the integrator and its settings, dt, G,
softening, and every body's mass, position and velocity. When any of them differs (the file was
edited, a command-line option changed dt or the integrator) the state cannot be used: the run
starts the map from the Cartesian bodies as any run does, and :meth:`Scenario.notes` says so.
"""

from __future__ import annotations

import hashlib
import json
import re
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

from orbitsim.scenario.fields import Fields, describe

if TYPE_CHECKING:
    from orbitsim.io.checkpoint import Checkpoint
    from orbitsim.scenario.model import Scenario
    from orbitsim.simulation import Simulation

__all__ = [
    "KEYS",
    "STATEFUL",
    "applies",
    "check_integrator_state",
    "install",
    "mismatch_note",
    "state_fingerprint",
    "state_from_checkpoint",
    "state_to_dict",
]

#: The schemes whose state between steps is more than the Cartesian bodies (and that a scenario can carry).
STATEFUL = ("wisdom_holman",)
KEYS = ("of", "phase", "mapping_positions", "mapping_velocities")
_ARRAYS = ("mapping_positions", "mapping_velocities")
#: wisdom_holman's phases with a mapping state: 1 started, no step yet; 2 owing the closing half drift.
_PHASES = (1, 2)
_SHA256 = re.compile(r"^[0-9a-f]{64}$")


def check_integrator_state(value: Any, n_bodies: int) -> dict[str, Any] | None:
    """``value`` (from a file, or already checked) as ``{of, phase, mapping_positions (N, 3), ...}``.

    Raises
    ------
    ScenarioError
        Naming the key (``integrator_state.phase``) for a missing or unknown key or a bad value.
    """
    if value is None:
        return None
    fields = Fields(value, "integrator_state", KEYS, "integrator_state (as orbitsim export writes it)")
    of = fields.string("of")
    if not _SHA256.match(of):
        raise fields.error("of", f"expected a SHA-256 (64 hex digits), got {describe(of)}")
    phase = fields.integer("phase")
    if phase not in _PHASES:
        raise fields.error("phase", f"expected 1 or 2, got {phase}")
    state: dict[str, Any] = {"of": of, "phase": phase}
    for name in _ARRAYS:
        raw = fields.raw(name)
        try:
            array = np.array(raw, dtype=np.float64)
        except (TypeError, ValueError):
            array = None
        if array is None or array.shape != (n_bodies, 3) or not np.all(np.isfinite(array)):
            raise fields.error(name, f"expected {n_bodies} rows of 3 finite numbers (one per body), got "
                                     f"{describe(raw)}")
        state[name] = array
    return state


def state_fingerprint(s: Scenario) -> str:
    """SHA-256 of the bits an integrator state belongs to (see the module docstring)."""
    digest = hashlib.sha256()
    head = json.dumps([s.integrator, s.integrator_settings, float(s.dt).hex(), float(s.G).hex(),
                       float(s.softening).hex()], sort_keys=True, default=str)
    digest.update(head.encode("utf-8"))
    for array in (s.masses, s.positions, s.velocities):
        digest.update(np.ascontiguousarray(array, dtype="<f8").tobytes())
    return digest.hexdigest()


def applies(s: Scenario) -> bool:
    """Whether ``s`` carries an integrator state its run can continue from."""
    state = s.integrator_state
    return state is not None and s.integrator in STATEFUL and state["of"] == state_fingerprint(s)


def mismatch_note(s: Scenario) -> str | None:
    """The note for a state that does not belong to ``s`` (None when there is none, or it fits)."""
    if s.integrator_state is None or applies(s):
        return None
    return (f"integrator_state was written for other bits (the integrator, its settings, dt, G, softening or a body "
            f"changed since the export): {s.integrator} starts from the Cartesian bodies, so the run continues the "
            "exported one only to round-off, not bit for bit")


def state_to_dict(state: Mapping[str, Any]) -> dict[str, Any]:
    """The state as plain Python for the resolved scenario's text."""
    return {"of": state["of"], "phase": int(state["phase"]),
            **{name: np.asarray(state[name]).tolist() for name in _ARRAYS}}


def install(sim: Simulation, s: Scenario) -> None:
    """Put ``s``'s integrator state into ``sim``'s work (a new run), when it applies."""
    if not applies(s):
        return
    from orbitsim.integrators.wisdom_holman import restore_internal_state

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
    from orbitsim.checkpoint.state import restore_work
    from orbitsim.integrators.wisdom_holman import make_work

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
    from orbitsim.scenario_simulation import scenario_simulation

    sim = scenario_simulation(s)  # the run that wrote the trace, from s's own integrator state if it has one
    for _ in sim.chunks(np.array([step], dtype=np.int64), record_positions=False):
        pass
    if sim.steps_done != step or sim.n != positions.shape[0]:
        return None
    return _state_at(sim.work, positions, velocities)


def _state_at(work: tuple[Any, ...], positions: np.ndarray, velocities: np.ndarray) -> dict[str, Any] | None:
    """The map's state in ``work`` if it was synchronised to exactly ``positions``, ``velocities``."""
    from orbitsim.integrators.wisdom_holman import internal_state

    arrays = internal_state(work)
    phase = int(arrays["phase"][0])
    synced = (np.array_equal(arrays["synced_positions"], positions.T)
              and np.array_equal(arrays["synced_velocities"], velocities.T))
    if phase not in _PHASES or not synced:
        return None
    return {"phase": phase, "mapping_positions": arrays["mapping_positions"].T.copy(),
            "mapping_velocities": arrays["mapping_velocities"].T.copy()}
