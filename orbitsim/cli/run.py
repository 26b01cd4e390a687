"""``orbitsim run``: run a scenario and write its HDF5 energy trace."""

from __future__ import annotations

import math
import sys
import time
from pathlib import Path
from typing import Any

import click

from orbitsim.cli.errors import fail, reports_errors, warn
from orbitsim.cli.options import (
    FINITE_POSITIVE,
    POSITIVE_TIME,
    check_trace_output,
    device_option,
    force_option,
    output_option,
    quiet_option,
    threads_option,
)

#: Scenario keys an option overrides: errors about them name the option instead of the file.
_OPTION_FOR_KEY = {"integrator": "--integrator", "dt": "--dt", "steps": "--steps", "t_end": "--t-end",
                   "every": "--every", "output.every": "--every", "interval": "--interval",
                   "output.interval": "--interval", "output.checkpoint.every": "--checkpoint-every",
                   "output.checkpoint.seconds": "--checkpoint-seconds"}
#: A relative energy error beyond this says the run's trajectory is not to be trusted, whatever the
#: scheme: a well-resolved orbit keeps its energy to far better than 1% (the bundled planetary and
#: two-body scenarios to below 1e-4), so crossing it means a close approach the step could not
#: follow (the bundled pythagorean problem with a fixed-dt scheme) or a scheme that drifts (explicit Euler).
UNTRUSTWORTHY_ENERGY_ERROR = 0.01
#: Options that would change what an extended run computes (``--from`` keeps the stored ones).
_FIXED_BY_FROM = ("every", "interval", "positions")


@click.command("run")
@click.argument("scenario", metavar="[SCENARIO]", required=False)
@output_option("HDF5 trace file to write, named .h5 (default: <scenario name>.h5 in the current directory). "
               "Example: -o runs/circ.h5")
@click.option("--integrator", metavar="NAME", default=None,
              help="Override the integrator (a name or alias from `orbitsim list integrators`). "
                   "Example: --integrator leapfrog4")
@click.option("--dt", type=POSITIVE_TIME, default=None,
              help="Override the timestep (> 0; --backward makes it negative), in the scenario's time unit or with a "
                   "unit as in the file (\"1 day\"). With a file that gives t_end the step count is re-derived; with "
                   "steps it is kept. With --from, the run continues with this step from its final state. "
                   "Example: --dt 0.001")
@click.option("--backward", is_flag=True, default=False,
              help="Run time backwards: dt becomes -|dt| and t_end -|t_end| (schemes that can step backwards: "
                   "`orbitsim list integrators`). With --from, the run continues backwards from its final state. "
                   "Example: --from out.h5 --backward --steps 1000")
@click.option("--steps", type=click.IntRange(min=1), default=None,
              help="Override the number of whole steps (replaces t_end). Example: --steps 20000")
@click.option("--t-end", "t_end", type=POSITIVE_TIME, default=None,
              help="Override the end time: the whole steps of dt that fit (replaces steps); a number or a time "
                   "with a unit, as in the file. Example: --t-end 100 or --t-end \"1000 yr\"")
@click.option("--every", type=click.IntRange(min=1), default=None,
              help="Sample every K steps (replaces output.interval). Example: --every 100")
@click.option("--interval", type=POSITIVE_TIME, default=None,
              help="Sample every T time units (or a time with a unit, \"10 yr\"), on the last whole step not past "
                   "each sample time (replaces output.every). Example: --interval 0.5")
@click.option("--positions/--no-positions", default=None,
              help="Record (or not) positions and velocities at every sample. Example: --no-positions")
@click.option("--checkpoint-every", "checkpoint_every", type=click.IntRange(min=1), default=None,
              help="Save a checkpoint (for `orbitsim resume` after a kill) once K steps have passed since the "
                   "last one (sets output.checkpoint.every). Example: --checkpoint-every 100000")
@click.option("--checkpoint-seconds", "checkpoint_seconds", type=FINITE_POSITIVE, default=None,
              help="Save a checkpoint once S seconds of wall time have passed since the last one (sets "
                   "output.checkpoint.seconds). Example: --checkpoint-seconds 600")
