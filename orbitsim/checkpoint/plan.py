"""Deciding how a run continues: ``orbitsim resume`` and ``orbitsim run --from``.

Where a run's state can be found, newest first:

1. ``<OUT>.ckpt`` with ``<OUT>.journal``: a checkpointed run that was killed (or is running:
   the journal's lock says so). Unless ``<OUT>`` is this run's complete trace, already renamed
   into place when the kill came, in which case the side files are stale and removed.
2. ``<OUT>`` with status ``interrupted`` and a ``checkpoint`` group: a run stopped by Ctrl-C,
   SIGTERM or ``stop()``; the group names how many of its samples go with the state.
3. ``<OUT>`` with status ``complete`` and a ``checkpoint`` group: nothing to resume; ``run --from``
   extends it.

Resuming always continues the scenario stored with the state. A scenario or integrator given
on top must be the same, or the request is refused with a one-line :class:`CheckpointError`:
another scheme's state cannot be restored, and another scenario would not be the same run.
``run --from`` may continue a complete run with another integrator or dt; the new scheme then
starts afresh from the final state (:mod:`orbitsim.checkpoint.switch`).
"""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path
from typing import TYPE_CHECKING, Any

from orbitsim.checkpoint.sinks import RunStart, check_side_files, remove_side_files, scenario_series
from orbitsim.io.checkpoint import (
    Checkpoint,
    CheckpointError,
    Journal,
    checkpoint_path,
    journal_dtype,
    journal_path,
    read_checkpoint,
    read_checkpoint_group,
)
from orbitsim.io.lock import describe_holder, hold_output, rerun_command
from orbitsim.io.schema import OutputError
from orbitsim.io.stored_scenario import read_scenario_bodies
from orbitsim.io.trace import TraceError, open_trace

if TYPE_CHECKING:
    from orbitsim.io.lock import OutputLock
    from orbitsim.scenario import Scenario

__all__ = ["Continuation", "TraceState", "prepare_extension", "prepare_resume", "read_trace_state",
           "resolve_output", "scenario_differences"]

#: Suffixes of the files beside an output path; ``resume`` accepts any of them for the output.
SIDE_SUFFIXES = (".ckpt.tmp", ".ckpt", ".journal", ".lock", ".tmp")


@dataclasses.dataclass
class Continuation:
    """What to run next: ``scenario`` from ``start`` into ``output``; ``start`` None means nothing
    (``note`` says why, e.g. the run is already complete)."""

    output: Path
    scenario: Scenario | None = None
    start: RunStart | None = None
    note: str = ""


@dataclasses.dataclass
class TraceState:
    """A trace's root attributes, sample count and final state (None when it has none); a large
    scenario's bodies, stored beside its ``scenario`` text (None when the text is whole)."""

    attrs: dict[str, Any]
    n_samples: int
    checkpoint: Checkpoint | None
    scenario_bodies: dict[str, Any] | None = None

    def stored_scenario(self, where: Path, sha256: str | None = None, source: str = "") -> Scenario:
        """The scenario the trace stores (see :func:`stored_scenario`); ``sha256`` defaults to the trace's."""
        text = str(self.attrs.get("scenario", ""))
        return stored_scenario(text, str(self.attrs.get("scenario_sha256", "")) if sha256 is None else sha256, where,
                               source, self.scenario_bodies)


def resolve_output(path: str | os.PathLike) -> Path:
    """The output path of a run, given it or one of its side files (``.tmp``, ``.ckpt``, ``.journal``)."""
    text = os.fspath(path)
    for suffix in SIDE_SUFFIXES:
        if text.endswith(suffix) and len(text) > len(suffix):
            return Path(text[: -len(suffix)])
    return Path(text)


def read_trace_state(path: Path) -> TraceState:
    """Attributes, sample count and ``checkpoint`` group of a trace.

    Raises
    ------
    TraceError
        If the file is missing, foreign or damaged (:class:`CheckpointError` for its group).
    """
    with open_trace(path) as f:
        try:
            attrs = {k: (v.decode() if isinstance(v, bytes) else v.item() if hasattr(v, "item") else v)
                     for k, v in f.attrs.items()}
            n_samples = int(f["time"].shape[0])
            bodies = read_scenario_bodies(f)
            group = f.get("checkpoint")
            ckpt = None
            if group is not None:
                ckpt = read_checkpoint_group(group, f"{path} (checkpoint)", scenario=str(attrs.get("scenario", "")),
                                             scenario_bodies=bodies)
        except (KeyError, OSError) as err:
            raise TraceError(f"{path}: damaged trace ({err})") from None
    if ckpt is not None and (ckpt.samples_written > n_samples or ckpt.scenario_sha256 != attrs.get("scenario_sha256")):
        raise CheckpointError(f"{path}: damaged trace (its checkpoint does not fit its samples or scenario)")
    return TraceState(attrs=attrs, n_samples=n_samples, checkpoint=ckpt, scenario_bodies=bodies)


