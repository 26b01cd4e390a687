"""``t_start``: a scenario's clock starts there; ``t_end`` stays the absolute end time."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from orbitsim.io.trace import read_trace
from orbitsim.runner import run_scenario
from orbitsim.scenario import ScenarioError, load_scenario, scenario_from_dict

TWO_BODIES = [
    {"name": "star", "m": 1.0, "x": [0.0, 0.0, 0.0], "v": [0.0, 0.0, 0.0]},
    {"name": "planet", "m": 1e-3, "x": [1.0, 0.0, 0.0], "v": [0.0, 1.0, 0.0]},
]


def doc(**changes: object) -> dict:
    return {"name": "clock", "integrator": "leapfrog", "dt": 0.25, "output": {"every": 1},
            "bodies": TWO_BODIES, **changes}


def write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "scenario.yaml"
    path.write_text(text, encoding="utf-8")
    return path


def test_sample_times_start_at_t_start(tmp_path: Path) -> None:
    scenario = scenario_from_dict(doc(t_start=100.0, steps=8))
    run_scenario(scenario, tmp_path / "run.h5")
    time = read_trace(tmp_path / "run.h5").time
    # 100 + n * 0.25 is exact in float64, so the clock t0 + n * dt is compared bit for bit.
    assert np.array_equal(time, 100.0 + 0.25 * np.arange(9))
    assert scenario.end_time == 102.0


def test_the_same_run_from_t_start_moves_the_same_way(tmp_path: Path) -> None:
    """Forces do not depend on time, so only the clock moves: the states are the same bits."""
    run_scenario(scenario_from_dict(doc(steps=8, output={"every": 1, "positions": True})), tmp_path / "a.h5")
    run_scenario(scenario_from_dict(doc(t_start=-3.5, steps=8, output={"every": 1, "positions": True})),
                 tmp_path / "b.h5")
    a, b = read_trace(tmp_path / "a.h5"), read_trace(tmp_path / "b.h5")
    assert np.array_equal(a.positions, b.positions)
    assert b.time[0] == -3.5 and b.time[-1] == -1.5


def test_steps_are_counted_from_t_start_to_t_end() -> None:
    assert scenario_from_dict(doc(t_start=10.0, t_end=12.0)).steps == 8
    assert scenario_from_dict(doc(t_start=10.0, t_end=12.1)).steps == 8  # a step is never shortened
    backward = scenario_from_dict(doc(t_start=10.0, t_end=9.0, dt=-0.25))
    assert backward.steps == 4 and backward.end_time == 9.0


def test_resolved_yaml_writes_t_start_only_when_set() -> None:
    plain = scenario_from_dict(doc(steps=8))
    assert "t_start" not in plain.to_yaml()
    assert scenario_from_dict(doc(steps=8, t_start=0)).sha256 == plain.sha256
    shifted = scenario_from_dict(doc(steps=8, t_start=12.5))
    assert "t_start: 12.5\n" in shifted.to_yaml() and shifted.sha256 != plain.sha256
    again = scenario_from_dict(shifted.to_dict())
    assert again.t_start == 12.5 and again.sha256 == shifted.sha256


def test_with_overrides_re_resolves_t_end_from_a_new_t_start() -> None:
    scenario = scenario_from_dict(doc(t_end=2.0))
    assert scenario.steps == 8
    assert scenario.with_overrides(t_start=1.0).steps == 4


def test_ias15_honours_t_start(tmp_path: Path) -> None:
    scenario = scenario_from_dict(doc(integrator="ias15", t_start=5.0, t_end=7.0, output={"interval": 0.5}))
    assert scenario.steps == 4
    run_scenario(scenario, tmp_path / "ias.h5")
    assert np.array_equal(read_trace(tmp_path / "ias.h5").time, [5.0, 5.5, 6.0, 6.5, 7.0])


def test_rebound_files_t_becomes_t_start(tmp_path: Path) -> None:
    rebound = pytest.importorskip("rebound")
    sim = rebound.Simulation()
    sim.add(m=1.0)
    sim.add(m=1e-3, a=1.0)
    sim.integrator = "leapfrog"
    sim.dt = 0.25
    sim.t = 12.5
    sim.save_to_file(str(tmp_path / "sim.bin"))
    scenario = load_scenario(write(tmp_path, "bodies: {rebound: sim.bin}\nt_end: 13.5\noutput: {every: 1}\n"))
    assert scenario.t_start == 12.5 and scenario.steps == 4  # t_end is absolute: 4 steps from 12.5
    run_scenario(scenario, tmp_path / "run.h5")
    assert np.array_equal(read_trace(tmp_path / "run.h5").time, 12.5 + 0.25 * np.arange(5))
    given = load_scenario(write(tmp_path, "bodies: {rebound: sim.bin}\nt_start: 0\nsteps: 2\n"))
    assert given.t_start == 0.0  # the scenario's own t_start wins over the file's t


BODIES_YAML = ("bodies:\n  - {name: a, m: 1, x: [0, 0, 0], v: [0, 0, 0]}\n"
               "  - {name: b, m: 0.001, x: [1, 0, 0], v: [0, 1, 0]}\n")


@pytest.mark.parametrize(("keys", "key", "says"), [
    ({"t_start": ".nan", "steps": "4"}, "t_start", "must be a finite number"),
    ({"t_start": "soon", "steps": "4"}, "t_start", "expected a number"),
    ({"t_start": "10", "t_end": "5"}, "t_end", "must be > t_start = 10"),
    ({"t_start": "10", "t_end": "12", "dt": "-0.25"}, "t_end", "must be < t_start = 10"),
    ({"t_start": "10", "t_end": "9", "integrator": "ias15"}, "t_end", "must be > t_start = 10"),
])
def test_bad_values_are_one_line_naming_the_file_and_key(tmp_path: Path, keys: dict, key: str, says: str) -> None:
    top = {"integrator": "leapfrog", "dt": "0.25", **keys}
    path = write(tmp_path, "".join(f"{k}: {v}\n" for k, v in top.items()) + BODIES_YAML)
    with pytest.raises(ScenarioError) as err:
        load_scenario(path)
    message = str(err.value)
    assert "\n" not in message and says in message
    assert message.startswith(f"{path}: {key}: ")


def test_run_from_extends_on_the_same_clock(tmp_path: Path) -> None:
    """The checkpoint keeps t0 = t_start, so `run --from --t-end` counts to the absolute t_end."""
    from click.testing import CliRunner

    from orbitsim.cli.main import cli

    path = write(tmp_path, "integrator: leapfrog\ndt: 0.25\nt_start: 10\nt_end: 12\noutput: {every: 1}\n"
                 + BODIES_YAML)
    out = tmp_path / "run.h5"
    first = CliRunner().invoke(cli, ["run", str(path), "-o", str(out), "-q"])
    assert first.exit_code == 0, first.output
    more = CliRunner().invoke(cli, ["run", "--from", str(out), "--t-end", "13", "-q"])
    assert more.exit_code == 0, more.output
    assert np.array_equal(read_trace(out).time, 10.0 + 0.25 * np.arange(13))