@click.option("--from", "from_trace", metavar="TRACE.h5", default=None,
              help="Extend the complete run in TRACE.h5 from its final state, bit for bit as one longer run: "
                   "--steps N more steps, or to --t-end T; with --integrator, --dt or --backward it continues with "
                   "that scheme or step (the trace records the change). Replaces TRACE.h5 (atomically, once done) "
                   "unless -o names another file. Example: --from out.h5 --steps 100000")
@device_option()
@threads_option()
@force_option()
@quiet_option()
@reports_errors
def command(scenario: str | None, output: str | None, integrator: str | None, dt: float | str | None, backward: bool,
            steps: int | None, t_end: float | str | None, every: int | None, interval: float | str | None,
            positions: bool | None, checkpoint_every: int | None, checkpoint_seconds: float | None,
            from_trace: str | None, device: str | None, threads: int | None, force: bool, quiet: bool) -> None:
    """Run SCENARIO (a YAML file or a bundled name) and write its HDF5 trace.

    Options override the file. Prints a summary: steps, wall time, steps/s, max |dE/E|. A
    progress bar appears on stderr for runs longer than about a second (not with -q, nor when
    stderr is not a terminal). An existing output file is never replaced without --force.
    Ctrl-C or SIGTERM stop the run and keep every sample taken so far (status "interrupted");
    `orbitsim resume OUT` continues it. With output.checkpoint (or --checkpoint-every/-seconds)
    even a hard kill can be resumed; --from TRACE.h5 extends a complete run (SCENARIO optional).
    With an events: section the summary adds a line of what happened (close encounters,
    collisions, escapes, unresolved steps), and the trace holds them all.
    A run expected to take more than an hour, or more than 10 s a step (timed on this machine, as
    `orbitsim validate` prints it), is announced by a note before its first step. Without
    --threads a run uses one thread per core that other processes leave free (`orbitsim info`
    shows the choice).

    \b
    Exit codes: 0 complete, 2 bad input (or another process writes OUT), 3 diverged, 4 an I/O
    error such as a full disk (OUT keeps what it had), 6 halted at an event the scenario's
    events: asked to halt on, 130 SIGINT, 143 SIGTERM, 1 unexpected error.

    \b
    Examples:
      orbitsim run two_body_circular
      orbitsim run my_system.yaml -o out.h5 --integrator leapfrog4 --dt 0.001 --t-end 50
      orbitsim run plummer_1k --steps 100 --every 10 --force -q
      orbitsim run long.yaml -o long.h5 --checkpoint-seconds 600
      orbitsim run --from long.h5 --steps 50000
      orbitsim run --from long.h5 --integrator wisdom_holman --dt 0.05 --steps 50000
      orbitsim run two_body_circular --backward --t-end 10
    """
    for first, second in (("steps", "t_end"), ("every", "interval")):
        if locals()[first] is not None and locals()[second] is not None:
            raise click.UsageError(f"give only one of --{first} or --{second.replace('_', '-')}")
    checkpoints = {"checkpoint_every": checkpoint_every, "checkpoint_seconds": checkpoint_seconds}
    if from_trace is not None:
        fixed = {"every": every, "interval": interval, "positions": positions, "device": device}
        change = {"integrator": integrator, "dt": dt, "backward": backward}
        _extend(from_trace, scenario, output, change, steps, t_end, checkpoints, threads, force, quiet, fixed)
        return
    if scenario is None:
        raise click.UsageError("missing argument 'SCENARIO' (or give --from TRACE.h5 to extend a run)")
    loaded = _rebound_or_yaml(scenario, steps, t_end)
    overrides = {"integrator": integrator, "dt": dt, "steps": steps, "t_end": t_end, "every": every,
                 "interval": interval, "record_positions": positions, "device": device, **checkpoints}
    chosen = _apply_overrides(loaded, overrides)
    if backward:
        chosen = _backward(chosen)
    if output is not None:
        check_trace_output(output, chosen.name)
    execute(chosen, output, force=force, threads=threads, quiet=quiet)


def _rebound_or_yaml(scenario: str, steps: int | None, t_end: float | str | None) -> Any:
    """``run sim.bin``: a REBOUND file (known by its first bytes) is a scenario of its own, run for
    --steps or --t-end with its integrator and dt; anything else is a YAML file or a bundled name."""
    from orbitsim.io.rebound_file import is_rebound_file
    from orbitsim.scenario import load_scenario
    from orbitsim.scenario.loader import rebound_scenario

    if is_rebound_file(scenario):
        return rebound_scenario(scenario, steps=steps, t_end=t_end)
    return load_scenario(scenario)


