"""The ensemble kernel: a system's bits are a single Wisdom-Holman run's, whatever the chunking or thread
count, and a system that stops (escape, collision, divergence) stops alone."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from ensemble_helpers import by_thread_count

from orbitsim.ensemble import run_ensemble
from orbitsim.ensemble.status import (
    COLLIDED,
    COMPLETE,
    DIVERGED,
    ENERGY_ERROR,
    ESCAPED,
    MAX_E,
    SURVIVAL_TIME,
)
from orbitsim.sampling import EveryPlan
from orbitsim.scenario import load_scenario
from orbitsim.simulation import Simulation

N_STEPS = 200
DT = 0.5


def _giants(k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """K copies of Sun, Jupiter, Saturn, Uranus (DE421), Saturn's x nudged differently in each."""
    sc = load_scenario("giants")
    m, x, v = sc.masses[:4], sc.positions[:4].T, sc.velocities[:4].T
    masses = np.tile(m, (k, 1))
    pos = np.tile(x, (k, 1, 1))
    vel = np.tile(v, (k, 1, 1))
    pos[:, 0, 2] *= 1.0 + 0.01 * np.arange(k)
    return masses, pos, vel


@pytest.mark.slow  # compiles the Wisdom-Holman ensemble kernel beside a lone run (~40 s cold)
def test_each_system_gets_the_bits_of_a_single_wisdom_holman_run():
    masses, pos, vel = _giants(3)
    result = run_ensemble(masses, pos, vel, G=1.0, dt=DT, n_steps=N_STEPS)
    assert (result.status == COMPLETE).all()
    assert (result.steps == N_STEPS).all()
    for k in range(3):
        sim = Simulation(masses[k], pos[k].T, vel[k].T, "wisdom_holman", DT, 1.0)
        list(sim.chunks(EveryPlan(N_STEPS, N_STEPS)))
        x, v = sim.state()
        assert np.array_equal(result.pos[k], x.T)  # same operators, same order: same bits
        assert np.array_equal(result.vel[k], v.T)
        e0 = Simulation(masses[k], pos[k].T, vel[k].T, "wisdom_holman", DT, 1.0).total_energy()
        assert result.indicators[k, ENERGY_ERROR] == pytest.approx(abs((sim.total_energy() - e0) / e0),
                                                                   rel=1e-6, abs=1e-15)  # two energy sums


@pytest.mark.slow  # the plain and the variational Wisdom-Holman ensembles compile for ~45 s cold
@pytest.mark.parametrize("variational", [False, True])
def test_bits_do_not_depend_on_chunking_or_threads(variational):
    from orbitsim.chaos.megno import random_initial_variation

    masses, pos, vel = _giants(6)
    dpos, dvel = random_initial_variation(4, 3)
    var = (np.tile(dpos, (6, 1, 1)), np.tile(dvel, (6, 1, 1))) if variational else None

    def part(i: int, j: int):
        return run_ensemble(masses[i:j], pos[i:j], vel[i:j], G=1.0, dt=DT, n_steps=N_STEPS,
                            variation=None if var is None else (var[0][i:j], var[1][i:j]))

    whole = part(0, 6)
    parts = [part(i, i + 2) for i in range(0, 6, 2)]
    assert np.array_equal(whole.indicators, np.concatenate([p.indicators for p in parts]), equal_nan=True)
    assert np.array_equal(whole.pos, np.concatenate([p.pos for p in parts]))
    first, last = by_thread_count(lambda: part(0, 6)).values()
    assert np.array_equal(first.indicators, last.indicators, equal_nan=True)
    assert np.array_equal(first.vel, last.vel)


def test_a_stopped_system_never_touches_the_others():
    masses, pos, vel = _giants(4)
    clean = run_ensemble(masses, pos, vel, G=1.0, dt=DT, n_steps=N_STEPS, escape_distance=40.0)
    vel2 = vel.copy()
    vel2[1, :, 3] *= 3.0  # Uranus of system 1 leaves on a hyperbola
    vel2[2, 0, 3] = 1e300  # Uranus of system 2: v^2 overflows, its Kepler drift cannot be finite
    mixed = run_ensemble(masses, pos, vel2, G=1.0, dt=DT, n_steps=N_STEPS, escape_distance=40.0)
    assert mixed.status[1] == ESCAPED
    assert mixed.steps[1] < N_STEPS
    assert mixed.indicators[1, SURVIVAL_TIME] == mixed.steps[1] * DT
    assert mixed.status[2] == DIVERGED
    for k in (0, 3):
        assert mixed.status[k] == COMPLETE
        assert np.array_equal(mixed.pos[k], clean.pos[k])
        assert np.array_equal(mixed.indicators[k], clean.indicators[k], equal_nan=True)