def stored_scenario(text: str, sha256: str, where: Path, source: str = "",
                    bodies: dict[str, Any] | None = None) -> Scenario:
    """The scenario a checkpoint or trace stores, checked against its SHA-256; ``source`` is where
    it first came from (kept in the continued trace's ``scenario_source``); ``bodies``, a large
    scenario's rows stored beside its text (:mod:`orbitsim.io.stored_scenario`)."""
    from orbitsim.scenario import ScenarioError  # noqa: PLC0415 -- lazy: loads yaml
    from orbitsim.scenario.loader import scenario_from_stored  # noqa: PLC0415 -- lazy: loads yaml

    label = f"{where} (stored scenario)"
    try:
        scenario = scenario_from_stored(text, bodies, source=label)
    except ScenarioError as err:
        raise CheckpointError(f"{where}: damaged stored scenario ({err})") from None
    if scenario.sha256 != sha256:
        raise CheckpointError(f"{where}: damaged stored scenario (it does not match its SHA-256)")
    return scenario.with_overrides(source=source) if source else scenario


def scenario_differences(a: Scenario, b: Scenario, ignore: tuple[str, ...] = ()) -> list[str]:
    """What differs between two scenarios, one short phrase per key (``dt: 0.01 vs 0.02``)."""
    da, db = a.to_dict(), b.to_dict()
    da.update({f"output.{k}": v for k, v in da.pop("output").items()})
    db.update({f"output.{k}": v for k, v in db.pop("output").items()})
    diffs = []
    for key in sorted(set(da) | set(db)):
        if key in ignore or da.get(key) == db.get(key):
            continue
        if key == "bodies":
            diffs.append(f"bodies differ ({len(da['bodies'])} vs {len(db['bodies'])} bodies)")
        else:
            diffs.append(f"{key}: {_short(da.get(key))} vs {_short(db.get(key))}")
    return diffs


def _short(value: Any) -> str:
    text = "(none)" if value is None else str(value)
    return text if len(text) <= 40 else text[:37] + "..."


def _check_same(stored: Scenario, where: Path, scenario: Scenario | None, integrator: str | None,
                ignore: tuple[str, ...] = ()) -> None:
    """Refuse another integrator or scenario than the stored one."""
    from orbitsim.integrators.registry import canonical_name  # noqa: PLC0415 -- lazy: loads numba

    if integrator is not None and canonical_name(integrator) != stored.integrator:
        raise CheckpointError(f"{where}: the run was made with integrator {stored.integrator}; it cannot continue "
                              f"with {canonical_name(integrator)} (a checkpoint holds one scheme's state). "
                              "Leave out --integrator, or start a new run")
    if scenario is not None:
        diffs = scenario_differences(stored, scenario, ignore)
        if diffs:
            raise CheckpointError(f"{where}: SCENARIO is not the scenario of this run ({'; '.join(diffs)}); it "
                                  "continues the scenario stored with it: leave SCENARIO out, or start a new run")


def prepare_resume(path: str | os.PathLike, *, scenario: Scenario | None = None,
                   integrator: str | None = None) -> Continuation:
    """How to continue the run writing ``path`` (or one of its side files).

    Parameters
    ----------
    path : path
        The run's output (``OUT``), or ``OUT.tmp``, ``OUT.ckpt``, ``OUT.journal``.
    scenario : Scenario, optional
        If given, it must be the run's scenario.
    integrator : str, optional
        If given, it must be the run's integrator.

    Returns
    -------
    Continuation
        With ``start`` None when there is nothing to continue (``note`` says why).

    Raises
    ------
    CheckpointError
        Nothing resumable, damaged or foreign files, a live writer, or a different
        scenario or integrator.
    """
    output = resolve_output(path)
    with hold_output(output) as lock:  # refuses while another process writes the output
        return _plan_resume(output, lock, scenario, integrator)


def _plan_resume(output: Path, lock: OutputLock, scenario: Scenario | None, integrator: str | None) -> Continuation:
    trace: TraceState | None = None
    foreign = ""
    if output.exists():
        try:
            trace = read_trace_state(output)
        except TraceError as err:
            if not checkpoint_path(output).exists():
                raise
            foreign = str(err)  # e.g. an unrelated file that a forced run will replace
    if checkpoint_path(output).exists():
        return _from_checkpoint_file(output, trace, foreign, scenario, integrator)
    if trace is None:
        lock.keep_previous()  # a second `resume` says the same
        raise CheckpointError(_nothing_to_resume(output, lock.previous))
    return _from_trace(output, trace, scenario, integrator)