def execute(scenario: Any, output: Any, *, force: bool, threads: int | None, quiet: bool, start: Any = None) -> None:
    """Run (or continue, from ``start``) with a progress bar, then report and exit like ``run``."""
    from orbitsim.runner import run_scenario

    if not quiet:
        for note in scenario.notes():
            warn(note)
    bar = _ProgressBar(scenario.name) if not quiet and _stderr_is_terminal() else None
    progress = None if quiet else _LongRunNote(scenario, threads, bar)
    try:
        summary = run_scenario(scenario, output, force=force, progress=progress, threads=threads, start=start,
                               on_compile=None if quiet else _CompileNote(bar))
    finally:
        if bar is not None:
            bar.close()
    _report(summary, scenario, quiet)


def _extend(source: str, scenario: str | None, output: str | None, change: dict[str, Any], steps: int | None,
            t_end: float | str | None, checkpoints: dict[str, Any], threads: int | None, force: bool, quiet: bool,
            fixed: dict[str, Any]) -> None:
    """``run --from``: the stored scenario, longer, continued from the trace's final state (with the
    integrator, dt or direction ``change`` asks for: :mod:`orbitsim.checkpoint.switch`)."""
    from orbitsim.checkpoint import prepare_extension
    from orbitsim.scenario import load_scenario

    given = [f"--{name}" for name, value in fixed.items() if value is not None]
    if given:
        raise click.UsageError(f"--from continues the stored run, whose settings are fixed: drop {', '.join(given)}")
    if steps is None and t_end is None:
        raise click.UsageError("--from needs --steps N (more steps) or --t-end T (the new end time)")
    _check_extension_output(source, output)
    from orbitsim.io.lock import hold_output

    given = load_scenario(scenario) if scenario is not None else None
    target = Path(output) if output is not None else Path(source)
    with hold_output(target):  # from the first look at its files to the last rename
        plan = prepare_extension(source, steps=steps, t_end=t_end, output=output, scenario=given, force=force,
                                 **change)
        chosen = _apply_overrides(plan.scenario, checkpoints)
        execute(chosen, plan.output, force=force, threads=threads, quiet=quiet, start=plan.start)


def _backward(scenario: Any) -> Any:
    """``--backward``: the scenario with dt = -|dt| and t_end = -|t_end| (the same number of steps,
    towards earlier times); a scheme that cannot step backwards is refused by the scenario's check."""
    from orbitsim.scenario import ScenarioError

    changes: dict[str, Any] = {"dt": -abs(scenario.dt)}
    if scenario.t_end is not None:
        changes["t_end"] = -abs(scenario.t_end)
    try:
        return scenario.with_overrides(**changes)
    except ScenarioError as err:
        fail(f"--backward: {err.reason}")  # one line, exit 2


def _check_extension_output(source: str, output: str | None) -> None:
    """``run --from``: the same output checks as ``run``; without ``-o`` the source is replaced in
    place, so an old trace named ``out.csv`` must not be renewed under that name either."""
    stem = Path(source).stem
    if output is not None:
        check_trace_output(output, stem)
    elif Path(source).is_file():
        check_trace_output(source, stem, fix=f"give -o {Path(source).with_suffix('.h5')} to write the extended run "
                                             "there")


def _apply_overrides(scenario: Any, overrides: dict[str, Any]) -> Any:
    """The scenario with the options applied; a bad value is blamed on its option."""
    from orbitsim.scenario import ScenarioError

    if all(v is None for v in overrides.values()):
        return scenario
    try:
        return scenario.with_overrides(**overrides)
    except ScenarioError as err:
        gpu = overrides.get("device") == "gpu" and "(device: gpu)" in err.reason  # what the GPU does not carry
        option = "--device" if gpu else _OPTION_FOR_KEY.get(err.key or "")
        if option is None:
            raise
        value = overrides.get(option[2:].replace("-", "_"))
        given = f"{option} {value:g}" if isinstance(value, float) else f"{option} {value}" if value else option
        fail(f"{given}: {err.reason}")  # one line, exit 2: click's usage text would bury the reason


