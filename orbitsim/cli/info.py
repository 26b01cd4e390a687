"""``orbitsim info``: what is in an HDF5 trace."""

from __future__ import annotations

import math
import os
from typing import Any

import click

from orbitsim.cli.errors import reports_errors
from orbitsim.cli.options import OneLineUsageError, trace_argument

#: Events listed one per line; the rest are counted ("... N more"): a run can log thousands of
#: encounters, and `info` is a glance; `info --events` lists them all.
SHOWN_EVENTS = 10
#: ``--events KIND``: orbitsim.events.log.EVENT_KINDS, written out so that the CLI imports only click
#: at start-up (a test checks that the two agree).
EVENT_KIND_CHOICES = ("encounter", "collision", "escape", "unresolved", "lost")
#: Attributes shown in the header; the rest are listed under "attributes".
_HEADER = ("format", "format_version", "orbitsim_version", "status", "message", "scenario_name",
           "scenario_source", "scenario_sha256", "integrator", "integrator_settings", "dt", "steps_requested",
           "steps_done", "G", "softening", "units", "wall_time_s", "threads")


class _EventKind(click.Choice):
    """``--events [KIND]``; a trace's name where KIND goes (``info --events run.h5``) gets the fix."""

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> Any:
        if value in self.choices:
            return value
        raise OneLineUsageError(f"--events: {value!r} is not an event kind (all, {', '.join(EVENT_KIND_CHOICES)}); "
                                "give the trace first: orbitsim info TRACE --events [KIND]")


@click.command("info")
@trace_argument()
@click.option("--scenario", "show_scenario", is_flag=True,
              help="Print only the fully resolved scenario stored in the trace, as YAML, to rerun it "
                   "exactly. Example: orbitsim info run.h5 --scenario > rerun.yaml")
@click.option("--events", "events_kind", is_flag=False, flag_value="all", default=None, metavar="[KIND]",
              type=_EventKind(["all", *EVENT_KIND_CHOICES]),
              help="Print only the run's events, every one (info alone lists the first 10), or only those of "
                   f"KIND ({', '.join(EVENT_KIND_CHOICES)}). Give it after the trace. "
                   "Example: orbitsim info run.h5 --events collision")
@reports_errors
def command(trace: str, show_scenario: bool, events_kind: str | None) -> None:
    """Show what is in TRACE.h5: status, run settings, samples, datasets and their shapes.

    For a run with events: the count of each kind, the first 10 events (--events lists them
    all), and the bodies that left the run (merged or removed); for a run that recorded
    orbital elements, their primary and shape; for a run with output.chaos, MEGNO, the mLCE
    and the Lyapunov time at the last sample.

    Also its checkpoint: the state the run stopped in and whether `orbitsim resume` or
    `orbitsim run --from` can continue it. Given a checkpoint (OUT.h5.ckpt), or the output of a
    killed run that has only a checkpoint so far, shows where that run stands instead.

    \b
    Examples:
      orbitsim info two_body_circular.h5
      orbitsim info run.h5 --scenario > rerun.yaml && orbitsim run rerun.yaml -o rerun.h5
      orbitsim info run.h5 --events collision
      orbitsim info long.h5.ckpt
    """
    from orbitsim.checkpoint.report import is_checkpoint_request
    from orbitsim.stability.store import is_map_file

    if os.path.isfile(trace) and is_map_file(trace):
        if events_kind is not None or show_scenario:
            raise OneLineUsageError(f"{trace} is a map file: --scenario and --events read traces")
        _map_info(trace)
        return
    if events_kind is not None:
        if show_scenario:
            raise OneLineUsageError("--scenario and --events print different things; give one")
        _list_events(trace, None if events_kind == "all" else events_kind)
        return
    if is_checkpoint_request(trace):
        _checkpoint_info(trace, show_scenario)
        return
    from orbitsim.checkpoint.report import history_lines, trace_checkpoint_lines
    from orbitsim.io.lock import current_holder, describe_holder
    from orbitsim.io.trace import open_trace_summary

    writer = current_holder(trace)
    if writer is not None and not os.path.exists(trace) and not show_scenario:
        click.echo(f"{trace}: a run is writing it now ({describe_holder(writer)}); the trace appears when it ends")
        return
    summary = open_trace_summary(trace)
    attrs = summary["attrs"]
    if show_scenario:
        click.echo(_whole_text(trace, attrs), nl=False)
        return
    sections = _event_lines(trace, summary["n_bodies"])  # read first: a damaged table is one line, nothing before
    click.echo(f"trace:    {summary['path']}")
    for key in _HEADER:
        if key in attrs and attrs[key] != "":
            # how the run's thread count was chosen (orbitsim.cores), beside it
            why = f" ({attrs['threads_choice']})" if key == "threads" and attrs.get("threads_choice") else ""
            click.echo(f"  {key:<20} {_show(attrs[key], full=key == 'message')}{why}")
    span = _time_range(trace, summary["n_samples"])
    if span and attrs.get("status") == "diverged":
        span += " (over the samples kept, the last finite ones; then the run diverged)"
    click.echo(f"samples:  {summary['n_samples']}{span}")
    click.echo(f"bodies:   {summary['n_bodies']}")
    for line in sections:  # none for a trace without events or elements
        click.echo(line)
    for line in _chaos_lines(trace, attrs):  # none for a trace without output.chaos
        click.echo(line)
    for line in history_lines(attrs.get("integrator_history", "")):
        click.echo(line)
    click.echo("datasets:")
    for name, shape in sorted(summary["shapes"].items()):
        click.echo(f"  {name:<20} {shape}")
    click.echo("attributes:")
    rest = sorted(k for k in attrs if k not in _HEADER and k not in ("integrator_history", "threads_choice"))
    width = max((len(k) for k in rest), default=0)
    for key in rest:
        value = _show(attrs[key])
        if key == "scenario":
            beside = ", the bodies in scenario_bodies/" if "scenario_bodies/names" in summary["shapes"] else ""
            value = f"<{len(attrs[key])} characters of YAML{beside}; see --scenario>"
        click.echo(f"  {key:<{width}}  {value}")
    for line in trace_checkpoint_lines(trace, attrs):
        click.echo(line)
    if writer is not None:
        click.echo(f"writer:   {describe_holder(writer)} is writing this output now; it replaces this file "
                   "when it ends")


