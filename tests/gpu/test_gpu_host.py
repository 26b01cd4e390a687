"""``device: gpu`` and ``--device`` without the simulator: every refusal, the gate, and what stays unloaded.

Nothing here launches a kernel: these are the paths that end before one (exit 2, nothing written).
The kernels themselves run under Numba's CUDA simulator in subprocesses (test_gpu_simulator.py), so
this process never imports the simulator; the last test checks that.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner

from orbitsim.cli.main import cli
from orbitsim.gpu.device import NO_DEVICE
from orbitsim.gpu.support import GPU_SCHEMES, GPU_SUPPORTS

SMALL = """name: small
integrator: {integrator}
dt: 0.001
steps: 20
output: {{every: 5}}
softening: 0.01
generator: {{kind: plummer, n: 16, seed: 3}}
"""


def write(tmp_path: Path, text: str, name: str = "s.yaml") -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def invoke(*args: str) -> tuple[int, str]:
    result = CliRunner().invoke(cli, list(args))
    return result.exit_code, result.output


def assert_one_line_refusal(code: int, text: str, *needles: str) -> None:
    lines = [line for line in text.splitlines() if line.strip()]
    assert code == 2, text
    assert len(lines) == 1 and lines[0].startswith("orbitsim: error: "), text
    assert "Traceback" not in text
    for needle in needles:
        assert needle in lines[0], (needle, lines[0])


@pytest.mark.parametrize(("extra", "key", "what"), [
    ("integrator: ias15\nt_end: 1\noutput: {interval: 0.1}\n", "integrator", "ias15 does not run on the GPU"),
    ("integrator: wisdom_holman\n", "integrator", "wisdom_holman does not run on the GPU"),
    ("events: {unresolved: true}\n", "events", "events are not watched on the GPU"),
    ("forces: [{force: gr, source: plummer00, c: 100.0}]\n", "forces", "forces are not applied on the GPU"),
    ("output: {every: 5, elements: true}\n", "output.elements", "output.elements"),
    ("output: {every: 5, chaos: {}}\n", "output.chaos", "output.chaos"),
    ("integrator: {name: verlet, order: 2}\n", "integrator", None),
])
def test_each_refusal_is_one_line_naming_the_key_and_what_the_gpu_runs(tmp_path: Path, extra: str, key: str,
                                                                        what: str | None) -> None:
    text = SMALL.format(integrator="verlet")
    for line in extra.splitlines():  # replace the base keys the extra gives again
        head = line.split(":")[0]
        text = "\n".join(k for k in text.splitlines() if not k.startswith(head + ":")) + "\n"
    if "steps" in text and "t_end" in extra:
        text = "\n".join(k for k in text.splitlines() if not k.startswith("steps:")) + "\n"
    path = write(tmp_path, text + extra + "device: gpu\n")
    out = tmp_path / "out.h5"
    code, output = invoke("run", str(path), "-o", str(out), "-q")
    if what is None:  # a setting the scheme itself does not know is refused before the device is looked at
        assert code == 2 and "Traceback" not in output
    else:
        assert_one_line_refusal(code, output, f"{path}: {key}: ", what, GPU_SUPPORTS)
    assert not out.exists() and list(tmp_path.iterdir()) == [path]


def test_device_option_names_itself_in_the_refusal(tmp_path: Path) -> None:
    path = write(tmp_path, SMALL.format(integrator="verlet") + "events: {unresolved: true}\n")
    code, output = invoke("run", str(path), "-o", str(tmp_path / "o.h5"), "--device", "gpu")
    assert_one_line_refusal(code, output, "--device gpu: events are not watched on the GPU", GPU_SUPPORTS)
    assert list(tmp_path.iterdir()) == [path]


@pytest.mark.parametrize("value", ["tpu", "GPU0", "1"])
def test_a_bad_device_value_names_file_and_key(tmp_path: Path, value: str) -> None:
    path = write(tmp_path, SMALL.format(integrator="verlet") + f"device: {value}\n")
    code, output = invoke("run", str(path), "-o", str(tmp_path / "o.h5"))
    assert_one_line_refusal(code, output, f"{path}: device: ", value)
    assert list(tmp_path.iterdir()) == [path]


def test_a_bad_device_option_is_a_usage_error(tmp_path: Path) -> None:
    path = write(tmp_path, SMALL.format(integrator="verlet"))
    code, output = invoke("run", str(path), "--device", "tpu")
    assert code == 2 and "'tpu' is not one of 'cpu', 'gpu'" in output


@pytest.fixture
def no_gpu(monkeypatch: pytest.MonkeyPatch) -> None:
    """``numba.cuda.is_available()`` False, whatever this machine has."""
    from orbitsim.gpu.device import require_cuda

    try:
        cuda = require_cuda()
    except Exception:
        return  # already no device: the gate says so by itself
    monkeypatch.setattr(cuda, "is_available", lambda: False)


@pytest.mark.parametrize("how", ["option", "scenario"])
def test_without_a_gpu_run_prints_the_gate_line_and_writes_nothing(tmp_path: Path, no_gpu: None, how: str) -> None:
    text = SMALL.format(integrator="leapfrog4") + ("device: gpu\n" if how == "scenario" else "")
    path = write(tmp_path, text)
    args = ["run", str(path), "-o", str(tmp_path / "o.h5")] + (["--device", "gpu"] if how == "option" else [])
    code, output = invoke(*args)
    assert_one_line_refusal(code, output, NO_DEVICE)
    assert list(tmp_path.iterdir()) == [path]  # no trace, no lock file, no checkpoint


def test_without_a_gpu_batch_prints_the_gate_line_and_writes_nothing(tmp_path: Path, no_gpu: None) -> None:
    base = write(tmp_path, SMALL.format(integrator="verlet"), "base.yaml")
    sweep = write(tmp_path, f"name: sw\nbase: {base}\ngrid:\n  dt: [0.001, 0.002]\n", "sweep.yaml")
    code, output = invoke("batch", str(sweep), "-o", str(tmp_path / "out"), "--device", "gpu", "--no-progress")
    assert_one_line_refusal(code, output, NO_DEVICE)
    assert not (tmp_path / "out").exists()


def test_batch_refuses_a_case_the_gpu_does_not_carry(tmp_path: Path) -> None:
    base = write(tmp_path, SMALL.format(integrator="verlet"), "base.yaml")
    sweep = write(tmp_path, f"name: sw\nbase: {base}\ngrid:\n  integrator: [verlet, ias15]\n  t_end: [0.02]\n"
                            "  steps: [null]\n", "sweep.yaml")
    code, output = invoke("batch", str(sweep), "-o", str(tmp_path / "out"), "--device", "gpu", "--no-progress")
    assert code == 2 and "Traceback" not in output
    assert not (tmp_path / "out").exists()


def test_run_from_refuses_a_device_change(tmp_path: Path) -> None:
    path = write(tmp_path, SMALL.format(integrator="verlet"))
    out = tmp_path / "o.h5"
    assert invoke("run", str(path), "-o", str(out), "-q")[0] == 0
    code, output = invoke("run", "--from", str(out), "--steps", "5", "--device", "gpu")
    assert code == 2 and "--from continues the stored run, whose settings are fixed: drop --device" in output


def test_every_gpu_scheme_is_a_registered_fixed_step_scheme() -> None:
    from orbitsim.integrators.registry import get_integrator

    for name in GPU_SCHEMES:
        spec = get_integrator(name).spec
        assert spec.name == name and spec.force_evals >= 1


def test_a_cpu_trace_and_scenario_are_unchanged_by_the_device_key(tmp_path: Path) -> None:
    from orbitsim.io.trace import read_trace
    from orbitsim.scenario import load_scenario

    path = write(tmp_path, SMALL.format(integrator="verlet"))
    plain = load_scenario(path)
    explicit = load_scenario(write(tmp_path, SMALL.format(integrator="verlet") + "device: cpu\n", "c.yaml"))
    assert "device" not in plain.to_yaml() and plain.sha256 == explicit.sha256
    assert "device: \"gpu\"" in plain.with_overrides(device="gpu").to_yaml()
    out = tmp_path / "o.h5"
    assert invoke("run", str(path), "-o", str(out), "-q")[0] == 0
    attrs = read_trace(out).attrs
    assert "device" not in attrs and "device_name" not in attrs


def test_a_cpu_run_never_loads_numba_cuda(tmp_path: Path) -> None:
    path = write(tmp_path, SMALL.format(integrator="verlet"))
    code = ("import sys\nfrom orbitsim.cli.main import cli\n"
            f"try:\n    cli(['run', {str(path)!r}, '-o', {str(tmp_path / 'o.h5')!r}, '-q'], standalone_mode=False)\n"
            "finally:\n    loaded = [m for m in sys.modules if m == 'numba.cuda' or m.startswith(('numba.cuda.', "
            "'numba_cuda', 'cuda.'))]\n"
            "    assert not loaded, loaded[:5]\n")
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_ENABLE_CUDASIM"}
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300, env=env)
    assert proc.returncode == 0, proc.stderr[-2000:]


def test_this_process_never_ran_the_simulator() -> None:
    """The simulator stays in the subprocesses of test_gpu_simulator.py: not in this worker's environment,
    and a numba.cuda this worker imported (the gate's tests) is the real one."""
    assert os.environ.get("NUMBA_ENABLE_CUDASIM", "0") in ("", "0")
    cuda = sys.modules.get("numba.cuda")
    assert cuda is None or "simulator" not in cuda.jit.__module__