def _report(summary: Any, scenario: Any, quiet: bool) -> None:
    """Print the summary line; exit non-zero for a diverged or interrupted run."""
    if not quiet:
        end = f"t = {summary.end_time:.10g}" if summary.samples else "no samples"
        done = _work_text(summary, scenario)
        own = summary.scheme_counters_here()
        if own is not None and "redone" in own:  # a hybrid's encounters: how often it switched and redid a step
            ias15 = f", {own['full_ias15_steps']:,} IAS15 steps" if own.get("full_ias15_steps") else ""
            done += (f" ({scenario.integrator}: {own['redone']:,} steps redone, "
                     f"{own['encounter_bs_substeps'] + own['full_bs_substeps']:,} Bulirsch-Stoer sub-steps{ias15})")
        chaos = ""
        if getattr(summary, "chaos", None) is not None:  # output.chaos: the indicators at the last sample
            from orbitsim.scenario.chaos import indicators_text

            chaos = f", {indicators_text(*summary.chaos, scenario.units)}"
        click.echo(f"{summary.name}: {summary.status}, {done}, max |dE/E| = {summary.max_abs_energy_error:.3g}"
                   f"{chaos}, {summary.samples} samples to {end} -> {summary.output}")
    if not quiet and summary.events:
        click.echo(f"{summary.name}: events: {summary.events}")
    if summary.unresolved_warning and summary.status == "complete":  # a failure stays one line; the trace keeps it
        warn(summary.unresolved_warning)  # a run without events: whose dt is far too long for an orbit
    err = summary.max_abs_energy_error
    # A dissipative force's note already said the energy error measures the force.
    if (summary.status == "complete" and math.isfinite(err) and err > UNTRUSTWORTHY_ENERGY_ERROR
            and not scenario.dissipative):
        warn(f"max |dE/E| = {err:.3g}: the energy is not kept to {UNTRUSTWORTHY_ENERGY_ERROR:.0%}, so the "
             "trajectory cannot be trusted (a dt too long for a close approach? `events:` in the scenario "
             "reports encounters, collisions and unresolved steps)")
    if summary.status == "halted":
        fail(f"run {summary.message}; the samples up to it are in {summary.output}", summary.exit_code)
    if summary.status == "diverged":
        fail(f"run diverged: {summary.message}; samples up to the last finite one are in {summary.output}",
             summary.exit_code)
    if summary.status == "interrupted":
        hint = f"; continue with `orbitsim resume {summary.output}`" if summary.resumable else ""
        fail(f"{summary.message}; the {summary.samples} samples taken are in {summary.output}{hint}",
             summary.exit_code)


def _work_text(summary: Any, scenario: Any) -> str:
    """What the run did, and at what rate: ``10000 of 10000 steps in 11.9 s (850 steps/s)``.

    A continued run (``resume``, ``run --from``) gives the rate of the steps this process took, in
    its own wall time: ``10100 of 10100 steps, 100 of them (from step 10000) in 0.05 s (2,000
    steps/s)``. The earlier parts' steps and wall time (kept in the trace) would make it meaningless.
    """
    unit = "output intervals" if scenario.adaptive else "steps"  # an adaptive scheme's grid is the output
    own = summary.scheme_counters_here()
    wall = summary.wall_here_s
    if own is not None and scenario.adaptive:  # its steps are its own; the grid is the output intervals
        rate = rate_text(own["steps_accepted"] / wall if wall > 0 else math.inf)
        pace = (f"({scenario.integrator}: {own['steps_accepted']:,} steps, {own['steps_rejected']:,} rejected, "
                f"{rate})")
    else:
        pace = f"({rate_text(summary.steps_per_s)})"
    done = f"{summary.steps_done} of {summary.steps_requested} {unit}"
    if not summary.continued:
        return f"{done} in {wall:.3g} s {pace}"
    where = "output interval" if scenario.adaptive else "step"
    return f"{done}, {summary.steps_here} of them (from {where} {summary.steps_before}) in {wall:.3g} s {pace}"


