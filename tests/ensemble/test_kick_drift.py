"""The kick-drift ensemble kernels (verlet, leapfrog 2/4/6/8): a system's bits are those of the same system
run alone through chaos_run, whatever the chunking or thread count, and a system that stops (escape,
collision, divergence) stops alone.

Compiling an ensemble kernel costs 15-25 s here, so the fast tier compiles two: verlet (kick-drift-kick,
with its first-same-as-last accelerations carried between calls) and leapfrog4 (a drift-kick-drift
composition with a backward substep). The order-2, 6 and 8 kernels are the order-4 kernel with another
coefficient table (the same ``advance_dkd_chaos``, the same system loop); that each names its own order's
step is checked from the source here, and their bits against chaos_run in the slow tier.
"""

from __future__ import annotations

import inspect

import numpy as np
import pytest
from ensemble_helpers import by_thread_count

from orbitsim.chaos.megno import lyapunov, megno_value, random_initial_variation
from orbitsim.chaos.run import chaos_run
from orbitsim.ensemble import run_ensemble
from orbitsim.ensemble.status import (
    COLLIDED,
    COMPLETE,
    DIVERGED,
    ENERGY_ERROR,
    ESCAPED,
    LYAPUNOV,
    MAX_E,
    MEGNO,
    SCHEMES,
    SURVIVAL_TIME,
)
from orbitsim.scenario import load_scenario

N_STEPS = 200
DT = 0.5


