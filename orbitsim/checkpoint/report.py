"""What ``orbitsim info`` says about checkpoints: where a run stands and whether it can continue."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

from orbitsim.checkpoint.plan import read_trace_state, resolve_output
from orbitsim.io.checkpoint import (
    Checkpoint,
    CheckpointError,
    check_journal,
    checkpoint_path,
    journal_is_locked,
    journal_path,
    read_checkpoint,
)

__all__ = ["checkpoint_file_lines", "history_lines", "is_checkpoint_request", "trace_checkpoint_lines"]


def is_checkpoint_request(path: str | os.PathLike) -> bool:
    """Whether ``info PATH`` is about a checkpoint: a ``.ckpt``/``.journal`` file, or an output
    path with no trace yet but a checkpoint beside it (a killed run)."""
    text = os.fspath(path)
    if text.endswith((".ckpt", ".journal")):
        return True
    return not Path(text).exists() and checkpoint_path(text).exists()


def checkpoint_file_lines(path: str | os.PathLike) -> list[str]:
    """The report on ``<OUT>.ckpt`` (given ``OUT`` or one of its side files).

    Raises
    ------
    CheckpointError
        If the checkpoint is missing, foreign or damaged.
    """
    output = resolve_output(path)
    ckpt = read_checkpoint(checkpoint_path(output))
    journal = journal_path(output)
    size = journal.stat().st_size if journal.exists() else 0
    rows = [
        ("scenario_name", ckpt.scenario_name),
        ("integrator", ckpt.integrator),
        ("scenario_sha256", ckpt.scenario_sha256),
        ("steps_done", f"{ckpt.steps_done} of {ckpt.steps_requested}"),
        ("samples", f"{ckpt.samples_written} in {journal} ({ckpt.journal_bytes:,} of {size:,} bytes valid)"),
        ("last_sample", "none" if ckpt.last_sample_step < 0 else
         f"step {ckpt.last_sample_step}, t = {ckpt.last_sample_time:.10g}"),
        ("written", f"{ckpt.written_at} by {ckpt.writer}"),
        ("resumes", str(ckpt.resumes)),
        ("resumable", _file_verdict(output, ckpt)),
    ]
    return [f"checkpoint: {checkpoint_path(output)}", *(f"  {key:<20} {value}" for key, value in rows),
            *history_lines(ckpt.history)]


def history_lines(history: Any) -> list[str]:
    """The ``history:`` section: each scheme or dt change ``run --from`` made (orbitsim.checkpoint.switch)."""
    if not isinstance(history, str) or not history:
        return []
    try:
        changes = json.loads(history)
        lines = [f"  step {c['step']} (t = {c['time']:.10g}): {_scheme(c['from'])} -> {_scheme(c['to'])}"
                 for c in changes]
    except (ValueError, TypeError, KeyError):
        return [f"history:  unreadable integrator_history attribute: {history[:100]}"]
    return [f"history:  {len(lines)} change{'s' if len(lines) != 1 else ''} of scheme or dt (run --from)", *lines]


def _scheme(side: dict[str, Any]) -> str:
    return f"{side['integrator']} (dt = {side['dt']:.10g})"


def _file_verdict(output: Path, ckpt: Checkpoint) -> str:
    if journal_is_locked(journal_path(output)):
        return f"not now: the run is in progress ({ckpt.writer})"
    try:
        check_journal(journal_path(output), ckpt.journal_bytes, ckpt.journal_crc32)
    except CheckpointError as err:
        return f"no: {err}"
    if output.exists():
        try:
            trace = read_trace_state(output)
        except (ValueError, OSError):
            trace = None
        if (trace is not None and trace.attrs.get("status") == "complete" and trace.checkpoint is not None
                and trace.attrs.get("scenario_sha256") == ckpt.scenario_sha256
                and trace.checkpoint.steps_done >= ckpt.steps_done):
            return f"no: stale ({output} is the complete trace); `orbitsim resume {output}` removes it"
    return f"yes: orbitsim resume {output}"


def trace_checkpoint_lines(path: str | os.PathLike, attrs: dict[str, Any]) -> list[str]:
    """The ``checkpoint:`` section of ``info`` on a trace: its final state and what can follow."""
    path = Path(path)
    try:
        state = read_trace_state(path)
    except (ValueError, OSError) as err:
        return ["checkpoint:", f"  {'state':<20} unreadable ({err})"]
    ckpt = state.checkpoint
    lines = ["checkpoint:"]
    if ckpt is not None:
        lines.append(f"  {'state':<20} step {ckpt.steps_done} of {attrs.get('steps_requested', '?')}, "
                     f"with the first {ckpt.samples_written} samples")
    else:
        lines.append(f"  {'state':<20} none")
    lines.append(f"  {'resumable':<20} {_trace_verdict(path, attrs.get('status'), ckpt)}")
    if not os.fspath(path).endswith(".tmp") and checkpoint_path(path).exists():
        try:
            pending = read_checkpoint(checkpoint_path(path))
            note = f"step {pending.steps_done} of {pending.steps_requested} (`orbitsim info {checkpoint_path(path)}`)"
        except CheckpointError as err:
            note = str(err)
        lines.append(f"  {'pending':<20} {checkpoint_path(path)}: {note}")
    return lines


def _trace_verdict(path: Path, status: Any, ckpt: Checkpoint | None) -> str:
    if status == "complete":
        if ckpt is None:
            return "no: complete, without a final state to extend from"
        return f"no: complete; extend it with `orbitsim run --from {path} --steps N`"
    if status == "halted":
        return "no: the run halted at an event its events: section asked to halt on"
    if status == "diverged":
        return "no: the run diverged"
    if status == "running":
        return "no: the partial trace of a run in progress, or killed (only a checkpoint can resume that)"
    if ckpt is None:
        return "no: the trace holds no checkpoint state"
    return f"yes: orbitsim resume {path}"
