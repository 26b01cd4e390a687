"""A full disk at every write: each failure is one line, exit code 4, and loses nothing.

The faults are injected where the bytes leave the process: ``fault_shim.c``, preloaded into a real
``python -m orbitsim run``, fails every ``write``, ``pwrite``, ``fsync`` and ``rename`` into the
output directory from call number K on with ENOSPC, as a disk that fills up at that moment would.
A first run counts and names the calls (``FAULT_LOG``); then K is set, in turn, to the first call,
the second, one in the middle, the last write, the fsync and the final rename. Each time:

* the process ends by itself, exit code 4 (no signal: HDF5 used to crash with SIGSEGV here);
* stderr is exactly one line, ``orbitsim: error: ...No space left on device...``;
* the file at the output path is byte for byte what it was before (a run with ``--force`` over an
  older file);
* nothing else is left in the directory, except a checkpoint and its journal when the message says
  the run can be resumed, and then ``orbitsim resume`` finishes it into a trace bit-identical to an
  undisturbed run's.

Without a C compiler (or LD_PRELOAD: not Linux) the test is skipped; tests/io/test_disk_full.py covers
the same promise on a real, small filesystem.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from test_checkpoint_kill import assert_same_datasets

SCENARIO = """\
name: faults
units: nbody
integrator: verlet
dt: 0.01
steps: 3000
output: {every: 1, positions: true}
bodies:
  - {name: star, m: 1.0, x: [0, 0, 0], v: [0, 0, 0]}
  - {name: planet, m: 1.0e-3, primary: star, a: 1.0, e: 0.1, M: 0}
"""
#: 2,000 bodies: a resolved text past 256 KiB, so the trace stores the bodies as datasets
#: (scenario_bodies/, issue 27 item 10): those writes fail in turn too. Streamed: with checkpoints
#: the count of writes would follow the jitted calls, which a run of this size sizes by wall time.
LARGE = """\
name: faults
units: nbody
integrator: leapfrog
dt: 0.001
steps: 20
softening: 0.01
output: {every: 1, positions: true}
generator: {kind: plummer, n: 2000, seed: 1}
"""
PREVIOUS = b"the previous contents of the output path\n"
#: Extra options and the scenario per variant: samples streamed into the trace, or journaled with
#: checkpoints; a large scenario, streamed.
VARIANTS = {"stream": ([], SCENARIO), "checkpoint": (["--checkpoint-every", "500"], SCENARIO),
            "large": ([], LARGE)}


@pytest.fixture(scope="module")
def shim(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The preloadable fault injector, compiled for this machine."""
    compiler = shutil.which("gcc") or shutil.which("cc")
    if compiler is None or not sys.platform.startswith("linux"):
        pytest.skip("needs a C compiler and LD_PRELOAD (Linux); tests/io/test_disk_full.py covers a real small disk")
    library = tmp_path_factory.mktemp("shim") / "fault_shim.so"
    source = Path(__file__).parents[1] / "fault_shim.c"
    subprocess.run([compiler, "-shared", "-fPIC", "-O1", "-o", str(library), str(source), "-ldl"], check=True)
    return library


def run(args: list[str], cwd: Path, shim: Path | None = None, fail_at: int = 0, log: Path | None = None,
        errno: int | None = None) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ)
    if shim is not None:
        env.update(LD_PRELOAD=str(shim), FAULT_DIR=f"{cwd / 'out'}/", FAULT_AT=str(fail_at))
        if log is not None:
            env["FAULT_LOG"] = str(log)
        if errno is not None:
            env["FAULT_ERRNO"] = str(errno)
    return subprocess.run([sys.executable, "-m", "orbitsim", *args], cwd=cwd, env=env, capture_output=True,
                          text=True, timeout=300)


def calls(log: Path) -> list[tuple[int, str, str]]:
    """The calls a clean run made into the output directory: (number, call, path)."""
    rows = []
    for line in log.read_text().splitlines():
        number, call, path = line.split(" ", 2)
        rows.append((int(number), call, path))
    return rows