def _giants(k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """K copies of Sun, Jupiter, Saturn, Uranus (DE421), Saturn's x nudged differently in each."""
    sc = load_scenario("giants")
    m, x, v = sc.masses[:4], sc.positions[:4].T, sc.velocities[:4].T
    pos = np.tile(x, (k, 1, 1))
    pos[:, 0, 2] *= 1.0 + 0.01 * np.arange(k)
    return np.tile(m, (k, 1)), pos, np.tile(v, (k, 1, 1))


def _variation(k: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    dpos, dvel = random_initial_variation(4, seed)
    return np.tile(dpos, (k, 1, 1)), np.tile(dvel, (k, 1, 1))


def _alone_equals_ensemble(scheme: str) -> None:
    masses, pos, vel = _giants(3)
    variation = _variation(3)
    result = run_ensemble(masses, pos, vel, G=1.0, dt=DT, n_steps=N_STEPS, variation=variation, integrator=scheme)
    assert (result.status == COMPLETE).all() and (result.steps == N_STEPS).all()
    rows = np.vstack([variation[0][0], variation[1][0]]).T  # (N, 6): dx dy dz dvx dvy dvz per body
    for k in range(3):
        alone = chaos_run(masses[k], pos[k].T, vel[k].T, integrator=scheme, dt=DT, steps=N_STEPS, every=N_STEPS,
                          G=1.0, variation=rows)
        assert alone.finite and alone.steps_done == N_STEPS
        assert np.array_equal(result.pos[k], alone.positions)  # the scheme's own step: the same bits
        assert np.array_equal(result.vel[k], alone.velocities)
        t = N_STEPS * DT
        assert result.indicators[k, MEGNO] == megno_value(alone.sums, t) == alone.megno[-1]
        assert result.indicators[k, LYAPUNOV] == lyapunov(alone.sums) == alone.mlce[-1]
        assert result.indicators[k, SURVIVAL_TIME] == t
    assert 1.5 < result.indicators[0, MEGNO] < 3.0  # the giants are regular: MEGNO near 2


@pytest.mark.parametrize("scheme", ["verlet", "leapfrog4"])
def test_each_system_gets_the_bits_of_a_lone_chaos_run(scheme):
    _alone_equals_ensemble(scheme)


@pytest.mark.slow
@pytest.mark.parametrize("scheme", ["leapfrog", "leapfrog6", "leapfrog8"])
def test_each_system_gets_the_bits_of_a_lone_chaos_run_other_orders(scheme):
    _alone_equals_ensemble(scheme)


def test_every_kernel_names_its_own_schemes_step():
    from orbitsim.ensemble import kick_drift

    assert SCHEMES == ("wisdom_holman", *kick_drift.KICK_DRIFT_KERNELS)
    steps = {"verlet": "verlet_advance_chaos", "leapfrog": "advance_chaos2", "leapfrog4": "advance_chaos4",
             "leapfrog6": "advance_chaos6", "leapfrog8": "advance_chaos8"}
    for name, kernel in kick_drift.KICK_DRIFT_KERNELS.items():
        system = inspect.getsource(kernel.py_func).split("= ")[1].split("(")[0].strip()  # st, done = system_x(
        source = inspect.getsource(getattr(kick_drift, system).py_func)
        assert f"run_kick_drift_system({steps[name]}," in source, name
        others = [s for n, s in steps.items() if n != name]
        assert not any(f"({s}," in source for s in others), name


def test_the_energy_error_is_that_of_the_lone_runs_state():
    from orbitsim.simulation import Simulation

    masses, pos, vel = _giants(1)
    result = run_ensemble(masses, pos, vel, G=1.0, dt=DT, n_steps=N_STEPS, variation=_variation(1),
                          integrator="leapfrog4")
    e0 = Simulation(masses[0], pos[0].T, vel[0].T, "leapfrog4", DT, 1.0).total_energy()
    e1 = Simulation(masses[0], result.pos[0].T, result.vel[0].T, "leapfrog4", DT, 1.0).total_energy()
    assert result.indicators[0, ENERGY_ERROR] == pytest.approx(abs((e1 - e0) / e0), rel=1e-6)  # two energy sums
    assert 0.04 < result.indicators[0, MAX_E] < 0.06  # Jupiter's e ~ 0.048 (Jacobi), a short run


def test_bits_do_not_depend_on_chunking_or_threads():
    masses, pos, vel = _giants(6)
    var = _variation(6, seed=3)

    def part(i: int, j: int):
        return run_ensemble(masses[i:j], pos[i:j], vel[i:j], G=1.0, dt=DT, n_steps=N_STEPS,
                            variation=(var[0][i:j], var[1][i:j]), integrator="leapfrog4")

    whole = part(0, 6)
    for size in (1, 4):  # chunks of one system, and of four then two
        parts = [part(i, min(i + size, 6)) for i in range(0, 6, size)]
        assert np.array_equal(whole.indicators, np.concatenate([p.indicators for p in parts]), equal_nan=True)
        assert np.array_equal(whole.pos, np.concatenate([p.pos for p in parts]))
    first, last = by_thread_count(lambda: part(0, 6)).values()
    assert np.array_equal(first.indicators, whole.indicators, equal_nan=True)
    assert np.array_equal(first.indicators, last.indicators, equal_nan=True)
    assert np.array_equal(first.vel, last.vel)


def test_stopped_systems_never_touch_the_others():
    masses, pos, vel = _giants(5)
    var = _variation(5)
    kwargs = {"G": 1.0, "dt": DT, "n_steps": N_STEPS, "escape_distance": 40.0, "variation": var,
              "integrator": "leapfrog4"}
    radii = np.zeros((5, 4))
    clean = run_ensemble(masses, pos, vel, radii=radii, **kwargs)
    pos2, vel2 = pos.copy(), vel.copy()
    vel2[1, :, 3] *= 3.0  # Uranus of system 1 leaves on a hyperbola
    pos2[2, :, 3] = pos2[2, :, 2]  # Uranus of system 2 on top of Saturn, moving with it: the pull is 0/0
    vel2[2, :, 3] = vel2[2, :, 2]
    radii[3, 1] = radii[3, 2] = 2.5  # Jupiter and Saturn of system 3 overlap from the start (4.4 apart)
    mixed = run_ensemble(masses, pos2, vel2, radii=radii, **kwargs)
    assert mixed.status.tolist() == [COMPLETE, ESCAPED, DIVERGED, COLLIDED, COMPLETE]
    assert 1 < mixed.steps[1] < N_STEPS
    assert mixed.indicators[1, SURVIVAL_TIME] == mixed.steps[1] * DT
    assert mixed.steps[2] == 1 and np.isnan(mixed.indicators[2, ENERGY_ERROR])
    assert mixed.steps[3] == 1 and np.isfinite(mixed.indicators[3, ENERGY_ERROR])
    for k in (0, 4):
        assert np.array_equal(mixed.pos[k], clean.pos[k])
        assert np.array_equal(mixed.indicators[k], clean.indicators[k], equal_nan=True)
    alone = run_ensemble(masses[3:4], pos[3:4], vel[3:4], **{**kwargs, "variation": _variation(1)})
    assert alone.status[0] == COMPLETE  # without radii nothing collides


@pytest.mark.parametrize(("change", "message"), [
    ({"variation": None}, "carries the variational equations: give variation"),
    ({"integrator": "rk4"}, "no ensemble kernel for integrator 'rk4'; schemes: wisdom_holman, verlet"),
    ({"masses_zero": True}, "every system's first mass must be > 0"),
    ({"n_bodies": 49}, "at most 48 bodies per system"),
])
def test_front_door_refuses_what_the_kernels_cannot_run(change, message):
    k, n = 2, change.pop("n_bodies", 4)
    masses = np.full((k, n), 1e-6)
    masses[:, 0] = 0.0 if change.pop("masses_zero", False) else 1.0
    pos = np.zeros((k, 3, n))
    pos[:, 0] = np.arange(n, dtype=float)
    vel = np.zeros((k, 3, n))
    kwargs = {"G": 1.0, "dt": DT, "n_steps": 10, "integrator": "leapfrog", "variation": (np.ones((k, 3, n)),
                                                                                         np.ones((k, 3, n)))}
    kwargs.update(change)
    with pytest.raises(ValueError, match=message):
        run_ensemble(masses, pos, vel, **kwargs)
