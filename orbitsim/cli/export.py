"""``orbitsim export``: a trace's state or series as a REBOUND file, a scenario or CSV."""

from __future__ import annotations

import os
from pathlib import Path

import click

from orbitsim.cli.errors import reports_errors, warn
from orbitsim.cli.options import OneLineUsageError, force_option, trace_argument

FORMATS = ("rebound", "scenario", "csv")


@click.command("export")
@trace_argument()
@click.option("--format", "fmt", type=click.Choice(FORMATS), required=True,
              help="rebound: one sample's state as a REBOUND .bin; scenario: a YAML scenario that continues the run "
                   "from one sample; csv: the time series (and, with --positions, every body's state). "
                   "Example: --format rebound")
@click.option("-o", "--output", type=click.Path(), required=True,
              help="File to write. Example: -o final.bin")
@click.option("--sample", type=int, default=-1, show_default=True,
              help="Which sample to export (rebound, scenario): 0 is the first, -1 the last. Example: --sample 100")
@click.option("--positions", is_flag=True,
              help="csv: also write every body's x, y, z, vx, vy, vz per sample, one row per body, to "
                   "OUT.positions.csv. Example: --positions")
@force_option()
@reports_errors
def command(trace: str, fmt: str, output: str, sample: int, positions: bool, force: bool) -> None:
    """Export TRACE.h5 to another format.

    rebound and scenario need a trace that recorded positions. The REBOUND file holds the sample's
    x, v and m bit for bit, with G, t, dt and the matching REBOUND integrator. The scenario has the
    same integrator, settings, dt, units and sampling, its bodies are the sample's state (floats
    written exactly) and it runs the steps left to the original end: for a fixed-dt integrator,
    running it continues the original run bit for bit (its t_start is the sample's time, so its clock
    goes on from there). After a merge or removal (events:) both hold the bodies still in the run at
    the sample, with their merged masses and radii, and say on stdout (and in the scenario's
    description) who merged into whom; a sample between two removals is refused. Files are written
    under a temporary name and renamed once complete; an existing file is replaced only with --force.

    \b
    Examples:
      orbitsim export run.h5 --format rebound -o final.bin
      orbitsim export run.h5 --format scenario --sample 100 -o next.yaml && orbitsim run next.yaml
      orbitsim export run.h5 --format csv --positions -o run.csv
    """
    from orbitsim.io import csv_export, export

    if positions and fmt != "csv":
        raise OneLineUsageError(f"--positions is for --format csv (--format {fmt} always writes the state)")
    if sample != -1 and fmt == "csv":
        raise OneLineUsageError("--sample is for --format rebound or scenario (csv writes every sample)")
    targets = [Path(output)] + ([csv_export.positions_csv_path(output)] if positions else [])
    for target in targets:
        _check_target(target, trace, force)
    if fmt == "csv":
        csv_export.export_csv(trace, output, positions=positions)
        return
    notes = (export.export_rebound if fmt == "rebound" else export.export_scenario)(trace, output, sample)
    if notes.departed:  # after a merge or removal: who left, and that the export holds the bodies still in the run
        click.echo(notes.departed)
    if notes.note:
        warn(notes.note)


def _check_target(target: Path, trace: str, force: bool) -> None:
    """Refuse, before reading anything, a directory, the trace itself, or an existing file without --force."""
    if target.is_dir():
        raise OneLineUsageError(f"{target}: is a directory; give a file name")
    if target.exists() and os.path.realpath(target) == os.path.realpath(trace):
        raise OneLineUsageError(f"{target}: is the trace being exported; give another file name")
    if target.exists() and not force:
        raise OneLineUsageError(f"{target}: exists; give --force to replace it")
    if not target.parent.is_dir() and str(target.parent):
        raise OneLineUsageError(f"{target}: its directory {target.parent} does not exist")
