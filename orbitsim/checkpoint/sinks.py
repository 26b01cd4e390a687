"""Where a run's samples go: straight into the trace, or into a journal with checkpoints beside it."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from orbitsim.io.checkpoint import (
    Checkpoint,
    CheckpointError,
    Journal,
    as_chunk,
    checkpoint_path,
    journal_dtype,
    journal_is_locked,
    journal_path,
    write_checkpoint,
    write_checkpoint_group,
)
from orbitsim.io.h5safe import in_memory
from orbitsim.io.schema import ELEMENTS, OutputError
from orbitsim.io.trace import TraceWriter, open_trace

if TYPE_CHECKING:
    from orbitsim.events.log import RunEvents
    from orbitsim.io.trace import TraceWriter
    from orbitsim.scenario import Scenario

__all__ = ["JournalSink", "RunStart", "StreamSink", "check_side_files", "copy_samples", "open_sink",
           "remove_side_files"]

#: Per-sample datasets copied from a trace into a new run (``energy`` is recomputed as T + U, the
#: same bits; ``energy_error`` is derived by the writer).
_COPIED = ("time", "step", "kinetic", "potential", "momentum", "angular_momentum")
_COPY_BLOCK_BYTES = 8 * 2**20


@dataclasses.dataclass
class RunStart:
    """Where a resumed or extended run starts: a checkpoint, and where its samples so far are.

    Exactly one of ``journal`` (a killed checkpointed run: continue its journal, already checked
    and cut back to the checkpoint) and ``source_trace`` (copy the first
    ``checkpoint.samples_written`` samples of that trace) is set. ``overwrite`` says whether the
    trace may replace a file at the output path.
    """

    checkpoint: Checkpoint
    journal: Journal | None = None
    source_trace: Path | None = None
    overwrite: bool = True
    resumes: int = 0
    # `run --from` with another integrator or dt: the state is the inertial pos and vel only, and
    # the new scheme builds its own work and accelerations from them (orbitsim.checkpoint.switch).
    rebuild: bool = False


class StreamSink:
    """Samples go straight into the HDF5 trace; no periodic checkpoints (the historic path)."""

    periodic = False

    def __init__(self, writer: TraceWriter) -> None:
        self.writer = writer
        self.record_positions = writer.record_positions
        self.series = writer.series

    @property
    def samples_written(self) -> int:
        """Samples appended so far."""
        return self.writer.samples_written

    def append(self, chunk: Any) -> None:
        """Append a chunk of samples."""
        self.writer.append(chunk)

    def set_attrs(self, **kw: Any) -> None:
        """Root attributes of the trace."""
        self.writer.set_attrs(**kw)

    def checkpoint(self, ckpt: Checkpoint) -> None:
        """Nothing to do: without ``output.checkpoint`` only the final state is kept."""

    def close(self, status: str, *, steps_done: int, wall_time_s: float, message: str,
              final: Checkpoint | None, events: RunEvents | None = None) -> Path:
        """Write the final state (when given) as the ``checkpoint`` group, the events and the
        bodies' fates (a run with events), and finish the trace."""
        if final is not None:
            add_checkpoint_group(self.writer, final)
        if events is not None:
            add_events(self.writer, events)
        return self.writer.close(status, steps_done=steps_done, wall_time_s=wall_time_s, message=message)

    def abort(self) -> None:
        """Leave nothing behind."""
        self.writer.abort()


class JournalSink:
    """Samples go to ``<OUT>.journal``, checkpoints to ``<OUT>.ckpt``; the trace is built at the end."""

    periodic = True

    def __init__(self, output: Path, journal: Journal, trace_args: dict[str, Any], overwrite: bool) -> None:
        self.output, self.journal = output, journal
        self.trace_args, self.overwrite = trace_args, overwrite
        self.record_positions = bool(trace_args["record_positions"])
        self.series = dict(trace_args["extra_series"])
        self.published: Checkpoint | None = None

    @property
    def samples_written(self) -> int:
        """Samples in the journal."""
        return self.journal.records

    def append(self, chunk: Any) -> None:
        """Append a chunk of samples to the journal (not yet durable: see :meth:`checkpoint`)."""
        self.journal.append(chunk)

    def set_attrs(self, **kw: Any) -> None:
        """Root attributes for the trace built at the end."""
        self.trace_args["attrs"].update(kw)

    def checkpoint(self, ckpt: Checkpoint) -> None:
        """Make the journal durable, then publish ``ckpt`` naming its length and CRC-32, atomically."""
        if ckpt.samples_written != self.journal.records:
            raise RuntimeError(f"checkpoint at {ckpt.samples_written} samples, journal holds {self.journal.records}")
        self.journal.sync()
        ckpt = dataclasses.replace(ckpt, journal_bytes=self.journal.bytes, journal_crc32=self.journal.crc32)
        write_checkpoint(checkpoint_path(self.output), ckpt)
        self.published = ckpt

    def close(self, status: str, *, steps_done: int, wall_time_s: float, message: str,
              final: Checkpoint | None, events: RunEvents | None = None) -> Path:
        """Publish the final state, build the trace from the journal, then remove the side files.

        A kill while the trace is built leaves the final checkpoint, so ``orbitsim resume``
        only rebuilds it. The final state is re-published only when it matches the journal
        (after an unsafe stop the runner passes the last published checkpoint instead).
        """
        if final is not None and final.samples_written == self.journal.records and final is not self.published:
            self.checkpoint(final)
        writer = TraceWriter(self.output, overwrite=self.overwrite, **self.trace_args)
        try:
            for chunk in self.journal.chunks():
                writer.append(chunk)
            if final is not None:
                add_checkpoint_group(writer, final)
            if events is not None:
                add_events(writer, events)
            path = writer.close(status, steps_done=steps_done, wall_time_s=wall_time_s, message=message)
        except BaseException:
            writer.abort()
            raise
        remove_side_files(self.output, self.journal)
        return path

    def abort(self) -> None:
        """Leave nothing behind (an error before the first sample)."""
        remove_side_files(self.output, self.journal)


