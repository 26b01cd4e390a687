"""``orbitsim map --device gpu`` under Numba's CUDA simulator (run by test_gpu_ensemble.py in its own process
with ``NUMBA_ENABLE_CUDASIM=1``): the files, the device in map.h5, the pixels against the CPU map's, and a
map interrupted mid-way that the same command finishes with the pixels of one run straight through."""

from __future__ import annotations

import os
from pathlib import Path

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

if os.environ.get("NUMBA_ENABLE_CUDASIM") != "1":  # pragma: no cover - a guard, not a path
    pytest.skip("run by test_gpu_ensemble.py under NUMBA_ENABLE_CUDASIM=1", allow_module_level=True)

from orbitsim.cli.main import cli

#: The planet has a small mass, not 0: a massless last body sends the CPU map to the restricted kernel
#: (orbitsim/ensemble/restricted.py), a kernel family of its own (~40 CPU-s cold) that ``make test`` leaves to
#: ``make test-slow`` (tests/ensemble/test_restricted.py gives it the whole-system kernel's bits, the kernel
#: compared here). The GPU against the CPU with a massless planet: benchmarks/gpu_check.py (sim_runs.py).
SCENARIO = """\
name: tp
units: nbody
integrator: wisdom_holman
dt: 0.5
t_end: 100
bodies:
  - {name: sun, m: 1.0, x: [0, 0, 0], v: [0, 0, 0]}
  - {name: jupiter, m: 0.000954791915, primary: sun, a: 5.2, e: 0.048, M: 10}
  - {name: saturn, m: 0.000285885672, primary: sun, a: 9.54, e: 0.054, M: 200, inc: 2.5}
  - {name: planet, m: 1.0e-12, primary: sun, a: 7.0, e: 0.1, M: 30}
"""
AXES = ["--x", "planet.a=7.0:8.0:3", "--y", "planet.e=0:0.3:2", "--t-end", "40", "--quiet"]
#: The GPU's pixels against the CPU's: relative for MEGNO and the Lyapunov time, absolute for the
#: differences of nearly equal numbers (max_e, delta_a, energy_error); see sim_ensemble.py.
RTOL = 1e-13
ATOL = 1e-13


@pytest.fixture
def scenario(tmp_path: Path) -> Path:
    path = tmp_path / "tp.yaml"
    path.write_text(SCENARIO, encoding="utf-8")
    return path


def _map(args: list[str]) -> tuple[int, str, str]:
    result = CliRunner().invoke(cli, ["map", *args])
    return result.exit_code, result.stdout, result.stderr


def _read(path: Path) -> tuple[dict[str, np.ndarray], dict[str, object]]:
    with h5py.File(path, "r") as f:
        grids = {name: f["indicators"][name][()] for name in f["indicators"]}
        grids["status"] = f["status"][()]
        grids["stop_time"] = f["stop_time"][()]
        return grids, dict(f.attrs)


def test_a_gpu_map_records_its_device_and_agrees_with_the_cpu_map(scenario, tmp_path):
    code, stdout, stderr = _map([str(scenario), *AXES, "--device", "gpu", "-o", str(tmp_path / "gpu")])
    assert code == 0, stderr
    assert "6 pixels: 6 complete" in stdout
    assert (tmp_path / "gpu" / "map.png").stat().st_size > 0
    assert not (tmp_path / "gpu" / "map.parts").exists()
    gpu, attrs = _read(tmp_path / "gpu" / "map.h5")
    assert attrs["device"] == "gpu" and attrs["device_name"] == "CUDA simulator"
    assert attrs["chunk"] == 65536  # the GPU's default chunk: one launch for this map
    info = CliRunner().invoke(cli, ["info", str(tmp_path / "gpu" / "map.h5")])
    assert info.exit_code == 0 and "device: gpu (CUDA simulator)" in info.stdout
    assert _map([str(scenario), *AXES, "-o", str(tmp_path / "cpu")])[0] == 0
    cpu, cpu_attrs = _read(tmp_path / "cpu" / "map.h5")
    assert "device" not in cpu_attrs and cpu_attrs["fingerprint"] != attrs["fingerprint"]
    assert np.array_equal(gpu["status"], cpu["status"]) and np.array_equal(gpu["stop_time"], cpu["stop_time"])
    for name in ("megno", "lyapunov_time"):
        assert np.all(np.abs(gpu[name] / cpu[name] - 1.0) < RTOL), name
    for name in ("max_e", "delta_a", "energy_error"):
        assert np.all(np.abs(gpu[name] - cpu[name]) < ATOL), name


