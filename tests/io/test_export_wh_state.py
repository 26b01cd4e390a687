"""An exported wisdom_holman scenario carries the map's own coordinates and continues the run bit for bit.

Wisdom-Holman steps in Jacobi (or democratic heliocentric) coordinates; a sample's Cartesian state is
converted from them, and converting back changes the last bits. So ``export --format scenario``
writes the mapping state as ``integrator_state``, from the trace's checkpoint (the last sample) or by
rerunning the stored scenario to the sample's step, tied by a SHA-256 to the exact bits it belongs to
(orbitsim.scenario.integrator_state).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml
from click.testing import CliRunner

from orbitsim.cli.main import cli
from orbitsim.io.trace import read_trace
from orbitsim.runner import run_scenario
from orbitsim.scenario import load_scenario, scenario_from_dict

BODIES = [
    {"name": "star", "m": 1.0, "x": [0.0, 0.0, 0.0], "v": [0.0, 0.0, 0.0]},
    {"name": "b", "m": 1e-3, "x": [1.0, 0.0, 0.0], "v": [0.0, 1.0, 0.0]},
    {"name": "c", "m": 3e-4, "x": [0.0, 2.2, 0.1], "v": [-0.68, 0.0, 0.0]},
]
SETTINGS = [{}, {"corrector": 5}, {"coordinates": "democratic_heliocentric"}]


def run(tmp_path: Path, name: str, steps: int, settings: dict) -> Path:
    doc = {"name": name, "integrator": {"name": "wisdom_holman", **settings}, "dt": 0.01, "steps": steps,
           "output": {"every": 1, "positions": True}, "bodies": BODIES}
    out = tmp_path / f"{name}.h5"
    run_scenario(scenario_from_dict(doc), out)
    return out


def export(*args: str) -> tuple[int, str]:
    result = CliRunner().invoke(cli, ["export", *args])
    assert "Traceback" not in result.output
    return result.exit_code, result.output


@pytest.mark.parametrize("settings", SETTINGS, ids=["jacobi", "corrector5", "democratic"])
def test_exported_last_sample_continues_the_run_bit_for_bit(tmp_path: Path, settings: dict) -> None:
    whole, first = run(tmp_path, "whole", 300, settings), run(tmp_path, "first", 150, settings)
    code, output = export(str(first), "--format", "scenario", "-o", str(tmp_path / "next.yaml"))
    assert code == 0 and output == "", output  # the last sample: no note, the state is there
    scenario = load_scenario(tmp_path / "next.yaml")
    assert scenario.integrator_state is not None and scenario.integrator_state["phase"] == 2
    run_scenario(scenario, tmp_path / "next.h5")
    a, b = read_trace(whole), read_trace(tmp_path / "next.h5")
    assert np.array_equal(b.positions, a.positions[150:]) and np.array_equal(b.velocities, a.velocities[150:])
    assert np.array_equal(b.energy, a.energy[150:])

    # Without the state the same scenario starts from the Cartesian sample: round-off, not the same bits.
    doc = yaml.safe_load((tmp_path / "next.yaml").read_text())
    del doc["integrator_state"]
    run_scenario(scenario_from_dict(doc), tmp_path / "cartesian.h5")
    c = read_trace(tmp_path / "cartesian.h5")
    assert not np.array_equal(c.positions[-1], a.positions[-1])
    # 150 steps of a few ulp each on positions of order 1: far below 1e-11.
    assert np.max(np.abs(c.positions[-1] - a.positions[-1])) < 1e-11


def test_the_resolved_text_round_trips(tmp_path: Path) -> None:
    first = run(tmp_path, "first", 50, {"corrector": 5})
    assert export(str(first), "--format", "scenario", "-o", str(tmp_path / "next.yaml"))[0] == 0
    scenario = load_scenario(tmp_path / "next.yaml")
    again = scenario_from_dict(yaml.safe_load(scenario.to_yaml()))
    assert again.to_yaml() == scenario.to_yaml()
    for key in ("mapping_positions", "mapping_velocities"):
        assert np.array_equal(again.integrator_state[key], scenario.integrator_state[key])


@pytest.mark.parametrize("settings", SETTINGS[1:], ids=["corrector5", "democratic"])
def test_a_middle_sample_continues_bit_for_bit_by_a_rerun(tmp_path: Path, settings: dict) -> None:
    first = run(tmp_path, "first", 100, settings)
    code, output = export(str(first), "--format", "scenario", "--sample", "40", "-o", str(tmp_path / "mid.yaml"))
    assert code == 0 and output == "", output
    scenario = load_scenario(tmp_path / "mid.yaml")
    assert scenario.integrator_state is not None and scenario.steps == 60
    run_scenario(scenario, tmp_path / "mid.h5")
    a, b = read_trace(first), read_trace(tmp_path / "mid.h5")
    assert np.array_equal(b.positions, a.positions[40:]) and np.array_equal(b.velocities, a.velocities[40:])


def test_a_switched_run_says_it_continues_to_round_off(tmp_path: Path) -> None:
    """After a run --from switch the stored scenario is not one run from its bodies: no state to be had."""
    first = run(tmp_path, "first", 60, {})
    result = CliRunner().invoke(cli, ["run", "--from", str(first), "--dt", "0.005", "--steps", "40", "-q"])
    assert result.exit_code == 0, result.output
    code, output = export(str(first), "--format", "scenario", "--sample", "-3", "-o", str(tmp_path / "sw.yaml"))
    assert code == 0
    assert "orbitsim: note: wisdom_holman steps in its own coordinates" in output
    assert "to round-off, not bit for bit" in output and len(output.strip().splitlines()) == 1
    assert "integrator_state" not in (tmp_path / "sw.yaml").read_text()
    scenario = load_scenario(tmp_path / "sw.yaml")
    run_scenario(scenario, tmp_path / "sw.h5")
    a, b = read_trace(first), read_trace(tmp_path / "sw.h5")
    # Two steps of a few ulp on positions of order 1: round-off, far below 1e-13.
    assert np.max(np.abs(b.positions[2] - a.positions[-1])) < 1e-13


def test_a_state_edited_away_from_its_bits_is_not_used_and_the_run_says_so(tmp_path: Path) -> None:
    first = run(tmp_path, "first", 50, {})
    assert export(str(first), "--format", "scenario", "-o", str(tmp_path / "next.yaml"))[0] == 0
    text = (tmp_path / "next.yaml").read_text()
    edited = tmp_path / "edited.yaml"
    edited.write_text(text.replace("dt: 0.01", "dt: 0.005"), encoding="utf-8")
    result = CliRunner().invoke(cli, ["run", str(edited), "-o", str(tmp_path / "e.h5")])
    assert result.exit_code == 0, result.output
    assert "note: integrator_state was written for other bits" in result.output
    assert "only to round-off, not bit for bit" in result.output
    # A command-line dt drops the state on purpose (it belongs to the old dt): no stale state, no note.
    result = CliRunner().invoke(cli, ["run", str(tmp_path / "next.yaml"), "--dt", "0.005", "-o",
                                      str(tmp_path / "o.h5")])
    assert result.exit_code == 0 and "integrator_state" not in result.output
    exact = load_scenario(tmp_path / "next.yaml")
    assert exact.notes() == [] and exact.with_overrides(dt=0.005).integrator_state is None
    assert exact.with_overrides(steps=7).integrator_state is not None  # a run length is not what it belongs to


@pytest.mark.parametrize(("old", "new", "message"), [
    ("phase: 2", "phase: 7", "integrator_state.phase: expected 1 or 2, got 7"),
    ("  of: ", "  sha: ", "integrator_state.sha: unknown key 'sha'"),
    ("    - [", "    - [1.0, ", "integrator_state.mapping_positions: expected 3 rows of 3 finite numbers"),
])
def test_a_malformed_state_is_one_line_naming_the_key(tmp_path: Path, old: str, new: str, message: str) -> None:
    first = run(tmp_path, "first", 20, {})
    assert export(str(first), "--format", "scenario", "-o", str(tmp_path / "next.yaml"))[0] == 0
    bad = tmp_path / "bad.yaml"
    bad.write_text((tmp_path / "next.yaml").read_text().replace(old, new, 1), encoding="utf-8")
    result = CliRunner().invoke(cli, ["run", str(bad), "-o", str(tmp_path / "bad.h5")])
    assert result.exit_code == 2 and len(result.output.strip().splitlines()) == 1, result.output
    assert f"{bad}: {message}" in result.output
    assert not (tmp_path / "bad.h5").exists()
