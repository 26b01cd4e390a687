"""The shared-massive-bodies ensemble (orbitsim.ensemble.restricted) against the whole-system kernel, bit for bit."""

from __future__ import annotations

import numpy as np
import pytest
from ensemble_helpers import assert_same_bits, by_thread_count

from orbitsim.chaos.megno import random_initial_variation
from orbitsim.ensemble import run_ensemble
from orbitsim.ensemble.restricted import BLOCK_STEPS, restricted_applies
from orbitsim.ensemble.status import COLLIDED, COMPLETE, ESCAPED, MEGNO
from orbitsim.scenario import load_scenario

# `make test-slow` only: the restricted Wisdom-Holman MEGNO kernel and its whole-system reference compile
# for ~75 s cold.
pytestmark = pytest.mark.slow

DT = 3.1415  # half a year, the bundled map's step
N_STEPS = BLOCK_STEPS + 300  # two blocks, the second one short


def _test_planets(k: int, seed: int = 1) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """K copies of the bundled map's Sun, Jupiter, Saturn and massless planet; the planet's start spread from
    inside Jupiter's orbit to beyond Saturn's (some escape, some meet Jupiter)."""
    sc = load_scenario("jupiter_saturn")
    m, x, v = sc.masses, sc.positions.T, sc.velocities.T
    masses, pos, vel = np.tile(m, (k, 1)), np.tile(x, (k, 1, 1)), np.tile(v, (k, 1, 1))
    rng = np.random.default_rng(seed)
    pos[:, :, 3] *= (0.6 + 1.0 * rng.random(k))[:, None]
    vel[:, :, 3] *= (0.8 + 0.5 * rng.random(k))[:, None]
    return masses, pos, vel


