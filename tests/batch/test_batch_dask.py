"""Sweeps on a real cluster: a ``dask scheduler`` and two ``dask worker`` processes on 127.0.0.1.

The fixture starts the processes itself (each in its own session, so a kill takes the nanny and
its worker together) and always stops them. One test kills a worker mid-sweep with SIGKILL and
checks that the scheduler reran its runs elsewhere and every result arrived.
"""

from __future__ import annotations

import csv
import os
import signal
import socket
import subprocess
import sys
import textwrap
import threading
import time
from pathlib import Path

import h5py
import pytest

from orbitsim.batch.driver import run_sweep
from orbitsim.batch.sweep import load_sweep
from orbitsim.io.trace import read_trace

BIN = Path(sys.executable).parent
HOST = "127.0.0.1"


def free_port() -> int:
    with socket.socket() as s:
        s.bind((HOST, 0))
        return int(s.getsockname()[1])


def wait_for(predicate, timeout: float, what: str) -> None:
    deadline = time.monotonic() + timeout
    while not predicate():
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out after {timeout} s waiting for {what}")
        time.sleep(0.1)


class DaskProcesses:
    """A scheduler and workers started as subprocesses; :meth:`stop` ends every one of them."""

    def __init__(self, tmp: Path) -> None:
        self.tmp = tmp
        self.address = f"tcp://{HOST}:{free_port()}"
        self.workers: list[subprocess.Popen] = []
        self.env = {**os.environ, "NUMBA_NUM_THREADS": "1"}  # 2 workers x 1 thread on 2 cores
        port = self.address.rsplit(":", 1)[1]
        self.scheduler = self._start("scheduler", [str(BIN / "dask"), "scheduler", "--host", HOST, "--port", port,
                                                   "--no-dashboard"])

    def _start(self, name: str, command: list[str]) -> subprocess.Popen:
        log = open(self.tmp / f"{name}.log", "w")
        return subprocess.Popen(command, stdout=log, stderr=subprocess.STDOUT, env=self.env,
                                start_new_session=True)

    def add_worker(self) -> subprocess.Popen:
        proc = self._start(f"worker{len(self.workers)}", [
            str(BIN / "dask"), "worker", self.address, "--host", HOST, "--nworkers", "1", "--nthreads", "1",
            "--no-dashboard", "--local-directory", str(self.tmp / "dask-worker-space"), "--death-timeout", "60"])
        self.workers.append(proc)
        return proc

    @staticmethod
    def kill(proc: subprocess.Popen) -> None:
        """SIGKILL the process and everything it started (its session), then reap it."""
        if proc.poll() is None:
            try:
                os.killpg(proc.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
        proc.wait(timeout=30)

    def stop(self) -> None:
        for proc in [*self.workers, self.scheduler]:
            self.kill(proc)


@pytest.fixture
def dask_cluster(tmp_path):
    from distributed import Client

    procs = DaskProcesses(tmp_path)
    try:
        procs.add_worker()
        procs.add_worker()
        wait_for(lambda: "Scheduler at" in (tmp_path / "scheduler.log").read_text(), 60, "the scheduler to listen")
        # A loaded machine can drop the very first connection while the scheduler finishes starting
        # (seen as CommClosedError during register-client): retry the handshake a few times.
        for attempt in range(5):
            try:
                with Client(procs.address, timeout="60s") as client:
                    client.wait_for_workers(2, timeout=120)
                    pids = client.run(os.getpid)  # worker address -> pid of the worker process
                break
            except OSError:
                if attempt == 4:
                    raise
                time.sleep(1.0)
        yield procs, pids
    finally:
        procs.stop()


def sweep_file(tmp_path: Path, n: int, steps: int) -> Path:
    dts = ", ".join(repr(0.01 * (1 + i / 16)) for i in range(n))
    path = tmp_path / "sweep.yaml"
    path.write_text(textwrap.dedent(f"""
        base: two_body_circular
        overrides: {{steps: {steps}, output.every: 1000}}
        grid: {{dt: [{dts}]}}
    """))
    return path


def test_cli_runs_a_sweep_on_an_existing_scheduler(dask_cluster, tmp_path):
    procs, pids = dask_cluster
    out = tmp_path / "out"
    result = subprocess.run([str(BIN / "orbitsim"), "batch", str(sweep_file(tmp_path, 4, 2000)), "-o", str(out),
                             "--scheduler", procs.address, "--no-progress"],
                            capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr
    assert f"on Dask scheduler {procs.address}" in result.stderr
    with open(out / "summary.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert [r["status"] for r in rows] == ["complete"] * 4
    assert {r["worker"] for r in rows} <= set(pids)


def test_a_worker_killed_mid_sweep_loses_no_result(dask_cluster, tmp_path):
    from distributed import Client

    procs, pids = dask_cluster
    sweep = load_sweep(sweep_file(tmp_path, 8, 4_000_000))  # 0.4 s (quiet) to 2 s (busy) per run
    out = tmp_path / "out"
    outcome: dict = {}
    thread = threading.Thread(target=lambda: outcome.update(result=run_sweep(sweep, out, scheduler=procs.address)),
                              daemon=True)
    thread.start()
    with Client(procs.address, timeout="60s") as watcher:
        # Kill a worker while it is running one of our tasks, before the sweep is over.
        def busy_worker() -> str | None:
            busy = [w for w, keys in watcher.processing().items() if keys]
            return busy[0] if len(busy) == 2 else None

        wait_for(lambda: busy_worker() is not None, 120, "both workers to be running runs")
        victim = busy_worker()
    # Each `dask worker` runs in its own session: the worker's process group names its Popen.
    group = os.getpgid(pids[victim])
    procs.kill(next(p for p in procs.workers if p.pid == group))
    thread.join(timeout=300)
    assert not thread.is_alive(), "the sweep did not finish after a worker was killed"
    rows = outcome["result"].rows
    assert [r["status"] for r in rows] == ["complete"] * 8, [r["error"] for r in rows]
    survivor = next(w for w in pids if w != victim)
    assert survivor in {r["worker"] for r in rows}
    for case, row in zip(sweep.cases, rows, strict=True):
        trace = read_trace(out / row["trace"])
        assert trace.attrs["status"] == "complete" and trace.attrs["scenario_sha256"] == case.scenario.sha256
        with h5py.File(out / row["trace"]) as f:
            assert int(f["step"][-1]) == 4_000_000
    assert not list((out / "runs").glob("*.tmp"))