def test_an_interrupted_gpu_map_is_finished_by_the_same_command(scenario, tmp_path, monkeypatch):
    import orbitsim.stability.store as store

    command = [str(scenario), *AXES, "--device", "gpu", "--chunk", "2"]
    real_write = store.MapParts.write
    written = []

    def write_then_die(self, result):
        real_write(self, result)
        written.append(result.index)
        if len(written) == 2:
            raise KeyboardInterrupt  # a Ctrl-C after the second chunk reached the disk

    monkeypatch.setattr(store.MapParts, "write", write_then_die)
    out = tmp_path / "resumed"
    code, _, _ = _map([*command, "-o", str(out)])
    assert code != 0
    assert not (out / "map.h5").exists()
    assert sorted(p.name for p in (out / "map.parts").glob("chunk-*.npz")) == ["chunk-000000.npz",
                                                                              "chunk-000001.npz"]
    monkeypatch.setattr(store.MapParts, "write", real_write)
    code, _, stderr = _map([*command, "-o", str(out)])
    assert code == 0, stderr
    _, attrs = _read(out / "map.h5")
    assert attrs["pixels_computed"] == 2  # only the third chunk ran again
    assert _map([*command[:-2], "--chunk", "6", "-o", str(tmp_path / "straight")])[0] == 0
    a, _ = _read(out / "map.h5")
    b, _ = _read(tmp_path / "straight" / "map.h5")
    for name in a:
        assert np.array_equal(a[name], b[name], equal_nan=True), name


def test_a_cpu_map_is_not_finished_on_the_gpu(scenario, tmp_path, monkeypatch):
    import orbitsim.stability.store as store

    real_write = store.MapParts.write

    def write_then_die(self, result):
        real_write(self, result)
        raise KeyboardInterrupt

    monkeypatch.setattr(store.MapParts, "write", write_then_die)
    out = tmp_path / "m"
    assert _map([str(scenario), *AXES, "--chunk", "2", "-o", str(out)])[0] != 0
    monkeypatch.setattr(store.MapParts, "write", real_write)
    code, _, stderr = _map([str(scenario), *AXES, "--chunk", "2", "--device", "gpu", "-o", str(out)])
    assert code == 2 and stderr.count("\n") == 1 and "holds the parts of another map" in stderr
    assert "device" in stderr


def _bench():
    import importlib.util

    path = Path(__file__).resolve().parents[2] / "benchmarks" / "gpu_check.py"
    spec = importlib.util.spec_from_file_location("gpu_check", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_device_checks_jupiter_saturn_pixels_are_the_maps_own():
    from orbitsim.scenario import load_scenario
    from orbitsim.scenario.loader import _locate
    from orbitsim.scenario.yamlio import parse_yaml
    from orbitsim.stability.axes import parse_axis
    from orbitsim.stability.plan import chunk_states, make_plan

    base = load_scenario("jupiter_saturn")
    path, label = _locate("jupiter_saturn")
    doc, _ = parse_yaml(path.read_text(encoding="utf-8"), label)
    axes = [parse_axis("--x", "planet.a=5.8:9.0:3", doc, False), parse_axis("--y", "planet.e=0:0.38:2", doc, False)]
    plan = make_plan(base, doc, axes, 100.0, None, 6, 0, "gpu")
    bench = _bench()
    assert plan.dt == bench.JS_DT and base.t_end == bench.JS_T_END
    for mine, theirs in zip(bench.js_grid(3, 2), chunk_states(plan, 0), strict=True):
        assert np.array_equal(mine, theirs)
