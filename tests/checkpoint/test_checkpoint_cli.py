"""``orbitsim resume``, ``run --from`` and ``info`` on checkpoints, through the command line.

Signals go to real processes (``python -m orbitsim run``); everything else uses click's runner.
Every error must be one line on stderr with exit code 2, never a traceback.
"""

from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py
import pytest
from click.testing import CliRunner
from test_checkpoint_kill import assert_same_datasets

from orbitsim.cli.main import cli
from orbitsim.runner import run_scenario
from orbitsim.scenario import load_scenario

# ~7 us a step: 400000 steps take about 3 s, long enough to be signalled mid-run.
SYSTEM = """\
name: sig
integrator: verlet
dt: 0.001
steps: 400000
softening: 0.05
output: {{every: 1000, positions: true{checkpoint}}}
generator: {{kind: plummer, n: 64, seed: 5}}
"""
TINY = """\
name: tiny
integrator: verlet
dt: 0.01
steps: 2000
output: {every: 10, checkpoint: {every: 100}}
bodies:
  - {name: star, m: 1.0, x: [0, 0, 0], v: [0, 0, 0]}
  - {name: planet, m: 1.0e-3, primary: star, a: 1.0, e: 0.1, M: 0}
"""
START_TIMEOUT = 120


def invoke(*args: str) -> tuple[int, str, str]:
    result = CliRunner().invoke(cli, list(args))
    assert "Traceback" not in result.output
    return result.exit_code, result.stdout, result.stderr


def one_error_line(stderr: str) -> str:
    assert stderr.startswith("orbitsim: error: ") and stderr.count("\n") == 1, stderr
    return stderr


@pytest.fixture
def tiny(tmp_path: Path) -> Path:
    path = tmp_path / "tiny.yaml"
    path.write_text(TINY, encoding="utf-8")
    return path