def _event_lines(path: str, n_bodies: int) -> list[str]:
    """The ``elements:``, ``events:`` and ``removed:`` sections, each only when the trace has its
    datasets (docs/trace.md), so a trace without events prints what it always printed."""
    import h5py

    from orbitsim.io.trace_events import bodies_left, elements_info, event_counts, first_events, format_time

    with h5py.File(path, "r") as f:
        elements, counts = elements_info(f), event_counts(f)
        shown, left = first_events(f, SHOWN_EVENTS), bodies_left(f)
    lines = []
    if elements is not None:
        lines.append(f"elements: {', '.join(elements.names)}, each {elements.shape}, primary {elements.primary} "
                     "(orbitsim plot --elements)")
    if counts is not None:
        total = sum(counts.values())
        lines.append(f"events:   {total} (" + ", ".join(f"{kind} {n}" for kind, n in counts.items()) + ")")
        width = max((len(e.kind) for e in shown), default=0)
        lines += [f"  t = {format_time(e.time):<14} {e.kind:<{width}}  {e.details}" for e in shown]
        if total > len(shown):
            lines.append(f"  ... {total - len(shown)} more: orbitsim info {path} --events")
    if left is not None:
        lines.append(f"removed:  {len(left)} of {n_bodies} bodies left the run" if left else
                     f"removed:  none of the {n_bodies} bodies left the run")
        width = max((len(b.name) for b in left), default=0)
        lines += [f"  {b.name:<{width}}  {f'merged into {b.into}' if b.into else 'removed'} at t = "
                  f"{format_time(b.time)} (step {b.step})" for b in left]
    return lines


def _chaos_lines(path: str, attrs: dict[str, Any]) -> list[str]:
    """The ``chaos:`` line of a run with ``output.chaos``: MEGNO, the mLCE and the Lyapunov time at
    the last sample (in the scenario's time unit), and what the tangent vector started from."""
    import h5py

    from orbitsim.scenario.chaos import indicators_text

    with h5py.File(path, "r") as f:
        if "megno" not in f or "mlce" not in f:
            return []
        if f["megno"].shape[0] == 0:
            return ["chaos:    megno, mlce: no samples"]
        megno, mlce, when = float(f["megno"][-1]), float(f["mlce"][-1]), float(f["time"][-1])
    start = f"seed {attrs['chaos_seed']}" if "chaos_seed" in attrs else "an explicit variation"
    return [f"chaos:    {indicators_text(megno, mlce, str(attrs.get('units', '')))} at t = {when:.10g} "
            f"(datasets megno, mlce; tangent vector from {start})"]


def _list_events(path: str, kind: str | None) -> None:
    """``info --events [KIND]``: the count line, then every event (of ``kind``), one per line, in the
    order they happened; read block by block, so a table of millions of rows prints in flat memory."""
    import h5py

    from orbitsim.io.trace import open_trace_summary
    from orbitsim.io.trace_events import event_counts, format_time, iter_events

    open_trace_summary(path)  # a missing, foreign or damaged file: the one line every command gives
    with h5py.File(path, "r") as f:
        counts = event_counts(f)
        if counts is None:
            raise OneLineUsageError(f"{path}: has no events table: the run had no events: section")
        total = sum(counts.values())
        head = f"events:   {total} (" + ", ".join(f"{k} {n}" for k, n in counts.items()) + ")"
        click.echo(head if kind is None else f"{head}; {counts.get(kind, 0)} of kind {kind}:")
        width = max((len(k) for k, n in counts.items() if n and kind in (None, k)), default=0)  # as info aligns
        for event in iter_events(f, kind):
            click.echo(f"  t = {format_time(event.time):<14} {event.kind:<{width}}  {event.details}")


