"""``orbitsim compare``: cross-check orbitsim against REBOUND on one scenario."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import click

from orbitsim.cli.errors import EXIT_FAILURE, EXIT_NOT_TESTABLE, fail, reports_errors, warn
from orbitsim.cli.options import POSITIVE_TIME, quiet_option, scenario_argument, threads_option

#: From this many bodies on, a note warns that the IAS15 reference will be slow.
SLOW_REFERENCE_N = 500

#: Files whose presence means OUTDIR already holds a comparison (replaced only with --force).
OUTPUT_FILES = ("compare.h5", "summary.json", "report.md", "report.html")


def split_list(value: str | None) -> list[str]:
    """``"a, b,c"`` -> ``["a", "b", "c"]`` (empty entries dropped)."""
    return [item.strip() for item in (value or "").split(",") if item.strip()]


def command_line(ctx: click.Context) -> str:
    """The command as a user would type it, rebuilt from the parameters they actually gave."""
    from click.core import ParameterSource

    # The group's name differs under test runners; the installed program is always `orbitsim`.
    parts = ["orbitsim", ctx.info_name or ""]
    for param in ctx.command.params:
        if param.name is None or ctx.get_parameter_source(param.name) in (ParameterSource.DEFAULT, None):
            continue
        value = ctx.params.get(param.name)
        if isinstance(param, click.Argument):
            parts.append(str(value))
        elif isinstance(param, click.Option):
            flag = max(param.opts, key=len)
            if param.is_flag:
                parts += [flag] if value else []
            else:
                parts += [f"{flag} {v}" for v in value] if param.multiple else [f"{flag} {value}"]
    return " ".join(parts)


def prepare_outdir(outdir: Path, names: tuple[str, ...], force: bool) -> None:
    """Create ``outdir``; refuse to overwrite earlier results unless ``force``."""
    existing = [n for n in names if (outdir / n).exists()]
    if existing and not force:
        fail(f"{outdir}: already holds {', '.join(existing)}; use --force to overwrite")
    if outdir.exists() and not outdir.is_dir():
        fail(f"{outdir}: exists and is not a directory")
    outdir.mkdir(parents=True, exist_ok=True)


def load_with_overrides(scenario: str, dt: float | str | None, steps: int | None, t_end: float | str | None) -> Any:
    """Load a scenario and apply the --dt/--steps/--t-end overrides."""
    from orbitsim.scenario import load_scenario

    if steps is not None and t_end is not None:
        fail("give only one of --steps and --t-end")
    return load_scenario(scenario).with_overrides(dt=dt, steps=steps, t_end=t_end)


def time_options(func: Any) -> Any:
    """--dt, --steps, --t-end (shared with ``orbitsim convergence``)."""
    func = click.option("--t-end", type=POSITIVE_TIME, default=None,
                        help="End time instead of the scenario's (whole steps that fit; an adaptive scenario "
                             "ends on it exactly), a number or a time with a unit as in the file (\"100 yr\"). "
                             "Example: --t-end 100")(func)
    func = click.option("--steps", type=click.IntRange(min=1), default=None,
                        help="Number of steps instead of the scenario's. Example: --steps 5000")(func)
    return click.option("--dt", type=POSITIVE_TIME, default=None,
                        help="Timestep instead of the scenario's, a number or a time with a unit as in the file "
                             "(\"1 day\"). Example: --dt 0.005")(func)


@click.command("compare")
@scenario_argument()
@click.option("-o", "--outdir", type=click.Path(file_okay=False, path_type=Path), required=True,
              help="Directory for compare.h5, summary.json, report.md, report.html and the PNGs. "
                   "Example: -o cmp/")
@click.option("--integrators", default=None, metavar="A,B,...",
              help="orbitsim integrators (default: the scenario's own, leapfrog, leapfrog4, and "
                   "wisdom_holman when body 0 holds >= 99% of the mass). Example: --integrators leapfrog4,rk4")
@click.option("--rebound", "rebound_schemes", default=None, metavar="A,B,...",
              help="REBOUND integrators as NAME[:OPTION]: leapfrog[:2|4|6|8], whfast, saba[:TYPE], ias15 "
                   "(default: the REBOUND partner of each orbitsim integrator, e.g. leapfrog:4 for "
                   "leapfrog4, plus whfast when body 0 dominates). IAS15 always runs as a reference. "
                   "Example: --rebound leapfrog:4,whfast")
@click.option("--reference", type=click.Choice(["rebound", "orbitsim"]), default="rebound", show_default=True,
              help="Whose IAS15 every run is measured against: REBOUND's or orbitsim's native ias15. Both "
                   "always run and are reported side by side. Example: --reference orbitsim")
@click.option("--pair", "pairs", multiple=True, metavar="ORBITSIM=REBOUND[:OPT]",
              help="Also judge this pair as matched (both are run). A pair that is not really the same "
                   "scheme fails, which is how the verdict itself is tested. Example: --pair verlet=leapfrog:4")
@time_options
@threads_option()
@click.option("--force", is_flag=True, help="Overwrite the results of an earlier comparison in OUTDIR. "
              "Example: --force")
@quiet_option()
@click.pass_context
@reports_errors
def command(ctx: click.Context, scenario: str, outdir: Path, integrators: str | None,
            rebound_schemes: str | None, reference: str, pairs: tuple[str, ...], dt: float | str | None,
            steps: int | None, t_end: float | str | None, threads: int | None, force: bool, quiet: bool) -> None:
    """Run SCENARIO in orbitsim and in REBOUND and cross-check them.

    Every run starts from the same state with the same G, softening, dt and sample steps. orbitsim's
    ias15 and REBOUND's IAS15 both run, landing exactly on the same times, and one of them is the
    reference (--reference, default rebound); the report shows the two side by side with their
    mutual position difference. For each run the report gives max |dE/E|,
    the drift of dE/E (least-squares slope), the final position error against the reference, wall
    time and steps per second. Matched pairs (orbitsim leapfrog/leapfrog4/6/8 and REBOUND leapfrog
    of order 2/4/6/8; wisdom_holman and WHFast) must agree within a tolerance of 1e-9 at 1e4 steps,
    growing as n^1.5 and with the scenario's own round-off amplification (docs/compare.md). When
    ias15 is compared (the scenario's integrator, or in --integrators), the two IAS15s are a pair
    too, n counting IAS15's own steps.

    An adaptive scenario (integrator: ias15) is sampled on its output grid (output.interval, and
    t_end exactly); by default only ias15 is compared, and fixed-dt schemes named with
    --integrators or --rebound step by the scenario's dt (ias15's first trial step), which must
    land on every output time.

    A pair agrees only if its tolerance still tests something: where round-off amplification (chaos,
    close encounters, measured by a REBOUND twin run) raises the allowed difference above 1e-3 of the
    system's size (the largest distance of a body from the origin), the verdict is "chaotic:
    agreement not testable". A reference whose own max |dE/E| exceeds 1e-6 is flagged as
    unreliable (an encounter IAS15 does not resolve), and no pair passes against it.

    \b
    Exit status:
      0  every matched pair agrees (testably, against a reliable reference)
      1  a matched pair disagrees (it is named)
      2  bad input
      4  an output file could not be written
      5  no pair disagrees, but the comparison is not testable: a pair is chaotic or the
         reference is unreliable (named on the error line; see summary.json "verdict")

    \b
    Examples:
      orbitsim compare outer_solar_system -o cmp/
      orbitsim compare two_body_eccentric -o ecc/ --integrators leapfrog4,rk4 --steps 5000
      orbitsim compare figure_eight -o fig8/ --rebound leapfrog:4,leapfrog:6,saba:10_6_4
      orbitsim compare pythagorean -o pyth/ --reference orbitsim
    """
    from orbitsim.compare.ias15 import fixed_step_plan, output_grid
    from orbitsim.compare.output import write_compare_outputs
    from orbitsim.compare.run import (
        default_candidates,
        default_integrators,
        default_rebound,
        defaults_left_out,
        run_compare,
    )
    from orbitsim.reference.bridge import parse_rebound_scheme
    from orbitsim.reference.pairs import parse_pair

    sc = load_with_overrides(scenario, dt, steps, t_end)
    notes = []
    try:
        names = split_list(integrators) or default_integrators(sc)
        if not integrators:
            notes = [f"{name} is not among the default integrators: {why}"
                     for name, why in defaults_left_out(sc, default_candidates(sc))]
        schemes = ([parse_rebound_scheme(s) for s in split_list(rebound_schemes)] if rebound_schemes
                   else default_rebound(names, sc.masses, whfast=not sc.adaptive))
        extra = [parse_pair(p) for p in pairs]
        if sc.adaptive and ([n for n in names if n != "ias15"] or [s for s in schemes if s.fixed_step] or extra):
            fixed_step_plan(sc, output_grid(sc)[4])  # fixed-dt runs must land on the output times
    except ValueError as err:
        fail(str(err))
    prepare_outdir(outdir, OUTPUT_FILES, force)
    say = (lambda _m: None) if quiet else click.echo
    if sc.adaptive:
        say(f"orbitsim compare: {sc.name}, {sc.n_bodies} bodies, {sc.integrator} (first dt = {sc.dt:g}) to t = "
            f"{sc.t_end:g}, {sc.steps} output intervals of {sc.grid_dt:g}; reference: {reference}'s IAS15")
    else:
        say(f"orbitsim compare: {sc.name}, {sc.n_bodies} bodies, dt = {sc.dt:g}, {sc.steps} steps; "
            f"reference: {reference}'s IAS15")
    if sc.n_bodies >= SLOW_REFERENCE_N:
        warn(f"{sc.n_bodies} bodies: each IAS15 reference (orbitsim's and REBOUND's) costs several O(N^2) force "
             "evaluations per adaptive step and will dominate the run time (plummer_1k: ~0.2 s per IAS15 step)")
    result = run_compare(sc, integrators=names, rebound=schemes, extra_pairs=extra, threads=threads, progress=say,
                         reference=reference, notes=notes)
    paths = write_compare_outputs(result, outdir, command_line(ctx))
    if result.reference_problem:
        say(f"  WARNING  reference unreliable: {result.reference_problem}")
    for v in result.verdicts:
        say(f"  {v.terminal_line()}")
    for note in result.notes:
        say(f"  note: {note}")
    say(f"report: {paths['html']}")
    exit_on_verdict(result)


def exit_on_verdict(result: Any) -> None:
    """End with one error line and exit 1 (a pair disagrees) or 5 (nothing disagrees, but not a pass)."""
    untestable = "; ".join(result.untestable_reasons())
    if result.failed_pairs:
        more = f"; also not testable: {untestable}" if untestable else ""
        fail("matched pair(s) disagree: " + "; ".join(result.failed_pairs) + more, EXIT_FAILURE)
    if result.verdict == "not_testable":
        fail(f"agreement not testable: {untestable}", EXIT_NOT_TESTABLE)