def _nothing_to_resume(output: Path, previous: dict[str, Any] | None) -> str:
    """Why a run left nothing to resume, from the files it left and its lock's record of it."""
    command = rerun_command(previous)
    again = f"run it again: `{command}`" if command else "run it again"
    if journal_path(output).exists():
        return (f"{output}: the run was killed before its first checkpoint (it saves one before its first step, once "
                f"its kernels are compiled), so there is nothing to resume; {again}")
    if Path(f"{output}.tmp").exists():
        return (f"{output}: only {output}.tmp is left: a run without output.checkpoint was killed before it could "
                f"save its state, so it cannot be resumed; {again} (with output.checkpoint in its scenario, or "
                "--checkpoint-every, a long run can be resumed after a kill)")
    if previous is not None:
        return (f"{output}: the run ({describe_holder(previous)}) was killed before it wrote anything, so there is "
                f"nothing to resume; {again}")
    return f"{output}: no trace or checkpoint to resume (no run has written it)"


def _from_checkpoint_file(output: Path, trace: TraceState | None, foreign: str, scenario: Scenario | None,
                          integrator: str | None) -> Continuation:
    ckpt = read_checkpoint(checkpoint_path(output))
    same_run = trace is not None and trace.attrs.get("scenario_sha256") == ckpt.scenario_sha256
    if (same_run and trace.attrs.get("status") == "complete" and trace.checkpoint is not None
            and trace.checkpoint.steps_done >= ckpt.steps_done):
        _check_complete(output, trace, scenario, integrator)  # before the stale side files go
        check_side_files(output, force=True)  # refuses if a live process holds the journal
        remove_side_files(output)
        return Continuation(output, note=_complete_note(output, trace))
    stored = stored_scenario(ckpt.scenario, ckpt.scenario_sha256, checkpoint_path(output), ckpt.scenario_source,
                             ckpt.scenario_bodies)
    _check_same(stored, output, scenario, integrator)
    if output.exists() and not (same_run or ckpt.force):
        why = f" ({foreign})" if foreign else ""
        raise CheckpointError(f"{output}: exists and is not this run's trace{why}; move it away, then resume")

    series = scenario_series(stored)[0]
    journal = Journal(journal_path(output), journal_dtype(stored.n_bodies, bool(stored.record_positions), series),
                      keep_bytes=ckpt.journal_bytes, crc32=ckpt.journal_crc32)
    if journal.records != ckpt.samples_written:
        journal.close()
        raise CheckpointError(f"{output}: damaged checkpoint ({ckpt.samples_written} samples, journal holds "
                              f"{journal.records})")
    return Continuation(output, stored, RunStart(ckpt, journal=journal, overwrite=True, resumes=ckpt.resumes + 1))


def _complete_note(output: Path, trace: TraceState) -> str:
    steps = trace.attrs.get("steps_done")
    return (f"{output}: the run is already complete ({steps} steps); extend it with "
            f"`orbitsim run --from {output} --steps N`")


def _check_complete(output: Path, trace: TraceState, scenario: Scenario | None, integrator: str | None) -> None:
    """A complete run is left alone, but a SCENARIO or --integrator given is still checked: exit 0
    would tell the user that the file holds the run they named."""
    if scenario is None and integrator is None:
        return
    text = trace.attrs.get("scenario")
    if not text:
        raise CheckpointError(f"{output}: the trace stores no scenario to check SCENARIO or --integrator against "
                              "(written by an older orbitsim)")
    stored = trace.stored_scenario(output)
    _check_same(stored, output, scenario, integrator)


def _from_trace(output: Path, trace: TraceState, scenario: Scenario | None, integrator: str | None) -> Continuation:
    status = trace.attrs.get("status")
    if status == "complete":
        _check_complete(output, trace, scenario, integrator)
        return Continuation(output, note=_complete_note(output, trace))
    if status == "diverged":
        raise CheckpointError(f"{output}: the run diverged; there is no finite state to continue from")
    if status == "halted":
        raise CheckpointError(f"{output}: the run halted at an event, as its events: section asked "
                              f"({trace.attrs.get('message', '')}); there is nothing to resume")
    if status != "interrupted":
        raise CheckpointError(f"{output}: is a partial trace (status {status!r}), not a resumable run")
    if trace.checkpoint is None:
        raise CheckpointError(f"{output}: not resumable: the trace holds no checkpoint state (the run stopped before "
                              "its first step, or was written by an older orbitsim); run it again")
    stored = trace.stored_scenario(output, trace.checkpoint.scenario_sha256,
                                   str(trace.attrs.get("scenario_source", "")))
    _check_same(stored, output, scenario, integrator)
    check_side_files(output, force=True)
    start = RunStart(trace.checkpoint, source_trace=output, overwrite=True, resumes=trace.checkpoint.resumes + 1)
    return Continuation(output, stored, start)


