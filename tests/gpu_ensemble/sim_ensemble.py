"""The GPU ensemble against the CPU's, under Numba's CUDA simulator (run by test_gpu_ensemble.py, each
``sim_ensemble*.py`` file in its own process with ``NUMBA_ENABLE_CUDASIM=1``).

Tolerances. The simulator runs the kernels' own Python (the GPU-only gravity with ``1 / sqrt`` for
``rsqrt``, and the CPU's jitted operators they call) without FMA, so a GPU system differs from the CPU's
by the reordered ``1 / r^3`` alone: a few ulps a step. Over 100 steps the states agree to ~1e-15
relative; 1e-13 is the issue's bar for FP64 on the device, where FMAs add their own ulps.
"""

from __future__ import annotations

import os

import numpy as np
import pytest

if os.environ.get("NUMBA_ENABLE_CUDASIM") != "1":  # pragma: no cover - a guard, not a path
    pytest.skip("run by test_gpu_ensemble.py under NUMBA_ENABLE_CUDASIM=1", allow_module_level=True)

from orbitsim.chaos.megno import random_initial_variation
from orbitsim.ensemble import run_ensemble
from orbitsim.ensemble.status import (
    COLLIDED,
    COMPLETE,
    DELTA_A,
    DIVERGED,
    ENERGY_ERROR,
    ESCAPED,
    LYAPUNOV,
    MAX_E,
    MEGNO,
    N_COLUMNS,
    SURVIVAL_TIME,
)
from orbitsim.gpu.ensemble import run_ensemble_gpu, upload_ensemble
from orbitsim.scenario import load_scenario

K = 16
N_STEPS = 100
DT = 0.5
#: States and MEGNO: relative, FP64 round-off of a few ulps a step over N_STEPS steps (module docstring).
STATE_RTOL = 1e-13
#: max_e, delta_a, energy_error: absolute. Each is a difference of nearly equal numbers (e from 1 - e^2,
#: |a - a0|, |E - E0|), so its round-off is an ulp of the O(1) operands, not of the small result.
DIFFERENCE_ATOL = 1e-13


def _giants(k: int = K) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """K copies of Sun, Jupiter, Saturn, Uranus (DE421, G = 1), Saturn's z nudged differently in each."""
    sc = load_scenario("giants")
    m, x, v = sc.masses[:4], sc.positions[:4].T, sc.velocities[:4].T
    masses = np.tile(m, (k, 1))
    pos = np.tile(x, (k, 1, 1))
    vel = np.tile(v, (k, 1, 1))
    pos[:, 2, 2] += 0.01 * np.arange(k)
    return masses, pos, vel


def _variation(k: int = K, n: int = 4) -> tuple[np.ndarray, np.ndarray]:
    dpos, dvel = random_initial_variation(n, 7)
    return np.tile(dpos, (k, 1, 1)), np.tile(dvel, (k, 1, 1))


def _state_error(a: np.ndarray, b: np.ndarray) -> float:
    """Largest |a - b| of each system over that system's largest |b|."""
    return float(np.max(np.max(np.abs(a - b), axis=(1, 2)) / np.max(np.abs(b), axis=(1, 2))))


def test_wisdom_holman_with_megno_agrees_with_the_cpu_ensemble():
    masses, pos, vel = _giants()
    cpu = run_ensemble(masses, pos, vel, G=1.0, dt=DT, n_steps=N_STEPS, variation=_variation(), watch=2)
    gpu = run_ensemble_gpu(masses, pos, vel, G=1.0, dt=DT, n_steps=N_STEPS, variation=_variation(), watch=2)
    assert gpu.status.tolist() == [COMPLETE] * K and gpu.steps.tolist() == [N_STEPS] * K
    assert _state_error(gpu.pos, cpu.pos) < STATE_RTOL
    assert _state_error(gpu.vel, cpu.vel) < STATE_RTOL
    assert np.all(gpu.indicators[:, SURVIVAL_TIME] == N_STEPS * DT)
    for column in (MEGNO, LYAPUNOV):
        assert np.all(cpu.indicators[:, column] != 0.0)  # a quantity, not a zero that matches anything
        assert np.max(np.abs(gpu.indicators[:, column] / cpu.indicators[:, column] - 1.0)) < STATE_RTOL, column
    for column in (MAX_E, DELTA_A, ENERGY_ERROR):
        assert np.max(np.abs(gpu.indicators[:, column] - cpu.indicators[:, column])) < DIFFERENCE_ATOL, column
    assert np.all(np.abs(cpu.indicators[:, MAX_E] - 0.054) < 0.01)  # Saturn's eccentricity, watched