def _checkpoint_info(path: str, show_scenario: bool) -> None:
    """``info`` on a checkpoint: where the run stands, or (``--scenario``) its stored scenario."""
    from orbitsim.checkpoint.plan import resolve_output
    from orbitsim.checkpoint.report import checkpoint_file_lines
    from orbitsim.io.checkpoint import checkpoint_path, read_checkpoint

    if show_scenario:
        where = checkpoint_path(resolve_output(path))
        ckpt = read_checkpoint(where)
        if ckpt.scenario_bodies is None:
            click.echo(ckpt.scenario, nl=False)
            return
        from orbitsim.checkpoint.plan import stored_scenario

        click.echo(stored_scenario(ckpt.scenario, ckpt.scenario_sha256, where, bodies=ckpt.scenario_bodies).to_yaml(),
                   nl=False)
        return
    for line in checkpoint_file_lines(path):
        click.echo(line)


def _whole_text(trace: str, attrs: dict[str, Any]) -> str:
    """The trace's resolved scenario as YAML: its ``scenario`` text, with a large scenario's bodies
    (stored as datasets beside it, :mod:`orbitsim.io.stored_scenario`) written back in."""
    from pathlib import Path

    from orbitsim.checkpoint.plan import stored_scenario
    from orbitsim.io.stored_scenario import read_scenario_bodies
    from orbitsim.io.trace import TraceError, open_trace

    with open_trace(trace) as f:
        try:
            bodies = read_scenario_bodies(f)
        except (KeyError, OSError) as err:
            raise TraceError(f"{trace}: damaged trace ({err})") from None
    text = str(attrs.get("scenario", ""))
    if bodies is None:
        return text
    return stored_scenario(text, str(attrs.get("scenario_sha256", "")), Path(trace), bodies=bodies).to_yaml()


def _show(value: Any, full: bool = False) -> str:
    if isinstance(value, float):
        return f"{value:.10g}"
    text = str(value)
    return text if full or len(text) <= 100 else text[:97] + "..."


def _time_range(path: str, n_samples: int) -> str:
    """`, t = a .. b, max |dE/E| = c` from the two small datasets (never the positions)."""
    if n_samples == 0:
        return ""
    import h5py
    import numpy as np

    with h5py.File(path, "r") as f:
        time = f["time"]
        first, last = float(time[0]), float(time[-1])
        err = np.asarray(f["energy_error"][()])
    worst = float(np.max(np.abs(err))) if err.size else math.nan
    return f", t = {first:.10g} .. {last:.10g}, max |dE/E| = {worst:.3g}"


def _map_info(path: str) -> None:
    """A map file (orbitsim map): axes, counts by status, indicator ranges, time taken, pixels/s."""
    import numpy as np

    from orbitsim.stability.driver import read_map

    data = read_map(path)
    click.echo(f"{path}: stability map of {data.get('scenario_name')} ({data['pixels']} pixels), "
               f"t = {data['t_start']:g} .. {data['t_end']:g}, {data.get('integrator', 'wisdom_holman')} "
               f"dt = {data['dt']:g}, {data['steps']} steps")  # maps written before the attribute were all WH
    for name in ("x", "y"):
        if name in data:
            axis = data[name]
            values = axis["values"]
            unit = f" {axis['unit']}" if axis.get("unit") else ""
            click.echo(f"  {name}: {axis['body']}.{axis['key']} {values[0]:g} .. {values[-1]:g}{unit}, "
                       f"{len(values)} values{' (log)' if axis['log'] else ''}")
    status = data["status"]
    counts = ", ".join(f"{int(np.sum(status == i))} {n}" for i, n in enumerate(data["status_names"]))
    click.echo(f"  status: {counts}; {int(np.sum(data['unreliable']))} unreliable (|dE/E| > "
               f"{data['max_energy_error']:g}); escape distance {data['escape_distance']:g}")
    click.echo("  indicators (min .. max over finite pixels):")
    for name, grid in data["indicators"].items():
        finite = grid[np.isfinite(grid)]
        shown = f"{finite.min():.6g} .. {finite.max():.6g}" if finite.size else "not computed (NaN)"
        click.echo(f"    {name}: {shown}")
    click.echo(f"  time: {data['wall_time_s']:.3g} s wall for {data['pixels_computed']} pixels computed in this "
               f"run; kernel {data['kernel_time_s']:.3g} s, {data['pixels_per_s']:.4g} pixels/s")
    if "setup_time_s" in data:  # maps written before it was recorded lack it
        click.echo(f"  set-up before the pixels: {data['setup_time_s']:.3g} s (Numba's start and the kernels "
                   f"from its cache; {data['compile_time_s']:.3g} s compiling, which a first run does)")
    if data.get("device") == "gpu":
        click.echo(f"  device: gpu ({data.get('device_name')})")
    click.echo(f"  orbitsim {data.get('provenance_orbitsim_version')}, {data.get('provenance_numba_threads')} "
               f"threads, {data.get('provenance_cpu_model')}; command: {data.get('command')}")
