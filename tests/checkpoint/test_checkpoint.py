"""Checkpoints in-process: exact restarts for every scheme, extension, the schema, refusals and damage.

A run is stopped (``stop()``) or its checkpoint files are copied mid-run (the state a SIGKILL
would leave) and continued with :func:`~orbitsim.checkpoint.prepare_resume`; the finished trace
must equal an uninterrupted run's in every dataset, bit for bit. The hard kills themselves are in
``test_checkpoint_kill.py``; the command line in ``test_checkpoint_cli.py``.
"""

from __future__ import annotations

import dataclasses
import json
import shutil
from pathlib import Path

import h5py
import numpy as np
import pytest
from test_checkpoint_kill import assert_same_datasets

from orbitsim.checkpoint import (
    CheckpointError,
    capture_state,
    prepare_extension,
    prepare_resume,
    resolve_output,
    restore_state,
)
from orbitsim.integrators.registry import INTEGRATORS
from orbitsim.io.checkpoint import read_checkpoint
from orbitsim.runner import OutputError, run_scenario
from orbitsim.scenario import ScenarioError, scenario_from_dict
from orbitsim.simulation import Simulation

SYSTEM = {
    "name": "trio",
    "integrator": "verlet",
    "dt": 0.01,
    "steps": 60_000,
    "output": {"every": 250},
    "bodies": [
        {"name": "star", "m": 1.0, "x": [0, 0, 0], "v": [0, 0, 0]},
        {"name": "inner", "m": 1e-3, "primary": "star", "a": 1.0, "e": 0.2, "M": 0},
        {"name": "outer", "m": 2e-3, "primary": "star", "a": 2.0, "e": 0.1, "M": 40, "inc": 3},
    ],
}
CHECKPOINTED = {**SYSTEM, "output": {"every": 250, "checkpoint": {"every": 2000}}}


def scenario(doc: dict, **changes: object):
    return scenario_from_dict({**doc, **changes})


def stop_after(calls: int):
    """A ``stop()`` that asks to stop once it has been polled ``calls`` times."""
    seen = [0]

    def stop() -> bool:
        seen[0] += 1
        return seen[0] > calls

    return stop


# -- the scenario key ------------------------------------------------------------------------


def test_output_checkpoint_is_read_validated_and_round_trips() -> None:
    sc = scenario(SYSTEM, output={"every": 10, "checkpoint": {"every": 500, "seconds": 30}})
    assert (sc.checkpoint_every, sc.checkpoint_seconds, sc.checkpoints) == (500, 30.0, True)
    again = scenario_from_dict(__import__("yaml").safe_load(sc.to_yaml()))
    assert again.to_yaml() == sc.to_yaml() and again.checkpoint_every == 500
    plain = scenario(SYSTEM)
    assert not plain.checkpoints and "checkpoint" not in plain.to_yaml()  # unchanged text and SHA-256
    for bad, key in (({"every": 0}, "output.checkpoint.every"), ({}, "output.checkpoint"),
                     ({"seconds": -1}, "output.checkpoint.seconds"), ({"evry": 3}, "output.checkpoint.evry"),
                     (7, "output.checkpoint")):
        with pytest.raises(ScenarioError, match=rf"{key.replace('.', '[.]')}:"):
            scenario(SYSTEM, output={"checkpoint": bad})


# -- capture and restore -----------------------------------------------------------------------


@pytest.mark.parametrize("name", [spec.name for spec in INTEGRATORS])
def test_capture_and_restore_continue_bit_for_bit(name: str) -> None:
    """Every registered scheme: run 70 steps, snapshot, run 50; restore the snapshot into a fresh
    simulation and run 50: the same bits (work restored generically, whatever its nesting)."""
    sc = scenario(SYSTEM)
    sims = [Simulation(sc.masses, sc.positions, sc.velocities, name, 0.01) for _ in range(2)]
    list(sims[0].chunks(np.array([70]), record_positions=False))
    state = capture_state(sims[0])
    restore_state(sims[1], state)
    for sim in sims:
        list(sim.chunks(np.array([120]), record_positions=False))
    assert np.array_equal(sims[0].pos, sims[1].pos) and np.array_equal(sims[0].vel, sims[1].vel)
    assert sims[1].steps_done == 120


