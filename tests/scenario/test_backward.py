"""Backward integration: ``dt < 0`` in a scenario, ``orbitsim run --backward``, ``run --from --backward``."""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

from orbitsim.cli.main import cli
from orbitsim.integrators.registry import INTEGRATORS
from orbitsim.scenario import ScenarioError, load_scenario, scenario_from_dict
from orbitsim.scenario.direction import can_step_backward
from orbitsim.simulation import simulate

STEPS = 400
#: Forward then back with a reversible scheme returns to the start up to round-off alone: each
#: step's operations round once each (a few ulp of the state), and those errors are not undone.
#: Their sum grows at most linearly with the steps (a random walk in practice, ~sqrt(n)), so the
#: bound is this many ulp per step; measured on the giants system: <= 6 ulp after 1000 steps in all.
ULP_PER_STEP = 4
REVERSIBLE = [spec.name for spec in INTEGRATORS if spec.reversible]


def ulps(a: np.ndarray, b: np.ndarray) -> float:
    """Largest |a - b| in ulps of each body's largest component of ``b`` (a relative measure per body)."""
    scale = np.spacing(np.max(np.abs(b), axis=1, keepdims=True))
    return float(np.max(np.abs(a - b) / scale))


def there_and_back(name: str) -> tuple[float, float]:
    sc = load_scenario("giants")
    forward = simulate(sc.masses, sc.positions, sc.velocities, integrator=name, dt=0.05, steps=STEPS, every=STEPS,
                       G=sc.G)
    back = simulate(sc.masses, forward.positions[-1], forward.velocities[-1], integrator=name, dt=-0.05,
                    steps=STEPS, every=STEPS, G=sc.G)
    return ulps(back.positions[-1], sc.positions), ulps(back.velocities[-1], sc.velocities)


def test_every_reversible_scheme_can_step_backwards() -> None:
    assert set(REVERSIBLE) >= {"verlet", "leapfrog", "leapfrog4", "leapfrog6", "leapfrog8", "wisdom_holman"}
    assert all(can_step_backward(name) for name in REVERSIBLE)
    assert not can_step_backward("ias15") and not can_step_backward("trace")


@pytest.mark.parametrize("name", REVERSIBLE)
def test_forward_then_backward_returns_to_the_start(name: str) -> None:
    dx, dv = there_and_back(name)
    assert dx <= ULP_PER_STEP * STEPS and dv <= ULP_PER_STEP * STEPS, (dx, dv)


def test_a_scheme_that_is_not_reversible_does_not_return() -> None:
    # The negative control: explicit Euler's step of -h does not undo its step of h.
    dx, dv = there_and_back("euler")
    assert max(dx, dv) > 1e6 * ULP_PER_STEP * STEPS


def run_cli(*args: str) -> tuple[int, str]:
    result = CliRunner().invoke(cli, list(args))
    assert "Traceback" not in result.output
    return result.exit_code, result.stderr


def times(path: Path) -> np.ndarray:
    with h5py.File(path) as f:
        return f["time"][()]


def test_negative_dt_in_a_scenario_writes_decreasing_times(tmp_path: Path) -> None:
    path = tmp_path / "back.yaml"
    path.write_text("name: back\nintegrator: leapfrog4\ndt: -0.01\nt_end: -1\noutput: {every: 10}\nbodies:\n"
                    "  - {name: s, m: 1, x: [0, 0, 0], v: [0, 0, 0]}\n"
                    "  - {name: p, m: 1.0e-3, x: [1, 0, 0], v: [0, 1, 0]}\n",
                    encoding="utf-8")
    assert load_scenario(str(path)).steps == 100
    code, err = run_cli("run", str(path), "-o", str(tmp_path / "b.h5"), "-q")
    assert code == 0, err
    t = times(tmp_path / "b.h5")
    assert t[0] == 0.0 and np.all(np.diff(t) < 0) and t[-1] == pytest.approx(-1.0, abs=4 * np.spacing(1.0))


def test_backward_option_negates_dt_and_t_end(tmp_path: Path) -> None:
    code, err = run_cli("run", "two_body_circular", "-o", str(tmp_path / "b.h5"), "--integrator", "verlet",
                        "--t-end", "2", "--backward", "-q")
    assert code == 0, err
    t = times(tmp_path / "b.h5")
    assert np.all(np.diff(t) < 0) and t[-1] == pytest.approx(-2.0, abs=4 * np.spacing(2.0))
    with h5py.File(tmp_path / "b.h5") as f:
        assert f.attrs["dt"] < 0 and f.attrs["t_end_requested"] == -2.0


def test_run_from_backward_retraces_the_run(tmp_path: Path) -> None:
    out = tmp_path / "f.h5"
    assert run_cli("run", "two_body_circular", "-o", str(out), "--integrator", "leapfrog4", "--steps", "300",
                   "--every", "100", "--positions", "-q")[0] == 0
    code, err = run_cli("run", "--from", str(out), "--backward", "--steps", "300", "-q")
    assert code == 0, err
    with h5py.File(out) as f:
        pos, t = f["positions"][()], f["time"][()]
    assert list(t[3:]) == sorted(t[3:], reverse=True)
    assert ulps(pos[-1], pos[0]) <= ULP_PER_STEP * 600  # 300 steps out, 300 back


@pytest.mark.parametrize(("change", "says"), [
    ({"t_end": 1.0}, "must be < 0 with dt = -0.01"),
    ({"integrator": "ias15", "t_end": 1.0}, "ias15 cannot run backwards"),
    ({"integrator": "trace", "t_end": -1.0}, "trace cannot run backwards"),
    ({"dt": 0.0, "t_end": None, "steps": 5}, "must be non-zero"),
])
def test_refusals_name_the_key(change: dict, says: str) -> None:
    doc = {"name": "b", "integrator": "verlet", "dt": -0.01, "t_end": -1.0,
           "bodies": [{"name": "s", "m": 1, "x": [0, 0, 0], "v": [0, 0, 0]},
                      {"name": "p", "m": 1e-3, "x": [1, 0, 0], "v": [0, 1, 0]}]}
    doc.update(change)
    doc = {k: v for k, v in doc.items() if v is not None}
    with pytest.raises(ScenarioError, match=says):
        scenario_from_dict(doc)