def test_collisions_only_with_radii():
    masses, pos, vel = _giants(2)
    radii = np.zeros((2, 4))
    radii[1, 1] = radii[1, 2] = 2.5  # Jupiter and Saturn of system 1 overlap from the start (4.4 apart)
    result = run_ensemble(masses, pos, vel, G=1.0, dt=DT, n_steps=N_STEPS, radii=radii)
    assert result.status.tolist() == [COMPLETE, COLLIDED]
    assert result.steps[1] == 1
    assert run_ensemble(masses, pos, vel, G=1.0, dt=DT, n_steps=N_STEPS).status.tolist() == [COMPLETE, COMPLETE]


def test_max_e_follows_the_watched_body():
    masses, pos, vel = _giants(1)
    result = run_ensemble(masses, pos, vel, G=1.0, dt=DT, n_steps=N_STEPS, watch=1)
    assert 0.04 < result.indicators[0, MAX_E] < 0.06  # Jupiter's e ~ 0.048 (Jacobi), a short run


@pytest.mark.parametrize(("change", "message"), [
    ({"dt": 0.0}, "dt must be"), ({"watch": 0}, "watch must be"), ({"n_steps": -1}, "n_steps"),
])
def test_front_door_refuses_bad_input(change, message):
    masses, pos, vel = _giants(1)
    kwargs = {"G": 1.0, "dt": DT, "n_steps": 10, **change}
    with pytest.raises(ValueError, match=message):
        run_ensemble(masses, pos, vel, **kwargs)


def test_the_variational_ensemble_gets_the_bits_of_a_single_system_chaos_run():
    from orbitsim.chaos.megno import lyapunov, megno_start, megno_value, random_initial_variation
    from orbitsim.ensemble.status import LYAPUNOV, MEGNO
    from orbitsim.integrators.wisdom_holman.tangent import TANGENT_SCRATCH_ROWS, tangent_run
    from orbitsim.physics.coordinates import jacobi_weights
    from orbitsim.physics.force_context import make_force

    masses, pos, vel = _giants(3)
    dpos, dvel = random_initial_variation(4, 0)
    variation = (np.tile(dpos, (3, 1, 1)), np.tile(dvel, (3, 1, 1)))
    result = run_ensemble(masses, pos, vel, G=1.0, dt=DT, n_steps=N_STEPS, variation=variation)
    assert (result.status == COMPLETE).all()
    for k in range(3):
        p, v, dp, dv = pos[k].copy(), vel[k].copy(), dpos.copy(), dvel.copy()
        m = masses[k]
        n_done, status, _, megno, _ = tangent_run(p, v, dp, dv, m, make_force(1.0, 0.0, 4), DT, jacobi_weights(m),
                                                  np.cumsum(m), np.zeros((TANGENT_SCRATCH_ROWS, 3, 4)),
                                                  megno_start(0.0), 0.0, 0, N_STEPS)
        assert (n_done, status) == (N_STEPS, 0)
        assert np.array_equal(result.pos[k], p)  # the same tangent map, step for step
        assert result.indicators[k, MEGNO] == megno_value(megno, N_STEPS * DT)
        assert result.indicators[k, LYAPUNOV] == lyapunov(megno)
    assert 1.5 < result.indicators[0, MEGNO] < 3.0  # the giants are regular: MEGNO near 2


def test_a_fresh_process_whose_first_parallel_call_is_a_cached_ensemble_runs() -> None:
    # the library's front door, not the CLI (which sets the thread count first): a process whose first
    # parallel call loaded a cached ensemble kernel was once seen aborting with "LLVM ERROR: Symbol not
    # found: allocate_sched" (not reproduced on demand since); run_ensemble now starts the threading layer
    script = (
        "import numpy as np\n"
        "from orbitsim.ensemble import run_ensemble\n"
        "m = np.array([[1.0, 1e-3], [1.0, 1e-3]])\n"
        "x = np.zeros((2, 3, 2)); x[:, 0, 1] = 1.0\n"
        "v = np.zeros((2, 3, 2)); v[:, 1, 1] = 1.0\n"
        "r = run_ensemble(m, x, v, G=1.0, dt=0.01, n_steps=3)\n"
        "print('ran', len(r.status))\n"
    )
    for _ in range(2):  # the first may compile (which starts the layer); the second loads from the cache
        done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=600)
        assert done.returncode == 0, done.stderr[-500:]
        assert done.stdout.strip() == "ran 2"