def signal_run(scenario: Path, out: Path, signum: int, marker: Path, run_for: float) -> tuple[int, str]:
    """Start ``orbitsim run``, wait until ``marker`` exists and ``run_for`` seconds more, signal it."""
    proc = subprocess.Popen([sys.executable, "-m", "orbitsim", "run", str(scenario), "-o", str(out), "-q",
                             "--force"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + START_TIMEOUT
    while not marker.exists() and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.01)
    time.sleep(run_for)
    proc.send_signal(signum)
    _, stderr = proc.communicate(timeout=60)
    return proc.returncode, stderr


@pytest.mark.parametrize(("signum", "code", "checkpoint"), [
    (signal.SIGINT, 130, ", checkpoint: {every: 5000}"),  # the journal path
    (signal.SIGTERM, 143, ""),  # a streamed run keeps its final state in the trace too
], ids=["SIGINT-checkpointed", "SIGTERM-streamed"])
def test_signalled_run_resumes_to_the_same_bits(tmp_path: Path, signum: int, code: int, checkpoint: str) -> None:
    scenario = tmp_path / "sig.yaml"
    scenario.write_text(SYSTEM.format(checkpoint=checkpoint), encoding="utf-8")
    reference = tmp_path / "ref.h5"
    run_scenario(load_scenario(scenario), reference, handle_signals=False)  # also warms the cache
    out = tmp_path / "out.h5"
    marker = Path(f"{out}.ckpt" if checkpoint else f"{out}.tmp")
    # A streamed run's .tmp appears before Numba's cache is loaded; on a loaded machine a signal
    # may then stop it before its first step (correct, but nothing to resume): wait longer, retry.
    for run_for in (1.0, 5.0, 15.0):
        returncode, stderr = signal_run(scenario, out, signum, marker, run_for)
        assert returncode == code, stderr
        if "continue with" in stderr:
            break
    assert f"continue with `orbitsim resume {out}`" in one_error_line(stderr)
    with h5py.File(out) as f:
        assert f.attrs["status"] == "interrupted" and "checkpoint" in f
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.h5", "ref.h5", "sig.yaml"]
    resumed = subprocess.run([sys.executable, "-m", "orbitsim", "resume", str(out), "--threads", "1"],
                             capture_output=True, text=True, timeout=300)
    assert resumed.returncode == 0 and "sig: complete, 400000 of 400000 steps" in resumed.stdout, resumed.stderr
    assert_same_datasets(reference, out)


def test_resume_help_and_run_from_help() -> None:
    code, out, _ = invoke("resume", "--help")
    assert code == 0 and "Example" in out and "OUT.h5" in out
    code, out, _ = invoke("run", "--help")
    assert code == 0 and "--from TRACE.h5" in out and "--checkpoint-every" in out


def test_run_from_extends_a_complete_run(tiny: Path, tmp_path: Path) -> None:
    assert invoke("run", str(tiny), "-o", str(tmp_path / "long.h5"), "--steps", "3000", "-q")[0] == 0
    assert invoke("run", str(tiny), "-o", str(tmp_path / "out.h5"), "-q")[0] == 0
    code, out, err = invoke("run", "--from", str(tmp_path / "out.h5"), "--steps", "1000")
    assert code == 0 and "tiny: complete, 3000 of 3000 steps" in out, err
    assert_same_datasets(tmp_path / "long.h5", tmp_path / "out.h5")
    code, out, err = invoke("run", "--from", str(tmp_path / "out.h5"), "--t-end", "35", "-o",
                            str(tmp_path / "t.h5"), "-q")
    assert code == 0 and out == "", err
    with h5py.File(tmp_path / "t.h5") as f:
        assert f.attrs["steps_done"] == 3500 and f["step"][-1] == 3500


def test_run_from_refusals(tiny: Path, tmp_path: Path) -> None:
    out = str(tmp_path / "out.h5")
    assert invoke("run", str(tiny), "-o", out, "-q")[0] == 0
    code, _, err = invoke("run", "--from", out, "--steps", "10", "--every", "5")
    assert code == 2 and "settings are fixed: drop --every" in err
    code, _, err = invoke("run", "--from", out)
    assert code == 2 and "--steps N (more steps) or --t-end T" in err
    # Another integrator is allowed now (tests/checkpoint/test_run_from_switch.py), but not an adaptive one.
    code, _, err = invoke("run", "--from", out, "--steps", "10", "--integrator", "ias15")
    assert code == 2 and "cannot switch to or from it" in one_error_line(err)
    code, _, err = invoke("run", "--from", str(tiny), "--steps", "10")
    assert code == 2 and "not an HDF5 file" in one_error_line(err)
    code, _, err = invoke("run")
    assert code == 2 and "SCENARIO" in err


def test_resume_refuses_another_scenario_or_integrator(tiny: Path, tmp_path: Path) -> None:
    out = tmp_path / "out.h5"
    sc = load_scenario(tiny)
    run_scenario(sc, out, stop=lambda: True, handle_signals=False)  # interrupted before the first step
    code, _, err = invoke("resume", str(out))
    assert code == 2 and "no checkpoint state" in one_error_line(err)
    calls = [0]

    def stop() -> bool:
        calls[0] += 1
        return calls[0] > 2

    run_scenario(sc.with_overrides(steps=2_000_000, every=1000), out, stop=stop, force=True, handle_signals=False)
    other = tmp_path / "other.yaml"
    other.write_text(TINY.replace("dt: 0.01", "dt: 0.02"), encoding="utf-8")
    code, _, err = invoke("resume", str(out), str(other))
    assert code == 2 and "not the scenario of this run" in one_error_line(err) and "dt: 0.01 vs 0.02" in err
    code, _, err = invoke("resume", str(out), "--integrator", "leapfrog4")
    assert code == 2 and "cannot continue with leapfrog4" in one_error_line(err)
    code, out_text, err = invoke("resume", str(out), "--integrator", "verlet")
    assert code == 0 and "complete, 2000000 of 2000000 steps" in out_text, err
    code, out_text, _ = invoke("resume", str(out))
    assert code == 0 and "already complete" in out_text


def test_info_shows_checkpoints_and_resumability(tiny: Path, tmp_path: Path) -> None:
    out = tmp_path / "out.h5"
    assert invoke("run", str(tiny), "-o", str(out), "-q")[0] == 0
    code, text, _ = invoke("info", str(out))
    assert code == 0 and "checkpoint/pos" in text and "extend it with `orbitsim run --from" in text
    stop = iter([False, True])
    run_scenario(load_scenario(tiny).with_overrides(steps=300_000), out, stop=lambda: next(stop, True),
                 force=True, handle_signals=False)
    code, text, _ = invoke("info", str(out))
    assert code == 0 and f"resumable            yes: orbitsim resume {out}" in text
    code, _, err = invoke("info", f"{out}.ckpt")
    assert code == 2 and "no such checkpoint file" in one_error_line(err)


def test_info_and_run_on_a_killed_runs_checkpoint(tiny: Path, tmp_path: Path) -> None:
    out = tmp_path / "out.h5"
    kept: list[bytes] = []

    def keep(sim: object, chunk: object) -> None:
        if not kept:
            kept.extend([Path(f"{out}.ckpt").read_bytes(), Path(f"{out}.journal").read_bytes()])

    run_scenario(load_scenario(tiny), out, on_chunk=keep, handle_signals=False)
    out.unlink()
    Path(f"{out}.ckpt").write_bytes(kept[0])
    Path(f"{out}.journal").write_bytes(kept[1])
    for given in (out, f"{out}.ckpt", f"{out}.journal"):
        code, text, _ = invoke("info", str(given))
        assert code == 0 and text.startswith(f"checkpoint: {out}.ckpt") and "resumable            yes" in text
    code, text, _ = invoke("info", str(out), "--scenario")
    assert code == 0 and text == load_scenario(tiny).to_yaml()
    code, _, err = invoke("run", str(tiny), "-o", str(out))
    assert code == 2 and "orbitsim resume" in one_error_line(err)
    Path(f"{out}.ckpt").write_bytes(kept[0][: len(kept[0]) // 2])  # torn
    code, _, err = invoke("info", str(out))
    assert code == 2 and "damaged or unreadable checkpoint" in one_error_line(err)
    code, _, err = invoke("resume", str(out))
    assert code == 2 and "damaged or unreadable checkpoint" in one_error_line(err)
