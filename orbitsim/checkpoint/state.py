"""Capture and restore a :class:`~orbitsim.simulation.Simulation`'s complete state, generically.

See :mod:`orbitsim.checkpoint` (point 1) for why everything is saved and nothing recomputed.
"""

from __future__ import annotations

import json
from typing import TYPE_CHECKING, Any

import numpy as np

from orbitsim.io.checkpoint import CheckpointError, SimState, layout_json

if TYPE_CHECKING:
    from orbitsim.simulation import Simulation

__all__ = ["capture_state", "restore_state", "restore_variational", "restore_work"]


def capture_state(sim: Simulation) -> SimState:
    """Copies of everything ``sim`` continues from (see the module docstring, point 1)."""
    arrays: list[np.ndarray] = []
    layout = _flatten(sim.work, arrays)
    events = sim.watcher.arrays() if sim.watcher is not None else {}
    chaos = sim.variational.arrays() if sim.variational is not None else {}
    return SimState(steps_done=int(sim.steps_done), pos=sim.pos.copy(), vel=sim.vel.copy(), acc=sim.acc.copy(),
                    work=tuple(arrays), work_layout=layout_json(layout), events=events, chaos=chaos)


def _flatten(obj: Any, out: list[np.ndarray]) -> Any:
    """Append every array (copied) and constant of ``obj`` to ``out``; return its nesting. A None (a part
    the run does not use: Wisdom-Holman's corrector tables without a corrector) is kept as an empty
    array, as such parts were before they were None, so checkpoints keep their bytes and layout."""
    if obj is None:
        out.append(np.zeros(0))
        return "a"
    if isinstance(obj, np.ndarray):
        out.append(obj.copy())
        return "a"
    if isinstance(obj, tuple | list):
        return [_flatten(item, out) for _, item in _saved_items(obj)]
    if isinstance(obj, bool | int | float | np.generic):
        out.append(np.asarray(obj))
        return "s"
    raise CheckpointError(f"cannot checkpoint integrator work of type {type(obj).__name__}")


def _saved_items(obj: tuple | list) -> list[tuple[str | None, Any]]:
    """The items of a work tuple that a checkpoint holds, with their field names (None in a plain tuple):
    all but the fields its class names in ``CHECKPOINT_DERIVED``, which the scheme's ``make_work`` sets from
    the settings (Wisdom-Holman's ``heliocentric``, the coordinates as a type), so checkpoints keep the
    layout they had before them."""
    derived = getattr(type(obj), "CHECKPOINT_DERIVED", ())
    names = getattr(obj, "_fields", None) or [None] * len(obj)
    return [(name, item) for name, item in zip(names, obj, strict=True) if name not in derived]


def restore_state(sim: Simulation, state: SimState) -> None:
    """Put ``state`` back into ``sim`` in place: arrays, work, step count.

    Raises
    ------
    CheckpointError
        If shapes, dtypes, the work layout or its constants do not match ``sim`` (the
        checkpoint belongs to another system, integrator or integrator settings).
    """
    for name in ("pos", "vel", "acc"):
        have, saved = getattr(sim, name), getattr(state, name)
        if have.shape != saved.shape:
            raise CheckpointError(f"checkpoint {name} has shape {saved.shape}, the run needs {have.shape}")
    arrays = iter(state.work)
    # Constants the run itself sets (ias15's t_end, which `run --from` moves): the new run's value stays.
    try:
        _restore(sim.work, json.loads(state.work_layout), arrays, sim.scheme.run_constants)
    except StopIteration:
        raise CheckpointError("checkpoint holds fewer work arrays than the integrator keeps") from None
    if next(arrays, None) is not None:
        raise CheckpointError("checkpoint holds more work arrays than the integrator keeps")
    sim.pos[...] = state.pos
    sim.vel[...] = state.vel
    sim.acc[...] = state.acc
    sim.steps_done = int(state.steps_done)
    if (sim.watcher is not None) != bool(state.events):
        raise CheckpointError("checkpoint and run differ in whether events are watched")
    if sim.watcher is not None:
        sim.watcher.restore(state.events)
    restore_variational(sim, state)


def restore_variational(sim: Simulation, state: SimState) -> None:
    """Put ``state``'s variational state (``output.chaos``: tangent vector, MEGNO's sums) back into ``sim``.

    Raises
    ------
    CheckpointError
        If one of them carries the variational equations and the other does not, or the state does not fit.
    """
    if (sim.variational is not None) != bool(state.chaos):
        raise CheckpointError("checkpoint and run differ in whether they carry the variational equations "
                              "(output.chaos)")
    if sim.variational is not None:
        try:
            sim.variational.restore(state.chaos)
        except ValueError as err:
            raise CheckpointError(str(err)) from None


def restore_work(work: Any, state: SimState) -> bool:
    """Write ``state``'s integrator work into ``work`` (a scheme's freshly made work, in place);
    False when it does not fit (another scheme, settings or number of bodies)."""
    arrays = iter(state.work)
    try:
        _restore(work, json.loads(state.work_layout), arrays)
    except (CheckpointError, StopIteration):
        return False
    return next(arrays, None) is None


def _restore(obj: Any, layout: Any, arrays: Any, run_constants: tuple[int, ...] = ()) -> None:
    """Write ``arrays`` back into ``obj`` following ``layout``; top-level items whose index is in
    ``run_constants`` are constants of the run, not of the checkpoint, and are not compared."""
    if obj is None:  # a part of the work the run does not use: an empty array in the checkpoint (_flatten)
        if layout == "a" and next(arrays).size == 0:
            return
        raise CheckpointError("checkpoint work layout does not fit this integrator")
    if layout == "a":
        saved = next(arrays)
        if not isinstance(obj, np.ndarray) or obj.shape != saved.shape or obj.dtype != saved.dtype:
            raise CheckpointError("checkpoint work arrays do not fit this integrator (shape or type differs)")
        obj[...] = saved
    elif layout == "s":
        if not np.array_equal(np.asarray(obj), next(arrays)):
            raise CheckpointError("checkpoint was written with other integrator settings (a constant differs)")
    elif isinstance(layout, list) and isinstance(obj, tuple | list) and len(items := _saved_items(obj)) == len(layout):
        # fields that hold settings the run's code was compiled for: compared, never overwritten
        compared = getattr(type(obj), "CHECKPOINT_COMPARED", ())
        for index, ((name, item), sub) in enumerate(zip(items, layout, strict=True)):
            if index in run_constants and sub == "s":
                next(arrays)
            elif name in compared:
                if not np.array_equal(item, next(arrays)):
                    raise CheckpointError(f"checkpoint was written with other integrator settings ({name} differs)")
            else:
                _restore(item, sub, arrays)
    else:
        raise CheckpointError("checkpoint work layout does not fit this integrator")