def test_restore_refuses_a_state_that_does_not_fit() -> None:
    sc = scenario(SYSTEM)
    verlet = Simulation(sc.masses, sc.positions, sc.velocities, "verlet", 0.01)
    rk4 = Simulation(sc.masses, sc.positions, sc.velocities, "rk4", 0.01)
    with pytest.raises(CheckpointError, match="work arrays do not fit"):
        restore_state(rk4, capture_state(verlet))
    wh = Simulation(sc.masses, sc.positions, sc.velocities, "wisdom_holman", 0.01)
    with pytest.raises(CheckpointError, match="work"):
        restore_state(wh, capture_state(verlet))


def test_work_parts_a_run_does_not_use_are_none_and_checkpoint_as_before() -> None:
    """Wisdom-Holman without a corrector keeps its stage tables as None (so it compiles no corrector): a
    checkpoint stores them as the empty arrays it stored before they were None (same bytes, same
    layout), and restores them, bit for bit; a non-empty table there (other settings) is refused, and
    so is a None-table checkpoint restored into a run with a corrector."""
    sc = scenario(SYSTEM)
    sims = [Simulation(sc.masses, sc.positions, sc.velocities, "wisdom_holman", 0.01) for _ in range(2)]
    assert sims[0].work.stage_a is None and sims[0].work.stage_b is None
    list(sims[0].chunks(np.array([70]), record_positions=False))
    state = capture_state(sims[0])
    fields = list(type(sims[0].work)._fields)
    stage_slots = [fields.index("stage_a"), fields.index("stage_b")]
    layout = json.loads(state.work_layout)
    assert [layout[i] for i in stage_slots] == ["a", "a"]
    flat_slots = [sum(1 for part in layout[:i] for _ in _leaves(part)) for i in stage_slots]
    assert all(state.work[k].shape == (0,) and state.work[k].dtype == np.float64 for k in flat_slots)
    restore_state(sims[1], state)
    for sim in sims:
        list(sim.chunks(np.array([120]), record_positions=False))
    assert np.array_equal(sims[0].pos, sims[1].pos) and np.array_equal(sims[0].vel, sims[1].vel)
    wrong = dataclasses.replace(state, work=tuple(np.ones(3) if k in flat_slots else a
                                                  for k, a in enumerate(state.work)))
    with pytest.raises(CheckpointError, match="work layout does not fit"):
        restore_state(Simulation(sc.masses, sc.positions, sc.velocities, "wisdom_holman", 0.01), wrong)
    corrected = Simulation(sc.masses, sc.positions, sc.velocities, "wisdom_holman", 0.01, settings={"corrector": 3})
    with pytest.raises(CheckpointError, match="do not fit"):
        restore_state(corrected, state)


def test_the_coordinates_as_a_type_leave_the_checkpoint_as_it_was_and_are_checked() -> None:
    """Wisdom-Holman's ``heliocentric`` (None in Jacobi coordinates, so a Jacobi run compiles no democratic
    heliocentric code) is made from the settings, not saved: the checkpoint holds one part per other field,
    in their order, as before the field existed. Each coordinate system resumes its own checkpoint bit for
    bit, and a checkpoint of the other coordinates is refused in one line rather than restored into code
    compiled for other coordinates."""
    sc = scenario(SYSTEM)
    states = {}
    for coordinates in ("jacobi", "democratic_heliocentric"):
        settings = {"coordinates": coordinates}
        sims = [Simulation(sc.masses, sc.positions, sc.velocities, "wisdom_holman", 0.01, settings=settings)
                for _ in range(2)]
        assert (sims[0].work.heliocentric is None) == (coordinates == "jacobi")
        list(sims[0].chunks(np.array([70]), record_positions=False))
        state = capture_state(sims[0])
        fields = [name for name in type(sims[0].work)._fields if name != "heliocentric"]
        assert len(json.loads(state.work_layout)) == len(fields)
        restore_state(sims[1], state)
        for sim in sims:
            list(sim.chunks(np.array([120]), record_positions=False))
        assert np.array_equal(sims[0].pos, sims[1].pos) and np.array_equal(sims[0].vel, sims[1].vel)
        states[coordinates] = state
    for saved, into in (("jacobi", "democratic_heliocentric"), ("democratic_heliocentric", "jacobi")):
        other = Simulation(sc.masses, sc.positions, sc.velocities, "wisdom_holman", 0.01,
                           settings={"coordinates": into})
        with pytest.raises(CheckpointError, match="other integrator settings \\(config differs\\)"):
            restore_state(other, states[saved])


