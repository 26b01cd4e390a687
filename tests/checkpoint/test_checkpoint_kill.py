"""The promise under hard kills: SIGKILL at 10 random moments, ``orbitsim resume`` after each, and the
finished trace is bit-identical, dataset for dataset, to an uninterrupted run's.

Real processes (``python -m orbitsim``), so nothing in the test process can help the run along.
The kill moments are random (fixed seed): ten steps drawn uniformly over 5-50 % of the run,
sorted; each process is killed once it has published a checkpoint of its own at or past its
step, plus a random delay of up to 50 ms, so kills land while it integrates, appends samples,
publishes a checkpoint or rebuilds nothing yet, never while it loads Numba's cache. Drawing the
moments as steps rather than seconds keeps the run going until the tenth kill on a machine of
any speed (a process makes at least one jitted call of progress, ~0.2 s); the last resume
finishes it. Three schemes: ``verlet`` (symplectic; its accelerations
are state carried from step to step), ``wisdom_holman`` (it keeps Jacobi mapping coordinates
and a phase between steps, in ``work``), ``ias15`` (adaptive: its predictor polynomial,
compensation terms, trial step and clock are the state; its "steps" are output intervals) and
``trace`` (close encounters sub-integrated by Bulirsch-Stoer on a summed clock).
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import pytest
from suite_split import fast_only

from orbitsim.data import SCENARIOS, bundled_dir
from orbitsim.runner import run_scenario
from orbitsim.scenario import load_scenario

# 64 bodies: ~7 us a step, so 600000 steps take about 4 s uninterrupted.
VERLET = """\
name: kill_verlet
integrator: verlet
dt: 0.001
steps: 600000
softening: 0.05
output: {every: 1000, positions: true, checkpoint: {every: 5000}}
generator: {kind: plummer, n: 64, seed: 5}
"""
KILLS = 10
#: Seconds to wait for a process to publish its first checkpoint (cold imports on a busy machine).
START_TIMEOUT = 120
#: Kill moments: steps drawn over this fraction of the run, then up to JITTER seconds later. The last
#: kill leaves half the run (1-2 s of integration, more under load, which slows the run as much as it
#: slows this watcher) between it and the end: with 15 % left (0.27 s for ias15) a loaded machine let
#: the run finish and rename its trace before the kill landed (issue 28).
SPAN = (0.05, 0.5)
JITTER = 0.05


def wisdom_holman_yaml() -> str:
    """A star and 12 planets: ~2 us a step, so 2.4 million steps take about 5 s."""
    rng = np.random.default_rng(7)
    lines = ["name: kill_wh", "integrator: wisdom_holman", "dt: 0.01", "steps: 2400000",
             "output: {every: 4000, checkpoint: {every: 10000}}", "bodies:",
             "  - {name: star, m: 1.0, x: [0, 0, 0], v: [0, 0, 0]}"]
    for k in range(12):
        lines.append(f"  - {{name: p{k}, m: {1e-5 * (1 + rng.random()):.6g}, primary: star, a: {1.0 + 0.5 * k}, "
                     f"e: {0.05 * rng.random():.4f}, inc: {2 * rng.random():.3f}, M: {360 * rng.random():.3f}}}")
    return "\n".join(lines) + "\n"


def ias15_yaml() -> str:
    """The bundled giants under IAS15 (8000 output intervals of 100 take about 3.6 s); its polynomial,
    compensation terms and clock all live in the checkpoint."""
    text = (bundled_dir(SCENARIOS) / "giants.yaml").read_text(encoding="utf-8")
    text = text.replace("name: giants", "name: kill_ias15").replace("t_end: 1000", "t_end: 800000")
    return text.replace("  interval: 10\n", "  interval: 100\n  checkpoint: {every: 80}\n")


def trace_yaml() -> str:
    """The bundled many-encounters system under TRACE (~2.5 us a step, encounters, redone steps and
    FULL_BS pericentre steps all along): 1.6 million steps take about 4 s; its summed clock is the
    state a checkpoint must carry beside the bodies."""
    text = (bundled_dir(SCENARIOS) / "many_encounters.yaml").read_text(encoding="utf-8")
    text = text.replace("name: many_encounters", "name: kill_trace")
    text = text.replace("steps: 58824 ", "steps: 1600000 ")
    return text.replace("  every: 100\n", "  every: 4000\n  checkpoint: {every: 20000}\n")


CASES = {"verlet": VERLET, "wisdom_holman": wisdom_holman_yaml(), "ias15": ias15_yaml(), "trace": trace_yaml()}


def orbitsim(*args: str) -> list[str]:
    return [sys.executable, "-m", "orbitsim", *args]


def datasets(path: Path) -> dict[str, np.ndarray]:
    """Every dataset of an HDF5 file, by path."""
    found: dict[str, np.ndarray] = {}
    with h5py.File(path, "r") as f:
        f.visititems(lambda name, obj: found.__setitem__(name, obj[()]) if isinstance(obj, h5py.Dataset) else None)
    return found


def _bytes(arr: np.ndarray) -> bytes:
    """The bytes of an array; text (object) arrays by their items."""
    if arr.dtype == object:
        return repr(arr.tolist()).encode()
    return np.ascontiguousarray(arr).tobytes()


def assert_same_datasets(a: Path, b: Path) -> None:
    da, db = datasets(a), datasets(b)
    assert sorted(da) == sorted(db)
    # Bytes, not values: bit for bit, and a NaN (a body that left the run) equals itself.
    differing = [name for name in da if not (da[name].dtype == db[name].dtype and da[name].shape == db[name].shape
                                             and _bytes(da[name]) == _bytes(db[name]))]
    assert not differing, f"datasets differ: {differing}"


class _References(dict):
    """Each case's scenario file and its uninterrupted trace (which also warms Numba's on-disk cache),
    made when a test first asks for it: `make test` runs one case, and compiles no other's kernels."""

    def __init__(self, folder: Path) -> None:
        super().__init__()
        self.folder = folder

    def __missing__(self, name: str) -> tuple[Path, Path]:
        scenario = self.folder / f"{name}.yaml"
        scenario.write_text(CASES[name], encoding="utf-8")
        reference = self.folder / f"{name}.h5"
        assert run_scenario(load_scenario(scenario), reference, handle_signals=False).status == "complete"
        self[name] = (scenario, reference)
        return self[name]


