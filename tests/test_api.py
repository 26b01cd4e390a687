"""The public Python API: shapes, validation, bit-for-bit reproducibility, and lazy imports."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

import orbitsim
from orbitsim.integrators.registry import UnknownIntegratorError
from orbitsim.simulation import Simulation, SimulationError, SimulationResult, simulate


def three_bodies() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    m = np.array([1.0, 1e-3, 1e-4])
    x = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, -1.5, 0.1]])
    v = np.array([[0.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.8, 0.0, 0.0]])
    return m, x, v


def test_lazy_public_names() -> None:
    assert orbitsim.simulate is simulate
    assert orbitsim.Simulation is Simulation
    assert orbitsim.SimulationResult is SimulationResult
    with pytest.raises(AttributeError):
        _ = orbitsim.no_such_name


def test_result_shapes() -> None:
    m, x, v = three_bodies()
    result = orbitsim.simulate(m, x, v, integrator="verlet", dt=0.01, steps=10, every=3)
    samples = 5  # steps 0, 3, 6, 9 and always the last, 10
    assert result.step.tolist() == [0, 3, 6, 9, 10]
    for name in ("time", "kinetic", "potential", "energy", "energy_error"):
        assert getattr(result, name).shape == (samples,), name
    assert result.momentum.shape == (samples, 3)
    assert result.angular_momentum.shape == (samples, 3)
    assert result.positions.shape == (samples, 3, 3)
    assert result.velocities.shape == (samples, 3, 3)
    assert result.final_positions.shape == (3, 3)
    assert result.final_velocities.shape == (3, 3)
    assert result.energy_error[0] == 0.0
    assert np.array_equal(result.energy, result.kinetic + result.potential)
    assert np.array_equal(result.positions[0], x) and np.array_equal(result.velocities[0], v)
    assert np.array_equal(result.positions[-1], result.final_positions)
    assert result.status == "complete" and result.steps_done == 10


def test_record_positions_false_gives_none() -> None:
    m, x, v = three_bodies()
    result = simulate(m, x, v, integrator="leapfrog", dt=0.01, steps=10, every=5, record_positions=False)
    assert result.positions is None and result.velocities is None
    assert result.kinetic.shape == (3,)
    full = simulate(m, x, v, integrator="leapfrog", dt=0.01, steps=10, every=5)
    assert np.array_equal(result.final_positions, full.final_positions)


def bad_inputs() -> list[tuple[str, dict]]:
    _, x, v = three_bodies()
    x_nan = x.copy()
    x_nan[1, 2] = np.nan
    v_inf = v.copy()
    v_inf[0, 0] = np.inf
    return [
        ("nan position", {"positions": x_nan}),
        ("inf velocity", {"velocities": v_inf}),
        ("nan mass", {"masses": np.array([1.0, np.nan, 1e-4])}),
        ("positions (N, 2)", {"positions": x[:, :2]}),
        ("velocities (N-1, 3)", {"velocities": v[:2]}),
        ("flat positions", {"positions": x.reshape(-1)}),
        ("too many masses", {"masses": np.array([1.0, 1e-3, 1e-4, 1.0])}),
        ("no bodies", {"masses": np.zeros(0), "positions": np.zeros((0, 3)), "velocities": np.zeros((0, 3))}),
        ("negative mass", {"masses": np.array([1.0, -1e-3, 1e-4])}),
        ("dt = 0", {"dt": 0.0}),
        ("dt = nan", {"dt": float("nan")}),
        ("dt = inf", {"dt": float("inf")}),
        ("negative softening", {"softening": -0.1}),
        ("nan softening", {"softening": float("nan")}),
        ("G = 0", {"G": 0.0}),
        ("negative steps", {"steps": -1}),
        ("fractional steps", {"steps": 2.5}),
        ("every = 0", {"every": 0}),
        ("sample_steps ending early", {"sample_steps": [0, 1]}),
        ("sample_steps past the end", {"sample_steps": [0, 4]}),
        ("empty sample_steps", {"sample_steps": []}),
    ]


@pytest.mark.parametrize(("label", "change"), bad_inputs(), ids=[label for label, _ in bad_inputs()])
def test_invalid_input_raises_simulation_error(label: str, change: dict) -> None:
    m, x, v = three_bodies()
    kwargs = {"masses": m, "positions": x, "velocities": v, "integrator": "verlet", "dt": 0.01, "steps": 3}
    kwargs.update(change)
    masses, positions, velocities = kwargs.pop("masses"), kwargs.pop("positions"), kwargs.pop("velocities")
    with pytest.raises(SimulationError):
        simulate(masses, positions, velocities, **kwargs)


def test_unknown_integrator_raises() -> None:
    m, x, v = three_bodies()
    with pytest.raises(UnknownIntegratorError, match="verlet"):
        simulate(m, x, v, integrator="velocity_verlett", dt=0.01, steps=3)


def test_both_errors_are_value_errors() -> None:
    assert issubclass(SimulationError, ValueError)
    assert issubclass(UnknownIntegratorError, ValueError)


@pytest.mark.parametrize("name", ["verlet", "rk4", "leapfrog6"])
def test_same_input_same_bits(name: str) -> None:
    m, x, v = three_bodies()
    runs = [simulate(m, x, v, integrator=name, dt=0.01, steps=300, every=10, softening=0.01) for _ in range(2)]
    for field in ("positions", "velocities", "kinetic", "potential", "momentum", "angular_momentum", "time"):
        assert np.array_equal(getattr(runs[0], field), getattr(runs[1], field)), field


def test_no_steps_and_no_samples() -> None:
    m, x, v = three_bodies()
    result = simulate(m, x, v, integrator="verlet", dt=0.01, steps=0, sample_steps=[])
    assert result.steps_done == 0 and result.time.size == 0 and result.status == "complete"
    assert np.array_equal(result.final_positions, x)


def test_splitting_a_run_into_calls_gives_the_same_bits() -> None:
    m, x, v = three_bodies()
    whole = simulate(m, x, v, integrator="verlet", dt=0.01, steps=70, every=70)
    sim = Simulation(m, x, v, "verlet", 0.01)
    list(sim.chunks(np.array([30]), record_positions=False))
    list(sim.chunks(np.array([55, 70]), record_positions=False))
    positions, velocities = sim.state()
    assert sim.steps_done == 70 and sim.time == 70 * 0.01
    assert np.array_equal(positions, whole.final_positions)
    assert np.array_equal(velocities, whole.final_velocities)


def test_input_arrays_are_not_modified() -> None:
    m, x, v = three_bodies()
    copies = (m.copy(), x.copy(), v.copy())
    simulate(m, x, v, integrator="rk4", dt=0.01, steps=10)
    for before, after in zip(copies, (m, x, v), strict=True):
        assert np.array_equal(before, after)


@pytest.mark.parametrize("module", ["orbitsim", "orbitsim.cli.main"])
def test_import_does_not_load_numba(module: str) -> None:
    code = f"import sys, {module}; assert 'numba' not in sys.modules, sorted(m for m in sys.modules if 'numba' in m)"
    completed = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert completed.returncode == 0, completed.stderr
