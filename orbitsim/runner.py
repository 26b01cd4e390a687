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

Exit codes (:attr:`RunSummary.exit_code`): 0 complete, 3 diverged, 128 + signal number when
interrupted by a signal (130 SIGINT, 143 SIGTERM), 1 when stopped by ``stop()``.
"""

from __future__ import annotations

import json
import math
import shutil
import signal
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from orbitsim.scenario import Scenario, ScenarioError
from orbitsim.stopping import Stopper, StopRequest

if TYPE_CHECKING:
    from orbitsim.checkpoint.sinks import RunStart
    from orbitsim.sampling import SamplePlan
    from orbitsim.simulation import SampleChunk, Simulation

__all__ = ["EXIT_DIVERGED", "OutputError", "RunSummary", "default_output", "run_scenario", "trace_attrs"]

EXIT_OK = 0
EXIT_STOPPED = 1
EXIT_DIVERGED = 3


class OutputError(ValueError):
    """The output path cannot be used: it exists (and ``force`` is off), or its directory does not."""


@dataclass(frozen=True)
class RunSummary:
    """What a run did; ``exit_code`` is what ``orbitsim run`` exits with."""

    name: str
    output: Path
    status: str
    exit_code: int
    steps_requested: int
    steps_done: int
    samples: int
    end_time: float
    wall_time_s: float
    max_abs_energy_error: float
    threads: int
    message: str = ""
    resumable: bool = False

    @property
    def steps_per_s(self) -> float:
        """Steps per second of wall time (compile time included on a cold cache)."""
        return self.steps_done / self.wall_time_s if self.wall_time_s > 0 else math.inf


def default_output(scenario: Scenario) -> Path:
    """``<scenario name>.h5`` in the current directory."""
    return Path(f"{scenario.name}.h5")


def trace_attrs(scenario: Scenario, threads: int) -> dict[str, Any]:
    """Root attributes describing a scenario's run (the writer adds format, status and provenance)."""
    attrs: dict[str, Any] = {
        "scenario": scenario.to_yaml(), "scenario_sha256": scenario.sha256, "scenario_name": scenario.name,
        "scenario_source": scenario.source, "integrator": scenario.integrator,
        "integrator_settings": json.dumps(scenario.integrator_settings, sort_keys=True),
        "dt": scenario.dt, "steps_requested": scenario.steps, "G": scenario.G, "softening": scenario.softening,
        "units": scenario.units, "frame": scenario.frame, "n_bodies": scenario.n_bodies, "threads": threads,
    }
    if scenario.t_end is not None:
        attrs["t_end_requested"] = scenario.t_end
    if scenario.interval is not None:
        attrs["sample_interval"] = scenario.interval
    else:
        attrs["sample_every"] = int(scenario.sample_every or 1)
    return attrs


def _check_output(scenario: Scenario, output: Path, force: bool, plan: SamplePlan) -> None:
    if output.is_dir():
        raise OutputError(f"{output}: is a directory; give a file name such as {output / scenario.name}.h5")
    if output.exists() and not force:
        raise OutputError(f"{output}: output file already exists; use --force to overwrite it")
    if not output.parent.is_dir():
        raise OutputError(f"{output}: directory {output.parent} does not exist")
    source = Path(scenario.source)
    if source.is_file() and source.resolve() == output.resolve():
        raise OutputError(f"{output}: is the scenario file itself; choose another output path")
    from orbitsim.checkpoint.sinks import check_side_files

    check_side_files(output, force)
    if scenario.record_positions:
        need = 2 * 3 * 8 * scenario.n_bodies * plan.count()  # positions and velocities, uncompressed
        need *= 2 if scenario.checkpoints else 1  # the journal and the trace built from it coexist at the end
        free = shutil.disk_usage(output.parent).free
        if need > free:
            raise ScenarioError(f"recording positions needs about {need / 2**30:.3g} GiB but {output.parent} has "
                                f"{free / 2**30:.3g} GiB free: set positions: false or sample less often",
                                file=scenario.source, key="output.positions")


