"""A run on the GPU, driven like a CPU :class:`~orbitsim.simulation.Simulation` by the same run loop.

:class:`GPUSimulation` offers what :class:`orbitsim.runloop.RunLoop`, the checkpoints
(:mod:`orbitsim.checkpoint.state`) and the trace read of a simulation: :meth:`GPUSimulation.chunks`
over the same sampling plans, cut into calls by the same :class:`~orbitsim.sampling.TargetWindow`
and step budget (:func:`~orbitsim.sampling.next_budget`), ``steps_done`` and the clock
``t0 + steps_done * dt``, and ``pos``/``vel``/``acc``/``work`` as host arrays. The state lives on the
device (:class:`~orbitsim.gpu.stepping.DeviceSystem`): a sample brings back nine numbers (and the
state only where positions are recorded); ``pos``, ``vel`` and ``acc`` are copied back when read
(a checkpoint, the sampled step check), and :meth:`GPUSimulation.upload` sends host arrays changed in
place (a checkpoint restored into them) back to the device.

Each call ends with a wait for the device, so it lasts about
:data:`~orbitsim.sampling.TARGET_CALL_SECONDS` however the kernels queue, and a stop lands between
calls. ``work`` is the CPU scheme's own (RK4's five (3, N) scratch slots, empty otherwise), kept on
the host only so that a checkpoint has the CPU's layout: a GPU checkpoint resumes on the CPU and a
CPU checkpoint on the GPU (the scratch is overwritten at every step's start).
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator
from typing import Any

import numpy as np

from orbitsim.gpu.device import simulated
from orbitsim.gpu.stepping import DeviceSystem
from orbitsim.gpu.support import GPU_SCHEMES
from orbitsim.integrators.registry import get_integrator
from orbitsim.results import SampleBuffers, SampleChunk
from orbitsim.sampling import ExplicitPlan, SamplePlan, SimulationError, TargetWindow, as_state, next_budget

__all__ = ["GPUSimulation", "gpu_simulation"]

#: Largest sample buffer of one call (as :data:`orbitsim.simulation.MAX_BUFFER_BYTES`).
MAX_BUFFER_BYTES = 32 * 2**20

#: Pair interactions the first call may take: ~1 ms on an H100 (issue 30: 5e11 pairs/s at large N); the
#: budget then follows the measured call time (:func:`~orbitsim.sampling.next_budget`).
FIRST_CALL_PAIRS = 5e8

#: The same under Numba's CUDA simulator, which manages ~1e4 pairs/s: a first call of ~0.2 s, as on hardware.
SIM_FIRST_CALL_PAIRS = 2e3


class GPUSimulation:
    """A system stepped on the GPU by a fixed-step scheme (:data:`~orbitsim.gpu.stepping.GPU_SCHEMES`).

    Parameters
    ----------
    masses : (N,) array
    positions, velocities : (N, 3) arrays
    integrator : str
        A registry name or alias of a scheme the GPU runs.
    dt : float
        The fixed timestep (non-zero, finite).
    G, softening : float
        Gravitational constant and Plummer softening length.
    t0 : float
        Time of step 0.
    settings : dict, optional
        Integrator settings: none of the GPU's schemes takes any.
    tile : int, optional
        Bodies per shared-memory tile (default :func:`orbitsim.gpu.direct.default_tile`).
    """

    device = "gpu"
    threads_used = 1  # the host loop: one thread launches the kernels
    threads_choice = "one host thread launches the GPU's kernels"
    elements = None
    watcher = None
    variational = None
    halted = None
    call_undone = False  # a stop between calls never leaves half a call to undo

    def __init__(self, masses: Any, positions: Any, velocities: Any, integrator: str, dt: float, G: float = 1.0,
                 softening: float = 0.0, t0: float = 0.0, settings: dict[str, Any] | None = None,
                 tile: int | None = None) -> None:
        if not (math.isfinite(dt) and dt != 0.0):
            raise SimulationError(f"dt must be a finite non-zero number, got {dt}")
        if not (math.isfinite(softening) and softening >= 0.0):
            raise SimulationError(f"softening must be >= 0, got {softening}")
        if not (math.isfinite(G) and G > 0.0):
            raise SimulationError(f"G must be > 0, got {G}")
        self.scheme = get_integrator(integrator)
        self.spec = self.scheme.spec
        if self.spec.name not in GPU_SCHEMES:
            raise SimulationError(f"{self.spec.name} does not run on the GPU; it runs {', '.join(GPU_SCHEMES)}")
        self.settings = dict(settings or {})
        if self.settings:
            raise SimulationError(f"{self.spec.name} on the GPU takes no integrator settings, got "
                                  f"{', '.join(self.settings)}")
        self.dt, self.G, self.softening, self.t0 = float(dt), float(G), float(softening), float(t0)
        m, pos, vel = as_state(masses, positions, velocities)
        self.m = m
        self.n = int(m.shape[0])
        self.work = self.scheme.make_work(m, self.G, self.settings)
        self.system = DeviceSystem(m, pos, vel, self.spec.name, self.G, self.softening ** 2, tile)
        self._host: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None  # None: fetch from the device
        self.steps_done = 0
        self.diverged = False

    # -- the state as host arrays -------------------------------------------------------------------

    def _mirror(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Host copies of (pos, vel, acc), fetched once per state (the steps since mark them stale)."""
        if self._host is None:
            self._host = self.system.download()
        return self._host

    @property
    def pos(self) -> np.ndarray:
        """Positions (3, N), a host copy: write into it, then :meth:`upload`."""
        return self._mirror()[0]

    @property
    def vel(self) -> np.ndarray:
        """Velocities (3, N), a host copy."""
        return self._mirror()[1]

    @property
    def acc(self) -> np.ndarray:
        """Accelerations (3, N) at ``pos``, a host copy."""
        return self._mirror()[2]

    def upload(self) -> None:
        """Send the host arrays (changed in place, e.g. a restored checkpoint) to the device."""
        pos, vel, acc = self._mirror()
        self.system.upload(pos, vel, acc)

    def _stale(self) -> None:
        self._host = None

    @property
    def time(self) -> float:
        """Time of the current state: ``t0 + steps_done * dt``."""
        return self.t0 + self.steps_done * self.dt

    def state(self) -> tuple[np.ndarray, np.ndarray]:
        """Current positions and velocities as (N, 3) copies."""
        return self.pos.T.copy(), self.vel.T.copy()

    def total_energy(self) -> float:
        """Kinetic plus potential energy of the current state, reduced on the device."""
        sums = self.system.sample()
        return sums.kinetic + sums.potential

    def non_finite_bodies(self) -> list[int]:
        """Indices of bodies whose position or velocity is not finite."""
        bad = ~(np.all(np.isfinite(self.pos), axis=0) & np.all(np.isfinite(self.vel), axis=0))
        return [int(k) for k in np.flatnonzero(bad)]

    def failure_detail(self) -> str | None:
        """Fixed-step schemes fail only by a non-finite state: nothing more to say."""
        return None

    # -- the run ------------------------------------------------------------------------------------

    def chunks(self, sample_steps: np.ndarray | SamplePlan, *, record_positions: bool = True,
               deadline: float | None = None, yield_empty: bool = False) -> Iterator[SampleChunk]:
        """Run to the last planned step, yielding the samples chunk by chunk: the contract of
        :meth:`orbitsim.simulation.Simulation.chunks` (``deadline`` is accepted and, as there, unused)."""
        plan = sample_steps if isinstance(sample_steps, SamplePlan) else ExplicitPlan(sample_steps)
        per_sample = (2 * 3 * self.n * 8 if record_positions else 0) + 80
        targets = TargetWindow(plan, max(1, MAX_BUFFER_BYTES // per_sample))
        if targets.pending.size == 0:
            return
        if targets.pending[0] < self.steps_done:
            raise SimulationError("sample steps must increase and start at or after the current step")
        self.diverged = False
        buffers = SampleBuffers(targets.max_samples(), self.n, record_positions)
        first = SIM_FIRST_CALL_PAIRS if simulated() else FIRST_CALL_PAIRS
        budget = max(1, int(first // max(1, self.n * self.n * self.spec.force_evals)))
        while targets.pending.size:
            call_targets, record = targets.plan_call(self.steps_done, budget)
            start = time.perf_counter()
            written, finite = self._call(call_targets, record, buffers)
            elapsed = time.perf_counter() - start
            targets.consume(written)
            chunk = buffers.chunk(written) if written or (yield_empty and finite) else None
            if chunk is not None:
                yield chunk
            if not finite:
                self.diverged = True
                return
            budget = next_budget(budget, elapsed)

    def _call(self, targets: np.ndarray, record: np.ndarray, buffers: SampleBuffers) -> tuple[int, bool]:
        """Step to each target, sampling where ``record`` says (the CPU's ``sample_loop``); returns
        (samples written, whether every sample was finite). Ends with the device idle."""
        written = 0
        for target, wanted in zip(targets.tolist(), record.tolist(), strict=True):
            if self.steps_done < target:
                self.system.advance(target - self.steps_done, self.dt)
                self.steps_done = int(target)
                self._stale()
            if wanted:
                if not self._record(written, buffers):
                    return written, False
                written += 1
        self.system.sync()
        return written, True

    def _record(self, r: int, buffers: SampleBuffers) -> bool:
        """Sample ``r`` of this call into ``buffers``; False, writing nothing, for a non-finite state."""
        sums = self.system.sample()
        if sums.non_finite:
            return False
        buffers.times[r] = self.time
        buffers.steps[r] = self.steps_done
        buffers.scalars[r] = sums.scalars
        if buffers.snapshots.shape[0] > 0:
            buffers.snapshots[r, 0] = self.pos
            buffers.snapshots[r, 1] = self.vel
        return True


def gpu_simulation(scenario: Any, start: Any = None) -> GPUSimulation:
    """The run of ``scenario`` on the GPU, from its bodies at ``t_start``, or from ``start``'s checkpoint
    (a :class:`~orbitsim.checkpoint.sinks.RunStart`: its state restored, then sent to the device)."""
    sc = scenario
    if start is None:
        return GPUSimulation(sc.masses, sc.positions, sc.velocities, sc.integrator, sc.grid_dt, sc.G, sc.softening,
                             sc.t_start, sc.run_settings)
    from orbitsim.checkpoint.state import restore_state  # noqa: PLC0415 - lazy: loads h5py, a continuation only

    ckpt = start.checkpoint
    sim = GPUSimulation(sc.masses, ckpt.state.pos.T, ckpt.state.vel.T, sc.integrator, sc.grid_dt, sc.G, sc.softening,
                        ckpt.t0, sc.run_settings)
    if start.rebuild:
        sim.steps_done = ckpt.steps_done  # a new scheme (`run --from --integrator`): accelerations evaluated afresh
    else:
        restore_state(sim, ckpt.state)
        sim.upload()
    return sim
