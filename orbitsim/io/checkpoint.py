"""Checkpoint files (``orbitsim.checkpoint``, version 1) and the sample journal beside them.

Why not checkpoint the HDF5 trace itself
----------------------------------------
HDF5 changes a file in place: appending samples rewrites dataset headers, chunk-index nodes and
the partly filled last chunk (whose old copy's space may be reused), and h5py writes that
metadata whenever its cache decides. A SIGKILL during an append can therefore leave a file that
does not open, or, worse, one whose *earlier* samples silently changed. No flush discipline makes
that impossible (measured: of 30 SIGKILLs of an appending writer that flushed and fsynced before
each checkpoint, 19 left checkpointed rows unreadable or changed; ``docs/checkpoints.md``), so a
checkpointed run keeps its samples out of HDF5 until it ends:

* ``<OUT>.journal``: the samples as fixed-size little-endian records (:func:`journal_dtype`),
  only ever appended. Bytes that were fsynced before a checkpoint was published are never
  touched again, so the prefix a checkpoint names survives any kill; on resume the file is
  truncated back to that prefix (the samples after it are recomputed, bit for bit).
* ``<OUT>.ckpt``: a small HDF5 file with the complete state (:class:`Checkpoint`), written to
  ``<OUT>.ckpt.tmp``, fsynced and renamed over the old one (``os.replace`` is atomic), so at any
  instant ``<OUT>.ckpt`` is the previous checkpoint or the new one, never a mixture. It names the
  journal's valid length and the CRC-32 of that prefix, and carries a SHA-256 of its own state
  arrays: a damaged journal or checkpoint is reported, never resumed from.

When the run ends the journal is converted into the usual trace (``orbitsim.io.trace``), whose
``checkpoint`` group holds the final state in the same layout, so a finished or interrupted trace
can be extended or resumed without the side files, which are then deleted.

Layout of a checkpoint (the root of ``<OUT>.ckpt``, or the trace's ``checkpoint`` group)
-----------------------------------------------------------------------------------------
Datasets ``pos``, ``vel``, ``acc`` (3, N): the simulation's arrays as it holds them (``acc`` is
state for first-same-as-last schemes, so it is saved, not recomputed); ``work/0000``, ... every
array of the integrator's ``work`` (scratch included, so any scheme that keeps state between
steps, e.g. ``wisdom_holman``'s mapping coordinates, continues exactly), flattened in order, with
the nesting in the ``work_layout`` attribute; ``events/*`` for a run with events and ``chaos/*``
(the tangent vector and MEGNO's sums) for a run with ``output.chaos``. Attributes: see
:data:`_COUNTERS` and :class:`Checkpoint`.

The journal's code is in :mod:`orbitsim.io.journal`; its names are re-exported here.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import socket
import time
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from orbitsim._version import __version__
from orbitsim.io.durable import replace_durably
from orbitsim.io.h5safe import in_memory, io_failure, write_image
from orbitsim.io.journal import (
    Journal,
    as_chunk,
    check_journal,
    journal_dtype,
    journal_is_locked,
    journal_path,
)
from orbitsim.io.schema import CheckpointError
from orbitsim.io.stored_scenario import read_scenario_bodies, write_scenario_bodies

__all__ = [
    "CHECKPOINT_FORMAT",
    "CHECKPOINT_VERSION",
    "Checkpoint",
    "CheckpointError",
    "Journal",
    "SimState",
    "as_chunk",
    "check_journal",
    "checkpoint_path",
    "journal_dtype",
    "journal_is_locked",
    "journal_path",
    "layout_json",
    "read_checkpoint",
    "read_checkpoint_group",
    "state_arrays",
    "write_checkpoint",
    "write_checkpoint_group",
]

CHECKPOINT_FORMAT = "orbitsim.checkpoint"
CHECKPOINT_VERSION = 1
#: Integer attributes of a checkpoint, beside the state arrays.
_COUNTERS = ("steps_done", "steps_requested", "samples_written", "last_sample_step", "journal_bytes",
             "journal_crc32", "resumes")


def checkpoint_path(output: str | os.PathLike) -> Path:
    """``<OUT>.ckpt``: the checkpoint of the run writing ``OUT``."""
    return Path(f"{os.fspath(output)}.ckpt")


@dataclasses.dataclass(frozen=True, eq=False)
class SimState:
    """The arrays a simulation continues from: (3, N) ``pos``, ``vel``, ``acc``, the flattened
    ``work`` arrays with their nesting (JSON, see :func:`orbitsim.checkpoint.capture_state`), and,
    for a run with events, the ``events`` arrays of its watcher by name (the bodies left, the open
    encounters, the energy offset, the log: :meth:`orbitsim.events.driver.Watcher.arrays`)."""

    steps_done: int
    pos: np.ndarray
    vel: np.ndarray
    acc: np.ndarray
    work: tuple[np.ndarray, ...]
    work_layout: str
    events: dict[str, np.ndarray] = dataclasses.field(default_factory=dict)
    #: A run with ``output.chaos``: its variational state by name (the tangent vector and MEGNO's sums,
    #: :meth:`orbitsim.chaos.state.VariationalState.arrays`); empty otherwise.
    chaos: dict[str, np.ndarray] = dataclasses.field(default_factory=dict)

    def digest(self) -> str:
        """SHA-256 over the step count, the layout and every array's dtype, shape and bytes."""
        h = hashlib.sha256(f"{self.steps_done}|{self.work_layout}".encode())
        named = [(name, self.events[name]) for name in sorted(self.events)]
        for arr in (self.pos, self.vel, self.acc, *self.work):
            h.update(f"{arr.dtype.str}{arr.shape}".encode())
            h.update(np.ascontiguousarray(arr).tobytes())
        for name, arr in named:  # absent for a run without events: its digest is unchanged
            h.update(f"{name}{arr.dtype.str}{arr.shape}".encode())
            h.update(np.ascontiguousarray(arr).tobytes())
        for name in sorted(self.chaos):  # absent for a run without output.chaos: its digest is unchanged
            arr = self.chaos[name]
            h.update(f"chaos/{name}{arr.dtype.str}{arr.shape}".encode())
            h.update(np.ascontiguousarray(arr).tobytes())
        return h.hexdigest()


