"""``orbitsim convergence``: measured order of accuracy against a REBOUND IAS15 reference."""

from __future__ import annotations

from pathlib import Path

import click

from orbitsim.cli.compare import command_line, prepare_outdir, split_list
from orbitsim.cli.errors import EXIT_FAILURE, EXIT_NOT_TESTABLE, fail, reports_errors
from orbitsim.cli.options import FINITE_POSITIVE, POSITIVE_TIME, quiet_option, scenario_argument

OUTPUT_FILES = ("summary.json", "report.md", "report.html", "convergence.png", "work_precision.png")


def parse_dts(text: str | None) -> list[float] | None:
    """``"0.01,0.005"`` -> [0.01, 0.005]; a bad entry ends the command with exit 2."""
    if not text:
        return None
    try:
        values = [float(item) for item in split_list(text)]
    except ValueError:
        fail(f"--dts expects comma-separated numbers, got {text!r}")
    return values


@click.command("convergence")
@scenario_argument()
@click.option("-o", "--outdir", type=click.Path(file_okay=False, path_type=Path), required=True,
              help="Directory for summary.json, report.md, report.html, convergence.png and "
                   "work_precision.png. Example: -o conv/")
@click.option("--integrators", default=None, metavar="A,B,...",
              help="orbitsim integrators (default: every registered one). Example: --integrators verlet,rk4")
@click.option("--rebound", "rebound_schemes", default=None, metavar="A,B,...",
              help="Fixed-step REBOUND integrators, NAME[:OPTION] as for compare (default: the partners of "
                   "the orbitsim integrators, plus whfast when body 0 dominates; 'none' for none). "
                   "Example: --rebound leapfrog:4,whfast")
@click.option("--dts", default=None, metavar="DT1,DT2,...",
              help="The dt ladder, run as given (default: the scenario's dt times 4, 2, 1, 1/2, 1/4, 1/8, "
                   "extended per integrator until it reaches that integrator's asymptotic range). "
                   "Example: --dts 0.004,0.002,0.001,0.0005")
@click.option("--t-end", type=POSITIVE_TIME, default=None,
              help="End time at which errors are measured, on the scenario's clock like its t_end "
                   "(default: the scenario's end time), a number or a time with a unit as in the file "
                   "(\"100 yr\"). Prefer one that is not a whole number of periods after t_start. "
                   "Example: --t-end 4.4")
@click.option("--steps", type=click.IntRange(min=1), default=None,
              help="End time as a number of steps of the scenario's dt. Example: --steps 5000")
@click.option("--check", is_flag=True,
              help="Exit with status 1 when a fitted order is off its declared order by more than "
                   "--order-tolerance. Example: --check")
@click.option("--order-tolerance", type=FINITE_POSITIVE, default=0.3, show_default=True,
              help="Allowed |fitted - declared| order for --check. Example: --order-tolerance 0.3")