def test_a_nudged_system_moves_only_its_own_results():
    masses, pos, vel = _giants()
    base = run_ensemble_gpu(masses, pos, vel, G=1.0, dt=DT, n_steps=N_STEPS, variation=_variation())
    pos2 = pos.copy()
    pos2[5, 0, 3] += 1e-3  # Uranus of system 5 only
    nudged = run_ensemble_gpu(masses, pos2, vel, G=1.0, dt=DT, n_steps=N_STEPS, variation=_variation())
    others = [k for k in range(K) if k != 5]
    assert np.array_equal(nudged.pos[others], base.pos[others])
    assert np.array_equal(nudged.indicators[others], base.indicators[others])
    assert not np.array_equal(nudged.pos[5], base.pos[5])


def advance(integrator, p, v, acc, m, force, work, n_steps):
    """``n_steps`` of the integrator's own step; ``acc`` first set to a(x), as a run's step expects."""
    from orbitsim.physics.gravity import accelerations, force_scratch

    slabs, bounds = force_scratch(m.size)
    accelerations(p, m, 1.0, 0.0, acc, slabs, bounds)
    for _ in range(n_steps):
        integrator.step(p, v, acc, m, force, DT, work)


def _cpu_fixed_step(scheme: str, masses: np.ndarray, pos: np.ndarray, vel: np.ndarray,
                    n_steps: int) -> tuple[np.ndarray, ...]:
    """Every system stepped by orbitsim's own scheme (its registered integrator's step), with its energy error."""
    from orbitsim.integrators.registry import get_integrator
    from orbitsim.physics.diagnostics import kinetic_energy, potential_energy
    from orbitsim.physics.force_context import make_force

    integrator = get_integrator(scheme)
    p, v = pos.copy(), vel.copy()
    error = np.zeros(len(masses))
    for k, m in enumerate(masses):
        force, work, acc = make_force(1.0, 0.0, m.size), integrator.make_work(m, 1.0), np.zeros((3, m.size))
        e0 = kinetic_energy(v[k], m) + potential_energy(p[k], m, 1.0, 0.0, np.zeros(0))
        advance(integrator, p[k], v[k], acc, m, force, work, n_steps)
        e1 = kinetic_energy(v[k], m) + potential_energy(p[k], m, 1.0, 0.0, np.zeros(0))
        error[k] = abs((e1 - e0) / e0)
    return p, v, error


@pytest.mark.parametrize("scheme", ["leapfrog", "verlet"])
def test_fixed_step_schemes_agree_with_the_cpus(scheme):
    masses, pos, vel = _giants()
    gpu = run_ensemble_gpu(masses, pos, vel, G=1.0, dt=DT, n_steps=N_STEPS, scheme=scheme)
    cpu_pos, cpu_vel, cpu_error = _cpu_fixed_step(scheme, masses, pos, vel, N_STEPS)
    assert gpu.status.tolist() == [COMPLETE] * K
    assert _state_error(gpu.pos, cpu_pos) < STATE_RTOL
    assert _state_error(gpu.vel, cpu_vel) < STATE_RTOL
    assert np.max(np.abs(gpu.indicators[:, ENERGY_ERROR] - cpu_error)) < DIFFERENCE_ATOL
    assert np.all(np.isnan(gpu.indicators[:, MEGNO])) and np.all(np.isnan(gpu.indicators[:, LYAPUNOV]))
    assert np.all(gpu.indicators[:, MAX_E] > 0.04)  # Jupiter's Jacobi e ~ 0.048, watched (body 1)


def _troubled(masses, pos, vel):
    """System 3 escapes (Uranus on a hyperbola), 7 collides (Jupiter and Saturn with overlapping radii),
    11 diverges (Uranus on top of Saturn, with its velocity: the pull between them is inf * 0)."""
    pos2, vel2 = pos.copy(), vel.copy()
    vel2[3, :, 3] *= 3.0
    pos2[11, :, 3] = pos2[11, :, 2]
    vel2[11, :, 3] = vel2[11, :, 2]
    radii = np.zeros((K, 4))
    radii[7, 1] = radii[7, 2] = 2.5  # 4.4 apart at the start
    return pos2, vel2, radii