@dataclasses.dataclass(frozen=True, eq=False)
class Checkpoint:
    """A state plus where the run stood: samples written, the journal prefix, the scenario.

    ``last_sample_step`` is -1 before the first sample; the run continues with the planned
    sample steps after it. ``scenario`` (resolved YAML; for a large scenario without its bodies,
    which are ``scenario_bodies``) is empty in a trace's group, whose root holds it. ``E0``,
    ``max_abs_energy_error``, ``last_sample_time`` and ``wall_time_s`` only let a resumed run
    report the same summary as an uninterrupted one; ``written_at`` and ``writer`` (pid and host)
    are filled in when a checkpoint is read.
    """

    state: SimState
    steps_requested: int
    samples_written: int
    last_sample_step: int
    integrator: str
    scenario_sha256: str
    scenario: str = ""
    # A large scenario's per-body rows, stored beside its text (orbitsim.io.stored_scenario); None when
    # the text is whole.
    scenario_bodies: dict[str, np.ndarray] | None = None
    scenario_name: str = ""
    scenario_source: str = ""
    journal_bytes: int = 0
    journal_crc32: int = 0
    resumes: int = 0
    force: bool = False
    E0: float = float("nan")
    energy_scale: float = float("nan")
    max_abs_energy_error: float = float("nan")
    last_sample_time: float = float("nan")
    wall_time_s: float = 0.0
    # Time of step 0 (a sample at step n is at t0 + n * dt) and the JSON list of scheme or dt
    # changes made by `run --from` (orbitsim.checkpoint.switch): a run that changed its dt
    # keeps counting steps, so its clock needs both to continue, resumed or extended.
    t0: float = 0.0
    history: str = ""
    written_at: str = ""
    writer: str = ""

    @property
    def steps_done(self) -> int:
        """Steps integrated at this checkpoint."""
        return self.state.steps_done


def state_arrays(state: SimState) -> dict[str, np.ndarray]:
    """The datasets of a checkpoint, by name (``work/0000``, ... for the work arrays)."""
    arrays = {"pos": state.pos, "vel": state.vel, "acc": state.acc}
    arrays.update({f"work/{i:04d}": arr for i, arr in enumerate(state.work)})
    arrays.update({f"events/{name}": arr for name, arr in state.events.items()})
    arrays.update({f"chaos/{name}": arr for name, arr in state.chaos.items()})
    return arrays


def write_checkpoint_group(group: h5py.Group, ckpt: Checkpoint) -> None:
    """Write ``ckpt`` into an empty HDF5 group (or a file's root)."""
    for name, arr in state_arrays(ckpt.state).items():
        group.create_dataset(name, data=arr)
    if not ckpt.state.work:
        group.create_group("work")
    attrs = {name: int(getattr(ckpt, name)) for name in _COUNTERS}
    attrs.update(
        integrator=ckpt.integrator, scenario_sha256=ckpt.scenario_sha256, scenario_name=ckpt.scenario_name,
        scenario_source=ckpt.scenario_source, work_layout=ckpt.state.work_layout,
        state_sha256=ckpt.state.digest(), force=bool(ckpt.force), E0=float(ckpt.E0),
        energy_scale=float(ckpt.energy_scale),
        max_abs_energy_error=float(ckpt.max_abs_energy_error), last_sample_time=float(ckpt.last_sample_time),
        wall_time_s=float(ckpt.wall_time_s), written_at=time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        writer_pid=os.getpid(), writer_host=socket.gethostname(), orbitsim_version=__version__)
    if ckpt.scenario:
        attrs["scenario"] = ckpt.scenario
        if ckpt.scenario_bodies is not None:
            write_scenario_bodies(group, ckpt.scenario_bodies)
    if ckpt.t0 != 0.0 or ckpt.history:  # absent in every run that never switched: old files read the same
        attrs.update(t0=float(ckpt.t0), history=ckpt.history)
    for key, value in attrs.items():
        group.attrs[key] = value


