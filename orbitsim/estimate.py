"""How long a run will take, measured on this machine: ``orbitsim validate`` prints it and
``orbitsim run`` warns before a run expected to take more than :data:`LONG_RUN_S`, or whose steps
are each expected to take more than :data:`SLOW_STEP_S`.

The estimate times the scenario's own integrator on a subsample of its bodies (see
:func:`estimate_time` for the assumptions); runs too small to be long are not timed at all
(:func:`rough_work`).
"""

from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from orbitsim.preflight import sample_count
from orbitsim.sampling import ExplicitPlan
from orbitsim.scenario import Scenario

__all__ = ["LONG_RUN_S", "SLOW_STEP_S", "TimeEstimate", "estimate_time", "format_seconds", "rough_work",
           "usable_threads"]

#: ``orbitsim run`` warns before a run estimated to take longer than this (seconds).
LONG_RUN_S = 3600.0
#: ... and says before a run whose steps are estimated to take longer than this (seconds) that a
#: stop discards the step in progress (the progress bar then moves once in this long).
SLOW_STEP_S = 10.0

#: Runs below this much work (:func:`rough_work`) get no time estimate: even on a slow, busy
#: machine (1e8 units a second; a 2-core laptop sustains 2e8-6e8) they take under two minutes,
#: unless one step is above :data:`SLOW_STEP_MIN_WORK`.
ESTIMATE_MIN_WORK = 1e10
#: A step below this much work takes under :data:`SLOW_STEP_S` at 1e8 units a second.
SLOW_STEP_MIN_WORK = SLOW_STEP_S * 1e8
#: Bodies in the subsample that is timed: big enough that the pair loop dominates as it does at
#: large N (and above the parallel threshold of 384), small enough that a step takes milliseconds.
TIMED_BODIES = 1000
#: Wall time spent stepping the subsample, over :data:`_REPEATS` timings whose fastest counts.
TIMING_BUDGET_S, _REPEATS = 0.03, 3


@dataclass(frozen=True)
class TimeEstimate:
    """A run's wall time, from timing its integrator on ``n_timed`` of its ``n_bodies`` bodies."""

    n_bodies: int
    n_timed: int
    step_s: float
    sample_s: float
    steps: int
    samples: int

    @property
    def total_s(self) -> float:
        """Estimated wall time of the whole run (steps and samples)."""
        return self.steps * self.step_s + self.samples * self.sample_s

    def describe(self) -> str:
        """E.g. ``about 2 s per step at N = 200000 on this machine, about 3.1 h in all``."""
        return (f"about {format_seconds(self.step_s)} per step at N = {self.n_bodies} on this machine, about "
                f"{format_seconds(self.total_s)} in all")


def format_seconds(seconds: float) -> str:
    """Two significant digits in a unit that reads well: ``3.1 h``, ``2 s``, ``450 us``."""
    units = (("years", 365.25 * 86400.0), ("days", 86400.0), ("h", 3600.0), ("min", 60.0), ("s", 1.0),
             ("ms", 1e-3), ("us", 1e-6))
    unit, size = next((u, z) for u, z in units if seconds >= z or u == "us")
    value = float(f"{seconds / size:.2g}")
    return f"{value:.0f} {unit}" if value >= 10 else f"{value:g} {unit}"


def rough_work(scenario: Scenario, steps: int | None = None) -> float:
    """A machine-free measure of a run's cost: pair interactions, plus per-body and per-step overheads.

    Units: a force evaluation costs N(N-1)/2 pairs plus 16 per body plus 64 per call; a sample costs
    the same again (its potential energy). Only used to skip the estimate for runs that cannot be long.
    """
    steps = scenario.steps if steps is None else steps
    return steps * step_work(scenario) + sample_count(scenario)[0] * _eval_work(scenario.n_bodies)


def _eval_work(n: int) -> float:
    return n * (n - 1) / 2 + 16 * n + 64


def step_work(scenario: Scenario) -> float:
    """:func:`rough_work` of one step."""
    from orbitsim.integrators.registry import get_spec  # noqa: PLC0415 -- lazy: loads numba

    return get_spec(scenario.integrator).force_evals * _eval_work(scenario.n_bodies)