def rate_text(steps_per_s: float) -> str:
    """A run's speed at any scale: ``68,197 steps/s``, ``2.5 steps/s``, ``0.25 steps/s``, ``12.3 s/step``.

    Whole steps/s from 100 up, else three significant figures; below 0.1 steps/s (a large N) the
    seconds per step read better. ``-`` when there is no rate (no step done, or no time measured).
    """
    if not (math.isfinite(steps_per_s) and steps_per_s > 0.0):
        return "- steps/s"
    if steps_per_s >= 100.0:
        return f"{steps_per_s:,.0f} steps/s"
    if steps_per_s >= 0.1:
        return f"{steps_per_s:.3g} steps/s"
    seconds = 1.0 / steps_per_s
    return f"{seconds:,.0f} s/step" if seconds >= 100.0 else f"{seconds:.3g} s/step"


def _stderr_is_terminal() -> bool:
    try:
        return sys.stderr.isatty()
    except (AttributeError, ValueError):  # replaced or closed stream
        return False


class _CompileNote:
    """Print the line a first run (an empty Numba cache) shows before it compiles its kernels."""

    def __init__(self, bar: _ProgressBar | None) -> None:
        self.bar = bar

    def __call__(self, line: str) -> None:
        if self.bar is not None and self.bar.shown:  # on a line of its own, not over the bar
            click.echo("", err=True)
        click.echo(f"orbitsim: {line}", err=True)


class _LongRunNote:
    """Warn, once the run's checks have passed and before its first step, when it will take hours.

    The runner calls its progress callback first just before it steps, after the output and the
    scenario are checked: a refused run prints only its error, not this note as well.
    """

    def __init__(self, scenario: Any, threads: int | None, bar: _ProgressBar | None) -> None:
        self.scenario, self.threads, self.bar = scenario, threads, bar
        self.checked = False

    def __call__(self, done: int, total: int) -> None:
        if not self.checked:
            self.checked = True
            self._warn_if_long(total - done)
        if self.bar is not None:
            self.bar(done, total)

    def _warn_if_long(self, steps: int) -> None:
        from orbitsim.estimate import LONG_RUN_S, SLOW_STEP_S, estimate_time

        estimate = estimate_time(self.scenario, threads=self.threads, steps=steps)
        if estimate is None:
            return
        # One line either way; a stop (Ctrl-C) cuts a slow step short and throws it away (orbitsim.stopping).
        slow = (f"; each step takes over {SLOW_STEP_S:.0f} s: Ctrl-C stops within 2 s and discards the step in "
                "progress" if estimate.step_s > SLOW_STEP_S else "")
        if estimate.total_s > LONG_RUN_S:
            hint = "" if self.scenario.checkpoints else "; --checkpoint-seconds 600 makes it resumable after a kill"
            warn(f"this run is expected to take a long time: {estimate.describe()}{hint}{slow}")
        elif slow:
            warn(f"this run's steps are expected to be slow: {estimate.describe()}{slow}")


class _ProgressBar:
    """A one-line progress bar on stderr that appears only once a run has lasted :attr:`DELAY`."""

    DELAY = 1.0  # seconds: short runs should print nothing but their summary
    WIDTH = 30
    REDRAW = 0.1  # seconds between redraws

    def __init__(self, label: str) -> None:
        self.label = label
        self.start = time.monotonic()
        self.last_draw = 0.0
        self.shown = False

    def __call__(self, done: int, total: int) -> None:
        now = time.monotonic()
        elapsed = now - self.start
        if elapsed < self.DELAY or (now - self.last_draw < self.REDRAW and done < total):
            return
        self.last_draw = now
        fraction = done / total if total else 1.0
        filled = int(fraction * self.WIDTH)
        eta = elapsed * (1.0 - fraction) / fraction if fraction > 0 else math.inf
        eta_text = f"{eta:.0f} s left" if math.isfinite(eta) else "..."
        sys.stderr.write(f"\r{self.label} [{'#' * filled}{'.' * (self.WIDTH - filled)}] {fraction:4.0%} "
                         f"{done}/{total} steps, {eta_text}   ")
        sys.stderr.flush()
        self.shown = True

    def close(self) -> None:
        """Erase the bar so the summary starts on a clean line."""
        if self.shown:
            sys.stderr.write("\r\033[K")
            sys.stderr.flush()