def _leaves(layout: object) -> list[str]:
    """The array and constant leaves of a work layout, in order."""
    return [layout] if isinstance(layout, str) else [leaf for part in layout for leaf in _leaves(part)]


# -- resume ------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["verlet", "rk4", "leapfrog6", "wisdom_holman"])
@pytest.mark.parametrize("doc", [SYSTEM, CHECKPOINTED], ids=["streamed", "checkpointed"])
def test_stopped_run_resumes_to_the_same_bits(tmp_path: Path, name: str, doc: dict) -> None:
    sc = scenario(doc, integrator=name)
    run_scenario(sc, tmp_path / "ref.h5")
    first = run_scenario(sc, tmp_path / "out.h5", stop=stop_after(1))
    assert first.status == "interrupted" and first.resumable and 0 < first.steps_done < sc.steps
    plan = prepare_resume(tmp_path / "out.h5")
    assert plan.start.checkpoint.steps_done == first.steps_done
    second = run_scenario(plan.scenario, plan.output, start=plan.start, threads=1)
    assert (second.status, second.samples) == ("complete", len(sc.sample_steps()))
    assert second.max_abs_energy_error == run_scenario(sc, tmp_path / "again.h5").max_abs_energy_error
    assert_same_datasets(tmp_path / "ref.h5", tmp_path / "out.h5")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["again.h5", "out.h5", "ref.h5"]


def test_killed_checkpointed_run_resumes_from_its_side_files(tmp_path: Path) -> None:
    """Copy the checkpoint and journal mid-run (what a SIGKILL leaves, plus a torn journal tail)."""
    sc = scenario(CHECKPOINTED, output={"every": 100, "checkpoint": {"every": 1000}})
    out, saved = tmp_path / "out.h5", tmp_path / "saved"
    saved.mkdir()
    seen: list[int] = []

    def snapshot(sim: object, chunk: object) -> None:
        if len(seen) == 0 and Path(f"{out}.ckpt").exists():
            for suffix in (".ckpt", ".journal"):
                shutil.copy(f"{out}{suffix}", saved / f"out.h5{suffix}")
            seen.append(read_checkpoint(f"{out}.ckpt").steps_done)

    run_scenario(sc, out, on_chunk=snapshot)
    ref = tmp_path / "ref.h5"
    out.rename(ref)
    with open(saved / "out.h5.journal", "ab") as fh:
        fh.write(b"\x00" * 1000)  # samples after the checkpoint, half written when the kill came
    for path in saved.iterdir():
        shutil.copy(path, tmp_path / path.name)
    plan = prepare_resume(f"{out}.ckpt")  # any side file names the run
    assert plan.output == out and plan.start.checkpoint.steps_done == seen[0]
    assert run_scenario(plan.scenario, plan.output, start=plan.start).status == "complete"
    assert_same_datasets(ref, out)
    assert not Path(f"{out}.ckpt").exists() and not Path(f"{out}.journal").exists()


def test_checkpoints_follow_steps_and_seconds(tmp_path: Path) -> None:
    out = tmp_path / "out.h5"
    published: list[int] = []

    def watch(sim: object, chunk: object) -> None:
        published.append(read_checkpoint(f"{out}.ckpt").steps_done)

    sc = scenario(SYSTEM, steps=600_000, output={"every": 2500, "checkpoint": {"seconds": 1e-6}})
    run_scenario(sc, out, on_chunk=watch)
    assert published == sorted(published) and len(set(published)) > 3  # one after every call
    with h5py.File(out) as f:
        assert f["checkpoint"].attrs["steps_done"] == 600_000 and f["checkpoint"].attrs["samples_written"] == 241
    published.clear()
    sc = scenario(SYSTEM, steps=600_000, output={"every": 2500, "checkpoint": {"every": 100_000}})
    run_scenario(sc, out, on_chunk=watch, force=True)
    assert set(published) <= {0, *range(100_000, 600_000)} and len(set(published)) >= 3
    assert np.all(np.diff(sorted(set(published)))[1:] >= 100_000)