def _variation(k: int, scale: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    dpos, dvel = random_initial_variation(4, 0)
    return np.tile(dpos * scale, (k, 1, 1)), np.tile(dvel * scale, (k, 1, 1))


@pytest.mark.slow  # compiles the whole-system and the restricted Wisdom-Holman MEGNO kernels (~1 min cold)
@pytest.mark.parametrize("case", ["plain", "escapes_and_collisions", "rescaled"])
def test_shared_massive_bodies_give_the_bits_of_the_whole_system_kernel(case):
    k = 24
    masses, pos, vel = _test_planets(k)
    kwargs = {"G": 1.0, "dt": DT, "n_steps": N_STEPS, "watch": 3}
    scale = 1.0
    if case == "escapes_and_collisions":
        radii = np.tile([0.005, 0.35, 0.3, 0.0], (k, 1))  # Jupiter's and Saturn's reach inflated
        kwargs.update(escape_distance=12.0, radii=radii)
    if case == "rescaled":
        scale = 2.0 ** 200  # |delta|^2 = 4 * 2^400 > 2^400 after the first step: the 2^-200 rescaling runs
    kwargs["variation"] = _variation(k, scale)
    assert restricted_applies(masses, pos, vel, kwargs.get("radii", np.zeros((k, 4))), *kwargs["variation"], 3)
    shared = run_ensemble(masses, pos, vel, **kwargs)
    whole = run_ensemble(masses, pos, vel, shared_massive=False, **kwargs)
    assert_same_bits(shared, whole)
    if case == "escapes_and_collisions":
        assert (shared.status == ESCAPED).any() and (shared.status == COLLIDED).any()
        assert (shared.status == COMPLETE).any()  # some pixels ran to the end beside the stopped ones
    assert np.isfinite(shared.indicators[shared.status == COMPLETE, MEGNO]).all()


def test_massive_bodies_that_collide_mid_block_stop_every_pixel_at_their_step_with_the_whole_system_bits():
    # radii of 2 au for Jupiter and Saturn: the giants meet at step 359, inside the first of two blocks, so the
    # block stepped ahead beside the pixels must not be; every pixel not stopped before (some meet an inflated
    # giant first) stops at that step, with the whole-system kernel's bits
    k = 20
    masses, pos, vel = _test_planets(k, seed=3)
    radii = np.tile([0.005, 2.0, 2.0, 0.0], (k, 1))
    kwargs = {"G": 1.0, "dt": DT, "n_steps": N_STEPS, "watch": 3, "radii": radii, "variation": _variation(k)}
    assert restricted_applies(masses, pos, vel, radii, *kwargs["variation"], 3)
    shared = run_ensemble(masses, pos, vel, **kwargs)
    assert_same_bits(shared, run_ensemble(masses, pos, vel, shared_massive=False, **kwargs))
    assert (shared.status == COLLIDED).all()
    giants_meet = shared.steps.max()
    assert giants_meet < BLOCK_STEPS and (shared.steps == giants_meet).sum() >= 2 and shared.steps.min() < giants_meet

def test_shared_massive_bits_do_not_depend_on_chunking():
    k = 8
    masses, pos, vel = _test_planets(k, seed=2)
    dpos, dvel = _variation(k)
    kwargs = {"G": 1.0, "dt": DT, "n_steps": 700, "watch": 3, "escape_distance": 15.0}
    whole = run_ensemble(masses, pos, vel, variation=(dpos, dvel), **kwargs)
    parts = [run_ensemble(masses[i:j], pos[i:j], vel[i:j], variation=(dpos[i:j], dvel[i:j]), **kwargs)
             for i, j in ((0, 3), (3, 4), (4, 8))]
    assert whole.indicators.tobytes() == np.concatenate([p.indicators for p in parts]).tobytes()
    assert np.array_equal(whole.status, np.concatenate([p.status for p in parts]))


def test_a_massive_tangent_vector_past_the_limit_falls_back_to_the_whole_system_kernel():
    k = 4
    masses, pos, vel = _test_planets(k)
    variation = _variation(k, 2.0 ** 301)  # the shared part's |delta|^2 > 2^600 at once: the shortcut gives up
    kwargs = {"G": 1.0, "dt": DT, "n_steps": 50, "watch": 3, "variation": variation}
    assert_same_bits(run_ensemble(masses, pos, vel, **kwargs),
                      run_ensemble(masses, pos, vel, shared_massive=False, **kwargs))


@pytest.mark.parametrize("change", ["planet_mass", "massive_differs", "watch", "variation_differs"])
def test_the_shortcut_applies_only_where_the_massive_bodies_are_shared(change):
    k = 3
    masses, pos, vel = _test_planets(k)
    dpos, dvel = _variation(k)
    radii = np.zeros((k, 4))
    assert restricted_applies(masses, pos, vel, radii, dpos, dvel, 3)
    watch = 3
    if change == "planet_mass":
        masses[1, 3] = 1e-9
    elif change == "massive_differs":
        pos[2, 0, 2] = np.nextafter(pos[2, 0, 2], np.inf)  # one bit of Saturn's x in one system
    elif change == "watch":
        watch = 2
    else:
        dvel[0, 1, 1] = -dvel[0, 1, 1]  # Jupiter's variation in one system
    assert not restricted_applies(masses, pos, vel, radii, dpos, dvel, watch)


def test_lanes_outside_the_common_case_take_the_scalar_drift_and_keep_their_bits():
    """Pixels in SIMD lanes (orbitsim.ensemble.lanes): a lane whose drift leaves the vector path (here a test
    planet so close to the Sun that half a step is longer than half its period, which the scalar solve
    reduces by whole periods) is redone by the scalar drift beside lanes that stay on it; 40 pixels make
    two full groups and one padded one."""
    from orbitsim.ensemble.lanes import LANES
    from orbitsim.physics.kepler_solver import setup_short

    k = 2 * LANES + LANES // 2
    masses, pos, vel = _test_planets(k, seed=3)
    close = [5, LANES + 1, k - 1]  # one in each group
    for i in close:
        pos[i, :, 3] = pos[i, :, 0] + np.array([0.05, 0.0, 0.0])
        vel[i, :, 3] = vel[i, :, 0] + np.array([0.0, 1.0 / np.sqrt(0.05), 0.0])
    r0 = np.linalg.norm(pos[close[0], :, 3] - pos[close[0], :, 0])
    assert not setup_short(r0, 1.0 / 0.05, 0.0, 1.0, 0.5 * DT)[4]  # the vector path refuses it
    assert k % LANES != 0
    kwargs = {"G": 1.0, "dt": DT, "n_steps": 300, "watch": 3, "variation": _variation(k)}
    shared = run_ensemble(masses, pos, vel, **kwargs)
    assert_same_bits(shared, run_ensemble(masses, pos, vel, shared_massive=False, **kwargs))
    assert (shared.status[close] == COMPLETE).all()  # they ran the whole way on the scalar drift


def test_shared_massive_bits_do_not_depend_on_the_thread_count():
    k = 40
    masses, pos, vel = _test_planets(k, seed=4)
    kwargs = {"G": 1.0, "dt": DT, "n_steps": 400, "watch": 3, "variation": _variation(k), "escape_distance": 15.0}
    runs = by_thread_count(lambda: run_ensemble(masses, pos, vel, **kwargs))
    first, *others = runs.values()
    for other in others:
        assert_same_bits(first, other)
