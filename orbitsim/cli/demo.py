"""``orbitsim demo``: the bundled lesson, one orbit stepped three ways, as an illustrated report."""

from __future__ import annotations

from pathlib import Path

import click

from orbitsim.cli.compare import command_line
from orbitsim.cli.errors import reports_errors
from orbitsim.cli.options import quiet_option

#: The bundled scenario of the lesson (orbitsim/data/scenarios/lesson.yaml).
LESSON_SCENARIO = "lesson"


def lesson_scenario() -> object:
    """The lesson scenario, bundled with the package (found without a working directory)."""
    from orbitsim.scenario import load_scenario

    return load_scenario(LESSON_SCENARIO)


@click.command("demo")
@click.option("-o", "--outdir", type=click.Path(file_okay=False, path_type=Path), default=Path("demo-report"),
              show_default=True, help="Directory for report.html, report.md, the figures and summary.json "
                                      "(files of an earlier demo there are replaced). Example: -o demo-report")
@quiet_option()
@click.pass_context
@reports_errors
def command(ctx: click.Context, outdir: Path, quiet: bool) -> None:
    """One orbit, three ways to step time: explicit Euler, semi-implicit Euler and velocity Verlet.

    Runs the bundled lesson (`orbitsim validate lesson`): a planet on an e = 0.3 orbit for 6.3 orbits at
    150 steps per orbit, under each scheme and under REBOUND's IAS15 as the reference, then a
    sweep of dt. Writes an HTML and a Markdown report with two figures (orbits over energy
    traces; errors against dt) and prints where the report is. Takes a few seconds once the
    kernels are compiled.

    \b
    Example:
      orbitsim demo -o demo-report
    """
    from orbitsim.lesson.output import write_lesson_outputs
    from orbitsim.lesson.run import run_lesson

    say = (lambda _m: None) if quiet else click.echo
    scenario = lesson_scenario()
    say("orbitsim demo: one orbit, three ways to step time")
    result = run_lesson(scenario, progress=say)
    paths = write_lesson_outputs(result, outdir, command_line(ctx))
    # Always printed, even with --quiet: telling the user where the report is is the demo's output.
    click.echo(f"report: {paths['html'].resolve()}")
