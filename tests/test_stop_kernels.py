"""A stop (Ctrl-C, SIGTERM) reaches a kernel that runs for minutes, and the step it cuts is undone.

At N = 10^6 one step takes minutes and a SIGINT used to take effect only once it ended (586 s).
The O(N^2) kernels now look at a stop flag between row blocks (``orbitsim._jit.stop_requested``),
the main thread waits on the call instead of running it (``orbitsim.stopping.run_interruptible``),
and a stopped call is undone so the state stays the last whole step. These tests check each part:
the kernels honour the flag (and give the same bits without it), cached kernels in a new process
honour it too, a stopped call leaves the state exactly as before it and the run continues bit for
bit, and a run stopped by SIGINT in the middle of a long call ends with a trace that
``orbitsim resume`` completes into the bits of an uninterrupted run.

Long calls are made by letting the call budget grow without bound (``next_budget``): a call then
spans thousands of steps at N = 2048, seconds even on a fast machine, so a signal sent a fraction
of a second after it starts lands inside it. No assertion is on a time.
"""

from __future__ import annotations

import functools
import os
import signal
import subprocess
import sys
import threading

import numpy as np
import pytest

import orbitsim.simulation as simulation_module
from orbitsim._jit import stop_kernels, stop_requested
from orbitsim.initial_conditions.generators import plummer
from orbitsim.physics.diagnostics import potential_energy, potential_rows_scratch
from orbitsim.physics.force_context import make_force
from orbitsim.physics.gravity import PARALLEL_MIN_N, accelerations
from orbitsim.sampling import ExplicitPlan
from orbitsim.simulation import INTERRUPTIBLE_MIN_N, Simulation

N_LONG = INTERRUPTIBLE_MIN_N  # the smallest N whose calls can be stopped inside


@pytest.fixture
def stop_flag():
    """The stop flag, lowered again whatever the test does."""
    yield stop_kernels
    stop_kernels(False)


def _system(n: int, seed: int = 3) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    return rng.random(n) / n, rng.standard_normal((3, n)), np.zeros((3, n))


@pytest.mark.parametrize("n", [200, 1000])  # one block of rows (serial), and 16 blocks on the threads
def test_force_kernel_stops_when_asked_and_keeps_its_bits_otherwise(stop_flag, n: int) -> None:
    m, pos, _ = _system(n)
    G, eps2, slabs, bounds, _ = make_force(1.0, 0.01, n)
    assert (bounds.shape[0] > 2) == (n >= PARALLEL_MIN_N)
    reference = np.zeros((3, n))
    accelerations(pos, m, G, eps2, reference, slabs, bounds)
    stop_flag(True)
    stopped = np.full((3, n), 7.0)
    accelerations(pos, m, G, eps2, stopped, slabs, bounds)
    assert np.all(stopped == 7.0)  # it returned before touching acc
    stop_flag(False)
    again = np.zeros((3, n))
    accelerations(pos, m, G, eps2, again, slabs, bounds)
    assert again.tobytes() == reference.tobytes()


def test_row_loops_stop_between_rows(stop_flag) -> None:
    """The loops themselves (not only the dispatcher) look at the flag: a stop raised before a
    row loop starts leaves every row undone."""
    from orbitsim.physics.gravity import _accumulate_rows

    n = 1000
    m, pos, _ = _system(n)
    ax, ay, az = np.zeros(n), np.zeros(n), np.zeros(n)
    stop_flag(True)
    _accumulate_rows(pos[0], pos[1], pos[2], m, 1e-4, 0, n, ax, ay, az)
    rows = np.full(n, np.nan)  # the parallel potential's row partials: untouched rows stay NaN
    stopped = potential_energy(pos, m, 1.0, 1e-4, rows)
    stop_flag(False)
    assert not ax.any() and not ay.any() and not az.any()
    assert np.isnan(stopped)
    assert np.isfinite(potential_energy(pos, m, 1.0, 1e-4, potential_rows_scratch(n)))