def estimate_time(scenario: Scenario, *, threads: int | None = None, steps: int | None = None,
                  always: bool = False) -> TimeEstimate | None:
    """Estimate the run's wall time by timing its own integrator on this machine.

    The scenario's integrator, dt, G, softening and settings step its first ``n = min(N,``
    :data:`TIMED_BODIES```)`` bodies on one thread for about :data:`TIMING_BUDGET_S`, after one
    warm-up step that loads (or compiles) the kernel the run needs anyway; the fastest of a few
    timings counts, as other processes only ever slow a timing down. One sample's cost is timed
    apart, on the potential energy that dominates it. Cost: about 0.05 s beyond loading kernels.

    Assumptions, each a source of error:

    * both costs grow with the pair count: they are scaled by N(N-1) / (n(n-1)) for N > n (which
      overstates the O(N) kick, drift and Kepler solves a little, and misses that large N leaves
      the L1 cache);
    * from N = 384 (the parallel threshold) the run's threads that have a core to themselves now
      (:func:`usable_threads`) divide that time. One thread is timed because a fork-join kernel on
      a busy machine waits for its slowest thread at every parallel region: at n = 1000 that wait
      outweighs the work (all threads overstated a 20,000-body run five-fold), at large N it does not;
    * the machine stays as busy as it is now, and the subsample's orbits cost what the system's do.

    Parameters
    ----------
    scenario : Scenario
    threads : int, optional
        The run's Numba threads (default: the current count, as the run would get).
    steps : int, optional
        Steps still to take (default: all of them).
    always : bool
        Measure even a run that :func:`rough_work` shows cannot take long.

    Returns
    -------
    TimeEstimate or None
        None for a run below :data:`ESTIMATE_MIN_WORK` whose steps are below :data:`SLOW_STEP_MIN_WORK`
        (not measured at all: it cannot matter), for
        a thread count the run will refuse, when the subsample diverged while being timed, or for
        an adaptive scheme (its step count is not known before it runs), or a run on the GPU (this
        times the CPU's kernels).
    """
    if scenario.adaptive or scenario.device == "gpu":
        return None
    from orbitsim._jit import set_num_threads  # noqa: PLC0415 -- lazy: loads numba
    from orbitsim.physics.gravity import PARALLEL_MIN_N  # noqa: PLC0415 -- lazy: loads numba
    from orbitsim.simulation import Simulation  # noqa: PLC0415 -- lazy: loads numba

    steps = scenario.steps if steps is None else steps
    if not always and rough_work(scenario, steps) < ESTIMATE_MIN_WORK and step_work(scenario) < SLOW_STEP_MIN_WORK:
        return None
    try:
        run_threads = set_num_threads(threads)  # the count the run will use (set as the run would set it)
    except ValueError:
        return None  # the run itself reports a bad thread count
    n = min(scenario.n_bodies, TIMED_BODIES)
    try:
        sim = Simulation(scenario.masses[:n].copy(), scenario.positions[:n].copy(),
                         scenario.velocities[:n].copy(), scenario.integrator, scenario.dt, scenario.G,
                         scenario.softening, 0.0, 1, dict(scenario.integrator_settings))
        sample_s = _time_sample(sim)
        step_s = _time_steps(sim, sample_s)
    finally:
        set_num_threads(run_threads)  # the timing's one thread must not become the run's
    if step_s is None:
        return None
    big = scenario.n_bodies
    scale = big * (big - 1) / (n * (n - 1)) if big > n else 1.0
    if big >= PARALLEL_MIN_N:
        scale /= usable_threads(run_threads)
    return TimeEstimate(n_bodies=big, n_timed=n, step_s=step_s * scale, sample_s=sample_s * scale, steps=steps,
                        samples=sample_count(scenario)[0])


def usable_threads(threads: int) -> float:
    """How many of ``threads`` have a core to themselves now: cores less the load of other processes.

    The 1-minute load average counts runnable processes (this one, timing, among them); what is
    above one is other work, and a core it keeps busy gives a fork-join kernel no speed-up.
    """
    try:
        cores = len(os.sched_getaffinity(0))
        others = max(0.0, os.getloadavg()[0] - 1.0)
    except (AttributeError, OSError):  # not Linux, or no load average: assume a quiet machine
        cores, others = os.cpu_count() or 1, 0.0
    return max(1.0, min(float(threads), cores - others))


def _time_steps(sim: Any, sample_s: float) -> float | None:
    """Seconds per step of ``sim`` (a Simulation), or None if it diverged.

    Each timed call ends on a recorded sample (a plan's targets are its samples), whose cost
    ``sample_s`` is taken off.
    """
    def run(k: int) -> float | None:
        first = sim.steps_done
        start = time.perf_counter()
        with np.errstate(all="ignore"):  # a timing subsample may misbehave; its warnings are not the user's
            for _ in sim.chunks(ExplicitPlan(np.array([first + k], dtype=np.int64)), record_positions=False):
                pass
        elapsed = time.perf_counter() - start
        done = sim.steps_done - first
        if sim.diverged or done == 0:
            return None
        return max(elapsed - sample_s, 0.5 * elapsed) / done  # noise may make the difference tiny

    if run(1) is None:  # warm-up: loads (or compiles) the integrator's kernel
        return None
    once = run(1)
    if once is None:
        return None
    k = int(min(10**7, max(1, TIMING_BUDGET_S / _REPEATS / max(once, 1e-9))))
    times = [run(k) for _ in range(_REPEATS)]
    finite = [t for t in times if t is not None]
    return min(finite) if finite else None


def _time_sample(sim: Any) -> float:
    """Seconds one sample costs: its potential energy (T, P and L are O(N) and cheap beside it)."""
    from orbitsim.physics.diagnostics import potential_energy  # noqa: PLC0415 -- lazy: loads numba

    eps2 = sim.softening * sim.softening
    best = math.inf
    for _ in range(_REPEATS):
        start = time.perf_counter()
        potential_energy(sim.pos, sim.m, sim.G, eps2, sim.rows)
        best = min(best, time.perf_counter() - start)
    return best