def add_events(writer: TraceWriter, events: RunEvents) -> None:
    """The trace's ``events`` table and the bodies' fates in ``bodies`` (docs/trace.md)."""
    names = writer.names
    writer.add_arrays("events", events.table(names))
    writer.add_arrays("bodies", events.fates)


def scenario_series(scenario: Scenario) -> tuple[dict[str, tuple[int, ...]], dict[str, dict[str, Any]]]:
    """The per-sample series a scenario's trace holds beyond the standard ones, with their shapes,
    and the attributes of their groups: ``energy_offset`` with events, ``elements/*`` with
    ``output.elements`` (group attribute ``primary``), ``megno`` and ``mlce`` with ``output.chaos``."""
    series: dict[str, tuple[int, ...]] = {}
    groups: dict[str, dict[str, Any]] = {}
    if scenario.events is not None:
        series["energy_offset"] = ()
    if scenario.record_elements:
        series.update({f"elements/{name}": (scenario.n_bodies,) for name in ELEMENTS})
        groups["elements"] = {"primary": scenario.elements_primary}
    if getattr(scenario, "chaos", None) is not None:  # output.chaos: MEGNO and the mLCE at every sample
        series.update({"megno": (), "mlce": ()})
    return series, groups


def add_checkpoint_group(writer: TraceWriter, ckpt: Checkpoint) -> None:
    """Give the trace its ``checkpoint`` group: built in memory, copied in by the writer (see
    :mod:`orbitsim.io.h5safe`). The scenario is in the trace's root (its attributes, and a large one's
    ``scenario_bodies``), and there is no journal."""
    with in_memory() as memory:
        group = memory.create_group("checkpoint")
        write_checkpoint_group(group, dataclasses.replace(ckpt, scenario="", scenario_bodies=None, journal_bytes=0,
                                                          journal_crc32=0))
        writer.copy_group("checkpoint", group)


def check_side_files(output: Path, force: bool) -> None:
    """Refuse to start over a resumable run's checkpoint unless forced, and never under a live run.

    Raises
    ------
    orbitsim.io.schema.OutputError
    """
    if journal_is_locked(journal_path(output)):
        raise OutputError(f"{output}: another orbitsim process is writing this output right now")
    if checkpoint_path(output).exists() and not force:
        raise OutputError(f"{output}: a resumable run of this output was checkpointed in {checkpoint_path(output)}; "
                          f"continue it with `orbitsim resume {output}`, or use --force to start over")


def remove_side_files(output: Path, journal: Journal | None = None) -> None:
    """Delete ``<OUT>.ckpt`` (first: a checkpoint without its journal is useless) and ``<OUT>.journal``.

    Only files that exist are unlinked: on a read-only filesystem, unlinking a missing file fails
    with EROFS rather than ENOENT, and a run that never asked for checkpoints must not fail on them.
    """
    for side in (checkpoint_path(output), Path(f"{checkpoint_path(output)}.tmp")):
        if side.exists():
            side.unlink()
    if journal is not None:
        journal.close(delete=True)
    elif journal_path(output).exists():
        journal_path(output).unlink()


def open_sink(scenario: Scenario, output: Path, attrs: dict[str, Any], *, overwrite: bool,
              start: RunStart | None) -> StreamSink | JournalSink:
    """Where a run's samples go: a journal when it checkpoints (or continues a journal), else the trace.

    Samples a resumed or extended run starts with are copied in from ``start.source_trace``.
    """
    series, groups = scenario_series(scenario)
    trace_args: dict[str, Any] = {"attrs": attrs, "names": list(scenario.names), "masses": scenario.masses,
                                  "n_bodies": scenario.n_bodies, "record_positions": bool(scenario.record_positions),
                                  "extra_series": series, "group_attrs": groups,
                                  "scenario_bodies": scenario.stored_form()[1]}
    sink: StreamSink | JournalSink
    if start is not None and start.journal is not None:
        return JournalSink(output, start.journal, trace_args, overwrite)
    if scenario.checkpoints:
        dtype = journal_dtype(scenario.n_bodies, bool(scenario.record_positions), series)
        sink = JournalSink(output, Journal(journal_path(output), dtype), trace_args, overwrite)
    else:
        sink = StreamSink(TraceWriter(output, overwrite=overwrite, **trace_args))
    if start is not None and start.source_trace is not None:
        try:
            copy_samples(start.source_trace, start.checkpoint.samples_written, sink)
        except BaseException:
            sink.abort()
            raise
    return sink


def copy_samples(path: Path, count: int, sink: Any) -> None:
    """Append the first ``count`` samples of the trace at ``path`` to ``sink``, block by block."""
    with open_trace(path) as f:
        try:
            have = int(f["time"].shape[0])
            if have < count:
                raise CheckpointError(f"{path}: damaged trace ({have} samples, its checkpoint needs {count})")
            names = _COPIED + (("positions", "velocities") if sink.record_positions else ()) + tuple(sink.series)
            row_bytes = sum(8 * int(np.prod(f[name].shape[1:])) for name in names)
            block = max(1, _COPY_BLOCK_BYTES // row_bytes)
            for start in range(0, count, block):
                stop = min(count, start + block)
                sink.append(as_chunk({name: f[name][start:stop] for name in names}))
        except (KeyError, OSError) as err:
            raise CheckpointError(f"{path}: damaged trace ({err})") from None