def run_scenario(scenario: Scenario, output: Path | str | None = None, *, force: bool = False,
                 progress: Callable[[int, int], None] | None = None, threads: int | None = None,
                 on_chunk: Callable[[Simulation, SampleChunk], None] | None = None,
                 stop: Callable[[], bool] | None = None, handle_signals: bool = True,
                 start: RunStart | None = None) -> RunSummary:
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
        Numba threads (default ``NUMBA_NUM_THREADS``); results do not depend on it.
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

    Returns
    -------
    RunSummary

    Raises
    ------
    OutputError
        If the output exists without ``force``, its directory is missing, or a resumable run's
        checkpoint is there without ``force`` (nothing is written).
    ScenarioError
        If recorded positions would not fit on the disk.
    SimulationError
        If the simulation rejects the input (nothing is written).
    """
    from orbitsim.checkpoint.sinks import open_sink, remove_side_files

    output = Path(output) if output is not None else default_output(scenario)
    plan = scenario.sample_plan()
    if start is None:
        _check_output(scenario, output, force, plan)
    else:
        plan = plan.after_step(start.checkpoint.last_sample_step)
    with Stopper(handle_signals, stop) as stopper:
        with stopper.critical(stop_after=False):
            if start is None:
                remove_side_files(output)  # a forced start over a checkpointed run must not resume it later
            sink = open_sink(scenario, output, trace_attrs(scenario, threads or 0),
                             overwrite=force if start is None else start.overwrite, start=start)
        loop = _Loop(sink, scenario, progress, on_chunk, start, force)
        try:
            loop.run(plan, threads, stopper)
        except StopRequest:
            pass  # the trace is closed as interrupted below
        except BaseException:
            with stopper.critical(stop_after=False):
                stopper.finished = True
                loop.fail()
            raise
        with stopper.critical(stop_after=False):
            stopper.finished = True
            return loop.finish(output, stopper)


class _Loop:
    """The chunk loop, its checkpoints, and the bookkeeping the summary and the trace need."""

    def __init__(self, sink: Any, scenario: Scenario, progress: Callable[[int, int], None] | None,
                 on_chunk: Callable[[Simulation, SampleChunk], None] | None, start: RunStart | None,
                 force: bool) -> None:
        from orbitsim.checkpoint.policy import Checkpointer

        self.sink, self.scenario, self.steps = sink, scenario, scenario.steps
        self.progress, self.on_chunk = progress, on_chunk
        self.start_point = start
        self.sim: Simulation | None = None
        self.samples = 0
        self.last_time = math.nan
        self.last_step = 0
        self.e0: float | None = None
        self.max_err = 0.0
        self.safe = False  # True where the state agrees with the samples written: a checkpoint may be taken
        self.checkpoints = Checkpointer(scenario, sink, start, force)
        if start is not None:
            self._continue_from(start)
        self.start = time.perf_counter()

    def _continue_from(self, start: RunStart) -> None:
        ckpt = start.checkpoint
        self.samples = ckpt.samples_written
        if self.samples:
            self.last_time, self.last_step = ckpt.last_sample_time, ckpt.last_sample_step
            self.e0, self.max_err = ckpt.E0, ckpt.max_abs_energy_error

    @property
    def diverged(self) -> bool:
        return bool(getattr(self.sim, "diverged", False))

    def run(self, plan: SamplePlan, threads: int | None, stopper: Stopper) -> None:
        if self.progress:
            self.progress(self.start_point.checkpoint.steps_done if self.start_point else 0, self.steps)
        if stopper.requested():
            return
        self.sim = self._make_simulation(threads)
        self.safe = True
        with stopper.critical():
            self.sink.set_attrs(threads=int(self.sim.threads_used))  # known only once numba is set up
            self.checkpoints.initial(self)
        stopper.in_chunks = True
        try:
            chunks = self.sim.chunks(plan, record_positions=self.sink.record_positions, yield_empty=True)
            while True:
                self.safe = False  # a stop raised inside the next call finds the state ahead of the samples
                chunk = next(chunks, None)
                if chunk is None:
                    break
                with stopper.critical():
                    self._take(chunk)
                    self.safe = True
                    self.checkpoints.maybe(self)
                if stopper.requested():
                    return
            self.safe = not self.diverged
        finally:
            stopper.in_chunks = False

    def _make_simulation(self, threads: int | None) -> Simulation:
        from orbitsim.checkpoint.state import restore_state
        from orbitsim.simulation import Simulation

        sc = self.scenario
        pos, vel = sc.positions, sc.velocities
        if self.start_point is not None:
            state = self.start_point.checkpoint.state
            pos, vel = state.pos.T, state.vel.T
        sim = Simulation(sc.masses.copy(), pos.copy(), vel.copy(), sc.integrator, sc.dt, sc.G, sc.softening, 0.0,
                         threads, dict(sc.integrator_settings))
        if self.start_point is not None:
            restore_state(sim, self.start_point.checkpoint.state)
        return sim

    def _take(self, chunk: SampleChunk) -> None:
        if len(chunk):
            self.sink.append(chunk)
            energy = chunk.energy
            if self.e0 is None:
                self.e0 = float(energy[0])
            scale = abs(self.e0) if self.e0 != 0.0 else 1.0
            self.max_err = max(self.max_err, float(abs(energy - self.e0).max()) / scale)
            self.samples += len(chunk)
            self.last_time = float(chunk.time[-1])
            self.last_step = int(chunk.step[-1])
            if self.on_chunk:
                self.on_chunk(self.sim, chunk)
        if self.progress:
            self.progress(self.sim.steps_done, self.steps)

    def wall(self) -> float:
        """Wall time of the run, the parts before any resume included."""
        return self.checkpoints.prior_wall + time.perf_counter() - self.start

    def fail(self) -> None:
        """An error ended the run: keep what can be kept, and never a resumable state's files."""
        kept = self.checkpoints.kept()
        if self.sink.periodic and self.checkpoints.published is not None:
            self.sink.journal.close()  # the checkpoint stays, resumable once the cause is fixed
        elif self.samples and not self.sink.periodic:
            self.sink.close("interrupted", steps_done=self.last_step, wall_time_s=self.wall(),
                            message="run ended by an error", final=kept)
        else:
            self.sink.abort()

    def finish(self, output: Path, stopper: Stopper) -> RunSummary:
        wall = self.wall()
        status, code, message = "complete", EXIT_OK, ""
        steps_done = self.last_step
        final = self.checkpoints.final(self)
        if self.diverged:
            status, code, message = "diverged", EXIT_DIVERGED, self._divergence_message()
            steps_done = self.sim.steps_done
        elif stopper.signum is not None or self.last_step < self.steps:
            status = "interrupted"
            code = 128 + stopper.signum if stopper.signum is not None else EXIT_STOPPED
            cause = signal.Signals(stopper.signum).name if stopper.signum is not None else "a stop request"
            taken = max(self.last_step, self.sim.steps_done if self.sim else 0)
            when = f"last sample at t = {self.last_time:g}" if self.samples else "before the first sample"
            message = f"interrupted by {cause} after {taken} of {self.steps} steps ({when})"
            steps_done = final.steps_done if final is not None else self.last_step
        self.sink.close(status, steps_done=steps_done, wall_time_s=wall, message=message, final=final)
        return RunSummary(
            name=self.scenario.name, output=output, status=status, exit_code=code, steps_requested=self.steps,
            steps_done=steps_done, samples=self.samples, end_time=self.last_time, wall_time_s=wall,
            max_abs_energy_error=self.max_err if self.samples else math.nan,
            threads=int(self.sim.threads_used) if self.sim else 0, message=message,
            resumable=status == "interrupted" and final is not None)

    def _divergence_message(self) -> str:
        bad = self.sim.non_finite_bodies()
        names = ", ".join(self.scenario.names[i] for i in bad[:10])
        if len(bad) > 10:
            names += f" and {len(bad) - 10} more"
        return (f"the state became non-finite between t = {self.last_time:g} (step {self.last_step}, the last "
                f"finite sample) and t = {self.sim.time:g} (step {self.sim.steps_done}); non-finite bodies: "
                f"{names}. Try a smaller dt, softening, or a higher-order integrator")