def test_stale_checkpoint_beside_a_complete_trace_is_cleared(tmp_path: Path) -> None:
    """A kill between renaming the finished trace into place and deleting the side files."""
    out = tmp_path / "out.h5"
    kept: list[bool] = []

    def keep(sim: object, chunk: object) -> None:
        if not kept:
            for suffix in (".ckpt", ".journal"):
                shutil.copy(f"{out}{suffix}", tmp_path / f"keep{suffix}")
            kept.append(True)

    run_scenario(scenario(CHECKPOINTED), out, on_chunk=keep)
    for suffix in (".ckpt", ".journal"):
        shutil.move(tmp_path / f"keep{suffix}", f"{out}{suffix}")
    plan = prepare_resume(out)
    assert plan.start is None and "already complete" in plan.note
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.h5"]


# -- extension -----------------------------------------------------------------------------------


@pytest.mark.parametrize("doc", [SYSTEM, CHECKPOINTED], ids=["streamed", "checkpointed"])
def test_extension_equals_one_longer_run(tmp_path: Path, doc: dict) -> None:
    run_scenario(scenario(doc, steps=80_000), tmp_path / "long.h5")
    run_scenario(scenario(doc, steps=50_000), tmp_path / "out.h5")
    plan = prepare_extension(tmp_path / "out.h5", steps=30_000)
    assert plan.output == tmp_path / "out.h5" and plan.scenario.steps == 80_000
    assert run_scenario(plan.scenario, plan.output, start=plan.start).status == "complete"
    assert_same_datasets(tmp_path / "long.h5", tmp_path / "out.h5")


def test_extension_to_t_end_into_a_new_file(tmp_path: Path) -> None:
    run_scenario(scenario(SYSTEM, steps=80_000), tmp_path / "long.h5")
    run_scenario(scenario(SYSTEM, steps=50_000), tmp_path / "out.h5")
    before = (tmp_path / "out.h5").read_bytes()
    plan = prepare_extension(tmp_path / "out.h5", t_end=800.0, output=tmp_path / "ext.h5")
    run_scenario(plan.scenario, plan.output, start=plan.start, force=True)
    assert_same_datasets(tmp_path / "long.h5", tmp_path / "ext.h5")
    assert (tmp_path / "out.h5").read_bytes() == before  # the source is left alone
    with pytest.raises(OutputError, match="already exists"):
        prepare_extension(tmp_path / "out.h5", steps=10, output=tmp_path / "ext.h5")
    with pytest.raises(CheckpointError, match="not past the run's end"):
        prepare_extension(tmp_path / "out.h5", t_end=100.0)


# -- refusals ----------------------------------------------------------------------------------


def test_refuses_another_integrator_or_scenario(tmp_path: Path) -> None:
    sc = scenario(SYSTEM)
    run_scenario(sc, tmp_path / "out.h5", stop=stop_after(1))
    with pytest.raises(CheckpointError, match="made with integrator verlet; it cannot continue with rk4"):
        prepare_resume(tmp_path / "out.h5", integrator="rk4")
    with pytest.raises(CheckpointError, match=r"not the scenario of this run \(dt: 0.01 vs 0.02\)"):
        prepare_resume(tmp_path / "out.h5", scenario=sc.with_overrides(dt=0.02))
    assert prepare_resume(tmp_path / "out.h5", scenario=sc, integrator="kdk").start is not None  # an alias
    run_scenario(sc, tmp_path / "done.h5")
    # Extending with another scheme is allowed (tests/checkpoint/test_run_from_switch.py), but not to an adaptive one.
    assert prepare_extension(tmp_path / "done.h5", steps=10, integrator="leapfrog4").start.rebuild
    with pytest.raises(CheckpointError, match="cannot switch to or from it"):
        prepare_extension(tmp_path / "done.h5", t_end=100.0, integrator="ias15")
    with pytest.raises(CheckpointError, match="bodies differ"):
        prepare_extension(tmp_path / "done.h5", steps=10, scenario=sc.with_overrides(
            masses=sc.masses * 2))
    with pytest.raises(CheckpointError, match="interrupted; finish it with `orbitsim resume"):
        prepare_extension(tmp_path / "out.h5", steps=10)


def test_a_new_run_will_not_start_over_a_resumable_checkpoint(tmp_path: Path) -> None:
    out = tmp_path / "out.h5"
    (tmp_path / "out.h5.ckpt").write_bytes(b"x")
    (tmp_path / "out.h5.journal").write_bytes(b"y")
    with pytest.raises(OutputError, match="orbitsim resume"):
        run_scenario(scenario(SYSTEM), out)
    assert run_scenario(scenario(SYSTEM, steps=100), out, force=True).status == "complete"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.h5"]