# The simulator runs the kernel as Python with numpy scalars, which warn where the device silently makes the
# inf and nan that system 11's divergence is made of.
@pytest.mark.filterwarnings("ignore:divide by zero:RuntimeWarning", "ignore:invalid value:RuntimeWarning")
@pytest.mark.parametrize("scheme", ["wisdom_holman", "leapfrog", "verlet"])
def test_each_system_stops_alone_and_never_touches_the_others(scheme):
    masses, pos, vel = _giants()
    variation = _variation() if scheme == "wisdom_holman" else None
    common = {"G": 1.0, "dt": DT, "n_steps": N_STEPS, "escape_distance": 25.0, "variation": variation,
              "scheme": scheme}
    clean = run_ensemble_gpu(masses, pos, vel, radii=np.zeros((K, 4)), **common)
    pos2, vel2, radii = _troubled(masses, pos, vel)
    mixed = run_ensemble_gpu(masses, pos2, vel2, radii=radii, **common)
    expected = [COMPLETE] * K
    expected[3], expected[7], expected[11] = ESCAPED, COLLIDED, DIVERGED
    assert mixed.status.tolist() == expected
    assert 1 < mixed.steps[3] < N_STEPS and mixed.steps[7] == 1 and mixed.steps[11] == 1
    assert mixed.indicators[3, SURVIVAL_TIME] == mixed.steps[3] * DT
    assert np.isnan(mixed.indicators[11, ENERGY_ERROR])
    healthy = [k for k in range(K) if k not in (3, 7, 11)]
    assert np.array_equal(mixed.pos[healthy], clean.pos[healthy])
    assert np.array_equal(mixed.indicators[healthy], clean.indicators[healthy], equal_nan=True)
    if scheme == "wisdom_holman":  # the CPU ensemble stops them at the same steps with the same verdicts
        cpu = run_ensemble(masses, pos2, vel2, radii=radii, **{k: v for k, v in common.items() if k != "scheme"})
        assert cpu.status.tolist() == expected and cpu.steps.tolist() == mixed.steps.tolist()


def test_zero_steps_and_bad_input():
    masses, pos, vel = _giants(2)
    none = run_ensemble_gpu(masses, pos, vel, G=1.0, dt=DT, n_steps=0, variation=_variation(2))
    assert none.status.tolist() == [COMPLETE, COMPLETE] and np.array_equal(none.pos, pos)
    assert none.indicators[:, ENERGY_ERROR].tolist() == [0.0, 0.0]
    with pytest.raises(ValueError, match="dt must be finite"):
        run_ensemble_gpu(masses, pos, vel, G=1.0, dt=-1.0, n_steps=3, variation=_variation(2))


def test_a_second_launch_goes_on_from_where_the_first_stopped():
    """upload_ensemble copies the systems once; each launch continues from the device's state (benchmarks
    time launches alone): two launches of 20 leapfrog steps are the bits of one of 40, and the copy back is
    run_ensemble_gpu's."""
    masses, pos, vel = _giants(4)
    common = {"G": 1.0, "dt": DT, "scheme": "leapfrog"}
    ensemble = upload_ensemble(masses, pos, vel, n_steps=20, **common)
    ensemble.launch()
    assert _results_equal(ensemble.result(), run_ensemble_gpu(masses, pos, vel, n_steps=20, **common))
    ensemble.launch()
    twice = ensemble.result()
    once = run_ensemble_gpu(masses, pos, vel, n_steps=40, **common)
    assert np.array_equal(twice.pos, once.pos) and np.array_equal(twice.vel, once.vel)
    assert twice.steps.tolist() == [20] * 4 and once.steps.tolist() == [40] * 4


def test_an_empty_ensemble_launches_nothing():
    masses, pos, vel = _giants(1)
    empty = upload_ensemble(masses[:0], pos[:0], vel[:0], G=1.0, dt=DT, n_steps=5, scheme="verlet")
    empty.launch()
    result = empty.result()
    assert result.status.shape == (0,) and result.indicators.shape == (0, N_COLUMNS) and result.pos.shape == (0, 3, 4)


def _results_equal(a, b) -> bool:
    return all(np.array_equal(x, y, equal_nan=True) for x, y in zip(a, b, strict=True))
