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

This module is the state as a scenario holds it: its keys, checks, fingerprint and text. Putting it
into a run's work, and recovering it from a checkpoint or by a replay, needs the engine and lives
beside it, in :mod:`orbitsim.scenario_simulation`.
"""

from __future__ import annotations

import hashlib
import json
import re
from collections.abc import Mapping
from typing import Any

import numpy as np

from orbitsim.scenario.data import ScenarioData
from orbitsim.scenario.fields import Fields, describe

__all__ = [
    "KEYS",
    "PHASES",
    "STATEFUL",
    "applies",
    "check_integrator_state",
    "mismatch_note",
    "state_fingerprint",
    "state_to_dict",
]

#: The schemes whose state between steps is more than the Cartesian bodies (and that a scenario can carry).
STATEFUL = ("wisdom_holman",)
KEYS = ("of", "phase", "mapping_positions", "mapping_velocities")
_ARRAYS = ("mapping_positions", "mapping_velocities")
#: wisdom_holman's phases with a mapping state: 1 started, no step yet; 2 owing the closing half drift.
PHASES = (1, 2)
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
    if phase not in PHASES:
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


def state_fingerprint(s: ScenarioData) -> str:
    """SHA-256 of the bits an integrator state belongs to (see the module docstring)."""
    digest = hashlib.sha256()
    head = json.dumps([s.integrator, s.integrator_settings, float(s.dt).hex(), float(s.G).hex(),
                       float(s.softening).hex()], sort_keys=True, default=str)
    digest.update(head.encode("utf-8"))
    for array in (s.masses, s.positions, s.velocities):
        digest.update(np.ascontiguousarray(array, dtype="<f8").tobytes())
    return digest.hexdigest()


def applies(s: ScenarioData) -> bool:
    """Whether ``s`` carries an integrator state its run can continue from."""
    state = s.integrator_state
    return state is not None and s.integrator in STATEFUL and state["of"] == state_fingerprint(s)


def mismatch_note(s: ScenarioData) -> str | None:
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
