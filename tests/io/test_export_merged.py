"""``orbitsim export`` after merges: the bodies still in the run, with their masses and radii then,
and a note of who merged into whom; every sample after a merge continues the run bit for bit.

The run: two planets on one circle going opposite ways meet at t = pi/2 (step 157) and merge; the
merged body, slowed, falls into the star at step 268; a third planet stays. Samples every 10 steps:
sample 20 (step 200) lies between the two merges, sample 30 on after both.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import h5py
import numpy as np
import pytest
from click.testing import CliRunner, Result

from orbitsim.cli.main import cli
from orbitsim.io.trace import read_trace
from orbitsim.runner import run_scenario
from orbitsim.scenario import load_scenario, scenario_from_dict

BODIES = [{"name": "star", "m": 1.0, "x": [0.0, 0.0, 0.0], "v": [0.0, 0.0, 0.0], "r": 0.005},
          {"name": "a", "m": 1e-4, "x": [1.0, 0.0, 0.0], "v": [0.0, 1.0, 0.0], "r": 0.01},
          {"name": "b", "m": 1e-4, "x": [-1.0, 0.0, 0.0], "v": [0.0, 1.0, 0.0], "r": 0.01},
          {"name": "c", "m": 1e-5, "x": [0.0, 2.0, 0.0], "v": [-0.7, 0.0, 0.0]}]
TWO_MERGES = {"dt": 0.01, "steps": 400, "output": {"every": 10, "positions": True},
              "events": {"collisions": {"resolve": "merge"}}, "bodies": BODIES}
#: b joins a at step 157, a (with b) joins the star at step 268.
REMOVED_STEP = [-1, 268, 157, -1]


def export(*args: str) -> Result:
    result = CliRunner().invoke(cli, ["export", *args])
    assert "Traceback" not in result.output, result.output
    return result


def run_doc(tmp_path: Path, doc: dict[str, Any], name: str) -> Path:
    out = tmp_path / f"{name}.h5"
    summary = run_scenario(scenario_from_dict({"name": name, **doc}), out, handle_signals=False)
    assert summary.status == "complete", summary.message
    return out


@pytest.fixture(params=["leapfrog", "wisdom_holman"])
def merges(request: pytest.FixtureRequest, tmp_path: Path) -> Path:
    out = run_doc(tmp_path, {**TWO_MERGES, "integrator": request.param}, "merges")
    with h5py.File(out, "r") as f:
        assert list(f["bodies/removed_step"][()]) == REMOVED_STEP
        assert list(f["bodies/merged_into"][()]) == [-1, 0, 1, -1]
    return out


@pytest.mark.parametrize(("sample", "kept", "left"), [
    (20, [0, 1, 3], "1 of 4 bodies left the run before sample 20 (t = 2): b merged into a at t = 1.57 (step 157)"),
    (30, [0, 3], "2 of 4 bodies left the run before sample 30 (t = 3): b merged into a at t = 1.57 (step 157); "
                 "a merged into star at t = 2.68 (step 268)"),
])
def test_a_sample_after_a_merge_continues_the_run_bit_for_bit(tmp_path: Path, merges: Path, sample: int,
                                                              kept: list[int], left: str) -> None:
    """Sample 20's masses come from a rerun to it (the trace keeps them only at the start and end);
    sample 30's from the trace's final masses. From either the run goes on with the same bits, and
    from sample 20 the second merge happens again at the same step."""
    out = tmp_path / "next.yaml"
    result = export(str(merges), "--format", "scenario", "--sample", str(sample), "-o", str(out))
    assert result.exit_code == 0, result.output
    assert result.stdout == f"{merges}: {left}; exported the {len(kept)} still in it\n"
    assert result.stderr == ""  # wisdom_holman: its own coordinates were found, no round-off note
    scenario = load_scenario(out)
    names = tuple(BODIES[i]["name"] for i in kept)
    assert scenario.names == names and scenario.t_start == sample / 10
    assert left.split(": ", 1)[1].split("; ")[0] in scenario.description
    run_scenario(scenario, tmp_path / "next.h5", handle_signals=False)
    whole, rest = read_trace(merges), read_trace(tmp_path / "next.h5")
    assert rest.positions.tobytes() == whole.positions[sample:, kept].tobytes()  # NaN rows too: bytes
    assert rest.velocities.tobytes() == whole.velocities[sample:, kept].tobytes()
    with h5py.File(tmp_path / "next.h5", "r") as f, h5py.File(merges, "r") as g:
        assert f["bodies/final_masses"][()].tolist() == g["bodies/final_masses"][()][kept].tolist()
        assert f["bodies/final_radii"][()].tolist() == g["bodies/final_radii"][()][kept].tolist()


def test_the_masses_between_merges_are_the_runs(tmp_path: Path, merges: Path) -> None:
    """At sample 20, a holds b: 1e-4 + 1e-4 (one addition, bit-exact) and the grown radius."""
    out = tmp_path / "s20.yaml"
    assert export(str(merges), "--format", "scenario", "--sample", "20", "-o", str(out)).exit_code == 0
    scenario = load_scenario(out)
    assert scenario.masses.tolist() == [1.0, 1e-4 + 1e-4, 1e-5]
    assert scenario.radii.tolist() == [0.005, float(np.cbrt(0.01**3 + 0.01**3)), 0.0]


def test_the_rebound_file_holds_the_bodies_left(tmp_path: Path, merges: Path) -> None:
    rebound = pytest.importorskip("rebound")
    out = tmp_path / "end.bin"
    result = export(str(merges), "--format", "rebound", "-o", str(out))
    assert result.exit_code == 0, result.output
    assert "a merged into star at t = 2.68 (step 268); exported the 2 still in it" in result.stdout
    sim = rebound.Simulation(str(out))
    whole = read_trace(merges)
    with h5py.File(merges, "r") as f:
        masses, radii = f["bodies/final_masses"][()], f["bodies/final_radii"][()]
    assert sim.N == 2 and sim.t == whole.time[-1]
    x = np.array([[p.x, p.y, p.z] for p in sim.particles])
    assert np.array_equal(x, whole.positions[-1, [0, 3]])
    assert [p.m for p in sim.particles] == masses[[0, 3]].tolist() and masses[0] != 1.0  # the star grew
    assert [p.r for p in sim.particles] == radii[[0, 3]].tolist()


def test_a_sample_between_merges_that_a_rerun_does_not_give_is_refused(tmp_path: Path) -> None:
    trace = run_doc(tmp_path, {**TWO_MERGES, "integrator": "leapfrog"}, "tampered")
    with h5py.File(trace, "a") as f:  # the trace no longer holds what its scenario makes
        f["positions"][20, 3, 0] += 1e-9
    out = tmp_path / "s20.yaml"
    result = export(str(trace), "--format", "scenario", "--sample", "20", "-o", str(out))
    assert result.exit_code == 2 and result.stdout == ""
    assert result.stderr == (f"orbitsim: error: {trace}: sample 20 (step 200) lies between removals (steps 157 and "
                             "268): the trace holds the masses only at the start and after the last removal, and a "
                             "rerun of its scenario to step 200 does not reproduce the sample's state; export a "
                             "sample from step 268 on, or before step 157\n")
    assert not out.exists()
    assert export(str(trace), "--format", "scenario", "--sample", "30", "-o", str(out)).exit_code == 0


def test_a_body_that_diverged_is_refused_naming_it(tmp_path: Path) -> None:
    trace = run_doc(tmp_path, {**TWO_MERGES, "integrator": "leapfrog"}, "nan")
    with h5py.File(trace, "a") as f:
        f["positions"][35, 3, 1] = np.nan  # c never left the run
    out = tmp_path / "s35.bin"
    result = export(str(trace), "--format", "scenario", "--sample", "35", "-o", str(out))
    assert result.exit_code == 2 and not out.exists()
    assert result.stderr == (f"orbitsim: error: {trace}: sample 35 has no finite state for 'c' (the run diverged by "
                             "then); export an earlier sample\n")


def test_a_setting_that_names_a_body_gone_is_refused_in_one_line(tmp_path: Path) -> None:
    doc = {**TWO_MERGES, "integrator": "leapfrog",
           "output": {**TWO_MERGES["output"], "elements": True, "primary": "b"}}
    trace = run_doc(tmp_path, doc, "primary")
    out = tmp_path / "end.yaml"
    result = export(str(trace), "--format", "scenario", "-o", str(out))
    assert result.exit_code == 2 and not out.exists() and result.stdout == ""
    assert result.stderr.startswith(f"orbitsim: error: {trace}: sample 40: the run's scenario does not hold without "
                                    "the bodies that left before it (b, a): output.primary: ")
    assert result.stderr.count("\n") == 1