def test_kernels_loaded_from_the_cache_see_the_flag(tmp_path) -> None:
    """The flag is a C symbol the compiled code names; a new process that loads the kernels from
    Numba's on-disk cache (not compiling them) must resolve it to its own flag."""
    script = (
        "import numpy as np\n"
        "from orbitsim._jit import stop_kernels\n"
        "from orbitsim.physics.force_context import make_force\n"
        "from orbitsim.physics.gravity import accelerations, accelerations_parallel\n"
        "n = 1000\n"
        "rng = np.random.default_rng(1)\n"
        "m, pos = rng.random(n), rng.standard_normal((3, n))\n"
        "G, eps2, slabs, bounds, _ = make_force(1.0, 0.01, n)\n"
        "acc = np.zeros((3, n))\n"
        "accelerations_parallel(pos, m, G, eps2, acc, slabs, bounds)\n"
        "moved = bool(acc.any())\n"
        "stop_kernels(True)\n"
        "acc[...] = 0.0\n"
        "accelerations_parallel(pos, m, G, eps2, acc, slabs, bounds)\n"
        "stats = accelerations_parallel.stats\n"
        "print(moved, bool(acc.any()), sum(stats.cache_hits.values()), sum(stats.cache_misses.values()))\n"
    )
    runs = [subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=600)
            for _ in range(2)]  # the first may compile and store; the second must load
    for run in runs:
        assert run.returncode == 0, run.stderr
    moved, after_stop, hits, misses = runs[1].stdout.split()
    assert moved == "True" and after_stop == "False"
    assert int(hits) >= 1 and int(misses) == 0


class _InterruptError(Exception):
    """What the test's signal handler raises in the main thread (as KeyboardInterrupt would)."""


def _long_calls(monkeypatch: pytest.MonkeyPatch, calls_before: int = 2) -> None:
    """From the ``calls_before + 1``-th jitted call on, a call runs to the next target however far."""
    seen = {"calls": 0}

    def budget(budget: int, elapsed: float) -> int:
        seen["calls"] += 1
        return 3 if seen["calls"] < calls_before else 10**9

    monkeypatch.setattr(simulation_module, "next_budget", budget)


def _signal_soon(signum: int, delay: float = 0.3) -> threading.Timer:
    timer = threading.Timer(delay, os.kill, (os.getpid(), signum))
    timer.start()
    return timer


def _arrays(sim: Simulation) -> bytes:
    work = b"".join(a.tobytes() for a in sim._changing_arrays()[4:])
    return sim.pos.tobytes() + sim.vel.tobytes() + sim.acc.tobytes() + sim.m.tobytes() + work


def test_a_stopped_call_is_undone_and_the_run_goes_on_bit_for_bit(monkeypatch, stop_flag) -> None:
    m, x, v = plummer(N_LONG, seed=2)
    make = functools.partial(Simulation, m, x, v, "leapfrog4", 1e-3, softening=0.01, threads=1)
    twin, sim = make(), make()
    for _ in twin.chunks(ExplicitPlan(np.array([4]))):
        pass
    at_four = _arrays(twin)
    for _ in sim.chunks(ExplicitPlan(np.array([3]))):
        pass
    # The next chunks: one step (the first call's budget), then one call to step 10^5 (minutes).
    _long_calls(monkeypatch, calls_before=1)
    previous = signal.signal(signal.SIGUSR1, lambda *_: (_ for _ in ()).throw(_InterruptError()))
    try:
        timer = _signal_soon(signal.SIGUSR1)
        with pytest.raises(_InterruptError):
            for _ in sim.chunks(ExplicitPlan(np.array([10**5]))):
                pass
        timer.join()
    finally:
        signal.signal(signal.SIGUSR1, previous)
    assert sim.call_undone and sim.steps_done == 4
    assert _arrays(sim) == at_four  # state, accelerations, masses and the scheme's work as before the call
    assert not stop_requested()
    monkeypatch.undo()
    for chunks in (sim.chunks(ExplicitPlan(np.array([7]))), twin.chunks(ExplicitPlan(np.array([7])))):
        for _ in chunks:
            pass
    assert sim.steps_done == twin.steps_done == 7 and _arrays(sim) == _arrays(twin)


