"""Sweeps on an embedded LocalCluster: results, failures, resume, and bit-identical output.

One two-worker cluster serves the whole module (starting one costs a few seconds on 2 cores).
"""

from __future__ import annotations

import csv
import math
import os
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

from orbitsim.batch.cluster import ClusterPlan, open_client
from orbitsim.batch.driver import run_sweep, trace_path_for
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
        grid: {dt: [0.01, 0.02, -1.0]}
    """)
    result = CliRunner().invoke(cli, ["batch", str(path), "-o", str(tmp_path / "out")])
    assert result.exit_code == 2
    assert f"orbitsim: error: {path}: grid.dt[2]: must be > 0, got -1.0 (line 3)" in result.output
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


def test_interrupted_sweep_finishes_when_the_command_is_run_again(tmp_path):
    # Runs of ~0.3 s (quiet machine) to ~1.5 s (busy), so that Ctrl-C lands while some are done and
    # others are not.
    path = grid_sweep(tmp_path, 8, steps=3_000_000, every=1000)
    out = tmp_path / "out"
    command = [ORBITSIM, "batch", str(path), "-o", str(out), "--workers", "2", "--no-progress"]
    proc = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        wait_for(lambda: len(list((out / "runs").glob("*.h5"))) >= 1, 120, "the first finished run")
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 130, err
    assert "run the same command again" in err
    done = {p.stem for p in (out / "runs").glob("*.h5")}
    partial = read_csv(out / "summary.csv")
    assert "not run" in {r["status"] for r in partial} and len(done) < 8
    rerun = subprocess.run(command, capture_output=True, text=True, timeout=300)
    assert rerun.returncode == 0, rerun.stderr
    rows = read_csv(out / "summary.csv")
    assert [r["status"] for r in rows] == ["complete"] * 8
    assert {r["run_id"] for r in rows if r["resumed"] == "true"} == done
    assert f"{len(done)} reused from earlier traces" in rerun.stdout
    assert not list((out / "runs").glob("*.tmp"))


@pytest.mark.skipif(not hasattr(os, "sched_getaffinity"), reason="Linux only")
def test_cli_prints_the_summary_table(tmp_path):
    path = grid_sweep(tmp_path, 2)
    result = CliRunner().invoke(cli, ["batch", str(path), "-o", str(tmp_path / "out"), "--workers", "1"])
    assert result.exit_code == 0, result.output
    assert "max|dE/E|" in result.output and "2 runs: 2 complete" in result.output
    assert (tmp_path / "out" / "summary.h5").is_file()