def fault_points(rows: list[tuple[int, str, str]], output: Path) -> dict[str, int]:
    """First, second, middle and last write, the last fsync, and the rename onto the output."""
    writes = [n for n, call, _ in rows if call in ("write", "pwrite", "pwrite64")]
    renames = [n for n, call, path in rows if call.startswith("rename") and path == str(output)]
    syncs = [n for n, call, _ in rows if call in ("fsync", "fdatasync")]
    assert writes and renames and syncs, rows
    return {"first write": writes[0], "second write": writes[1], "middle write": writes[len(writes) // 2],
            "last write": writes[-1], "last fsync": syncs[-1], "final rename": renames[-1]}


@pytest.fixture(scope="module", params=sorted(VARIANTS))
def undisturbed(request: pytest.FixtureRequest, shim: Path, tmp_path_factory: pytest.TempPathFactory,
                ) -> tuple[str, Path, dict[str, int]]:
    """A clean run of one variant under the shim (counting only): its trace and its fault points."""
    variant = request.param
    folder = tmp_path_factory.mktemp(f"clean-{variant}")
    options, scenario = VARIANTS[variant]
    (folder / "faults.yaml").write_text(scenario, encoding="utf-8")
    (folder / "out").mkdir()
    output = folder / "out" / "faults.h5"
    log = folder / "calls.log"
    done = run(["run", "faults.yaml", "-o", str(output), "-q", *options], folder, shim, 0, log)
    assert done.returncode == 0, done.stderr
    reference = folder / "reference.h5"
    output.rename(reference)
    return variant, reference, fault_points(calls(log), output)


POINTS = ("first write", "second write", "middle write", "last write", "last fsync", "final rename")


@pytest.mark.parametrize("point", POINTS)
def test_a_full_disk_at_any_write_is_one_line_and_loses_nothing(
        undisturbed: tuple[str, Path, dict[str, int]], point: str, shim: Path, tmp_path: Path) -> None:
    variant, reference, points = undisturbed
    options, scenario = VARIANTS[variant]
    (tmp_path / "faults.yaml").write_text(scenario, encoding="utf-8")
    (tmp_path / "out").mkdir()
    output = tmp_path / "out" / "faults.h5"
    output.write_bytes(PREVIOUS)

    failed = run(["run", "faults.yaml", "-o", str(output), "--force", "-q", *options], tmp_path, shim,
                 points[point])

    assert failed.returncode == 4, (failed.returncode, failed.stderr)  # not -11: no crash
    lines = failed.stderr.splitlines()
    assert len(lines) == 1, failed.stderr
    assert lines[0].startswith("orbitsim: error: ") and "No space left on device" in lines[0]
    assert str(output) in lines[0]
    assert output.read_bytes() == PREVIOUS
    left = sorted(p.name for p in (tmp_path / "out").iterdir())
    if "orbitsim resume" in lines[0]:
        assert variant == "checkpoint"
        assert left == ["faults.h5", "faults.h5.ckpt", "faults.h5.journal"]
        resumed = run(["resume", str(output), "-q"], tmp_path)
        assert resumed.returncode == 0, resumed.stderr
        assert_same_datasets(reference, output)
    else:
        assert left == ["faults.h5"]


def test_a_device_error_is_reported_in_its_own_words(undisturbed: tuple[str, Path, dict[str, int]], shim: Path,
                                                      tmp_path: Path) -> None:
    """Not only ENOSPC: an EIO in the middle of the run names that cause (errno 5)."""
    variant, _, points = undisturbed
    options, scenario = VARIANTS[variant]
    (tmp_path / "faults.yaml").write_text(scenario, encoding="utf-8")
    (tmp_path / "out").mkdir()
    output = tmp_path / "out" / "faults.h5"
    failed = run(["run", "faults.yaml", "-o", str(output), "-q", *options], tmp_path, shim,
                 points["middle write"], errno=5)
    assert failed.returncode == 4, failed.stderr
    assert failed.stderr.count("\n") == 1 and "Input/output error" in failed.stderr
    assert not output.exists()
