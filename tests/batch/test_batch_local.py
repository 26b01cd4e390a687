"""Sweeps on an embedded LocalCluster: results, failures, resume, and bit-identical output.

One two-worker cluster serves the whole module (starting one costs a few seconds on 2 cores).
"""

from __future__ import annotations

import contextlib
import csv
import math
import os
import resource
import shutil
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import h5py
import numpy as np
import pytest
from click.testing import CliRunner
from suite_split import fast_only

from orbitsim.batch.cluster import ClusterPlan, open_client
from orbitsim.batch.driver import SweepInterrupted, run_sweep, trace_path_for
from orbitsim.batch.sweep import load_sweep
from orbitsim.cli.main import cli
from orbitsim.io.trace import read_trace

ORBITSIM = str(Path(sys.executable).with_name("orbitsim"))
TRACE_DATASETS = ("time", "step", "kinetic", "potential", "energy", "energy_error", "momentum",
                  "angular_momentum", "positions", "velocities")
#: Summary columns that legitimately differ between two identical sweeps.
TIMING_COLUMNS = ("wall_time_s", "steps_per_second", "worker", "resumed")


@pytest.fixture(scope="module")
def client():
    with open_client(None, ClusterPlan(workers=2, threads=1)) as c:
        yield c


def write_sweep(tmp_path: Path, body: str, name: str = "sweep.yaml") -> Path:
    path = tmp_path / name
    path.write_text(textwrap.dedent(body))
    return path


def grid_sweep(tmp_path: Path, n: int, steps: int = 2000, every: int = 100) -> Path:
    """``n`` two-body verlet runs that differ in dt only."""
    dts = ", ".join(repr(0.01 * (1 + i / 16)) for i in range(n))
    return write_sweep(tmp_path, f"""
        base: two_body_circular
        overrides: {{steps: {steps}, output.every: {every}}}
        grid: {{dt: [{dts}]}}
    """)


