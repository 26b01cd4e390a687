"""The chunk loop of one run: samples into the sink, checkpoints, divergence, and the summary.

:func:`orbitsim.runner.run_scenario` checks the output, takes its lock, opens the sink and the
signal handling, and hands the rest to :class:`RunLoop`; this module holds what happens between
the first jitted call and the closed trace, and what a run that ended by an I/O error reports
(:func:`run_failure`).

Exit codes (:attr:`RunSummary.exit_code`): 0 complete, 3 diverged, 6 halted at an event the
scenario asked to halt on, 128 + signal number when interrupted by a signal (130 SIGINT, 143
SIGTERM), 1 when stopped by ``stop()``.
"""

from __future__ import annotations

import contextlib
import math
import signal
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from orbitsim.events import sampled
from orbitsim.events.log import describe
from orbitsim.stopping import Stopper, StopRequest

if TYPE_CHECKING:
    from orbitsim.checkpoint.sinks import RunStart
    from orbitsim.io.checkpoint import Checkpoint
    from orbitsim.io.schema import OutputWriteError
    from orbitsim.sampling import SamplePlan
    from orbitsim.scenario import Scenario
    from orbitsim.simulation import SampleChunk, Simulation

__all__ = ["EXIT_DIVERGED", "EXIT_HALTED", "EXIT_OK", "EXIT_STOPPED", "RunLoop", "RunSummary", "run_failure"]

EXIT_OK = 0
EXIT_STOPPED = 1
EXIT_DIVERGED = 3
EXIT_HALTED = 6


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
    events: str = ""
    scheme_counters: dict[str, Any] | None = None  # an adaptive scheme's own steps (ias15)
    unresolved_warning: str = ""  # a step too long for an orbit, seen at the samples of a run without events
    # A continued run (resume, run --from): where it started, and what the earlier parts took. The
    # totals above cover the whole run; the rate is this process's own work.
    steps_before: int = 0
    wall_before_s: float = 0.0
    scheme_counters_before: dict[str, Any] | None = None
    chaos: tuple[float, float] | None = None  # output.chaos: (MEGNO, mLCE) at the last sample

    @property
    def continued(self) -> bool:
        """Whether this process continued a run that earlier processes began."""
        return self.steps_before > 0 or self.wall_before_s > 0.0

    @property
    def steps_here(self) -> int:
        """Steps this process integrated (all of them, for a run that was not continued)."""
        return max(0, self.steps_done - self.steps_before)

    @property
    def wall_here_s(self) -> float:
        """Wall time of this process's part of the run."""
        return max(0.0, self.wall_time_s - self.wall_before_s)

    @property
    def steps_per_s(self) -> float:
        """This process's steps per second of its wall time (a cold cache's compile time left out)."""
        return self.steps_here / self.wall_here_s if self.wall_here_s > 0 else math.inf

    def scheme_counters_here(self) -> dict[str, Any] | None:
        """An adaptive scheme's counts (steps, rejections) made by this process: the trace keeps the
        whole run's (:attr:`scheme_counters`)."""
        if self.scheme_counters is None or self.scheme_counters_before is None:
            return self.scheme_counters
        before = self.scheme_counters_before
        return {key: value - before[key] if isinstance(value, int) and key in before else value
                for key, value in self.scheme_counters.items()}


