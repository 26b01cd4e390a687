"""``orbitsim info``: what is in an HDF5 trace."""

from __future__ import annotations

import math
import os
from typing import Any

import click

from orbitsim.cli.errors import reports_errors
from orbitsim.cli.options import trace_argument

#: Events listed one per line; the rest are counted ("... N more"): a run can log thousands of
#: encounters, and `info` is a glance, the whole table is in the trace.
SHOWN_EVENTS = 10
#: Attributes shown in the header; the rest are listed under "attributes".
_HEADER = ("format", "format_version", "orbitsim_version", "status", "message", "scenario_name",
           "scenario_source", "scenario_sha256", "integrator", "integrator_settings", "dt", "steps_requested",
           "steps_done", "G", "softening", "units", "wall_time_s", "threads")


@click.command("info")
@trace_argument()
@click.option("--scenario", "show_scenario", is_flag=True,
              help="Print only the fully resolved scenario stored in the trace, as YAML, to rerun it "
                   "exactly. Example: orbitsim info run.h5 --scenario > rerun.yaml")
@reports_errors
def command(trace: str, show_scenario: bool) -> None:
    """Show what is in TRACE.h5: status, run settings, samples, datasets and their shapes.

    For a run with events: the count of each kind, the first 10 events, and
    the bodies that left the run (merged or removed); for a run that recorded
    orbital elements, their primary and shape.

    Also its checkpoint: the state the run stopped in and whether `orbitsim resume` or
    `orbitsim run --from` can continue it. Given a checkpoint (OUT.h5.ckpt), or the output of a
    killed run that has only a checkpoint so far, shows where that run stands instead.

    \b
    Examples:
      orbitsim info two_body_circular.h5
      orbitsim info run.h5 --scenario > rerun.yaml && orbitsim run rerun.yaml -o rerun.h5
      orbitsim info long.h5.ckpt
    """
    from orbitsim.checkpoint.report import is_checkpoint_request

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
        click.echo(attrs.get("scenario", ""), nl=False)
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
    for line in history_lines(attrs.get("integrator_history", "")):
        click.echo(line)
    click.echo("datasets:")
    for name, shape in sorted(summary["shapes"].items()):
        click.echo(f"  {name:<20} {shape}")
    click.echo("attributes:")
    rest = sorted(k for k in attrs if k not in _HEADER and k not in ("integrator_history", "threads_choice"))
    width = max((len(k) for k in rest), default=0)
    for key in rest:
        value = f"<{len(attrs[key])} characters of YAML; see --scenario>" if key == "scenario" else _show(attrs[key])
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

    from orbitsim.analysis.trace_events import bodies_left, elements_info, event_counts, first_events, format_time

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
            lines.append(f"  ... {total - len(shown)} more (the trace's events table has them all)")
    if left is not None:
        lines.append(f"removed:  {len(left)} of {n_bodies} bodies left the run" if left else
                     f"removed:  none of the {n_bodies} bodies left the run")
        width = max((len(b.name) for b in left), default=0)
        lines += [f"  {b.name:<{width}}  {f'merged into {b.into}' if b.into else 'removed'} at t = "
                  f"{format_time(b.time)} (step {b.step})" for b in left]
    return lines


def _checkpoint_info(path: str, show_scenario: bool) -> None:
    """``info`` on a checkpoint: where the run stands, or (``--scenario``) its stored scenario."""
    from orbitsim.checkpoint.plan import resolve_output
    from orbitsim.checkpoint.report import checkpoint_file_lines
    from orbitsim.io.checkpoint import checkpoint_path, read_checkpoint

    if show_scenario:
        click.echo(read_checkpoint(checkpoint_path(resolve_output(path))).scenario, nl=False)
        return
    for line in checkpoint_file_lines(path):
        click.echo(line)


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