def read_csv(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def test_failed_and_diverged_runs_are_recorded_and_the_others_complete(client, tmp_path):
    sweep = load_sweep(write_sweep(tmp_path, """
        base: two_body_circular
        overrides: {steps: 500}
        cases:
          - {dt: 0.01}
          - {dt: 0.02}
          # The planet 1e-200 from the star: the first kick overflows, the run diverges.
          - {bodies.1: {name: planet, m: 1.0e-3, x: [1.0e-200, 0, 0], v: [0, 0, 0]}}
          - {dt: 0.03}
    """))
    out = tmp_path / "out"
    blocked = trace_path_for(out.resolve(), sweep.cases[3])
    blocked.mkdir(parents=True)  # its trace cannot be written: the run fails at run time
    outcome = run_sweep(sweep, out, client=client)
    status = [row["status"] for row in outcome.rows]
    assert status == ["complete", "complete", "diverged", "failed"]
    assert "non-finite" in outcome.rows[2]["error"] and outcome.rows[2]["steps_done"] >= 0
    assert "is a directory" in outcome.rows[3]["error"] and math.isnan(outcome.rows[3]["max_abs_energy_error"])
    assert outcome.rows[3]["trace"] == ""
    rows = read_csv(out / "summary.csv")
    assert [r["status"] for r in rows] == status and rows[3]["error"] == outcome.rows[3]["error"]
    assert all(r["worker"].startswith("tcp://127.0.0.1:") for r in rows)
    assert read_trace(out / rows[2]["trace"]).attrs["status"] == "diverged"
    with h5py.File(out / "summary.h5") as f:
        assert list(f["status"].asstr()[()]) == status


def _limit_file_size(limit: int) -> None:
    resource.setrlimit(resource.RLIMIT_FSIZE, (limit, resource.getrlimit(resource.RLIMIT_FSIZE)[1]))


def test_a_run_whose_disk_write_fails_is_a_failed_row_with_the_reason(client, tmp_path):
    # A real I/O error in the middle of a run, on the workers: a file-size limit makes a write fail
    # with EFBIG ("File too large") as a full disk fails one with ENOSPC. It used to crash workers.
    sweep = load_sweep(write_sweep(tmp_path, """
        base: two_body_circular
        overrides: {steps: 2000, output.every: 100}
        cases:
          - {dt: 0.01}
          - {dt: 0.02, steps: 200000, output.every: 1}   # ~20 MB of samples
          - {dt: 0.03}
    """))
    out = tmp_path / "out"
    hard = client.run(lambda: resource.getrlimit(resource.RLIMIT_FSIZE)[1])
    client.run(_limit_file_size, 1_000_000)
    try:
        outcome = run_sweep(sweep, out, client=client)
    finally:
        client.run(_limit_file_size, min(hard.values()))
    assert [row["status"] for row in outcome.rows] == ["complete", "failed", "complete"]
    error = outcome.rows[1]["error"]
    # The reason first: the terminal table shows an error's first 40 characters.
    assert error.startswith("File too large") and "\n" not in error and outcome.rows[1]["trace"] == ""
    rows = read_csv(out / "summary.csv")
    assert [r["status"] for r in rows] == ["complete", "failed", "complete"] and rows[1]["error"] == error
    assert not list((out / "runs").glob("*.tmp"))
    result = CliRunner().invoke(cli, ["batch", str(tmp_path / "sweep.yaml"), "-o", str(out), "--workers", "1"])
    assert result.exit_code == 0, result.output  # the failed run is rerun, and completes without the limit


def test_skip_invalid_runs_the_valid_cases_and_lists_the_invalid_ones(tmp_path):
    path = write_sweep(tmp_path, """
        base: two_body_circular
        overrides: {steps: 200}
        grid:
          integrator: [verlet, rk4]
          dt: [0.01, 0.0]
    """)
    out = tmp_path / "out"
    result = CliRunner().invoke(cli, ["batch", str(path), "-o", str(out), "--workers", "1", "--no-progress"])
    assert result.exit_code == 2 and not out.exists()  # the default: the sweep is refused
    command = ["batch", str(path), "-o", str(out), "--workers", "1", "--no-progress", "--skip-invalid"]
    result = CliRunner().invoke(cli, command)
    assert result.exit_code == 1, result.output
    reason = "grid.dt[1]: must be non-zero (> 0 runs forwards, < 0 backwards), got 0 (line 6)"
    assert result.stderr.splitlines()[-1] == (
        f"orbitsim: error: 2 invalid case(s) skipped (cases 1, 3: {reason}); the errors are in the summary")
    assert "4 runs: 2 complete, 2 invalid; 0 reused" in result.stdout
    table = result.stdout.splitlines()
    assert [line.split()[0] for line in table[1:5]] == ["0", "1", "2", "3"]
    assert "invalid" in table[2] and "grid.dt[1]: must be non-zero" in table[2]
    rows = read_csv(out / "summary.csv")
    assert [r["status"] for r in rows] == ["complete", "invalid", "complete", "invalid"]
    assert [(r["run_id"], r["trace"], r["error"]) for r in rows[1::2]] == [("", "", reason)] * 2
    assert [(r["integrator"], r["dt"]) for r in rows[1::2]] == [("verlet", "0.0"), ("rk4", "0.0")]
    with h5py.File(out / "summary.h5") as f:
        assert list(f["status"].asstr()[()]) == ["complete", "invalid", "complete", "invalid"]
        assert list(f["run_id"].asstr()[()])[1::2] == ["", ""] and list(f["params/dt"][()]) == [0.01, 0.0] * 2
    again = CliRunner().invoke(cli, command)
    assert again.exit_code == 1 and "4 runs: 2 complete, 2 invalid; 2 reused" in again.stdout


def test_resume_skips_complete_matching_traces_and_reruns_the_rest(client, tmp_path):
    sweep = load_sweep(grid_sweep(tmp_path, 4))
    out = tmp_path / "out"
    first = run_sweep(sweep, out, client=client)
    assert first.counts["complete"] == 4 and first.resumed == 0
    paths = [out / row["trace"] for row in first.rows]
    paths[0].unlink()  # lost
    shutil.copy(paths[2], paths[1])  # complete, but of another scenario: must not be trusted
    kept = paths[3].stat().st_mtime_ns
    second = run_sweep(sweep, out, client=client)
    assert [row["resumed"] for row in second.rows] == [False, False, True, True]
    assert second.counts["complete"] == 4 and paths[3].stat().st_mtime_ns == kept
    for case, path in zip(sweep.cases, paths, strict=True):
        assert read_trace(path).attrs["scenario_sha256"] == case.scenario.sha256
    # Resumed rows keep the numbers and the worker of the run that made them.
    assert second.rows[3]["max_abs_energy_error"] == first.rows[3]["max_abs_energy_error"]
    assert second.rows[3]["worker"] == first.rows[3]["worker"]
    third = run_sweep(sweep, out, client=client, resume=False)
    assert third.resumed == 0 and not any(row["resumed"] for row in third.rows)


def test_results_do_not_depend_on_the_number_of_workers(client, tmp_path):
    sweep = load_sweep(grid_sweep(tmp_path, 6))
    two = run_sweep(sweep, tmp_path / "two", client=client)
    one = run_sweep(sweep, tmp_path / "one", workers=1)
    for a, b in zip(two.rows, one.rows, strict=True):
        assert a["trace"] == b["trace"]
        with h5py.File(tmp_path / "two" / a["trace"]) as fa, h5py.File(tmp_path / "one" / b["trace"]) as fb:
            for name in TRACE_DATASETS:
                assert np.array_equal(fa[name][()], fb[name][()]), name
    rows_two, rows_one = read_csv(tmp_path / "two" / "summary.csv"), read_csv(tmp_path / "one" / "summary.csv")
    for a, b in zip(rows_two, rows_one, strict=True):
        assert {k: v for k, v in a.items() if k not in TIMING_COLUMNS} == \
            {k: v for k, v in b.items() if k not in TIMING_COLUMNS}


def test_cli_rejects_an_invalid_sweep_with_exit_2_and_writes_nothing(tmp_path):
    path = write_sweep(tmp_path, """
        base: two_body_circular
        grid: {dt: [0.01, 0.02, 0.0]}
    """)
    result = CliRunner().invoke(cli, ["batch", str(path), "-o", str(tmp_path / "out")])
    assert result.exit_code == 2
    assert (f"orbitsim: error: {path}: grid.dt[2]: must be non-zero (> 0 runs forwards, < 0 backwards), got 0 "
            "(line 3)") in result.output
    assert not (tmp_path / "out").exists()


def test_cli_reports_an_unreachable_scheduler(tmp_path, monkeypatch):
    import orbitsim.batch.cluster as cluster

    monkeypatch.setattr(cluster, "CONNECT_TIMEOUT_S", 1.0)
    path = grid_sweep(tmp_path, 1)
    result = CliRunner().invoke(cli, ["batch", str(path), "-o", str(tmp_path / "out"),
                                      "--scheduler", "tcp://127.0.0.1:9"])
    assert result.exit_code == 2
    assert "orbitsim: error: cannot reach tcp://127.0.0.1:9" in result.output
    assert not (tmp_path / "out").exists()


def wait_for(predicate, timeout: float, what: str) -> None:
    deadline = time.monotonic() + timeout
    while not predicate():
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out after {timeout} s waiting for {what}")
        time.sleep(0.1)


def process_group_alive(pgid: int) -> bool:
    """Whether a process of the group is still running (zombies waiting for a reaper do not count)."""
    if not Path("/proc/self/stat").is_file():
        try:
            os.killpg(pgid, 0)
        except ProcessLookupError:
            return False
        return True
    for stat in Path("/proc").glob("[0-9]*/stat"):
        with contextlib.suppress(OSError, IndexError, ValueError):
            fields = stat.read_text().rsplit(")", 1)[1].split()  # state, ppid, pgrp, ...
            if int(fields[2]) == pgid and fields[0] != "Z":
                return True
    return False


@pytest.mark.parametrize("presses", fast_only([1, 2], [1]))  # a sweep interrupted twice: 12 s, make test-slow
def test_ctrl_c_is_one_line_exit_130_and_a_summary_of_what_really_finished(tmp_path, presses):
    # Ctrl-C in a terminal sends SIGINT to the whole foreground process group: the driver and the
    # local cluster's workers alike. Eight equal runs of ~0.5 s (quiet machine) to a few seconds
    # (busy) on two workers: when the first trace appears the second run is usually finishing too
    # and the next is in flight, so some runs end while the cluster shuts down (they used to be
    # listed as `not run`); the rest are queued and cancelled.
    path = grid_sweep(tmp_path, 8, steps=10_000_000, every=1000)
    out = tmp_path / "out"
    command = [ORBITSIM, "batch", str(path), "-o", str(out), "--workers", "2", "--no-progress"]
    proc = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)
    try:
        wait_for(lambda: any((out / "runs").glob("*.h5")), 300, "the first finished run")
        os.killpg(proc.pid, signal.SIGINT)
        if presses == 2:
            time.sleep(0.2)  # while it cancels, closes the cluster and writes the summary
            with contextlib.suppress(ProcessLookupError):
                os.killpg(proc.pid, signal.SIGINT)
        _, err = proc.communicate(timeout=120)
        wait_for(lambda: not process_group_alive(proc.pid), 30, "the workers to exit")
    finally:
        if process_group_alive(proc.pid):
            os.killpg(proc.pid, signal.SIGKILL)
        if proc.poll() is None:
            proc.wait()
    lines = err.splitlines()
    assert proc.returncode == 130, err
    assert len(lines) == 2 and lines[0].startswith("running 8 run(s) on local Dask cluster"), err
    assert lines[1].startswith("orbitsim: error: interrupted; ") and "run the same command again" in lines[1]
    # What the summary says finished is exactly what is on disk, runs completed during the shutdown included.
    rows = read_csv(out / "summary.csv")
    done = {p.stem for p in (out / "runs").glob("*.h5")}
    assert {r["run_id"] for r in rows if r["status"] == "complete"} == done
    assert all(r["status"] == "not run" and r["trace"] == "" for r in rows if r["run_id"] not in done)
    assert 1 <= len(done) < 8  # the queued runs were cancelled
    assert f"{len(done)} of 8 run(s) finished, {8 - len(done)} not run" in lines[1]
    with h5py.File(out / "summary.h5") as f:
        assert list(f["status"].asstr()[()]) == [r["status"] for r in rows] and f.attrs["interrupted"]
    rerun = subprocess.run(command, capture_output=True, text=True, timeout=300)
    assert rerun.returncode == 0, rerun.stderr
    rows = read_csv(out / "summary.csv")
    assert [r["status"] for r in rows] == ["complete"] * 8
    assert {r["run_id"] for r in rows if r["resumed"] == "true"} == done
    assert f"{len(done)} reused from earlier traces" in rerun.stdout
    assert not list((out / "runs").glob("*.tmp"))