def test_a_live_run_is_neither_resumed_nor_overwritten(tmp_path: Path) -> None:
    out = tmp_path / "out.h5"
    errors: list[str] = []

    def meddle(sim: object, chunk: object) -> None:  # while this run holds its journal
        if errors:
            return
        with pytest.raises(CheckpointError, match="another orbitsim process is writing this run") as resumed:
            prepare_resume(out)
        with pytest.raises(OutputError, match="another orbitsim process is writing this output") as rerun:
            run_scenario(scenario(CHECKPOINTED), out, force=True, handle_signals=False)
        errors.extend([str(resumed.value), str(rerun.value)])

    assert run_scenario(scenario(CHECKPOINTED), out, on_chunk=meddle).status == "complete"
    assert len(errors) == 2


def test_damaged_and_foreign_files_are_clear_errors(tmp_path: Path) -> None:
    out = tmp_path / "out.h5"
    with pytest.raises(CheckpointError, match="no trace or checkpoint to resume"):
        prepare_resume(out)
    (tmp_path / "out.h5.tmp").write_bytes(b"partial")
    with pytest.raises(CheckpointError, match="cannot be resumed"):
        prepare_resume(out)
    out.write_bytes(b"not hdf5")
    with pytest.raises(ValueError, match="not an HDF5 file"):
        prepare_resume(out)
    with h5py.File(out, "w") as f:
        f.attrs["format"] = "something.else"
    with pytest.raises(ValueError, match="not an orbitsim trace"):
        prepare_resume(out)
    out.unlink()
    (tmp_path / "out.h5.ckpt").write_bytes(b"\x89HDF\r\n\x1a\n" + b"\x00" * 40)  # a torn HDF5 header
    with pytest.raises(CheckpointError, match="damaged or unreadable checkpoint"):
        prepare_resume(out)


def test_a_corrupted_journal_or_checkpoint_is_refused(tmp_path: Path) -> None:
    out = tmp_path / "out.h5"
    saved: list[bool] = []

    def keep(sim: object, chunk: object) -> None:
        if not saved and read_checkpoint(f"{out}.ckpt").samples_written > 10:
            for suffix in (".ckpt", ".journal"):
                shutil.copy(f"{out}{suffix}", tmp_path / f"keep{suffix}")
            saved.append(True)

    run_scenario(scenario(CHECKPOINTED), out, on_chunk=keep)
    out.unlink()
    for suffix in (".ckpt", ".journal"):
        shutil.copy(tmp_path / f"keep{suffix}", f"{out}{suffix}")
    with open(f"{out}.journal", "r+b") as fh:
        fh.seek(100)
        byte = fh.read(1)
        fh.seek(100)
        fh.write(bytes([byte[0] ^ 1]))  # one flipped bit inside the checkpointed prefix
    with pytest.raises(CheckpointError, match="CRC-32"):
        prepare_resume(out)
    shutil.copy(tmp_path / "keep.journal", f"{out}.journal")
    with h5py.File(f"{out}.ckpt", "r+") as f:
        f["pos"][0, 1] += 1e-12
    with pytest.raises(CheckpointError, match="does not match its SHA-256"):
        prepare_resume(out)


def test_resolve_output_strips_side_suffixes() -> None:
    for given in ("a/out.h5", "a/out.h5.tmp", "a/out.h5.ckpt", "a/out.h5.journal", "a/out.h5.ckpt.tmp"):
        assert resolve_output(given) == Path("a/out.h5")


def test_small_read_blocks_give_the_same_trace(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The journal and a source trace are read back block by block: block boundaries change nothing."""
    import orbitsim.checkpoint.sinks as sinks
    import orbitsim.io.journal as io_journal

    sc = scenario(CHECKPOINTED)
    run_scenario(sc, tmp_path / "ref.h5")
    monkeypatch.setattr(io_journal, "_JOURNAL_BLOCK_BYTES", 1000)  # a few records per block
    monkeypatch.setattr(sinks, "_COPY_BLOCK_BYTES", 1000)
    run_scenario(sc, tmp_path / "out.h5", stop=stop_after(1))
    plan = prepare_resume(tmp_path / "out.h5")
    run_scenario(plan.scenario, plan.output, start=plan.start)
    assert_same_datasets(tmp_path / "ref.h5", tmp_path / "out.h5")
