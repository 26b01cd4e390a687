"""``orbitsim resume``: continue an interrupted or killed run to the end it asked for."""

from __future__ import annotations

import click

from orbitsim.cli.errors import reports_errors
from orbitsim.cli.options import quiet_option, threads_option


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
    Exit codes: as `orbitsim run` (0 complete, 2 nothing resumable or a mismatch, 3 diverged,
    130 SIGINT, 143 SIGTERM, 1 other failure).

    \b
    Examples:
      orbitsim resume long.h5
      orbitsim resume long.h5 long.yaml --integrator verlet
    """
    from orbitsim.checkpoint import prepare_resume
    from orbitsim.cli.run import execute
    from orbitsim.scenario import load_scenario

    given = load_scenario(scenario) if scenario is not None else None
    plan = prepare_resume(output, scenario=given, integrator=integrator)
    if plan.start is None:
        if not quiet:
            click.echo(plan.note)
        return
    execute(plan.scenario, plan.output, force=False, threads=threads, quiet=quiet, start=plan.start)
