"""Run a :class:`~orbitsim.scenario.Scenario` into an HDF5 trace: the one function behind ``orbitsim run``.

:func:`run_scenario` is what the CLI, batch sweeps and comparisons call. It guarantees:

* an existing output file is never replaced unless ``force`` is true, and even then only once the
  new trace is consistent (the writer fills ``<output>.tmp`` and renames it at the end), so a
  hard kill never leaves a corrupt file at the output path;
* samples stream to disk chunk by chunk, so memory stays flat however long the run;
* SIGINT/SIGTERM (in the main thread) or a ``stop()`` callback end the run between chunks: the
  trace keeps every sample taken so far with status ``interrupted``;
* a state that turns non-finite ends the run with status ``diverged``, keeping the samples up to
  the last finite one, and a message naming the bodies and the time;
* with ``output.checkpoint`` the run saves checkpoints a kill cannot damage, and ``start`` (built
  by :mod:`orbitsim.checkpoint`) continues a killed, interrupted or finished run bit for bit; every
  complete or interrupted trace keeps its final state (:mod:`orbitsim.checkpoint` explains how).

The loop itself, the summary and the exit codes (:attr:`RunSummary.exit_code`) are in
:mod:`orbitsim.runloop`.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from orbitsim.io.lock import hold_output
from orbitsim.io.schema import OutputError
from orbitsim.preflight import check_disk, check_initial_state, check_overlaps
from orbitsim.runloop import EXIT_DIVERGED, RunLoop, RunSummary, run_failure
from orbitsim.scenario import Scenario
from orbitsim.stopping import Stopper, StopRequest

if TYPE_CHECKING:
    from orbitsim.checkpoint.sinks import RunStart
    from orbitsim.sampling import SamplePlan
    from orbitsim.simulation import SampleChunk, Simulation

__all__ = ["EXIT_DIVERGED", "OutputError", "RunSummary", "default_output", "run_scenario", "trace_attrs"]


def default_output(scenario: Scenario) -> Path:
    """``<scenario name>.h5`` in the current directory."""
    return Path(f"{scenario.name}.h5")


def trace_attrs(scenario: Scenario, threads: int) -> dict[str, Any]:
    """Root attributes describing a scenario's run (the writer adds format, status and provenance).

    ``scenario`` is the stored form's text: a large scenario's bodies go into datasets beside it
    (:mod:`orbitsim.io.stored_scenario`; :func:`orbitsim.checkpoint.sinks.open_sink` writes them).
    """
    attrs: dict[str, Any] = {
        "scenario": scenario.stored_form()[0], "scenario_sha256": scenario.sha256, "scenario_name": scenario.name,
        "scenario_source": scenario.source, "integrator": scenario.integrator,
        "integrator_settings": json.dumps(scenario.integrator_settings, sort_keys=True),
        "dt": scenario.dt, "steps_requested": scenario.steps, "G": scenario.G, "softening": scenario.softening,
        "units": scenario.units, "frame": scenario.frame, "n_bodies": scenario.n_bodies, "threads": threads,
    }
    if getattr(scenario, "forces", ()):
        # The resolved forces (names, parameters in the scenario's units): what the run applied.
        attrs["forces"] = json.dumps([dict(entry) for entry in scenario.forces], sort_keys=True, default=float)
    if getattr(scenario, "chaos", None) is not None:  # what the megno and mlce datasets were computed from
        from orbitsim.scenario.chaos import chaos_attrs  # noqa: PLC0415 -- lazy: a chaos run only

        attrs.update(chaos_attrs(scenario.chaos, scenario.names))
    if scenario.t_end is not None:
        attrs["t_end_requested"] = scenario.t_end
    if scenario.interval is not None:
        attrs["sample_interval"] = scenario.interval
    else:
        attrs["sample_every"] = int(scenario.sample_every or 1)
    return attrs


def _check_output(scenario: Scenario, output: Path, force: bool, plan: SamplePlan) -> None:
    if output.exists() and not force:
        raise OutputError(f"{output}: output file already exists; use --force to overwrite it")
    source = Path(scenario.source)
    if source.is_file() and source.resolve() == output.resolve():
        raise OutputError(f"{output}: is the scenario file itself; choose another output path")
    from orbitsim.checkpoint.sinks import check_side_files  # noqa: PLC0415 -- lazy: loads h5py

    check_side_files(output, force)

    # The checks `orbitsim validate` makes too (orbitsim.preflight): a first sample that is not
    # finite, bodies that overlap with nothing to resolve it, or a trace that does not fit, is
    # refused before anything is written.
    check_initial_state(scenario)
    check_overlaps(scenario)
    check_disk(scenario, output.parent)


def run_scenario(scenario: Scenario, output: Path | str | None = None, *, force: bool = False,
                 progress: Callable[[int, int], None] | None = None, threads: int | None = None,
                 on_chunk: Callable[[Simulation, SampleChunk], None] | None = None,
                 stop: Callable[[], bool] | None = None, handle_signals: bool = True,
                 start: RunStart | None = None, on_compile: Callable[[str], None] | None = None) -> RunSummary:
    """Run a scenario and stream its samples into an HDF5 trace.

    Parameters
    ----------
    scenario : Scenario
        What to run.
    output : path, optional
        Trace file; default ``<scenario.name>.h5`` in the current directory.
    force : bool
        Replace an existing output file (only when the new trace is complete or stopped), and
        start over a resumable run's checkpoint there.
    progress : callable, optional
        ``progress(steps_done, steps_total)``, called after every jitted call.
    threads : int, optional
        Numba threads (default: one per core other processes leave free now, at most
        ``NUMBA_NUM_THREADS``: :mod:`orbitsim.cores`); results do not depend on it.
    on_chunk : callable, optional
        ``on_chunk(simulation, chunk)`` after each chunk of samples is written.
    stop : callable, optional
        Polled between chunks; returning true ends the run as ``interrupted``.
    handle_signals : bool
        Install SIGINT/SIGTERM handlers for the run (main thread only).
    start : RunStart, optional
        Continue from a checkpoint instead of the scenario's initial state (see
        :func:`orbitsim.checkpoint.prepare_resume` and :func:`~orbitsim.checkpoint.prepare_extension`,
        which also check the output path).
    on_compile : callable, optional
        ``on_compile(line)``, called once, before Numba compiles the first of the run's kernels
        that its on-disk cache does not hold (a first run): "compiling kernels for <scheme> (first
        run only)". Compile time is left out of the run's wall time and steps/s.

    Returns
    -------
    RunSummary

    Raises
    ------
    OutputError
        If the output exists without ``force``, its directory is missing or cannot be written, a
        resumable run's checkpoint is there without ``force``, or another process is writing it
        (:class:`~orbitsim.io.schema.OutputBusyError`); nothing is written.
    OutputWriteError
        An I/O error (a full disk) ended the run. Its one-line message names the path, the cause
        and what is kept: the output path holds what it held before, and the only file left
        beside it is a checkpoint the run can be resumed from.
    ScenarioError
        If recorded positions would not fit on the disk.
    SimulationError
        If the simulation rejects the input (nothing is written).
    GPUUnavailableError
        ``device: gpu`` without a usable CUDA device or without numba-cuda (nothing is written).
    """
    output = Path(output) if output is not None else default_output(scenario)
    if scenario.device == "gpu":  # no usable GPU: one line, before anything at the output is touched
        from orbitsim.gpu.device import require_cuda  # noqa: PLC0415 -- lazy: loads numba-cuda, a GPU run only

        require_cuda()
    _check_path(scenario, output)
    with hold_output(output):  # before anything at or beside the output is looked at or touched
        return _run_locked(scenario, output, force, progress, threads, on_chunk, stop, handle_signals, start,
                           on_compile)


def _check_path(scenario: Scenario, output: Path) -> None:
    """What is wrong with the path itself, checked before its lock file is made beside it."""
    if output.is_dir():
        raise OutputError(f"{output}: is a directory; give a file name such as {output / scenario.name}.h5")
    if not output.parent.is_dir():
        raise OutputError(f"{output}: directory {output.parent} does not exist")


def _run_locked(scenario: Scenario, output: Path, force: bool, progress: Callable[[int, int], None] | None,
                threads: int | None, on_chunk: Callable[[Simulation, SampleChunk], None] | None,
                stop: Callable[[], bool] | None, handle_signals: bool, start: RunStart | None,
                on_compile: Callable[[str], None] | None) -> RunSummary:
    from orbitsim.checkpoint.sinks import open_sink, remove_side_files  # noqa: PLC0415 -- lazy: loads h5py

    plan = scenario.sample_plan()
    existed = output.exists()
    if start is None:
        _check_output(scenario, output, force, plan)
    else:
        plan = plan.after_step(start.checkpoint.last_sample_step)
    with Stopper(handle_signals, stop) as stopper:
        with stopper.critical(stop_after=False):
            try:
                if start is None:
                    remove_side_files(output)  # a forced start over a checkpointed run must not resume it later
                sink = open_sink(scenario, output, trace_attrs(scenario, threads or 0),
                                 overwrite=force if start is None else start.overwrite, start=start)
            except OSError as exc:
                raise run_failure(exc, output, existed, "before the first step", None) from None
        loop = RunLoop(sink, scenario, progress, on_chunk, start, force, on_compile)
        try:
            loop.run(plan, threads, stopper)
        except StopRequest:
            pass  # the trace is closed as interrupted below
        except BaseException as exc:
            with stopper.critical(stop_after=False):
                stopper.finished = True
                kept = loop.fail(exc)
            if isinstance(exc, OSError):
                raise run_failure(exc, output, existed, loop.where(), kept) from None
            raise
        with stopper.critical(stop_after=False):
            stopper.finished = True
            try:
                return loop.finish(output, stopper)
            except OSError as exc:
                raise run_failure(exc, output, existed, loop.where(), loop.fail(exc)) from None


