"""``orbitsim validate``: check scenario files without running them."""

from __future__ import annotations

import click

from orbitsim.cli.errors import EXIT_USAGE, is_user_error, one_line, reports_errors
from orbitsim.cli.options import quiet_option, scenario_argument


@click.command("validate")
@scenario_argument(nargs=-1)
@click.option("--resolved", is_flag=True,
              help="Print each scenario fully resolved (explicit Cartesian bodies, whole steps) as YAML; "
                   "that text reloads to the same bits. Example: --resolved > resolved.yaml")
@quiet_option()
@reports_errors
def command(scenario: tuple[str, ...], resolved: bool, quiet: bool) -> None:
    """Check every SCENARIO (a YAML file or a bundled name) without running it.

    Each valid scenario gets one "ok" line (bodies, integrator, steps, samples, the trace's size)
    plus any notes, such as a t_end that is not a whole number of steps; each invalid one gets one
    error line naming the file, the key and what to fix. Exits 2 if any scenario is invalid.

    Every check `orbitsim run` makes before its first step is made here too: a first sample whose
    energy or momentum would not be finite, bodies that overlap at the start (closer than the sum
    of their radii) without an events: collisions section, and a trace that would not fit in the free space of
    the current directory (where `run` writes by default). A run long enough to matter is timed
    on up to 1,000 of its own bodies, and the estimate printed ("time: about 2 s per step at
    N = 200000 on this machine, about 3.1 h in all").

    \b
    Examples:
      orbitsim validate my_system.yaml
      orbitsim validate systems/*.yaml
      orbitsim validate figure_eight --resolved > figure_eight_resolved.yaml
    """
    from orbitsim.scenario import load_scenario

    failed = 0
    for spec in scenario:
        try:
            loaded = load_scenario(spec)
            size = _preflight(loaded)
        except Exception as exc:
            if not is_user_error(exc):
                raise
            failed += 1
            click.echo(f"orbitsim: error: {one_line(exc)}", err=True)
            continue
        if resolved:
            click.echo(loaded.to_yaml(), nl=False)
            continue
        if not quiet:
            _describe(spec, loaded, size)
    if failed:
        raise click.exceptions.Exit(EXIT_USAGE)


def _preflight(scenario: object) -> int:
    """The checks `run` makes before stepping (:mod:`orbitsim.preflight`); returns the trace's bytes."""
    from pathlib import Path

    from orbitsim.preflight import check_disk, check_initial_state, check_overlaps

    check_initial_state(scenario)
    check_overlaps(scenario)
    return check_disk(scenario, Path.cwd())


def _describe(spec: str, scenario: object, size: int) -> None:
    from orbitsim.estimate import estimate_time
    from orbitsim.preflight import format_bytes, sample_count

    s = scenario  # a Scenario; typed loosely so this module imports nothing heavy at start-up
    length = f"t_end = {s.t_end:g} ({s.steps} steps)" if s.t_end is not None else f"{s.steps} steps"
    if s.t_start:  # only then: the line of a scenario without t_start stays as it was
        length = f"t_start = {s.t_start:g}, {length}"
    sampling = f"every {s.sample_every} steps" if s.interval is None else f"every {s.interval:g} time units"
    samples, exact = sample_count(s)
    click.echo(f"ok: {spec}: {s.name}, {s.n_bodies} bodies, {s.integrator}, dt = {s.dt:g}, {length}, "
               f"{'' if exact else 'at most '}{samples} samples ({sampling}), positions "
               f"{'on' if s.record_positions else 'off'}, trace about {format_bytes(size)}")
    if s.forces:
        from orbitsim.scenario.forces import describe_forces

        click.echo(f"  forces: {describe_forces(s.forces)}")
    estimate = estimate_time(s)
    if estimate is not None:
        click.echo(f"  time: {estimate.describe()}")
    for line in getattr(s, "input_notes", ()):
        click.echo(f"  input: {line}")
    for note in s.notes():
        click.echo(f"  note: {note}")
