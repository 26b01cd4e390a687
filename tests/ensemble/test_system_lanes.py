"""Whole Wisdom-Holman systems in SIMD lanes (orbitsim.ensemble.system_lanes) against the scalar kernel, bit for bit."""

from __future__ import annotations

import numpy as np
import pytest
from ensemble_helpers import assert_same_bits, by_thread_count, giants_systems, stopping_group

from orbitsim.ensemble import run_ensemble
from orbitsim.ensemble.status import COLLIDED, COMPLETE, DIVERGED, ESCAPED
from orbitsim.ensemble.system_lanes import LANES
from orbitsim.physics.kepler_solver import setup_short

DT = 0.5
N_STEPS = 300


def _both(masses, pos, vel, **kwargs):
    lanes = run_ensemble(masses, pos, vel, **kwargs)
    scalar = run_ensemble(masses, pos, vel, lanes=False, **kwargs)
    assert_same_bits(lanes, scalar)
    return lanes


@pytest.mark.parametrize(("k", "n", "watch"), [(40, 4, 1), (16, 2, 1), (5, 5, 3)])
def test_lanes_give_the_bits_of_the_scalar_kernel(k, n, watch):
    """Ordinary systems: 40 make two full groups and a padded one; two-body systems have no pair to kick;
    five bodies, another watched body, one group mostly padding."""
    masses, pos, vel = giants_systems(k, n)
    masses[:, 1] *= 1.0 + 0.1 * np.arange(k) / k  # masses, weights and Kepler parameters differ per lane too
    result = _both(masses, pos, vel, G=1.0, dt=DT, n_steps=N_STEPS, watch=watch)
    assert (result.status == COMPLETE).all() and (result.steps == N_STEPS).all()


def test_systems_that_stop_at_different_steps_stop_alone_with_the_scalar_kernels_bits():
    """One group: systems that escape and collide, each at a step of its own, and diverge (a drift that fails at
    once; a body so massive that the first kick overflows, so the second drift fails) beside systems that run to
    the end."""
    k = LANES
    masses, pos, vel, radii = stopping_group(k)
    result = _both(masses, pos, vel, G=1.0, dt=DT, n_steps=N_STEPS, escape_distance=60.0, radii=radii)
    steps = {code: set(result.steps[result.status == code].tolist()) for code in (ESCAPED, COLLIDED, DIVERGED)}
    assert len(steps[ESCAPED]) == 3 and len(steps[COLLIDED]) == 3 and steps[DIVERGED] == {1, 2}, steps
    assert min(steps[ESCAPED] | steps[COLLIDED]) > 1  # stopped after steps the others took too
    assert (result.status == COMPLETE).sum() == k - 8
    assert (result.steps[result.status == COMPLETE] == N_STEPS).all()


def test_a_lane_outside_the_vector_drift_takes_the_scalar_drift_and_keeps_its_bits():
    """Uranus so close to the Sun in three systems (one per group) that half a step is longer than half its
    period, which the scalar solve reduces by whole periods: those lanes are drifted by kepler_drift beside
    lanes that stay on the vector path."""
    k = 40
    masses, pos, vel = giants_systems(k)
    close = [5, 17, 39]
    for i in close:
        pos[i, :, 3] = pos[i, :, 0] + np.array([0.05, 0.0, 0.0])
        vel[i, :, 3] = vel[i, :, 0] + np.array([0.0, 1.0 / np.sqrt(0.05), 0.0])
    assert not setup_short(0.05, 1.0 / 0.05, 0.0, 1.0, 0.5 * DT)[4]  # the vector path refuses it
    result = _both(masses, pos, vel, G=1.0, dt=DT, n_steps=N_STEPS)
    assert (result.status[close] == COMPLETE).all()  # they ran the whole way on the scalar drift


def test_no_steps_and_one_step():
    masses, pos, vel = giants_systems(3)
    for n_steps in (0, 1):
        result = _both(masses, pos, vel, G=1.0, dt=DT, n_steps=n_steps)
        assert (result.steps == n_steps).all()


def test_lane_bits_do_not_depend_on_chunking_or_threads():
    k = 40
    masses, pos, vel = giants_systems(k)
    vel[3, :, 3] *= 3.0  # one escapes
    kwargs = {"G": 1.0, "dt": DT, "n_steps": N_STEPS, "escape_distance": 60.0}
    whole = run_ensemble(masses, pos, vel, **kwargs)
    assert whole.status[3] == ESCAPED
    parts = [run_ensemble(masses[i:j], pos[i:j], vel[i:j], **kwargs) for i, j in ((0, 3), (3, 20), (20, 40))]
    for name in ("status", "steps", "indicators", "pos", "vel"):
        assert getattr(whole, name).tobytes() == np.concatenate([getattr(p, name) for p in parts]).tobytes()
    runs = by_thread_count(lambda: run_ensemble(masses, pos, vel, **kwargs))
    for other in runs.values():
        assert_same_bits(whole, other)
