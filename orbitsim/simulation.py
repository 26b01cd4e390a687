"""The Python side of a run (``orbitsim.simulation``; ``orbitsim.simulate`` is its main function):

The jitted ``run`` of each integrator takes whole steps and records samples; this module walks a
sampling plan (:mod:`orbitsim.sampling` decides *which* steps are sampled), cuts the run into
calls of about :data:`TARGET_CALL_SECONDS` each (so Ctrl-C, progress bars and checkpoints get a
say between calls without slowing the loop) and hands every chunk of samples to the caller
(:mod:`orbitsim.results` holds the chunk and result types). Chunking never changes the
arithmetic: the same input gives the same bits however the run is cut.

Public entry points: :func:`simulate` (collect everything into a :class:`SimulationResult`) and
:class:`Simulation` (iterate over :class:`SampleChunk` objects, e.g. to append to an HDF5 trace).
The plan helpers and result types are re-exported here, where they used to live.

Why one module: :class:`Simulation` is one object, the engine of a run. Its methods share the
state arrays, the integrator's work, the force context and the events watch it keeps, and each
changes them together (bodies replaced after a merge, a jitted call undone on a stop, samples
extended with elements); :func:`simulate` is its one-call front door, a few lines around
:meth:`Simulation.chunks`. The pieces with a concept of their own already live apart: the
sampling plans (:mod:`orbitsim.sampling`), the results (:mod:`orbitsim.results`), the stopping
of long calls (:mod:`orbitsim.stopping`) and the events driver (:mod:`orbitsim.events.driver`).
"""

from __future__ import annotations

import functools
import math
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field, replace
from typing import Any

import numba
import numpy as np

from orbitsim._jit import set_num_threads
from orbitsim.forces.hooks import forced_context
from orbitsim.integrators.base import Integrator, IntegratorSpec
from orbitsim.integrators.registry import get_integrator
from orbitsim.physics.diagnostics import kinetic_energy, potential_energy_at, potential_rows_scratch
from orbitsim.physics.force_context import accelerations_at, make_force
from orbitsim.physics.gravity import PARALLEL_MIN_N
from orbitsim.results import SampleBuffers, SampleChunk, SimulationResult, collect_result, relative_energy_error
from orbitsim.sampling import (
    TARGET_CALL_SECONDS,
    EveryPlan,
    ExplicitPlan,
    SamplePlan,
    SimulationError,
    TargetWindow,
    as_state,
    next_budget,
    sample_steps_every,
    sample_steps_interval,
)

__all__ = ["MAX_BUFFER_BYTES", "TARGET_CALL_SECONDS", "SampleChunk", "Simulation", "SimulationError",
           "SimulationResult", "relative_energy_error", "sample_steps_every", "sample_steps_interval",
           "simulate"]


#: Upper bound on the sample buffer of one call, so recording positions stays flat in memory.
MAX_BUFFER_BYTES = 32 * 2**20

#: From this N on every jitted call goes through :func:`orbitsim.stopping.run_interruptible`: a stop
#: reaches the running kernels within milliseconds, and the call is undone. Below it a call lasts
#: about :data:`TARGET_CALL_SECONDS` and a step at most a few tens of milliseconds (16 force
#: evaluations of 2048 bodies on half a busy core), so a stop lands between calls within the
#: Stopper's grace; there the hand-off to the kernel thread (50-250 us a call measured on this
#: 2-core machine, busy) would be a visible part of short calls (the first ones, a 5-body run).
INTERRUPTIBLE_MIN_N = 2048


