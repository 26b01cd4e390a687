"""Whole GPU runs under Numba's CUDA simulator (run by test_gpu_simulator.py): the CLI, the trace,
a continuation from the trace's final state, and benchmarks/gpu_check.py itself.

Tolerance: 1e-13 relative against the CPU, for the reasons given in sim_kernels.py (FP64 on both
sides, not bitwise: the order of the force sum, fused multiply-adds, rsqrt on hardware).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
from click.testing import CliRunner

if os.environ.get("NUMBA_ENABLE_CUDASIM") != "1":  # pragma: no cover - a guard, not a path
    raise RuntimeError("run under Numba's CUDA simulator: tests/gpu/test_gpu_simulator.py does")

from orbitsim.cli.main import cli
from orbitsim.io.trace import read_trace

RTOL = 1e-13  # FP64, not bitwise (order of the sum, FMA, rsqrt): sim_kernels.py's module docstring
ROOT = Path(__file__).resolve().parents[2]

SCENARIO = """name: small
integrator: {integrator}
dt: 0.001
steps: {steps}
output: {{every: 5}}
softening: 0.01
generator: {{kind: plummer, n: 24, seed: 3}}
"""


def run(*args: str) -> str:
    result = CliRunner().invoke(cli, list(args))
    assert result.exit_code == 0, result.output
    return result.output


def scenario(tmp_path: Path, integrator: str = "verlet", steps: int = 20, name: str = "s.yaml") -> Path:
    path = tmp_path / name
    path.write_text(SCENARIO.format(integrator=integrator, steps=steps), encoding="utf-8")
    return path


def test_a_gpu_run_writes_the_cpus_trace_layout_and_agrees_with_it(tmp_path: Path) -> None:
    path = scenario(tmp_path, "leapfrog4", steps=10)  # two samples after the start: each step is ~0.3 s simulated
    run("run", str(path), "-o", str(tmp_path / "cpu.h5"), "-q")
    text = run("run", str(path), "-o", str(tmp_path / "gpu.h5"), "--device", "gpu")
    assert "small: complete, 10 of 10 steps" in text
    cpu, gpu = read_trace(tmp_path / "cpu.h5"), read_trace(tmp_path / "gpu.h5")
    assert gpu.attrs["device"] == "gpu" and gpu.attrs["device_name"] == "CUDA simulator"
    assert "device" not in cpu.attrs
    assert gpu.attrs["status"] == "complete" and gpu.attrs["integrator"] == "leapfrog4"
    assert np.array_equal(gpu.step, cpu.step) and np.array_equal(gpu.time, cpu.time)
    assert np.max(np.abs(gpu.energy / cpu.energy - 1.0)) < RTOL
    assert np.max(np.abs(gpu.positions - cpu.positions)) < RTOL * np.max(np.abs(cpu.positions))
    assert np.max(np.abs(gpu.momentum - cpu.momentum)) < RTOL * np.max(np.abs(cpu.velocities))
    # the same datasets, shapes and dtypes: a GPU trace is a trace
    assert datasets(tmp_path / "gpu.h5") == datasets(tmp_path / "cpu.h5")


def datasets(path: Path) -> dict[str, tuple[tuple[int, ...], str]]:
    import h5py

    found: dict[str, tuple[tuple[int, ...], str]] = {}
    with h5py.File(path, "r") as f:
        f.visititems(lambda name, obj: found.update({name: (obj.shape, obj.dtype.str)})
                     if isinstance(obj, h5py.Dataset) else None)
    return found


def test_a_gpu_run_continues_from_its_final_state_bit_for_bit(tmp_path: Path) -> None:
    """The trace's final state (copied back from the device) continues on the device: 5 + 5 steps give
    the bits of one 10-step GPU run (same operations, same device, deterministic sums)."""
    short, whole = scenario(tmp_path, steps=5, name="short.yaml"), scenario(tmp_path, steps=10, name="whole.yaml")
    run("run", str(short), "-o", str(tmp_path / "ext.h5"), "--device", "gpu", "-q")
    run("run", "--from", str(tmp_path / "ext.h5"), "--steps", "5", "-q")
    run("run", str(whole), "-o", str(tmp_path / "one.h5"), "--device", "gpu", "-q")
    ext, one = read_trace(tmp_path / "ext.h5"), read_trace(tmp_path / "one.h5")
    assert ext.attrs["device"] == "gpu" and ext.attrs["status"] == "complete"
    assert np.array_equal(ext.step, one.step)
    assert np.array_equal(ext.positions, one.positions) and np.array_equal(ext.energy, one.energy)


def test_an_interrupted_gpu_run_resumes_on_the_gpu_bit_for_bit(tmp_path: Path) -> None:
    """Stopped after its second call, with checkpoints every 5 steps: `orbitsim resume` restores the state
    copied back from the device, sends it back, and ends with the bits of an uninterrupted GPU run."""
    from orbitsim.runner import run_scenario
    from orbitsim.scenario import load_scenario

    sc = load_scenario(scenario(tmp_path, steps=20)).with_overrides(device="gpu", checkpoint_every=5)
    polls = iter(range(1000))
    summary = run_scenario(sc, tmp_path / "r.h5", stop=lambda: next(polls) >= 2, handle_signals=False)
    assert summary.status == "interrupted" and summary.resumable and 0 < summary.steps_done < 20
    run("resume", str(tmp_path / "r.h5"), "-q")
    run("run", str(scenario(tmp_path, steps=20, name="w.yaml")), "-o", str(tmp_path / "one.h5"), "--device", "gpu",
        "-q", "--checkpoint-every", "5")
    resumed, one = read_trace(tmp_path / "r.h5"), read_trace(tmp_path / "one.h5")
    assert resumed.attrs["status"] == "complete" and resumed.attrs["device"] == "gpu"
    assert np.array_equal(resumed.step, one.step)
    assert np.array_equal(resumed.positions, one.positions) and np.array_equal(resumed.energy, one.energy)


def test_gpu_check_quick_prints_one_json_line_per_figure(tmp_path: Path) -> None:
    """benchmarks/gpu_check.py as a GPU machine runs it, with h5py, yaml and click unavailable."""
    out = tmp_path / "check.jsonl"
    code = ("import runpy, sys\n"
            "for name in ('h5py', 'yaml', 'click', 'matplotlib', 'dask', 'distributed'):\n"
            "    sys.modules[name] = None\n"
            f"sys.argv = ['gpu_check.py', '--quick', '--out', {str(out)!r}]\n"
            f"runpy.run_path({str(ROOT / 'benchmarks' / 'gpu_check.py')!r}, run_name='__main__')\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=600, cwd=ROOT)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    printed = [json.loads(line) for line in proc.stdout.splitlines() if line.startswith("{")]
    written = [json.loads(line) for line in out.read_text(encoding="utf-8").splitlines()]
    assert printed == written
    figures = {(r["section"], r["figure"]): r for r in written}
    assert {("direct", "accelerations_vs_cpu_rel"), ("direct", "verlet_3_steps_positions_vs_cpu_rel"),
            ("direct", "pair_interactions_per_s"), ("direct", "verlet_step_over_force"),
            ("plummer_16k", "energy_after_steps_vs_cpu_rel")} <= set(figures)
    assert all(r["device"] == "CUDA simulator" and "error" not in r for r in written)
    for key in (("direct", "accelerations_vs_cpu_rel"), ("plummer_16k", "energy_after_steps_vs_cpu_rel")):
        assert figures[key]["ok"] is True and 0.0 <= figures[key]["value"] < figures[key]["target"]
    assert figures[("direct", "pair_interactions_per_s")]["value"] > 0.0
    # the ensemble's sections (orbitsim map --device gpu), in order after the direct sum's
    ensemble = [r["figure"] for r in written if r["section"] in ("ensemble", "js_map")]
    assert ensemble == ["wh_megno_positions_vs_cpu_rel", "wh_megno_velocities_vs_cpu_rel", "wh_statuses_equal_cpu",
                        "wh_megno_vs_cpu_rel", "wh_lyapunov_vs_cpu_rel", "leapfrog_positions_vs_cpu_rel",
                        "leapfrog_5body_system_steps_per_s", "leapfrog_5body_with_copies_system_steps_per_s",
                        "wh_megno_4body_system_steps_per_s", "wh_megno_4body_with_copies_system_steps_per_s",
                        "js_map_4x4_s", "js_map_4x4_with_copies_s", "js_map_8x8_s", "js_map_8x8_with_copies_s",
                        "js_map_1000x1000_estimate_s"]
    correctness = [r for r in written if r["section"] == "ensemble" and r["figure"].endswith(("_rel", "_cpu"))]
    assert len(correctness) == 6 and all(r["ok"] for r in correctness)  # the correctness figures meet 1e-13
    assert all(r["value"] > 0 for r in written if r["section"] in ("ensemble", "js_map"))