def prepare_extension(source: str | os.PathLike, *, steps: int | None = None, t_end: float | str | None = None,
                      output: str | os.PathLike | None = None, integrator: str | None = None,
                      scenario: Scenario | None = None, force: bool = False, dt: float | str | None = None,
                      backward: bool = False) -> Continuation:
    """How to extend the complete run in ``source`` by ``steps`` more steps, or to ``t_end``.

    The extended run is the stored scenario with the longer duration, continued from the final
    state: its samples are those of one longer run with the same sampling rule (plus the old
    final sample when it was not on that rule's grid). ``output`` defaults to ``source``, which is
    then replaced, atomically, once the extension has finished; another existing file needs
    ``force``. Another ``integrator`` or ``dt`` (``backward``: dt = -|dt|) continues the final state
    with that scheme and step, and the trace records the change (:mod:`orbitsim.checkpoint.switch`).
    ``t_end`` and ``dt`` may be times with a unit (``"100 yr"``), converted into the stored scenario's units.

    Raises
    ------
    CheckpointError
        If ``source`` is not a complete trace with a final state, a different scenario (other
        than its duration) is given, or a change of scheme or dt cannot be honoured.
    OutputError
        If ``output`` exists (and is not ``source``) without ``force``.
    """
    src = Path(source)
    dst = Path(output) if output is not None else src
    if dst.is_dir() or not dst.parent.is_dir():
        raise OutputError(f"{dst}: not a file path in an existing directory")
    with hold_output(dst):  # refuses while another process writes the new output
        return _plan_extension(src, dst, steps, t_end, (integrator, dt, backward), scenario, force)


def _option_times(stored: Scenario, t_end: float | str | None,
                  change: tuple[Any, ...]) -> tuple[float | None, tuple[Any, ...]]:
    """``--t-end`` and ``--dt`` given with a unit (``"100 yr"``) in the stored scenario's units."""
    from orbitsim.scenario import ScenarioError  # noqa: PLC0415 -- lazy: loads yaml
    from orbitsim.scenario.quantities import scenario_time  # noqa: PLC0415 -- lazy: loads yaml

    integrator, dt, backward = change
    converted = []
    for option, value in (("--t-end", t_end), ("--dt", dt)):
        try:
            converted.append(scenario_time(value, stored.units, stored.G, option) if isinstance(value, str) else value)
        except ScenarioError as err:
            raise CheckpointError(f"{option} {value}: {err.reason}") from None
    return converted[0], (integrator, converted[1], backward)


def _plan_extension(src: Path, dst: Path, steps: int | None, t_end: float | str | None, change: tuple[Any, ...],
                    scenario: Scenario | None, force: bool) -> Continuation:
    from orbitsim.checkpoint.switch import plan_switch, resolve_request  # noqa: PLC0415 -- lazy: off `orbitsim run`

    trace = read_trace_state(src)
    status = trace.attrs.get("status")
    if status == "interrupted":
        raise CheckpointError(f"{src}: the run was interrupted; finish it with `orbitsim resume {src}`, then extend it")
    if status != "complete":
        raise CheckpointError(f"{src}: only a complete run can be extended (status {status!r})")
    if trace.checkpoint is None:
        raise CheckpointError(f"{src}: holds no final state (written by an older orbitsim), so it cannot be extended "
                              "bit for bit; run the longer scenario instead")
    stored = trace.stored_scenario(src, trace.checkpoint.scenario_sha256, str(trace.attrs.get("scenario_source", "")))
    _check_same(stored, src, scenario, None, ignore=("steps",))
    t_end, change = _option_times(stored, t_end, change)
    if trace.checkpoint.steps_done != stored.steps:
        raise CheckpointError(f"{src}: damaged trace (final state at step {trace.checkpoint.steps_done}, the run "
                              f"asked for {stored.steps})")
    switch = plan_switch(src, stored, trace.checkpoint, *resolve_request(stored, *change), steps, t_end)
    longer = switch.scenario
    if longer.steps <= stored.steps:
        raise CheckpointError(f"{src}: --t-end {t_end:g} is not past the run's end (t = {stored.end_time:.10g})")
    in_place = dst.exists() and dst.resolve() == src.resolve()
    if not in_place and dst.exists() and not force:
        raise OutputError(f"{dst}: output file already exists; use --force to overwrite it")
    check_side_files(dst, force)
    remove_side_files(dst)
    start = RunStart(switch.checkpoint, source_trace=src, overwrite=in_place or force,
                     resumes=trace.checkpoint.resumes, rebuild=switch.rebuild)
    return Continuation(dst, longer, start)