@click.option("--force", is_flag=True, help="Overwrite earlier results in OUTDIR. Example: --force")
@quiet_option()
@click.pass_context
@reports_errors
def command(ctx: click.Context, scenario: str, outdir: Path, integrators: str | None,
            rebound_schemes: str | None, dts: str | None, t_end: float | str | None, steps: int | None,
            check: bool, order_tolerance: float, force: bool, quiet: bool) -> None:
    """Error at the end time against a REBOUND IAS15 reference for a ladder of dt values.

    For every integrator and every dt the run takes the whole steps that fit in T and is compared
    with IAS15 stopped exactly at the same time. The order is the least-squares slope of
    log(error) against log(dt) over the asymptotic range: rungs below 10 % error and above the
    round-off floor whose local slopes agree. The default ladder is extended per integrator
    until it reaches that range (finer or coarser, up to 4 rungs); where no order can be fitted
    the report says why and which --dts to try. The report shows the order next to the declared
    one, a log-log error-vs-dt figure and a work-precision figure (error against wall time) with
    both codes on one chart. The scenario's forces are applied in both codes (REBOUND through
    REBOUNDx); an integrator that cannot apply them is left out of the defaults (named: exit 2),
    and forces REBOUND's IAS15 reference cannot carry end the command with exit 5.

    \b
    Examples:
      orbitsim convergence two_body_eccentric -o conv/ --t-end 4.4
      orbitsim convergence two_body_eccentric -o conv/ --integrators verlet,rk4,leapfrog4 \\
          --dts 0.002,0.001,0.0005,0.00025 --t-end 4.4 --check
    """
    from orbitsim.compare.run import default_rebound, settings_for
    from orbitsim.convergence.output import write_convergence_outputs
    from orbitsim.convergence.run import ladder, run_convergence
    from orbitsim.integrators.registry import INTEGRATORS, canonical_name
    from orbitsim.reference.bridge import parse_rebound_scheme
    from orbitsim.reference.force_pairing import orbitsim_refusal, rebound_refusal
    from orbitsim.reference.sampling import REFERENCE_SCHEME
    from orbitsim.scenario import load_scenario
    from orbitsim.scenario_simulation import scenario_forces

    if steps is not None and t_end is not None:
        fail("give only one of --steps and --t-end")
    sc = load_scenario(scenario)
    if isinstance(t_end, str):  # a time with a unit, in the scenario's units
        from orbitsim.scenario import ScenarioError
        from orbitsim.scenario.quantities import scenario_time

        try:
            t_end = scenario_time(t_end, sc.units, sc.G, "--t-end")
        except ScenarioError as err:
            fail(f"--t-end {t_end}: {err.reason}")
    # Rungs run forwards from t_start over the span T (a backwards scenario's ladder uses |dt|).
    end_time = t_end - sc.t_start if t_end is not None else (steps or sc.steps) * abs(sc.dt)
    if not end_time > 0:
        fail(f"--t-end {t_end:g} is not after the scenario's t_start = {sc.t_start:g}")
    try:
        names = [canonical_name(n) for n in split_list(integrators)] or [spec.name for spec in INTEGRATORS]
        if rebound_schemes and rebound_schemes.strip().lower() == "none":
            schemes = []
        elif rebound_schemes:
            schemes = [s for s in (parse_rebound_scheme(t) for t in split_list(rebound_schemes)) if s.fixed_step]
        else:
            schemes = default_rebound(names, sc.masses)
        rungs = ladder(abs(sc.dt), parse_dts(dts))
    except ValueError as err:
        fail(str(err))
    forces = scenario_forces(sc)
    why = rebound_refusal(forces, REFERENCE_SCHEME)
    if why:
        fail(f"{scenario}: not comparable: the IAS15 reference (REBOUND) cannot carry the forces: {why}",
             EXIT_NOT_TESTABLE)
    left_out = [(n, orbitsim_refusal(forces, n, settings_for(sc, n))) for n in names]
    left_out += [(s.display, rebound_refusal(forces, s)) for s in schemes]
    left_out = [(n, why) for n, why in left_out if why]
    named = {n for n in names if integrators} | {s.display for s in schemes if rebound_schemes}
    for name, why in left_out:
        if name in named:
            fail(f"{scenario}: forces: {name} cannot apply them as the other code does: {why}")
    skipped = {n for n, _ in left_out}
    names = [n for n in names if n not in skipped]
    schemes = [s for s in schemes if s.display not in skipped]
    if any(dt > end_time for dt in rungs):
        fail(f"every dt must be at most the end time T = {end_time:g}; got {max(rungs):g}")
    prepare_outdir(outdir, OUTPUT_FILES, force)
    say = (lambda _m: None) if quiet else click.echo
    span = f"T = {end_time:g}" + (f" from t_start = {sc.t_start:g}" if sc.t_start else "")
    say(f"orbitsim convergence: {sc.name}, {span}, dt ladder {', '.join(f'{d:g}' for d in rungs)}"
        + ("" if dts else " (extended per integrator to its asymptotic range)"))
    for name, why in left_out:
        say(f"  note: {name} left out: {why}")
    result = run_convergence(sc, integrators=names, rebound=schemes, dts=rungs, end_time=end_time, progress=say,
                             extend=not dts)
    for note in result.notes:  # what the run found about T itself (whole_periods)
        say(f"  note: {note}")
    result.notes = [f"{name} left out: {why}" for name, why in left_out] + result.notes
    paths = write_convergence_outputs(result, outdir, command_line(ctx), order_tolerance)
    for s in result.series:
        fitted = f"{s.fitted_order:5.2f}" if s.fitted_order == s.fitted_order else "  n/a"
        say(f"  {s.display:<34} declared {s.declared_order!s:>4}  fitted {fitted}  {s.note}")
    say(f"report: {paths['html']}")
    off = result.check(order_tolerance)
    if check and off:
        fail("fitted order missing or off the declared order: " + "; ".join(off), EXIT_FAILURE)
