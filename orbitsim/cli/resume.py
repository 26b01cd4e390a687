"""``orbitsim resume``: continue an interrupted or killed run to the end it asked for."""

from __future__ import annotations

import click

from orbitsim.cli.errors import reports_errors
from orbitsim.cli.options import OneLineUsageError, is_hdf5_name, quiet_option, threads_option


@click.command("resume")
@click.argument("output", metavar="OUT.h5")
@click.argument("scenario", metavar="[SCENARIO]", required=False)
@click.option("--integrator", metavar="NAME", default=None,
              help="Only a check: refuse unless the run was made with this integrator (a checkpoint holds one "
                   "scheme's state). Example: --integrator verlet")
@threads_option()
@quiet_option()
@reports_errors
def command(output: str, scenario: str | None, integrator: str | None, threads: int | None, quiet: bool) -> None:
    """Continue the run that writes OUT.h5 from its last checkpoint, bit for bit.

    OUT.h5 is the run's output path, or a file beside it (OUT.h5.ckpt, OUT.h5.journal,
    OUT.h5.tmp). A run killed outright (SIGKILL, a node lost) continues from OUT.h5.ckpt, which
    runs with output.checkpoint write; one stopped by Ctrl-C or SIGTERM from the state kept in
    OUT.h5. The finished trace is the same, dataset for dataset, as an uninterrupted run's.
    The run continues the scenario stored with it: a SCENARIO (or --integrator) given here is
    only checked against it, and a mismatch is refused (exit code 2). A complete run is left as
    it is (exit 0); extend it with `orbitsim run --from OUT.h5 --steps N`.

    \b
    Exit codes: as `orbitsim run` (0 complete, 2 nothing resumable, a mismatch, or another process
    writes OUT, 3 diverged, 4 an I/O error such as a full disk, 130 SIGINT, 143 SIGTERM, 1 unexpected).

    \b
    Examples:
      orbitsim resume long.h5
      orbitsim resume long.h5 long.yaml --integrator verlet
    """
    from orbitsim.checkpoint import prepare_resume, resolve_output
    from orbitsim.cli.run import execute
    from orbitsim.io.lock import hold_output
    from orbitsim.scenario import load_scenario

    _check_name(output)
    given = load_scenario(scenario) if scenario is not None else None
    with hold_output(resolve_output(output)):  # from the first look at its files to the last rename
        plan = prepare_resume(output, scenario=given, integrator=integrator)
        if plan.start is None:
            if not quiet:
                click.echo(plan.note)
            return
        execute(plan.scenario, plan.output, force=False, threads=threads, quiet=quiet, start=plan.start)


def _check_name(path: str) -> None:
    """Refuse to continue a run whose output is not named as HDF5 (``out.csv``, from an orbitsim that
    allowed it): resuming would write HDF5 under that name again. Renaming its files is all it takes."""
    from orbitsim.checkpoint.plan import resolve_output
    from orbitsim.io.checkpoint import checkpoint_path, journal_path

    output = resolve_output(path)
    if is_hdf5_name(output) or not (output.exists() or checkpoint_path(output).exists()):
        return  # an HDF5 name, or nothing there to resume (prepare_resume says so)
    new = output.with_suffix(".h5")
    files = [p for p in (output, checkpoint_path(output), journal_path(output)) if p.exists()]
    renames = ", ".join(f"{p.name} to {new.name}{p.name[len(output.name):]}" for p in files)
    raise OneLineUsageError(f"{output}: orbitsim writes HDF5 traces, and this is not an HDF5 file name; rename "
                            f"{renames}, then run `orbitsim resume {new}`")
