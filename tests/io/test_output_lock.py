"""One writer per output path, and what a user sees when a run was killed before its first checkpoint.

Before the lock, a second ``orbitsim run -o same.h5`` truncated the first run's ``same.h5.tmp``,
failed with a raw HDF5 locking message (exit 1), and the first run then ended ``complete`` with
all-zero masses and empty names. Now the second process is refused (exit 2, one line) before it
touches anything, whichever command it is: ``run``, ``resume``, ``run --from`` or a batch worker.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import h5py
import numpy as np
import pytest

from orbitsim.batch.task import run_case
from orbitsim.io.lock import clear_abandoned_lock, hold_output, lock_path
from orbitsim.io.schema import OutputBusyError
from orbitsim.runner import run_scenario
from orbitsim.scenario import load_scenario

SCENARIO = """\
name: long
units: nbody
integrator: verlet
dt: 0.01
steps: {steps}
output: {{every: 100, positions: false}}
bodies:
  - {{name: star, m: 1.0, x: [0, 0, 0], v: [0, 0, 0]}}
  - {{name: planet, m: 1.0e-3, primary: star, a: 1.0, e: 0.0, M: 0}}
"""
#: Seconds to wait for a child process to reach a given point (cold imports on a busy machine).
TIMEOUT = 120
BUSY = "another orbitsim process is writing this output"


def orbitsim(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "orbitsim", *args], cwd=cwd, capture_output=True, text=True,
                          timeout=600)


def wait_for(path: Path, process: subprocess.Popen[bytes] | None = None) -> None:
    deadline = time.monotonic() + TIMEOUT
    while not path.exists():
        assert process is None or process.poll() is None, "the process ended before it got there"
        assert time.monotonic() < deadline, f"{path} never appeared"
        time.sleep(0.005)


def one_line(result: subprocess.CompletedProcess[str], code: int = 2) -> str:
    assert result.returncode == code, result.stderr
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("orbitsim: error: "), result.stderr
    return lines[0]


@pytest.fixture
def folder(tmp_path: Path) -> Path:
    # Minutes long: the tests stop it (SIGINT) or kill it once they have checked what they need.
    (tmp_path / "long.yaml").write_text(SCENARIO.format(steps=1_000_000_000), encoding="utf-8")
    (tmp_path / "short.yaml").write_text(SCENARIO.format(steps=2000), encoding="utf-8")
    return tmp_path


def test_a_second_run_is_refused_and_the_first_trace_stays_whole(folder: Path) -> None:
    first = subprocess.Popen([sys.executable, "-m", "orbitsim", "run", "long.yaml", "-o", "same.h5", "-q"],
                             cwd=folder, stderr=subprocess.PIPE)
    try:
        wait_for(folder / "same.h5.tmp", first)
        tmp_inode = os.stat(folder / "same.h5.tmp").st_ino
        second = orbitsim("run", "long.yaml", "-o", "same.h5", "--steps", "2000000", "--force", cwd=folder)
        line = one_line(second)
        assert BUSY in line and f"pid {first.pid}" in line and "orbitsim run long.yaml -o same.h5" in line
        assert os.stat(folder / "same.h5.tmp").st_ino == tmp_inode  # the first run's file was not replaced
        first.send_signal(signal.SIGINT)
        assert first.wait(timeout=TIMEOUT) == 130
    finally:
        first.kill()
    with h5py.File(folder / "same.h5", "r") as f:
        assert f.attrs["status"] == "interrupted"
        assert np.array_equal(f["bodies/masses"][()], [1.0, 1e-3])
        assert [n.decode() for n in f["bodies/names"][()]] == ["star", "planet"]
    assert not lock_path(folder / "same.h5").exists()  # removed by its holder at the end


@pytest.fixture
def held(folder: Path) -> Iterator[subprocess.Popen[str]]:
    """Another process holding the lock on ``folder/out.h5`` (a complete trace is already there)."""
    assert orbitsim("run", "short.yaml", "-o", "out.h5", "-q", cwd=folder).returncode == 0
    holder = subprocess.Popen([sys.executable, "-c", "import sys, time\nfrom orbitsim.io.lock import hold_output\n"
                               "with hold_output('out.h5'):\n    print('held', flush=True)\n    time.sleep(600)"],
                              cwd=folder, stdout=subprocess.PIPE, text=True)
    assert holder.stdout.readline().strip() == "held"
    yield holder
    holder.kill()
    holder.wait()


@pytest.mark.parametrize("command", [
    ["run", "short.yaml", "-o", "out.h5", "--force"],
    ["resume", "out.h5"],
    ["run", "--from", "out.h5", "--steps", "100"],
    ["run", "--from", "other.h5", "--steps", "100", "-o", "out.h5", "--force"],
])
def test_every_writing_command_is_refused_while_another_holds_the_output(
        folder: Path, held: subprocess.Popen[str], command: list[str]) -> None:
    if "other.h5" in command:
        assert orbitsim("run", "short.yaml", "-o", "other.h5", "-q", cwd=folder).returncode == 0
    before = {p.name: p.stat().st_mtime_ns for p in folder.iterdir()}
    line = one_line(orbitsim(*command, cwd=folder))
    assert line.startswith("orbitsim: error: out.h5: " + BUSY) and f"pid {held.pid}" in line
    assert {p.name: p.stat().st_mtime_ns for p in folder.iterdir()} == before  # nothing touched


def test_a_batch_worker_records_a_busy_output_as_failed(folder: Path, held: subprocess.Popen[str]) -> None:
    result = run_case(load_scenario(folder / "short.yaml"), str(folder / "out.h5"))
    assert result["status"] == "failed" and BUSY in result["error"]


def test_a_killed_holder_blocks_nobody(folder: Path, held: subprocess.Popen[str]) -> None:
    held.kill()  # SIGKILL: the lock file stays, the kernel drops the lock
    held.wait()
    assert lock_path(folder / "out.h5").exists()
    assert orbitsim("run", "short.yaml", "-o", "out.h5", "--force", "-q", cwd=folder).returncode == 0
    assert not lock_path(folder / "out.h5").exists()


def test_an_abandoned_lock_is_cleared_and_a_held_one_is_kept(folder: Path, held: subprocess.Popen[str]) -> None:
    """What ``orbitsim batch`` does before a rerun and after its shutdown (issue 27, item 11)."""
    out = folder / "out.h5"
    tmp = Path(f"{out}.tmp")
    tmp.write_bytes(b"half a trace")  # as if the holder were writing it
    assert not clear_abandoned_lock(out)  # a live holder: nothing touched
    assert lock_path(out).exists() and tmp.exists() and held.poll() is None
    held.kill()  # SIGKILL: the lock file stays, unlocked, and the .tmp too
    held.wait()
    assert clear_abandoned_lock(out)
    assert not lock_path(out).exists() and not tmp.exists() and out.exists()  # the finished trace stays
    assert not clear_abandoned_lock(out)  # nothing left to clear


def test_the_lock_is_reentrant_in_one_thread_and_exclusive_between_runs(tmp_path: Path) -> None:
    output = tmp_path / "x.h5"
    with hold_output(output) as outer, hold_output(output) as inner:
        assert inner is outer
    assert not lock_path(output).exists()
    (tmp_path / "s.yaml").write_text(SCENARIO.format(steps=10), encoding="utf-8")
    with hold_output(output):
        # The runner takes the same lock: inside the holder's own thread that is allowed.
        assert run_scenario(load_scenario(tmp_path / "s.yaml"), output, handle_signals=False).status == "complete"


def test_a_different_thread_of_the_same_process_is_refused(tmp_path: Path) -> None:
    import threading

    output = tmp_path / "x.h5"
    errors: list[BaseException] = []

    def other() -> None:
        try:
            with hold_output(output):
                pass
        except OutputBusyError as err:
            errors.append(err)

    with hold_output(output):
        thread = threading.Thread(target=other)
        thread.start()
        thread.join()
    assert len(errors) == 1 and "another run in this process" in str(errors[0])


def test_a_run_killed_before_its_first_checkpoint_says_so_and_how_to_rerun(folder: Path) -> None:
    command = ["run", "long.yaml", "-o", "k.h5", "--checkpoint-every", "100000"]
    for _attempt in range(3):  # the kill must land before the first checkpoint (~0.3 s of imports)
        for stale in folder.glob("k.h5*"):
            stale.unlink()
        process = subprocess.Popen([sys.executable, "-m", "orbitsim", *command], cwd=folder,
                                   stderr=subprocess.DEVNULL)
        wait_for(folder / "k.h5.journal", process)
        process.kill()
        process.wait()
        if not (folder / "k.h5.ckpt").exists():
            break
    else:
        pytest.skip("the first checkpoint was always written before the kill landed")
    expected = ("k.h5: the run was killed before its first checkpoint (it saves one before its first step, once its "
                "kernels are compiled), so there is nothing to resume; run it again: `orbitsim run long.yaml -o k.h5 "
                "--checkpoint-every 100000`")
    for _ in range(2):  # a second resume says the same
        assert one_line(orbitsim("resume", "k.h5", cwd=folder)) == f"orbitsim: error: {expected}"
