"""Runs the GPU tests (``tests/gpu/sim_*.py``) under Numba's CUDA simulator, each file in its own process.

Numba decides at ``import numba.cuda`` whether it is the simulator (``NUMBA_ENABLE_CUDASIM``), and then
for the life of the process: run in this worker, the simulator would stand in for numba.cuda in every
later test here (a "no device" test would find one), and the variable would reach every subprocess
those tests start. So each simulator file runs in a fresh interpreter with the variable set there
alone, and this worker never sees it (test_gpu_host.py checks that).
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent
SIM_FILES = sorted(p.name for p in HERE.glob("sim_*.py"))


def test_the_simulator_files_are_there() -> None:
    assert {"sim_kernels.py", "sim_runs.py"} <= set(SIM_FILES)


@pytest.mark.parametrize("name", SIM_FILES)
def test_under_the_cuda_simulator(name: str, tmp_path: Path) -> None:
    env = {**os.environ, "NUMBA_ENABLE_CUDASIM": "1"}
    args = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-p", "no:randomly", "-o",
            "python_files=sim_*.py", "-o", "addopts=-ra", "--basetemp", str(tmp_path / "tmp"), str(HERE / name)]
    proc = subprocess.run(args, capture_output=True, text=True, timeout=600, env=env, cwd=HERE.parents[1])
    tail = proc.stdout[-6000:] + proc.stderr[-2000:]
    assert proc.returncode == 0, tail
    summary = proc.stdout.strip().splitlines()[-1]
    assert " passed" in summary and "skipped" not in summary and "failed" not in summary, tail
