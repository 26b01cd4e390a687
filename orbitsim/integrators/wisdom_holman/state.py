"""The Wisdom-Holman state a checkpoint saves, and the Kepler failure a run recorded.

What a checkpoint must save to continue a run bit for bit is described in
:mod:`orbitsim.integrators.wisdom_holman` ("Internal state"): :func:`internal_state` copies it out
of a run's :class:`~.operators.WHWork`, :func:`restore_internal_state` puts it back. A Kepler
failure is recorded in ``work.flags``; :func:`failure_message` turns it into one line and
:func:`raise_for_failure` into a :class:`~orbitsim.physics.kepler.KeplerConvergenceError`.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from orbitsim.integrators.wisdom_holman.operators import (
    F_BODY,
    F_PHASE,
    F_STATUS,
    F_STEP,
    PHASE_LAGGING,
    PHASE_SYNCED,
    PHASE_UNSET,
    WHWork,
)
from orbitsim.physics.kepler import KEPLER_OK, KeplerConvergenceError, describe_status

__all__ = ["failure_message", "internal_state", "raise_for_failure", "restore_internal_state"]


#: The arrays a checkpoint saves, by the name it saves them under: the fields of :class:`WHWork`.
_STATE_SLOTS = {
    "mapping_positions": "jpos",
    "mapping_velocities": "jvel",
    "synced_positions": "last_pos",
    "synced_velocities": "last_vel",
}


def internal_state(work: WHWork) -> dict[str, np.ndarray]:
    """Copies of the arrays a checkpoint must save to continue bit for bit (the module docstring)."""
    arrays = {name: getattr(work, slot).copy() for name, slot in _STATE_SLOTS.items()}
    arrays["phase"] = np.array([work.flags[F_PHASE]], dtype=np.int64)
    return arrays


def restore_internal_state(work: WHWork, arrays: Mapping[str, np.ndarray]) -> None:
    """Put arrays saved by :func:`internal_state` back into ``work`` (in place).

    The inertial ``pos``/``vel`` of the simulation must be restored to ``synced_positions`` and
    ``synced_velocities`` as well, or the next call restarts the map from them.
    """
    missing = sorted((set(_STATE_SLOTS) | {"phase"}) - set(arrays))
    if missing:
        raise ValueError(f"wisdom_holman internal state lacks {', '.join(missing)}")
    for name, slot in _STATE_SLOTS.items():
        value = np.asarray(arrays[name], dtype=np.float64)
        target = getattr(work, slot)
        if value.shape != target.shape:
            raise ValueError(
                f"wisdom_holman internal state {name!r} has shape {value.shape}, expected {target.shape}"
            )
        target[...] = value
    phase = int(np.asarray(arrays["phase"]).reshape(-1)[0])
    if phase not in (PHASE_UNSET, PHASE_SYNCED, PHASE_LAGGING):
        raise ValueError(f"wisdom_holman internal state 'phase' must be 0, 1 or 2, got {phase}")
    flags = work.flags
    flags[:] = 0
    flags[F_PHASE] = phase


def failure_message(work: WHWork) -> str | None:
    """One line describing a Kepler failure recorded in ``work``, or None if there was none."""
    flags = work.flags
    status = int(flags[F_STATUS])
    if status == KEPLER_OK:
        return None
    step_index = int(flags[F_STEP])
    return describe_status(status, body=int(flags[F_BODY]), step=step_index if step_index >= 0 else None)


def raise_for_failure(work: WHWork) -> None:
    """Raise :class:`KeplerConvergenceError` if a Kepler failure is recorded in ``work``."""
    message = failure_message(work)
    if message is not None:
        raise KeplerConvergenceError(message)