@pytest.mark.parametrize("target", ["driver", "group"])
def test_sigterm_is_handled_like_ctrl_c(tmp_path, target):
    # SIGTERM is what `timeout` sends (to the driver alone) and what Slurm sends (to every process of
    # the job). It used to kill the driver outright: no summary, the killed runs' lock files left
    # behind, and "There appear to be 12 leaked semaphore objects" on stderr (issue 27, item 11).
    path = grid_sweep(tmp_path, 6, steps=10_000_000, every=1000)
    out = tmp_path / "out"
    command = [ORBITSIM, "batch", str(path), "-o", str(out), "--workers", "2", "--no-progress"]
    proc = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)
    try:
        wait_for(lambda: any((out / "runs").glob("*.h5")), 300, "the first finished run")
        (os.killpg if target == "group" else os.kill)(proc.pid, signal.SIGTERM)
        _, err = proc.communicate(timeout=120)
        wait_for(lambda: not process_group_alive(proc.pid), 30, "the workers to exit")
    finally:
        if process_group_alive(proc.pid):
            os.killpg(proc.pid, signal.SIGKILL)
        if proc.poll() is None:
            proc.wait()
    lines = err.splitlines()
    assert proc.returncode == 143, err
    assert len(lines) == 2 and lines[1].startswith("orbitsim: error: interrupted by SIGTERM; "), err
    rows = read_csv(out / "summary.csv")
    done = {p.stem for p in (out / "runs").glob("*.h5")}
    assert {r["run_id"] for r in rows if r["status"] == "complete"} == done and 1 <= len(done) < 6
    assert sorted(p.name for p in (out / "runs").iterdir()) == sorted(f"{d}.h5" for d in done)  # no .lock, .tmp


