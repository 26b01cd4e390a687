"""``orbitsim batch``: run a parameter sweep on Dask (local cluster by default)."""

from __future__ import annotations

import signal
import sys
from typing import Any

import click

from orbitsim.cli.errors import EXIT_FAILURE, EXIT_USAGE, fail, reports_errors
from orbitsim.cli.options import device_option


@click.command("batch")
@click.argument("sweep_file", type=click.Path(dir_okay=False), metavar="SWEEP")
@click.option("-o", "--outdir", type=click.Path(file_okay=False), default=None,
              help="Output directory (default: out/<sweep name>). Must be shared with the workers.")
@click.option("--scheduler", metavar="ADDRESS", default=None,
              help="Submit to an existing Dask scheduler, e.g. tcp://10.0.0.5:8786 "
                   "(default: start a local cluster).")
@click.option("--workers", type=click.IntRange(min=1), default=None,
              help="Worker processes of the local cluster (default: one per core).")
@click.option("--threads", type=click.IntRange(min=1), default=None,
              help="Numba threads per run (default: cores // workers locally; the workers' "
                   "NUMBA_NUM_THREADS on an existing cluster).")
@click.option("--resume/--no-resume", default=True, show_default=True,
              help="Skip runs whose trace is complete and matches its scenario; --no-resume reruns all.")
@click.option("--progress/--no-progress", default=True, show_default=True,
              help="Show a progress bar of finished runs on stderr.")
@click.option("--skip-invalid", is_flag=True,
              help="Run the valid cases and list each invalid one, with its error, in the summary "
                   "(status `invalid`) and exit 1 (default: an invalid case stops the sweep, exit 2).")
@device_option()
@reports_errors
def command(sweep_file: str, outdir: str | None, scheduler: str | None, workers: int | None,
            threads: int | None, resume: bool, progress: bool, skip_invalid: bool, device: str | None) -> None:
    """Run every case of a sweep and write OUTDIR/runs/<run-id>.h5 per run,
    OUTDIR/summary.csv and OUTDIR/summary.h5.

    SWEEP is a sweep file or the name of a bundled sweep (`orbitsim list sweeps`).
    A sweep file names a base scenario and either a `grid` of values for dotted
    key paths (every combination runs) or a list of `cases`. Running the same
    command again finishes an interrupted sweep. See docs/batch.md.

    Exit status: 0 when every run finished (complete, diverged, or halted at
    an event the scenario asked to halt on: all are results), 1 when a run
    failed or, with --skip-invalid, a case was invalid (the errors are in the
    summary), 2 for an invalid sweep or an unreachable cluster, 130 after
    Ctrl-C and 143 after SIGTERM (`timeout`, Slurm): the summary lists what
    finished, the killed runs' lock files are removed; run the same command
    again to finish the sweep.

    The summary has a column per kind of event (encounters, collisions,
    escapes, unresolved) read from each trace's events table.

    \b
    Examples:
      orbitsim batch integrators_dt -o out/int_dt
      orbitsim batch plummer_seeds --workers 2
      orbitsim batch sweep.yaml --scheduler tcp://127.0.0.1:8786
    """
    from pathlib import Path

    from orbitsim.batch.cluster import ClusterError
    from orbitsim.batch.driver import SweepInterrupted, run_sweep
    from orbitsim.batch.signals import interrupt_once
    from orbitsim.batch.summary import format_table
    from orbitsim.batch.sweep import SweepError, load_sweep

    try:
        sweep = load_sweep(sweep_file, skip_invalid=skip_invalid)
    except SweepError as err:
        fail(str(err), EXIT_USAGE)
    if device is not None:
        sweep = _on_device(sweep, device)
    target = Path(outdir) if outdir else Path("out") / sweep.name
    bar = _Bar(progress)
    # Held past run_sweep, so that a Ctrl-C while the error line below is printed is ignored too.
    with interrupt_once():
        try:
            outcome = run_sweep(sweep, target, scheduler=scheduler, workers=workers, threads=threads,
                                resume=resume, progress=bar.update, on_start=bar.start)
        except ClusterError as err:
            bar.close()
            fail(str(err), EXIT_USAGE)
        except KeyboardInterrupt as exc:
            bar.close()
            outcome = exc.outcome if isinstance(exc, SweepInterrupted) else None
            signum = outcome.signum if outcome is not None else getattr(exc, "signum", signal.SIGINT)
            fail(_interrupted(outcome, signum), 128 + signum)  # 130 after Ctrl-C, 143 after SIGTERM
        bar.close()
    click.echo(format_table(outcome.rows, sweep.params))
    counts = outcome.counts
    parts = [f"{counts[s]} {s}" for s in ("complete", "diverged", "halted", "failed", "invalid") if counts[s]]
    click.echo(f"{len(outcome.rows)} runs: {', '.join(parts)}; {outcome.resumed} reused from earlier traces. "
               f"Summary: {outcome.files[0]}")
    problems = [f"{counts['failed']} run(s) failed"] if counts["failed"] else []
    if sweep.invalid:
        problems.append(f"{len(sweep.invalid)} invalid case(s) skipped ({_invalid_list(sweep.invalid)})")
    if problems:
        fail(f"{' and '.join(problems)}; the errors are in the summary", EXIT_FAILURE)