def read_checkpoint_group(group: h5py.Group, where: str, scenario: str = "",
                          scenario_bodies: dict[str, np.ndarray] | None = None) -> Checkpoint:
    """Read a checkpoint written by :func:`write_checkpoint_group`; verify its state digest.

    ``scenario`` and ``scenario_bodies`` stand in for a trace's group, whose root holds them.

    Raises
    ------
    CheckpointError
        If a field is missing or malformed, or the arrays do not match their digest.
    """
    try:
        attrs = {k: (v.decode() if isinstance(v, bytes) else v) for k, v in group.attrs.items()}
        work_group = group["work"]
        work = tuple(work_group[name][()] for name in sorted(work_group))
        events: dict[str, np.ndarray] = {}
        if "events" in group:
            group["events"].visititems(
                lambda name, obj: events.__setitem__(name, obj[()]) if isinstance(obj, h5py.Dataset) else None)
        chaos = {name: group["chaos"][name][()] for name in group["chaos"]} if "chaos" in group else {}
        state = SimState(steps_done=int(attrs["steps_done"]), pos=group["pos"][()], vel=group["vel"][()],
                         acc=group["acc"][()], work=work, work_layout=str(attrs["work_layout"]), events=events,
                         chaos=chaos)
        counters = {name: int(attrs[name]) for name in _COUNTERS if name != "steps_done"}
        ckpt = Checkpoint(
            state=state, integrator=str(attrs["integrator"]), scenario_sha256=str(attrs["scenario_sha256"]),
            scenario=str(attrs.get("scenario", scenario)),
            scenario_bodies=read_scenario_bodies(group) if "scenario" in attrs else scenario_bodies,
            scenario_name=str(attrs.get("scenario_name", "")),
            scenario_source=str(attrs.get("scenario_source", "")),
            force=bool(attrs["force"]), E0=float(attrs["E0"]), energy_scale=float(attrs.get("energy_scale", np.nan)),
            max_abs_energy_error=float(attrs["max_abs_energy_error"]),
            last_sample_time=float(attrs["last_sample_time"]), wall_time_s=float(attrs["wall_time_s"]),
            t0=float(attrs.get("t0", 0.0)), history=str(attrs.get("history", "")),
            written_at=str(attrs.get("written_at", "")),
            writer=f"pid {attrs.get('writer_pid', '?')} on {attrs.get('writer_host', '?')}", **counters)
        expected = str(attrs["state_sha256"])
    except (KeyError, ValueError, TypeError, OSError) as err:
        raise CheckpointError(f"{where}: damaged checkpoint ({type(err).__name__}: {err})") from None
    if state.digest() != expected:
        raise CheckpointError(f"{where}: damaged checkpoint (its state does not match its SHA-256)")
    return ckpt


def write_checkpoint(path: str | os.PathLike, ckpt: Checkpoint) -> None:
    """Publish ``ckpt`` at ``path`` atomically: write ``<path>.tmp``, fsync, rename, fsync the directory.

    A kill at any instant leaves either the previous file or this one at ``path``; an I/O error
    removes ``<path>.tmp`` and raises :class:`~orbitsim.io.schema.OutputWriteError`, the previous file
    untouched.
    """
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    with in_memory() as f:  # built in memory, so that only plain writes can meet a full disk
        f.attrs["format"] = CHECKPOINT_FORMAT
        f.attrs["format_version"] = CHECKPOINT_VERSION
        write_checkpoint_group(f, ckpt)
        try:
            write_image(f, tmp)
        except OSError as err:
            raise io_failure(err, f"{path}: {{reason}}", tmp) from None
    try:
        replace_durably(tmp, path)
    except OSError as err:  # the previous checkpoint, if any, is still whole at ``path``
        tmp.unlink(missing_ok=True)
        raise io_failure(err, f"{path}: {{reason}}", tmp) from None


def read_checkpoint(path: str | os.PathLike) -> Checkpoint:
    """Read and verify a checkpoint file.

    Raises
    ------
    CheckpointError
        If the file is missing, not an orbitsim checkpoint, of another version, or damaged.
    """
    where = os.fspath(path)
    if not os.path.isfile(where):
        raise CheckpointError(f"{where}: no such checkpoint file")
    try:
        with h5py.File(where, "r") as f:
            fmt = f.attrs.get("format")
            fmt = fmt.decode() if isinstance(fmt, bytes) else fmt
            if fmt != CHECKPOINT_FORMAT:
                raise CheckpointError(f"{where}: not an orbitsim checkpoint (format {fmt!r})")
            version = f.attrs.get("format_version")
            if version != CHECKPOINT_VERSION:
                raise CheckpointError(f"{where}: unsupported checkpoint format_version {version!r} "
                                      f"(supported: {CHECKPOINT_VERSION})")
            return read_checkpoint_group(f, where)
    except OSError as err:
        raise CheckpointError(f"{where}: damaged or unreadable checkpoint ({err})") from None


def layout_json(layout: Any) -> str:
    """Canonical JSON for a work layout (see :func:`orbitsim.checkpoint.capture_state`)."""
    return json.dumps(layout, separators=(",", ":"))