def _scenario(tmp_path, steps: int):
    from orbitsim.scenario import load_scenario

    path = tmp_path / "long.yaml"
    path.write_text(f"name: long\nintegrator: verlet\ndt: 0.001\nsteps: {steps}\nsoftening: 0.01\n"
                    f"output: {{every: {steps}, positions: true}}\n"
                    f"generator: {{kind: plummer, n: {N_LONG}, seed: 5}}\n", encoding="utf-8")
    return load_scenario(str(path))


@pytest.mark.slow  # a long call of every kind of loop, stopped (~17 s cold)
def test_sigint_inside_a_long_call_keeps_the_last_whole_step_and_resumes_bit_for_bit(monkeypatch, tmp_path) -> None:
    """The runner's own SIGINT handling: the Stopper stops at once while the main thread waits on
    kernels, the call in flight is undone (its samples are not written), and the trace keeps the
    state of the step before it, from which ``resume`` completes the run into the same bits as a
    run never stopped. Before, the whole call ran to its end (and wrote its sample) first."""
    from orbitsim.checkpoint import prepare_resume
    from orbitsim.io.trace import read_trace
    from orbitsim.runner import run_scenario

    steps = 2000  # one call of ~2000 steps of 2048 bodies: seconds on any machine
    scenario = _scenario(tmp_path, steps)
    reference = read_trace(run_scenario(scenario, tmp_path / "ref.h5", threads=1).output)
    _long_calls(monkeypatch)  # calls: step 0's sample, 3 steps, then the rest in one call
    started: list[threading.Timer] = []

    def progress(done: int, total: int) -> None:
        if done == 3 and not started:  # the long call starts as this returns
            started.append(_signal_soon(signal.SIGINT))

    out = tmp_path / "stopped.h5"
    summary = run_scenario(scenario, out, threads=1, progress=progress)
    started[0].join()
    assert summary.status == "interrupted" and summary.exit_code == 130
    assert summary.resumable and summary.steps_done == 3
    stopped = read_trace(out)
    assert list(stopped.step) == [0]  # the long call's sample (step 2000) was never written
    assert stopped.attrs["steps_done"] == 3
    monkeypatch.undo()
    plan = prepare_resume(out)
    resumed = read_trace(run_scenario(plan.scenario, plan.output, start=plan.start, threads=1).output)
    assert resumed.attrs["status"] == "complete"
    assert list(resumed.step) == list(reference.step) == [0, steps]
    assert resumed.positions.tobytes() == reference.positions.tobytes()
    assert resumed.velocities.tobytes() == reference.velocities.tobytes()
    assert resumed.energy.tobytes() == reference.energy.tobytes()


def test_a_call_in_another_thread_is_redone_when_a_stop_cut_it(stop_flag) -> None:
    """The flag is one per process: a run in another thread whose kernels it cut short repeats the
    call (restored first), so its results never come from a cut-short kernel."""
    from orbitsim.stopping import run_interruptible

    n = 1000
    m, pos, _ = _system(n)
    G, eps2, slabs, bounds, _ = make_force(1.0, 0.01, n)
    reference = np.zeros((3, n))
    accelerations(pos, m, G, eps2, reference, slabs, bounds)
    calls = {"made": 0, "restored": 0}
    acc = np.zeros((3, n))

    def call() -> None:
        calls["made"] += 1
        if calls["made"] == 1:
            stop_flag(True)  # as if the main thread's run were stopped during this call
            accelerations(pos, m, G, eps2, acc, slabs, bounds)
            stop_flag(False)
        else:
            accelerations(pos, m, G, eps2, acc, slabs, bounds)

    def restore() -> None:
        calls["restored"] += 1

    worker = threading.Thread(target=run_interruptible, args=(call, 1, restore))
    worker.start()
    worker.join()
    assert calls == {"made": 2, "restored": 1}
    assert acc.tobytes() == reference.tobytes()