def _on_device(sweep: Any, device: str) -> Any:
    """The sweep with every case on ``device`` (``--device``): a case the GPU does not carry is refused in
    one line, and without a usable GPU the gate's line (:func:`orbitsim.gpu.device.require_cuda`), before
    anything is written. A case's run id follows its scenario, so a GPU run never reuses a CPU trace."""
    from dataclasses import replace

    from orbitsim.scenario import ScenarioError

    cases = []
    for case in sweep.cases:
        try:
            scenario = case.scenario.with_overrides(device=device)
        except ScenarioError as err:
            fail(f"--device {device}: case {case.index}: {err.reason}", EXIT_USAGE)
        cases.append(replace(case, scenario=scenario, sha256=scenario.sha256))
    if device == "gpu":
        from orbitsim.gpu.device import require_cuda

        require_cuda()
    return replace(sweep, cases=tuple(cases))


def _interrupted(outcome: Any, signum: int = signal.SIGINT) -> str:
    """The one line after Ctrl-C or SIGTERM: what finished, where it is, and how to finish the sweep."""
    what = "interrupted" if signum == signal.SIGINT else f"interrupted by {signal.Signals(signum).name}"
    if outcome is None:  # a bare KeyboardInterrupt: it came before anything was submitted
        return f"{what} before any run started; run the same command again to start the sweep"
    counts = outcome.counts
    done = counts["complete"] + counts["diverged"] + counts["halted"] + counts["failed"]
    where = f"traces in {outcome.outdir / 'runs'}, summary in {outcome.files[0]}"
    if not counts["not run"]:
        return f"{what}, but all {done} run(s) had finished; {where}"
    return (f"{what}; {done} of {done + counts['not run']} run(s) finished, {counts['not run']} not run; "
            f"{where}: run the same command again to finish the sweep")


def _invalid_list(invalid: Any) -> str:
    """Each distinct error once, with the cases it hit: in a grid one bad value spoils many cases."""
    cases: dict[str, list[str]] = {}
    for case in invalid:
        cases.setdefault(case.message, []).append(str(case.index))
    return "; ".join(f"case{'s' if len(c) > 1 else ''} {', '.join(c)}: {message}" for message, c in cases.items())


class _Bar:
    """A click progress bar of finished runs, opened once the number of runs to do is known."""

    def __init__(self, enabled: bool) -> None:
        self.enabled = enabled
        self.bar: Any = None
        self.shown = 0

    def start(self, pending: int, reused: int, where: str) -> None:
        if reused:
            click.echo(f"{reused} run(s) already complete: reusing their traces", err=True)
        if not pending:
            return
        click.echo(f"running {pending} run(s) on {where}", err=True)
        if self.enabled:
            self.bar = click.progressbar(length=pending, label="runs", file=sys.stderr,
                                         show_pos=True, show_eta=True,
                                         item_show_func=lambda row: row and f"{row['run_id']} {row['status']}")
            self.bar.__enter__()

    def update(self, finished: int, total: int, row: dict[str, Any]) -> None:
        if self.bar is not None:
            self.bar.update(finished - self.shown, row)
            self.shown = finished

    def close(self) -> None:
        if self.bar is not None:
            self.bar.__exit__(None, None, None)
            self.bar = None