@pytest.fixture(scope="module")
def references(tmp_path_factory: pytest.TempPathFactory) -> dict[str, tuple[Path, Path]]:
    """:class:`_References` for this module's tests."""
    return _References(tmp_path_factory.mktemp("kill"))


def _inode(path: Path) -> int | None:
    try:
        return os.stat(path).st_ino
    except FileNotFoundError:
        return None


def _checkpoint_step(path: Path) -> int:
    """Steps done at the checkpoint now at ``path`` (it is only ever replaced whole), or -1."""
    try:
        with h5py.File(path, "r") as f:
            return int(f.attrs["steps_done"])
    except (OSError, KeyError):
        return -1


def run_and_kill(command: list[str], checkpoint: Path, step: int, delay: float) -> int | None:
    """Start ``command``; once it has published a checkpoint of its own (the file is replaced, so
    its inode changes) at or past ``step``, wait ``delay`` seconds and SIGKILL it. Returns its exit
    code if it finished first, else None."""
    before = _inode(checkpoint)
    proc = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + START_TIMEOUT
    own = False
    while not (own and _checkpoint_step(checkpoint) >= step):
        if proc.poll() is not None:
            return proc.returncode
        if time.monotonic() > deadline:
            proc.kill()
            pytest.fail(f"no checkpoint past step {step} within {START_TIMEOUT} s: {proc.communicate()[1]}")
        own = own or _inode(checkpoint) not in (before, None)
        time.sleep(0.002)
    time.sleep(delay)
    proc.kill()
    _, stderr = proc.communicate(timeout=60)
    if proc.returncode != -9:
        assert proc.returncode == 0, stderr
        return proc.returncode
    return None


# Each case is ten killed processes and a scheme's loop with checkpoints (15-35 s): `make test` kills verlet,
# `make test-slow` every scheme.
@pytest.mark.parametrize("name", fast_only(CASES, ["verlet"]))
def test_ten_sigkills_then_resume_is_bit_identical(references: dict[str, tuple[Path, Path]], tmp_path: Path,
                                                   name: str) -> None:
    scenario, reference = references[name]
    out = tmp_path / "killed.h5"
    checkpoint = Path(f"{out}.ckpt")
    rng = np.random.default_rng(1234 + list(CASES).index(name))
    total = load_scenario(scenario).steps
    moments = np.sort(rng.uniform(*SPAN, KILLS)) * total
    command = orbitsim("run", str(scenario), "-o", str(out), "-q")
    steps_at_kill = []
    for moment in moments:
        code = run_and_kill(command, checkpoint, int(moment), float(rng.uniform(0.0, JITTER)))
        assert code is None, "the run finished before it could be killed ten times: make it longer"
        # A killed run never leaves a trace at the output path; a complete one there means the run
        # finished before the kill landed (the same cause as above, seen after the rename).
        assert not out.exists(), "the run finished before its kill landed: make it longer or SPAN shorter"
        done = subprocess.run(orbitsim("info", str(out)), capture_output=True, text=True, timeout=120)
        assert done.returncode == 0 and "resumable            yes" in done.stdout, done.stdout + done.stderr
        steps_at_kill.append(int(done.stdout.split("steps_done")[1].split()[0]))
        command = orbitsim("resume", str(out), "-q")
    assert steps_at_kill == sorted(steps_at_kill) and steps_at_kill[-1] > steps_at_kill[0]
    final = subprocess.run(command, capture_output=True, text=True, timeout=300)
    assert final.returncode == 0, final.stderr
    assert_same_datasets(reference, out)
    assert not [p.name for p in tmp_path.iterdir() if p.name != out.name]  # no side files left
    with h5py.File(out, "r") as f:
        assert f.attrs["status"] == "complete" and f["checkpoint"].attrs["resumes"] == KILLS
