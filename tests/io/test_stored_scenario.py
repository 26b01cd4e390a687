"""A large scenario is stored with its bodies as datasets, not as YAML text (issue 27, item 10).

An interrupted 10^6-body Plummer run used to leave a 231 MB trace with 0 samples, 176 MB of it the
resolved scenario as one YAML attribute. Now a scenario whose text passes
``STORED_TEXT_MAX`` keeps its per-body rows in the datasets of ``scenario_bodies``; resume,
``run --from``, ``export`` and ``info --scenario`` read it back to the same bits, and its SHA-256
stays that of the whole text.
"""

from __future__ import annotations

import hashlib
import shutil
from pathlib import Path

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

from orbitsim.checkpoint import prepare_extension, prepare_resume
from orbitsim.checkpoint.plan import read_trace_state
from orbitsim.cli.main import cli
from orbitsim.io.stored_scenario import SCENARIO_BODIES
from orbitsim.runner import run_scenario
from orbitsim.scenario import scenario_from_dict
from orbitsim.scenario.serialize import BODIES_GROUP, STORED_TEXT_MAX

#: What the issue allows a trace's metadata (every attribute of every object) to take, at any N.
METADATA_MAX = 2**20


def plummer(n: int, **changes: object):
    doc = {"name": f"plummer{n}", "units": "nbody", "integrator": "leapfrog", "dt": 0.001, "steps": 40,
           "softening": 0.01, "output": {"every": 4, "positions": True},
           "generator": {"kind": "plummer", "n": n, "seed": 7}}
    return scenario_from_dict({**doc, **changes})


def metadata_bytes(path: Path) -> int:
    """Bytes of every attribute in the file (text by its length, numbers by their size)."""
    def size(value: object) -> int:
        return len(value) if isinstance(value, str | bytes) else int(getattr(value, "nbytes", 8))

    with h5py.File(path) as f:
        total = [sum(size(v) for v in f.attrs.values())]
        f.visititems(lambda _, obj: total.append(sum(size(v) for v in obj.attrs.values())))
    return sum(total)


def same_samples(a: Path, b: Path) -> bool:
    with h5py.File(a) as f, h5py.File(b) as g:
        return all(np.array_equal(f[k][()], g[k][()]) for k in ("time", "step", "energy", "positions", "velocities"))


def invoke(*args: str) -> tuple[int, str]:
    result = CliRunner().invoke(cli, list(args))
    assert "Traceback" not in result.output, result.output
    return result.exit_code, result.stdout


def stop_after(calls: int):
    seen = [0]

    def stop() -> bool:
        seen[0] += 1
        return seen[0] > calls

    return stop


@pytest.fixture(scope="module")
def large():
    """2,000 bodies: 350 kB of text, past STORED_TEXT_MAX, so stored as datasets."""
    sc = plummer(2000)
    assert len(sc.to_yaml()) > STORED_TEXT_MAX
    return sc


def test_the_group_name_is_one() -> None:
    assert SCENARIO_BODIES == BODIES_GROUP


def test_a_large_scenario_keeps_its_bodies_out_of_the_metadata(tmp_path: Path) -> None:
    """N = 50,000, stopped before its first step (the issue's case at 1/20 the size): the text was
    8.7 MB of one attribute; now the metadata is a few kB, and the stored scenario is the same."""
    sc = plummer(50_000, output={"every": 4})
    out = tmp_path / "big.h5"
    summary = run_scenario(sc, out, stop=lambda: True, handle_signals=False)
    assert summary.status == "interrupted" and summary.samples == 0
    assert metadata_bytes(out) < METADATA_MAX
    with h5py.File(out) as f:
        assert "\nbodies:" not in f.attrs["scenario"] and f[f"{SCENARIO_BODIES}/x"].shape == (50_000, 3)
        assert f.attrs["scenario_sha256"] == hashlib.sha256(sc.to_yaml().encode()).hexdigest()
    stored = read_trace_state(out).stored_scenario(out)
    for name in ("masses", "positions", "velocities"):
        assert np.array_equal(getattr(stored, name), getattr(sc, name)), name
    assert stored.names == sc.names and stored.sha256 == sc.sha256


def test_the_sha256_of_a_large_scenario_is_its_whole_texts() -> None:
    """Hashed line by line without building the text; the same digest as the text's (so a batch
    rerun still recognises its traces)."""
    sc = plummer(5000)
    hashed = sc.sha256
    assert "_yaml" not in sc.__dict__  # the text was never built
    assert hashed == hashlib.sha256(sc.to_yaml().encode()).hexdigest()


def test_a_small_scenario_is_stored_as_before(tmp_path: Path) -> None:
    sc = plummer(100)
    out = tmp_path / "small.h5"
    run_scenario(sc, out)
    with h5py.File(out) as f:
        assert f.attrs["scenario"] == sc.to_yaml() and SCENARIO_BODIES not in f


