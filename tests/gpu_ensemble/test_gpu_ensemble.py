"""The GPU ensemble from the host: its simulator tests (``sim_ensemble*.py``, each in a fresh interpreter
with ``NUMBA_ENABLE_CUDASIM=1``), and what a user sees without a GPU, where nothing loads numba-cuda.

Numba decides at ``import numba.cuda`` whether it is the simulator, for the life of the process: run in this
worker, the simulator would stand in for numba.cuda in every later test here. So the simulator files run in
subprocesses with the variable set there alone, and so does the "no device" test (it imports numba.cuda).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from orbitsim.cli.main import cli
from orbitsim.gpu.device import NO_DEVICE
from orbitsim.gpu.ensemble import run_ensemble_gpu

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
SIM_FILES = sorted(p.name for p in HERE.glob("sim_ensemble*.py"))
#: A small planet mass, not 0: a CPU map of a massless last body runs the restricted kernel, a family of its own
#: (~40 CPU-s cold) left to make test-slow (as in sim_ensemble_map.py)
SCENARIO = """\
name: tp
units: nbody
integrator: wisdom_holman
dt: 0.5
t_end: 100
bodies:
  - {name: sun, m: 1.0, x: [0, 0, 0], v: [0, 0, 0]}
  - {name: jupiter, m: 0.000954791915, primary: sun, a: 5.2, e: 0.048, M: 10}
  - {name: planet, m: 1.0e-12, primary: sun, a: 7.0, e: 0.1, M: 30}
"""
AXES = ["--x", "planet.a=7.0:8.0:3", "--t-end", "40", "--quiet"]


def _without_simulator() -> dict[str, str]:
    return {k: v for k, v in os.environ.items() if k != "NUMBA_ENABLE_CUDASIM"}


def test_the_simulator_files_are_there() -> None:
    assert SIM_FILES == ["sim_ensemble.py", "sim_ensemble_map.py"]


@pytest.mark.parametrize("name", SIM_FILES)
def test_under_the_cuda_simulator(name: str, tmp_path: Path) -> None:
    env = {**_without_simulator(), "NUMBA_ENABLE_CUDASIM": "1"}
    args = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-p", "no:randomly", "-o",
            "python_files=sim_*.py", "-o", "addopts=-ra", "--basetemp", str(tmp_path / "tmp"), str(HERE / name)]
    proc = subprocess.run(args, capture_output=True, text=True, timeout=600, env=env, cwd=ROOT)
    tail = proc.stdout[-6000:] + proc.stderr[-2000:]
    assert proc.returncode == 0, tail
    summary = proc.stdout.strip().splitlines()[-1]
    assert " passed" in summary and "skipped" not in summary and "failed" not in summary, tail


def test_without_a_device_the_map_is_one_line_exit_2_and_writes_nothing(tmp_path: Path) -> None:
    scenario = tmp_path / "tp.yaml"
    scenario.write_text(SCENARIO, encoding="utf-8")
    out = tmp_path / "m"
    code = ("import sys; from numba import cuda; cuda.is_available = lambda: False; "  # as on a machine without one
            "from orbitsim.cli.main import main; sys.argv[0] = 'orbitsim'; main()")
    proc = subprocess.run([sys.executable, "-c", code, "map", str(scenario), *AXES, "--device", "gpu", "-o", str(out)],
                          capture_output=True, text=True, timeout=300, env=_without_simulator(), cwd=ROOT)
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr == f"orbitsim: error: {NO_DEVICE}\n"
    assert not out.exists()


def test_gpu_with_a_scheduler_is_refused_before_anything_loads(tmp_path: Path) -> None:
    scenario = tmp_path / "tp.yaml"
    scenario.write_text(SCENARIO, encoding="utf-8")
    out = tmp_path / "m"
    result = CliRunner().invoke(cli, ["map", str(scenario), *AXES, "--device", "gpu", "--scheduler",
                                      "tcp://127.0.0.1:1", "-o", str(out)])
    assert result.exit_code == 2
    assert result.stderr.count("\n") == 1 and "--device gpu with --scheduler" in result.stderr
    assert not out.exists()


def test_the_front_door_refuses_what_the_gpu_kernels_cannot_run() -> None:
    m = np.array([[1.0, 1e-3]])
    x = np.array([[[0.0, 1.0], [0.0, 0.0], [0.0, 0.0]]])
    v = np.array([[[0.0, 0.0], [0.0, 1.0], [0.0, 0.0]]])
    var = (np.ones((1, 3, 2)), np.ones((1, 3, 2)))
    with pytest.raises(ValueError, match="has no GPU kernel; use one of wisdom_holman, leapfrog, verlet"):
        run_ensemble_gpu(m, x, v, G=1.0, dt=0.1, n_steps=1, scheme="ias15")
    with pytest.raises(ValueError, match="carries the tangent vector; give variation"):
        run_ensemble_gpu(m, x, v, G=1.0, dt=0.1, n_steps=1)
    for scheme in ("leapfrog", "verlet"):
        with pytest.raises(ValueError, match=f"the GPU {scheme} kernel has no variational equations"):
            run_ensemble_gpu(m, x, v, G=1.0, dt=0.1, n_steps=1, variation=var, scheme=scheme)
    with pytest.raises(ValueError, match="central body"):  # the CPU ensemble's own check (prepare_systems)
        run_ensemble_gpu(m * 0.0, x, v, G=1.0, dt=0.1, n_steps=1, variation=var)
    with pytest.raises(ValueError, match="initial variation must be finite and non-zero"):
        run_ensemble_gpu(m, x, v, G=1.0, dt=0.1, n_steps=1, variation=(var[0] * 0.0, var[1] * 0.0))


def test_a_cpu_map_never_loads_numba_cuda(tmp_path: Path) -> None:
    scenario = tmp_path / "tp.yaml"
    scenario.write_text(SCENARIO, encoding="utf-8")
    code = ("import sys, json; from click.testing import CliRunner; from orbitsim.cli.main import cli; "
            f"r = CliRunner().invoke(cli, ['map', {str(scenario)!r}, *{AXES!r}, '-o', {str(tmp_path / 'm')!r}]); "
            "print(r.output); print(json.dumps([r.exit_code, 'numba.cuda' in sys.modules]))")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300,
                          env=_without_simulator(), cwd=ROOT)
    assert json.loads(proc.stdout.strip().splitlines()[-1]) == [0, False], proc.stderr