class RunLoop:
    """The chunk loop, its checkpoints, and the bookkeeping the summary and the trace need."""

    def __init__(self, sink: Any, scenario: Scenario, progress: Callable[[int, int], None] | None,
                 on_chunk: Callable[[Simulation, SampleChunk], None] | None, start: RunStart | None,
                 force: bool, on_compile: Callable[[str], None] | None = None) -> None:
        from orbitsim.checkpoint.policy import Checkpointer  # noqa: PLC0415 -- lazy: loads h5py

        self.sink, self.scenario, self.steps = sink, scenario, scenario.steps
        self.progress, self.on_chunk, self.on_compile = progress, on_chunk, on_compile
        self.compiles: Any = None  # orbitsim._jit.CompileWatch of this run (run): what Numba compiled, and how long
        self.start_point = start
        self.sim: Simulation | None = None
        self.step_check: Any = None  # orbitsim.events.sampled.StepCheck, for a run without events
        self.counters_before: dict[str, Any] | None = None  # a continuation's scheme counters at its start
        self.samples = 0
        self.last_time = math.nan
        self.last_step = 0
        self.e0: float | None = None
        self.scale = math.nan  # what |dE| is divided by (orbitsim.results.energy_scale), from the first sample
        self.max_err = 0.0
        self.energy_failure: tuple[int, float, float] | None = None  # step, time, energy of the first bad sample
        self.chaos_last: tuple[float, float] | None = None  # output.chaos: (MEGNO, mLCE) at the last sample taken
        self.safe = False  # True where the state agrees with the samples written: a checkpoint may be taken
        self.history = start.checkpoint.history if start is not None else ""  # `run --from` scheme/dt changes
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
            # A checkpoint written before the scale was stored: it was |E0| then.
            self.scale = ckpt.energy_scale if math.isfinite(ckpt.energy_scale) else abs(ckpt.E0) or 1.0

    @property
    def diverged(self) -> bool:
        return self.energy_failure is not None or bool(getattr(self.sim, "diverged", False))

    def run(self, plan: SamplePlan, threads: int | None, stopper: Stopper) -> None:
        """Make the simulation and step it through ``plan``, a chunk at a time.

        What Numba compiles on the way (a first run, an empty cache) is announced once through
        ``on_compile`` ("compiling kernels for <scheme> (first run only)") and its time is kept out
        of :meth:`wall`, and so out of the steps/s the summary reports. A run whose kernels load
        from the cache compiles nothing and says nothing.
        """
        from orbitsim._jit import CompileWatch, watch_compiles  # noqa: PLC0415 -- lazy: loads numba

        note, line = self.on_compile, f"compiling kernels for {self.scenario.integrator} (first run only)"
        self.compiles = CompileWatch(None if note is None else lambda: note(line))
        with watch_compiles(self.compiles):
            self._run(plan, threads, stopper)

    def _run(self, plan: SamplePlan, threads: int | None, stopper: Stopper) -> None:
        if self.progress:
            self.progress(self.start_point.checkpoint.steps_done if self.start_point else 0, self.steps)
        if stopper.requested():
            return
        self.sim = self._make_simulation(threads)
        self.step_check = sampled.step_check(self.scenario, self.sim)  # looks at the state between calls only
        self.counters_before = self._scheme_counters() if self.start_point is not None else None
        self.safe = True
        with stopper.critical():
            # known only once numba is set up; the choice without --threads is orbitsim.cores'
            self.sink.set_attrs(threads=int(self.sim.threads_used), threads_choice=self.sim.threads_choice)
            if self.scenario.device == "gpu":  # only a GPU run says so: a CPU trace keeps its attributes
                from orbitsim.gpu.device import device_name  # noqa: PLC0415 -- lazy: loads numba-cuda

                self.sink.set_attrs(device="gpu", device_name=device_name())
            if self.history:  # where `run --from` changed the scheme or dt (orbitsim.checkpoint.switch)
                self.sink.set_attrs(integrator_history=self.history)
            self.checkpoints.initial(self)
        stopper.in_chunks = True
        try:
            chunks = self.sim.chunks(plan, record_positions=self.sink.record_positions, yield_empty=True)
            while True:
                self.safe = False  # a stop raised inside the next call finds the state ahead of the samples
                try:
                    chunk = next(chunks, None)
                except StopRequest:  # unless the stop undid a kernel call: then it is the last chunk's state
                    self.safe = self.sim.call_undone
                    raise
                if chunk is None:
                    break
                with stopper.critical():
                    self._take(chunk)
                    if self.energy_failure is not None:
                        break  # diverged: the state is past the samples kept, so no checkpoint from here
                    self.safe = True
                    self.checkpoints.maybe(self)
                if stopper.requested():
                    return
            self.safe = not self.diverged
        finally:
            stopper.in_chunks = False

    def _make_simulation(self, threads: int | None) -> Simulation:
        from orbitsim.checkpoint.state import restore_state, restore_variational  # noqa: PLC0415 -- lazy: loads h5py
        from orbitsim.scenario_simulation import scenario_simulation  # noqa: PLC0415 -- lazy: loads yaml

        sc = self.scenario
        if sc.device == "gpu":
            from orbitsim.gpu.simulation import gpu_simulation  # noqa: PLC0415 -- lazy: loads numba-cuda

            return gpu_simulation(sc, self.start_point)
        primary: str | int | None = None
        if sc.record_elements:
            primary = sc.elements_primary
            primary = sc.names.index(primary) if primary in sc.names else primary
        if self.start_point is None:
            return scenario_simulation(sc, threads, elements=primary)
        # A continuation keeps its checkpoint's clock (a `run --from` switch of dt moves it) and state.
        ckpt = self.start_point.checkpoint
        state = ckpt.state
        masses, radii = sc.masses, sc.radii
        if state.events:  # merges or removals may have changed the bodies: continue with those left
            masses = state.events["final_masses"][state.events["alive"]]
            radii = state.events["radii"]
        sim = scenario_simulation(sc, threads, elements=primary, start=(masses, state.pos.T, state.vel.T, radii,
                                                                        ckpt.t0))
        if self.start_point.rebuild:
            sim.steps_done = ckpt.steps_done  # a new scheme: its work is made fresh
            restore_variational(sim, state)  # the tangent vector is the bodies', whatever the scheme
        else:
            restore_state(sim, state)
        return sim

    def _take(self, chunk: SampleChunk) -> None:
        chunk, energy = self._finite_energy_part(chunk) if len(chunk) else (chunk, None)
        if len(chunk):
            self.sink.append(chunk)
            if self.e0 is None:
                from orbitsim.results import energy_scale  # noqa: PLC0415 -- lazy: loads numba

                self.e0 = float(energy[0])
                self.scale = energy_scale(float(chunk.kinetic[0]), float(chunk.potential[0]), self.e0)
            err = self._energy_error(energy)
            if not err <= self.max_err:  # not max(): max(0.0, nan) is 0.0, a nan would read as perfect
                self.max_err = err
            self.samples += len(chunk)
            self.last_time = float(chunk.time[-1])
            self.last_step = int(chunk.step[-1])
            if chunk.extra is not None and "megno" in chunk.extra:
                self.chaos_last = (float(chunk.extra["megno"][-1]), float(chunk.extra["mlce"][-1]))
            if self.on_chunk:
                self.on_chunk(self.sim, chunk)
        if self.step_check is not None:
            self.step_check.look(self.sim)
        if self.energy_failure is not None:  # |dE/E| is inf (or nan) from here: never a finite number
            bad = self.energy_failure[2]
            self.max_err = self._energy_error(np.array([bad])) if self.e0 is not None else math.nan
        if self.progress:
            self.progress(self.sim.steps_done, self.steps)

    def _finite_energy_part(self, chunk: SampleChunk) -> tuple[SampleChunk, np.ndarray]:
        """The samples before the first whose energy is not finite (all of them, normally).

        The state can stay finite while T + U overflows (m |v|^2 / 2 of a body thrown out at
        1e160): such a sample ends the run as diverged, and is neither stored nor counted.
        """
        head, energy, bad = chunk.finite_energy_head()
        if bad is not None:
            with np.errstate(all="ignore"):  # inf + -inf is the point here, not a warning
                self.energy_failure = (int(chunk.step[bad]), float(chunk.time[bad]), float(chunk.energy[bad]))
        return head, energy

    def _energy_error(self, energy: np.ndarray) -> float:
        """max |dE/E| over ``energy``; inf where the difference overflows."""
        from orbitsim.results import relative_energy_error  # noqa: PLC0415 -- lazy: loads numba

        with np.errstate(over="ignore", invalid="ignore"):  # an overflow gives inf, honestly, not a warning
            return float(np.max(np.abs(relative_energy_error(energy, self.e0, self.scale))))

    def wall(self) -> float:
        """Wall time of the run, the parts before any resume included, without the time Numba spent
        compiling (a first run's, :meth:`run`)."""
        compiling = self.compiles.seconds if self.compiles is not None else 0.0
        return self.checkpoints.prior_wall + time.perf_counter() - self.start - compiling

    def where(self) -> str:
        """How far the run got, for an error message."""
        done = self.sim.steps_done if self.sim is not None else self.last_step
        return f"at step {done} of {self.steps}"

    def fail(self, exc: BaseException) -> Checkpoint | None:
        """An error ended the run: keep what can be kept, and never a resumable state's files.

        Returns the checkpoint the run can be resumed from, if one is kept. After an I/O error
        nothing more is written (the disk may be full): the trace is discarded, and only a
        published checkpoint with its journal stays.
        """
        published = getattr(self.sink, "published", None) or self.checkpoints.published
        if self.sink.periodic and published is not None:
            self.sink.journal.close()  # the checkpoint stays, resumable once the cause is fixed
            return published
        if self.samples and not self.sink.periodic and not isinstance(exc, OSError):
            with contextlib.suppress(OSError):  # keep the samples as a resumable trace if that can be written
                self.sink.close("interrupted", steps_done=self.last_step, wall_time_s=self.wall(),
                                message="run ended by an error", final=self.checkpoints.kept())
                return None
        self.sink.abort()
        return None

    def finish(self, output: Path, stopper: Stopper) -> RunSummary:
        wall = self.wall()
        status, code, message = "complete", EXIT_OK, ""
        steps_done = self.last_step
        final = self.checkpoints.final(self)
        watcher = self.sim.watcher if self.sim is not None else None
        if self.diverged:
            status, code, message = "diverged", EXIT_DIVERGED, self._divergence_message()
            steps_done = self.energy_failure[0] if self.energy_failure is not None else self.sim.steps_done
        elif watcher is not None and watcher.halted is not None and stopper.signum is None:
            status, code, steps_done = "halted", EXIT_HALTED, self.sim.steps_done
            message = (f"halted at t = {watcher.halted.time:.10g} (step {watcher.halted.step}) as events: asked: "
                       f"{describe(watcher.halted, self.scenario.names)}")
        elif stopper.signum is not None or self.last_step < self.steps:
            status = "interrupted"
            code = 128 + stopper.signum if stopper.signum is not None else EXIT_STOPPED
            cause = signal.Signals(stopper.signum).name if stopper.signum is not None else "a stop request"
            taken = max(self.last_step, self.sim.steps_done if self.sim else 0)
            when = f"last sample at t = {self.last_time:g}" if self.samples else "before the first sample"
            message = f"interrupted by {cause} after {taken} of {self.steps} steps ({when})"
            steps_done = final.steps_done if final is not None else self.last_step
        scheme_counters = self._scheme_counters()
        if scheme_counters is not None:  # an adaptive scheme's own steps (accepted, rejected, force evaluations)
            self.sink.set_attrs(**{f"{self.sim.spec.name}_{key}": value for key, value in scheme_counters.items()})
        unresolved = self.step_check.warning if self.step_check is not None else ""
        if unresolved:
            self.sink.set_attrs(unresolved_warning=unresolved)
        outcome = watcher.outcome(final_run=status != "interrupted") if watcher is not None else None
        self.sink.close(status, steps_done=steps_done, wall_time_s=wall, message=message, final=final,
                        events=outcome)
        return RunSummary(
            name=self.scenario.name, output=output, status=status, exit_code=code, steps_requested=self.steps,
            steps_done=steps_done, samples=self.samples, end_time=self.last_time, wall_time_s=wall,
            max_abs_energy_error=self.max_err if self.samples else math.nan,
            threads=int(self.sim.threads_used) if self.sim else 0, message=message,
            resumable=status == "interrupted" and final is not None,
            events=outcome.summary(self.scenario.names) if outcome is not None else "",
            scheme_counters=scheme_counters, steps_before=self.start_point.checkpoint.steps_done if self.start_point
            else 0, wall_before_s=self.checkpoints.prior_wall, scheme_counters_before=self.counters_before,
            unresolved_warning=unresolved, chaos=self._chaos_at_end())

    def _chaos_at_end(self) -> tuple[float, float] | None:
        """(MEGNO, mLCE) at the last sample: this process's, or for a continuation that took none, the
        sums it continued from when they are the last sample's (the state is at that step)."""
        variational = getattr(self.sim, "variational", None)
        if self.chaos_last is not None or variational is None or not self.samples:
            return self.chaos_last
        return variational.now(self.sim.time) if self.sim.steps_done == self.last_step else None

    def _scheme_counters(self) -> dict[str, Any] | None:
        """An adaptive scheme's own counts so far (None for a fixed-step scheme, or before the simulation)."""
        return self.sim.scheme.counters(self.sim.work) if self.sim is not None else None

    def _divergence_message(self) -> str:
        if self.energy_failure is not None:
            step, when, energy = self.energy_failure
            last = (f"the last finite sample is at t = {self.last_time:g} (step {self.last_step})" if self.samples
                    else "no sample was finite")
            return (f"the energy became non-finite (E = {energy:g}) at t = {when:g} (step {step}) while the state "
                    f"was still finite: a product of masses, velocities and positions overflowed float64; {last}. "
                    "Try units in which these numbers are smaller, softening, or a smaller dt")
        bad = self.sim.non_finite_bodies()
        names = ", ".join(self.scenario.names[i] for i in bad[:10])
        if len(bad) > 10:
            names += f" and {len(bad) - 10} more"
        return (f"the state became non-finite between t = {self.last_time:g} (step {self.last_step}, the last "
                f"finite sample) and t = {self.sim.time:g} (step {self.sim.steps_done}); non-finite bodies: "
                f"{names}. Try a smaller dt, softening, or a higher-order integrator")



def run_failure(exc: OSError, output: Path, existed: bool, where: str, kept: Checkpoint | None) -> OutputWriteError:
    """The one-line error of a run ended by an I/O error: the cause, where, and what is on disk."""
    from orbitsim.io.h5safe import io_failure  # noqa: PLC0415 -- lazy: loads h5py

    failed = f" while writing {exc.filename}" if getattr(exc, "filename", None) else ""
    before = f"{output} is unchanged" if existed else f"no trace was written at {output}"
    if kept is not None:
        after = (f"the run can be resumed from its checkpoint at step {kept.steps_done}: fix the cause (free some "
                 f"space), then `orbitsim resume {output}`")
    else:
        after = "nothing is left behind"
    return io_failure(exc, f"{output}: {{reason}}{failed}; the run stopped {where}; {before}, and {after}",
                      getattr(exc, "filename", "") or "")