def test_resume_and_run_from_continue_a_large_run_bit_for_bit(tmp_path: Path, large) -> None:
    ref = tmp_path / "ref.h5"
    run_scenario(large, ref)
    out = tmp_path / "out.h5"
    first = run_scenario(large.with_overrides(steps=20), out)
    assert first.status == "complete"
    plan = prepare_extension(out, steps=20)
    assert plan.scenario.sha256 == large.sha256  # the longer run is the reference's scenario
    run_scenario(plan.scenario, plan.output, start=plan.start)
    assert same_samples(ref, out)
    stopped = tmp_path / "stopped.h5"
    run_scenario(large, stopped, stop=stop_after(1), handle_signals=False)
    with h5py.File(stopped) as f:
        assert f.attrs["status"] == "interrupted" and SCENARIO_BODIES in f
    assert invoke("resume", str(stopped), "-q")[0] == 0
    assert same_samples(ref, stopped)


def test_a_checkpoint_file_stores_a_large_scenario_as_datasets(tmp_path: Path, large) -> None:
    """A killed checkpointed run's ``.ckpt`` (what `resume` reads first, rewritten at every checkpoint,
    which used to carry the whole text each time): small metadata, and the run resumes bit for bit.
    The kill is made by copying the side files away while the run is going."""
    sc = large.with_overrides(checkpoint_every=8, every=1)
    ref = tmp_path / "ref.h5"
    run_scenario(sc, ref)
    out = tmp_path / "out.h5"
    killed = tmp_path / "killed"
    killed.mkdir()

    def snapshot(sim: object, chunk: object) -> None:
        if not (killed / "out.h5.ckpt").exists() and Path(f"{out}.ckpt").exists():
            for suffix in (".ckpt", ".journal"):
                shutil.copy(f"{out}{suffix}", killed / f"out.h5{suffix}")

    run_scenario(sc, out, on_chunk=snapshot, handle_signals=False)
    ckpt_file = killed / "out.h5.ckpt"
    assert ckpt_file.exists() and metadata_bytes(ckpt_file) < 64 * 1024
    with h5py.File(ckpt_file) as f:
        assert SCENARIO_BODIES in f
    code, text = invoke("info", str(ckpt_file), "--scenario")
    assert code == 0 and text == sc.to_yaml()
    assert invoke("resume", str(killed / "out.h5"), "-q")[0] == 0
    assert same_samples(ref, killed / "out.h5")


def test_info_scenario_prints_the_whole_text(tmp_path: Path, large) -> None:
    out = tmp_path / "out.h5"
    run_scenario(large.with_overrides(steps=4), out)
    code, text = invoke("info", str(out), "--scenario")
    assert code == 0 and text == large.with_overrides(steps=4).to_yaml()
    code, shown = invoke("info", str(out))
    assert code == 0 and "the bodies in scenario_bodies/" in shown


def test_damaged_stored_bodies_are_refused(tmp_path: Path, large) -> None:
    out = tmp_path / "out.h5"
    run_scenario(large.with_overrides(steps=4), out)
    damaged = Path(shutil.copy(out, tmp_path / "damaged.h5"))
    with h5py.File(damaged, "r+") as f:
        x = f[f"{SCENARIO_BODIES}/x"]
        row = x[7]
        row[0] = np.nextafter(row[0], np.inf)  # one ulp of one coordinate
        x[7] = row
    from orbitsim.io.checkpoint import CheckpointError

    with pytest.raises(CheckpointError, match="does not match its SHA-256"):
        prepare_extension(damaged, steps=4, output=tmp_path / "longer.h5")
    with h5py.File(damaged, "r+") as f:
        del f[f"{SCENARIO_BODIES}/v"]
    with pytest.raises(CheckpointError, match=r"damaged stored scenario.*'v'"):
        prepare_extension(damaged, steps=4, output=tmp_path / "longer.h5")


@pytest.mark.slow  # compiles Wisdom-Holman for the row kernels' N (~13 s cold)
def test_export_of_a_large_wisdom_holman_run_continues_bit_for_bit(tmp_path: Path) -> None:
    """The exported scenario's integrator_state (two (N, 3) arrays) is stored as datasets too, and
    the exported run, stored that way, continues the original bit for bit."""
    doc = {"name": "disc", "units": "nbody", "integrator": "wisdom_holman", "dt": 0.01, "steps": 30,
           "output": {"every": 10, "positions": True},
           "generator": {"kind": "disc", "n": 1600, "seed": 3, "r_min": 1.0, "r_max": 5.0, "e_max": 0.05}}
    sc = scenario_from_dict(doc)
    original = tmp_path / "d.h5"
    run_scenario(sc, original)
    scenario_file = tmp_path / "next.yaml"
    code, _ = invoke("export", str(original), "--format", "scenario", "--sample", "1", "-o", str(scenario_file))
    assert code == 0
    continued = tmp_path / "next.h5"
    assert invoke("run", str(scenario_file), "-o", str(continued), "-q")[0] == 0
    with h5py.File(continued) as f:
        assert {"mapping_positions", "mapping_velocities"} <= set(f[SCENARIO_BODIES])
        assert "mapping_positions:\n" not in f.attrs["scenario"] and metadata_bytes(continued) < 64 * 1024
    with h5py.File(original) as f, h5py.File(continued) as g:
        assert np.array_equal(f["positions"][1:], g["positions"][()])
    plan = prepare_resume(continued)  # complete: nothing to resume, but its stored scenario is checked
    assert plan.start is None
    assert read_trace_state(continued).stored_scenario(continued).integrator_state is not None