@dataclass
class Simulation:
    """A system ready to step with one integrator at a fixed ``dt``.

    Parameters
    ----------
    masses : (N,) array
    positions, velocities : (N, 3) arrays
    integrator : str
        A registry name or alias (see ``orbitsim list integrators``).
    dt : float
        The fixed timestep (> 0 forward; < 0 integrates backwards, e.g. for reversibility tests).
    G : float
        Gravitational constant of the unit system.
    softening : float
        Plummer softening length eps (>= 0).
    t0 : float
        Time of step 0; sample n is at ``t0 + n * dt``.
    threads : int, optional
        Numba threads for the parallel kernels (default: one per core that other processes leave
        free now, at most ``NUMBA_NUM_THREADS``: :mod:`orbitsim.cores`; :attr:`threads_choice` says
        why). Results do not depend on it.
    settings : dict
        Integrator settings (its record's ``settings``, :mod:`orbitsim.integrators.base`).
    events : EventsConfig, optional
        Watch for collisions, close encounters, escapes and unresolved steps after every step
        (:mod:`orbitsim.events`); without it the run is the plain fixed-dt loop.
    radii : (N,) array, optional
        Body radii for collisions (default 0: point masses never touch).
    elements : str or int, optional
        Record every body's osculating orbital elements at every sample, relative to this
        primary (``"heaviest"``, ``"jacobi"`` or a body index; see
        :func:`orbitsim.physics.orbital_elements.osculating_elements`): the chunks then carry
        ``extra["elements/a"]``, ... (S, N).
    forces : ForceSet, optional
        Forces beyond Newtonian point masses (:mod:`orbitsim.forces`): the scheme's own loop applies
        them through the force hooks (:mod:`orbitsim.forces.hooks`), and every energy (samples,
        :meth:`total_energy`) includes the forces' energy. Without it nothing about forces is
        imported or compiled.
    chaos : (N, 6) array, optional
        Integrate the first-order variational equations beside the bodies, from this initial
        tangent vector (rows dx dy dz dvx dvy dvz per body), with the scheme's ``run_chaos``
        (:mod:`orbitsim.chaos`): every chunk then carries ``extra["megno"]`` and ``extra["mlce"]``,
        and :attr:`variational` holds the tangent state and MEGNO's sums. Refused (SimulationError,
        one line) for a scheme, force or events the variational equations do not cover.
    """

    masses: Any
    positions: Any
    velocities: Any
    integrator: str
    dt: float
    G: float = 1.0
    softening: float = 0.0
    t0: float = 0.0
    threads: int | None = None
    settings: dict[str, Any] = field(default_factory=dict)
    events: Any = None
    radii: Any = None
    elements: str | int | None = None
    forces: Any = None
    chaos: Any = None

    def __post_init__(self) -> None:
        from orbitsim.cores import choose_threads  # noqa: PLC0415 -- lazy: off `orbitsim validate`

        if not (math.isfinite(self.dt) and self.dt != 0.0):
            raise SimulationError(f"dt must be a finite non-zero number, got {self.dt}")
        if not (math.isfinite(self.softening) and self.softening >= 0.0):
            raise SimulationError(f"softening must be >= 0, got {self.softening}")
        if not (math.isfinite(self.G) and self.G > 0.0):
            raise SimulationError(f"G must be > 0, got {self.G}")
        self.scheme: Integrator = get_integrator(self.integrator)
        self.spec: IntegratorSpec = self.scheme.spec
        # Without a count, one thread per core other processes leave free (orbitsim.cores).
        count, self.threads_choice = choose_threads(self.threads, numba.config.NUMBA_NUM_THREADS,
                                                    int(np.size(self.masses)) >= PARALLEL_MIN_N)
        self.threads_used = set_num_threads(count)
        self.call_undone = False  # True once a stop undid a jitted call (_call_kernels): the state is as before it
        if self.forces is not None:
            self._check_forces()
        self.replace_bodies(*as_state(self.masses, self.positions, self.velocities))
        self.steps_done = 0
        self.diverged = False
        self.watcher = None
        self.variational: Any = None  # orbitsim.chaos.state.VariationalState of a run with chaos
        if self.chaos is not None:
            self._start_variational()
        if self.events is not None:
            from orbitsim.events.driver import Watcher  # noqa: PLC0415 -- lazy: off `orbitsim run`/`validate`

            self.watcher = Watcher(self, self.events, self.radii)

    def _check_forces(self) -> None:
        """Refuse, in one line, what a scheme cannot do with these forces."""
        from orbitsim.forces.compat import check_run  # noqa: PLC0415 -- lazy: off `orbitsim run`/`validate`

        why = check_run(self.forces.names, self.spec.name, self.settings, self.events is not None)
        if why is None and self.forces.per_body.shape[2] != len(np.atleast_1d(self.masses)):
            why = "the forces were made for a different number of bodies"
        if why is not None:
            raise SimulationError(why)

    def _start_variational(self) -> None:
        """The tangent state from ``chaos``, refused in one line where the variational equations cannot run."""
        from orbitsim.chaos.state import VariationalState, variational_refusal  # noqa: PLC0415 -- lazy: a chaos run only

        names = self.forces.names if self.forces is not None else ()
        refusal = variational_refusal(self.spec.name, dict(self.settings), names, self.events is not None)
        if refusal is not None:
            raise SimulationError(refusal[1])
        rows = np.asarray(self.chaos, dtype=np.float64)
        if rows.shape != (self.n, 6) or not np.all(np.isfinite(rows)) or not np.any(rows != 0.0):
            raise SimulationError(f"chaos must be {self.n} finite rows of 6 numbers (dx dy dz dvx dvy dvz per body), "
                                  f"not all zero; got shape {rows.shape}")
        self.variational = VariationalState(rows[:, :3].T, rows[:, 3:].T, self.t0, self.scheme.make_tangent)

    @property
    def halted(self) -> Any:
        """The event the run stopped at (``halt`` in the scenario's ``events:``), or None."""
        return self.watcher.halted if self.watcher is not None else None

    def replace_bodies(self, m: np.ndarray, pos: np.ndarray, vel: np.ndarray) -> None:
        """Go on with these bodies: (N,) masses, (3, N) positions and velocities, used as given.

        The force context and the integrator's work are made for them and the accelerations
        evaluated at ``pos``, exactly as for a new simulation: this is how a run starts, and how it
        continues after a merge or a removal (:mod:`orbitsim.events.driver`).
        """
        self.m, self.pos, self.vel = (np.ascontiguousarray(a, dtype=np.float64) for a in (m, pos, vel))
        self.n = int(self.m.shape[0])
        self.force = make_force(self.G, self.softening, self.n)
        old_work = getattr(self, "work", None)
        self.work = self.scheme.make_work(self.m, self.G, self.settings)
        if old_work is not None:  # what the scheme keeps across a change of bodies (ias15's clock)
            self.scheme.carry_over(old_work, self.work)
        self.acc = np.zeros((3, self.n))
        self.rows = potential_rows_scratch(self.n)
        self._call_kernels(functools.partial(accelerations_at, self.force, self.pos, self.m, self.acc),
                           undo=False)  # a stop here ends the run before its first step: nothing to undo
        self.step_force = self.force  # the context the run loop gets: with the forces, when there are some
        if self.forces is not None:
            self.step_force = forced_context(self.force, self.forces, self.n)

    def total_energy(self) -> float:
        """Kinetic plus potential energy of the current state, plus the forces' energy
        (:func:`orbitsim.forces.kernels.force_energy`) in a run with forces."""
        potential = self._call_kernels(functools.partial(potential_energy_at, self.force, self.pos, self.m,
                                                         self.rows), undo=False)
        energy = float(kinetic_energy(self.vel, self.m)) + float(potential)
        if self.forces is not None:
            from orbitsim.forces.kernels import force_energy  # noqa: PLC0415 -- lazy: off `orbitsim run`/`validate`

            energy += float(force_energy(self.pos, self.vel, self.m, self.G, self.step_force.forces.terms))
        return energy

    @property
    def time(self) -> float:
        """Time of the current state: ``t0 + steps_done * dt``, or an adaptive scheme's own clock."""
        return self.scheme.clock_time(self.work, self.t0 + self.steps_done * self.dt)

    def state(self) -> tuple[np.ndarray, np.ndarray]:
        """Current positions and velocities as (N, 3) copies."""
        return self.pos.T.copy(), self.vel.T.copy()

    def chunks(
        self,
        sample_steps: np.ndarray | SamplePlan,
        *,
        record_positions: bool = True,
        deadline: float | None = None,
        yield_empty: bool = False,
    ) -> Iterator[SampleChunk]:
        """Run to the last planned step, yielding the samples at ``sample_steps`` chunk by chunk.

        ``sample_steps`` is a :class:`~orbitsim.sampling.SamplePlan`, whose steps are produced
        block by block (memory stays flat however many samples), or an array of absolute step
        indices; either way increasing and none below ``steps_done``. The run stops early,
        leaving :attr:`diverged` true, at the first sample whose state is not finite. With
        ``yield_empty`` a chunk (possibly of no samples) follows every jitted call, so the caller
        gets control about every :data:`TARGET_CALL_SECONDS` even when samples are sparse; at each
        yield the state is consistent with the samples yielded so far (every sample step <=
        ``steps_done`` has been yielded), which is what a checkpoint needs.
        """
        plan = sample_steps if isinstance(sample_steps, SamplePlan) else ExplicitPlan(sample_steps)
        keep_positions = record_positions
        record_positions = record_positions or self.elements is not None  # elements come from the states
        per_sample = (2 * 3 * self.n * 8 if record_positions else 0) + 80
        targets = TargetWindow(plan, max(1, MAX_BUFFER_BYTES // per_sample))
        if targets.pending.size == 0:
            return
        if targets.pending[0] < self.steps_done:
            raise SimulationError("sample steps must increase and start at or after the current step")
        self.diverged = False
        buffers = SampleBuffers(targets.max_samples(), self.n, record_positions)
        watcher = self.watcher
        if watcher is not None and watcher.halted is not None:
            # halted before any step (bodies that overlapped at the start, resolve: halt)
            yield self._halt_sample(buffers, keep_positions)
            return
        budget = max(1, int(2e5 // max(1, self.n * self.n * self.spec.force_evals)))
        state = (self.pos, self.vel, self.acc, self.m)
        while targets.pending.size:
            call_targets, record = targets.plan_call(self.steps_done, budget)
            out = buffers.views(self.rows)
            start = time.perf_counter()
            if watcher is None and self.variational is not None:
                written, n_done, finite, sums = self._call_kernels(functools.partial(
                    self.variational.run, self.scheme, state, self.step_force, self.dt, self.work, self.t0,
                    self.steps_done, call_targets, record, out))
                self.variational.megno = sums  # only once the call stands (a stop that undid it raised above)
            elif watcher is None:
                written, n_done, finite = self._call_kernels(functools.partial(
                    self.scheme.run, state, self.step_force, self.dt, self.work, self.t0, self.steps_done, call_targets,
                    record, out))
            else:
                written, n_done, finite, acted = self._call_kernels(
                    functools.partial(watcher.call, self, call_targets, record, out))
            elapsed = time.perf_counter() - start
            self.steps_done = int(n_done)
            # Every recorded target is one sample, so the samples written are the targets consumed.
            targets.consume(int(written))
            chunk = buffers.chunk(int(written)) if written or (yield_empty and finite) else None
            if chunk is not None and self.variational is not None:
                chunk = replace(chunk, extra={**(chunk.extra or {}), **self.variational.series(int(written))})
            if chunk is not None and self.elements is not None:
                chunk = self._with_elements(watcher.expand(chunk) if watcher is not None else chunk, keep_positions)
            elif chunk is not None and watcher is not None:
                chunk = watcher.expand(chunk)
            if watcher is not None:
                n_before = self.n
                watcher.after_call(self, acted)
                if self.n != n_before:  # a merge or a removal: new arrays, sized for the bodies left
                    state = (self.pos, self.vel, self.acc, self.m)
                    buffers = SampleBuffers(targets.max_samples(), self.n, record_positions)
            if chunk is not None:
                yield chunk
            if not finite:
                self.diverged = True
                return
            if watcher is not None and watcher.halted is not None:
                yield self._halt_sample(buffers, keep_positions)
                return
            budget = next_budget(budget, elapsed)

    def _call_kernels(self, call: Callable[[], Any], *, undo: bool = True) -> Any:
        """``call()``, a jitted call on this simulation's arrays; where one call can be long, stoppable.

        From :data:`INTERRUPTIBLE_MIN_N` bodies on it runs through
        :func:`orbitsim.stopping.run_interruptible`: a signal then stops the kernels within
        milliseconds, and with ``undo`` every array the call may change (state, accelerations,
        masses, the integrator's work, the events watch) is put back as it was before the call,
        so the state stays the last whole step, the one the samples so far agree with, and
        :attr:`call_undone` says so. The copies cost O(N) a call, against its O(N^2) steps.
        """
        self.call_undone = False
        if self.n < INTERRUPTIBLE_MIN_N:
            return call()
        from orbitsim.stopping import run_interruptible  # noqa: PLC0415 -- lazy: off `orbitsim validate`

        if not undo:
            return run_interruptible(call, self.threads_used)
        saved = [(array, array.copy()) for array in self._changing_arrays()]

        def restore() -> None:
            for array, copy in saved:
                array[...] = copy
            self.call_undone = True

        return run_interruptible(call, self.threads_used, restore)

    def _changing_arrays(self) -> list[np.ndarray]:
        """Every array a jitted call may change: state, accelerations, masses (TRACE merges inside
        a step), the integrator's work and the events watch (nested tuples of arrays)."""
        arrays: list[np.ndarray] = []

        def collect(obj: Any) -> None:
            if isinstance(obj, np.ndarray):
                arrays.append(obj)
            elif isinstance(obj, tuple | list):
                for item in obj:
                    collect(item)

        collect((self.pos, self.vel, self.acc, self.m, self.work))
        if self.variational is not None:
            collect(self.variational.changing_arrays())
        if self.watcher is not None:
            collect(self.watcher.watch)
        return arrays

    def _halt_sample(self, buffers: SampleBuffers, keep_positions: bool) -> SampleChunk:
        """The sample of the state a run halted in (whatever the plan): a trace then ends where the
        run did. The scheme's own ``run`` records it without taking a step."""
        target = np.array([self.steps_done], dtype=np.int64)
        state = (self.pos, self.vel, self.acc, self.m)
        self.scheme.run(state, self.force, self.dt, self.work, self.t0, self.steps_done, target,
                         np.ones(1, dtype=np.bool_), buffers.views(self.rows))
        chunk = self.watcher.expand(buffers.chunk(1))
        return self._with_elements(chunk, keep_positions) if self.elements is not None else chunk

    def _with_elements(self, chunk: SampleChunk, keep_positions: bool) -> SampleChunk:
        """The chunk with every body's elements in ``extra`` (NaN for bodies out of the run), its
        states dropped unless they were asked for."""
        from orbitsim.physics.orbital_elements import osculating_elements  # noqa: PLC0415 -- lazy: off `orbitsim run`/`validate`

        masses = self.m if self.watcher is None else self.watcher.scenario_masses()
        elements = osculating_elements(masses, chunk.positions, chunk.velocities, self.G, self.elements)
        extra = dict(chunk.extra or {})
        extra.update({f"elements/{name}": values for name, values in elements.items()})
        if keep_positions:
            return replace(chunk, extra=extra)
        return replace(chunk, extra=extra, positions=None, velocities=None)

    def failure_detail(self) -> str | None:
        """Why the scheme failed, when it knows (e.g. wisdom_holman: which body's Kepler solve)."""
        return self.scheme.failure_message(self.work)

    def non_finite_bodies(self) -> list[int]:
        """Indices of bodies whose position or velocity is not finite."""
        bad = ~(np.all(np.isfinite(self.pos), axis=0) & np.all(np.isfinite(self.vel), axis=0))
        return [int(k) for k in np.flatnonzero(bad)]


def simulate(
    masses: Any,
    positions: Any,
    velocities: Any,
    *,
    integrator: str,
    dt: float,
    steps: int,
    every: int = 1,
    sample_steps: np.ndarray | None = None,
    G: float = 1.0,
    softening: float = 0.0,
    record_positions: bool = True,
    threads: int | None = None,
    settings: dict[str, Any] | None = None,
    on_chunk: Callable[[SampleChunk], None] | None = None,
    forces: Any = None,
) -> SimulationResult:
    """Integrate an N-body system for ``steps`` whole steps of ``dt`` and return its samples.

    Parameters
    ----------
    masses, positions, velocities
        (N,), (N, 3), (N, 3) arrays in a consistent unit system.
    integrator : str
        Registry name or alias, e.g. ``"verlet"`` or ``"leapfrog4"``.
    dt : float
        Fixed timestep; never shortened.
    steps : int
        Number of whole steps.
    every : int
        Sample every K steps (the first sample is step 0, the last is the final step).
    sample_steps : array, optional
        Explicit increasing step indices to sample instead of ``every``; the last must be ``steps``
        (an empty list only with ``steps=0``).
    G, softening : float
        Gravitational constant and Plummer softening length.
    record_positions : bool
        Keep positions and velocities at every sample.
    threads : int, optional
        Numba threads (default: the cores free now, :mod:`orbitsim.cores`); results do not depend on it.
    on_chunk : callable, optional
        Called with every :class:`SampleChunk` as it is produced.
    forces : ForceSet, optional
        Forces beyond Newtonian point masses (see :class:`Simulation`).

    Returns
    -------
    SimulationResult
    """
    if int(steps) != steps or steps < 0:
        raise SimulationError(f"steps must be a whole number >= 0, got {steps}")
    if sample_steps is not None:
        sample_steps = np.asarray(sample_steps, dtype=np.int64)
        last = int(sample_steps[-1]) if sample_steps.size else 0
        if last != steps:
            # The loop stops at its last sample: a plan that ends early would silently shorten the run.
            raise SimulationError(f"sample_steps must end at the last step ({steps}), got {last}")
    sim = Simulation(masses, positions, velocities, integrator, dt, G, softening, 0.0, threads, settings or {},
                     forces=forces)
    plan = EveryPlan(int(steps), int(every)) if sample_steps is None else ExplicitPlan(sample_steps)
    start = time.perf_counter()
    parts: list[SampleChunk] = []
    for chunk in sim.chunks(plan, record_positions=record_positions):
        parts.append(chunk)
        if on_chunk is not None:
            on_chunk(chunk)
    wall = time.perf_counter() - start
    return collect_result(sim, parts, record_positions, wall)
