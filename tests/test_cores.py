"""The default thread count: one per core other processes leave free (orbitsim.cores).

With one of two cores taken by another process, the default two threads made an N = 2,000
cluster 2.4x slower than one thread (the fork-join kernel waits for the thread that shares the
busy core at every evaluation). A run given no count now measures how busy the cores are and
takes one thread per free core; a count that is asked for still rules; ``orbitsim info`` shows
the choice. The measurement itself is replaced by a fixed value where a test needs one (the
machine running the tests is shared, its load is anything), and checked against a real busy
process where only its direction matters.
"""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import numba
import pytest
from click.testing import CliRunner

import orbitsim.cores as cores
from orbitsim.initial_conditions.generators import plummer
from orbitsim.physics.gravity import PARALLEL_MIN_N
from orbitsim.simulation import Simulation

needs_two = pytest.mark.skipif(numba.config.NUMBA_NUM_THREADS < 2, reason="needs NUMBA_NUM_THREADS >= 2")


@pytest.fixture
def machine(monkeypatch: pytest.MonkeyPatch):
    """A two-core machine whose other processes keep ``busy`` cores busy (set by the test)."""
    state = {"busy": 0.0, "measured": 0}

    def busy_cores(window_s: float = cores.WINDOW_S) -> float:
        state["measured"] += 1
        return state["busy"]

    monkeypatch.setattr(cores, "busy_cores", busy_cores)
    monkeypatch.setattr(cores, "usable_cores", lambda: [0, 1])
    before = numba.get_num_threads()
    yield state
    numba.set_num_threads(before)


def _simulation(n: int, threads: int | None = None) -> Simulation:
    m, x, v = plummer(n, seed=1)
    return Simulation(m, x, v, "verlet", 1e-3, softening=0.01, threads=threads)


@needs_two
def test_one_core_busy_gives_one_thread(machine) -> None:
    machine["busy"] = 1.0
    sim = _simulation(PARALLEL_MIN_N)
    assert sim.threads_used == 1 == numba.get_num_threads()
    assert sim.threads_choice == "default: 1 of 2 cores free, 1.0 busy with other processes"


@needs_two
@pytest.mark.parametrize(("busy", "threads"), [(0.0, 2), (0.3, 2), (0.5, 1), (0.9, 1), (2.0, 1), (3.5, 1)])
def test_a_core_counts_when_two_thirds_of_it_are_free(machine, busy: float, threads: int) -> None:
    machine["busy"] = busy
    assert _simulation(PARALLEL_MIN_N).threads_used == threads


@needs_two
def test_a_count_asked_for_rules(machine) -> None:
    machine["busy"] = 2.0
    sim = _simulation(PARALLEL_MIN_N, threads=2)
    assert sim.threads_used == 2 and sim.threads_choice == "as asked"
    assert machine["measured"] == 0  # nothing to measure


def test_small_systems_measure_nothing(machine) -> None:
    """Below N = 384 the kernels run on one thread whatever the count: no 0.1 s measurement."""
    sim = _simulation(PARALLEL_MIN_N - 1)
    assert machine["measured"] == 0 and "below N = 384" in sim.threads_choice


def test_never_more_than_numba_can_run(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(cores, "busy_cores", lambda window_s=cores.WINDOW_S: 0.0)
    monkeypatch.setattr(cores, "usable_cores", lambda: list(range(8)))
    assert cores.choose_threads(None, 2, True) == (2, "default: 8 of 8 cores free, 0.0 busy with other processes, "
                                                     "at most 2 (NUMBA_NUM_THREADS)")


@pytest.mark.skipif(not Path("/proc/stat").is_file(), reason="needs /proc/stat (Linux)")
def test_a_spinning_process_is_seen_busy(monkeypatch: pytest.MonkeyPatch) -> None:
    """The real measurement: a process that spins keeps about one core busy, so at least half a
    core reads busy and one thread fewer than the cores is chosen (more load elsewhere only adds)."""
    usable = cores.usable_cores()
    if len(usable) < 2:
        pytest.skip("needs two usable cores")
    spinner = subprocess.Popen([sys.executable, "-c", "while True: pass"])
    try:
        time.sleep(0.3)  # started and spinning
        monkeypatch.setattr(cores, "_last", None)  # no reuse of an earlier measurement
        busy = cores.busy_cores()
        monkeypatch.setattr(cores, "_last", None)
        threads, why = cores.choose_threads(None, len(usable), True)
    finally:
        spinner.kill()
        spinner.wait()
    assert busy >= 0.5
    assert threads <= len(usable) - 1 and why.startswith(f"default: {threads} of {len(usable)} cores free")


@needs_two
def test_info_shows_the_choice(machine, tmp_path: Path) -> None:
    from orbitsim.cli.main import cli

    machine["busy"] = 1.0
    scenario = tmp_path / "cluster.yaml"
    scenario.write_text(f"name: cluster\nintegrator: verlet\ndt: 0.001\nsteps: 2\nsoftening: 0.01\n"
                        f"generator: {{kind: plummer, n: {PARALLEL_MIN_N}, seed: 1}}\n", encoding="utf-8")
    out = tmp_path / "cluster.h5"
    runner = CliRunner()
    run = runner.invoke(cli, ["run", str(scenario), "-o", str(out), "-q"])
    assert run.exit_code == 0, run.output
    info = runner.invoke(cli, ["info", str(out)])
    assert info.exit_code == 0, info.output
    line = next(line for line in info.output.splitlines() if line.strip().startswith("threads "))
    assert line.split() == ["threads", "1", "(default:", "1", "of", "2", "cores", "free,", "1.0", "busy", "with",
                            "other", "processes)"]
    asked = runner.invoke(cli, ["run", str(scenario), "-o", str(out), "-q", "--force", "--threads", "2"])
    assert asked.exit_code == 0, asked.output
    info = runner.invoke(cli, ["info", str(out)])
    assert "  threads              2 (as asked)" in info.output.splitlines()