def test_a_rerun_clears_the_locks_of_killed_runs_it_reuses(client, tmp_path):
    # A run killed after its trace was renamed into place, but before it removed its lock, left a
    # lock that no later sweep touched: the rerun reuses the finished trace (issue 27, item 11).
    sweep = load_sweep(grid_sweep(tmp_path, 2))
    out = tmp_path / "out"
    assert run_sweep(sweep, out, client=client).counts["complete"] == 2
    stale, live = (trace_path_for(out, case) for case in sweep.cases)
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    Path(f"{stale}.lock").write_text(f'{{"pid": {dead.stdout.strip()}, "host": "{os.uname().nodename}"}}\n')
    Path(f"{stale}.tmp").write_bytes(b"half a trace")
    holder = subprocess.Popen([sys.executable, "-c", "import sys, time\nfrom orbitsim.io.lock import hold_output\n"
                               f"with hold_output({str(live)!r}):\n    print('held', flush=True)\n    time.sleep(600)"],
                              stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        outcome = run_sweep(sweep, out, client=client)
        assert outcome.resumed == 2 and outcome.counts["complete"] == 2
        assert not Path(f"{stale}.lock").exists() and not Path(f"{stale}.tmp").exists()
        assert Path(f"{live}.lock").exists() and holder.poll() is None  # a live holder's lock is its own
    finally:
        holder.kill()
        holder.wait()


def test_an_interrupted_no_resume_sweep_does_not_report_old_traces_as_its_own(client, tmp_path):
    sweep = load_sweep(grid_sweep(tmp_path, 6, steps=3_000_000, every=1000))
    out = tmp_path / "out"
    assert run_sweep(sweep, out, client=client).counts["complete"] == 6
    old = {row["run_id"]: (out / row["trace"]).stat().st_ino for row in read_csv(out / "summary.csv")}

    def stop(finished, total, row):  # Ctrl-C as the first result comes back
        raise KeyboardInterrupt

    with pytest.raises(SweepInterrupted) as info:
        run_sweep(sweep, out, workers=2, resume=False, progress=stop)
    rows = info.value.outcome.rows
    assert len(rows) == 6
    redone = {rid for rid, ino in old.items() if (out / "runs" / f"{rid}.h5").stat().st_ino != ino}
    assert {r["run_id"] for r in rows if r["status"] == "complete"} == redone  # rewritten by this sweep
    assert 1 <= len(redone) < 6 and all(r["status"] == "not run" for r in rows if r["run_id"] not in redone)
    assert [r["status"] for r in read_csv(out / "summary.csv")] == [r["status"] for r in rows]


def test_workers_ignore_ctrl_c_even_after_a_restart(client):
    # The driver alone answers Ctrl-C; a worker that took it would die with a traceback.
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler  # the driver's is back
    assert set(client.run(signal.getsignal, signal.SIGINT).values()) == {signal.SIG_IGN}
    pids = client.run(os.getpid)
    victim = next(iter(pids))
    os.kill(pids[victim], signal.SIGKILL)  # its nanny starts a new worker process
    wait_for(lambda: victim not in client.scheduler_info()["workers"] and len(client.scheduler_info()["workers"]) == 2,
             120, "the killed worker to be replaced")
    client.wait_for_workers(2, timeout=120)
    assert set(client.run(signal.getsignal, signal.SIGINT).values()) == {signal.SIG_IGN}


def test_the_docs_way_of_loading_a_summary_runs(client, tmp_path, capsys):
    # docs/batch.md used to suggest pandas, which orbitsim does not install (issue 27, item 8): its
    # example now uses csv and h5py, and this runs it, as written, on a real sweep.
    text = (Path(__file__).parents[2] / "docs" / "batch.md").read_text(encoding="utf-8")
    block = text.split("<!-- docs-example: summary", 1)[1].split("```python\n", 1)[1].split("```", 1)[0]
    out = tmp_path / "out"
    run_sweep(load_sweep(grid_sweep(tmp_path, 2)), out, client=client)
    assert 'Path("out/integrators_dt")' in block
    exec(block.replace('Path("out/integrators_dt")', f"Path({str(out)!r})"), {})
    printed = capsys.readouterr().out.splitlines()
    assert len(printed) == 3 and printed[1].startswith("dt = 0.01: complete, max |dE/E| = "), printed


@pytest.mark.skipif(not hasattr(os, "sched_getaffinity"), reason="Linux only")
def test_cli_prints_the_summary_table(tmp_path):
    path = grid_sweep(tmp_path, 2)
    result = CliRunner().invoke(cli, ["batch", str(path), "-o", str(tmp_path / "out"), "--workers", "1"])
    assert result.exit_code == 0, result.output
    assert "max|dE/E|" in result.output and "2 runs: 2 complete" in result.output
    assert (tmp_path / "out" / "summary.h5").is_file()
