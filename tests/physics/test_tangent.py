"""The tangent gravity is the Jacobian of the accelerations times the displacement, as REBOUND's."""

from __future__ import annotations

import numpy as np
import pytest
import rebound

from orbitsim.physics.gravity import all_pairs_accelerations
from orbitsim.physics.tangent import ALL_PAIRS, SKIP_BODY_0, SKIP_PAIR_0_1, tangent_accelerations


def _system(n: int, seed: int = 3) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    pos = np.ascontiguousarray(rng.uniform(-2.0, 2.0, (3, n)))
    m = rng.uniform(0.1, 1.0, n)
    m[-1] = 0.0  # a test particle: pulled, pulls nothing
    dpos = np.ascontiguousarray(rng.standard_normal((3, n)))
    return pos, m, dpos


@pytest.mark.parametrize("eps2", [0.0, 0.05])
def test_tangent_is_the_jacobian_of_the_accelerations(eps2: float) -> None:
    pos, m, dpos = _system(6)
    G = 1.3
    dacc = np.zeros_like(pos)
    tangent_accelerations(pos, m, G, eps2, dpos, dacc, ALL_PAIRS)
    h = 1e-5
    a_plus = np.zeros_like(pos)
    a_minus = np.zeros_like(pos)
    all_pairs_accelerations(pos + h * dpos, m, G, eps2, a_plus)
    all_pairs_accelerations(pos - h * dpos, m, G, eps2, a_minus)
    central = (a_plus - a_minus) / (2 * h)
    # central differences are exact to O(h^2 |a'''|) ~ 1e-10 here; round-off of a/h ~ 1e-11
    assert np.max(np.abs(dacc - central)) < 1e-8 * np.max(np.abs(central))


def test_skips_leave_out_the_pairs_a_splitting_keeps_in_its_kepler_part() -> None:
    pos, m, dpos = _system(5)
    full, no01, no0 = (np.zeros_like(pos) for _ in range(3))
    tangent_accelerations(pos, m, 1.0, 0.0, dpos, full, ALL_PAIRS)
    tangent_accelerations(pos, m, 1.0, 0.0, dpos, no01, SKIP_PAIR_0_1)
    tangent_accelerations(pos, m, 1.0, 0.0, dpos, no0, SKIP_BODY_0)
    only01 = np.zeros_like(pos)
    tangent_accelerations(pos[:, :2].copy(), m[:2].copy(), 1.0, 0.0, dpos[:, :2].copy(), only01[:, :2], ALL_PAIRS)
    # the 0-1 pair alone is what the skip removes: equal up to the round-off of a reordered sum
    assert np.allclose(full - no01, only01, rtol=1e-12, atol=1e-12 * np.max(np.abs(full)))
    assert np.all(no0[:, 0] == 0.0)
    # the momentum of the variation is conserved pair by pair: sum m_i da_i = 0
    assert np.max(np.abs(full @ m)) < 1e-13 * np.max(np.abs(full))


def test_agrees_with_rebound_variational_particles() -> None:
    sim = rebound.Simulation()
    sim.add(m=1.0)
    sim.add(m=1e-3, a=1.0, e=0.1, inc=0.2)
    sim.add(m=3e-4, a=1.6, e=0.05, inc=0.1, Omega=1.0)
    sim.add(m=0.0, a=2.3, e=0.2, inc=0.3, omega=0.7)
    var = sim.add_variation()
    rng = np.random.default_rng(11)
    for p in var.particles:
        p.x, p.y, p.z, p.vx, p.vy, p.vz = rng.standard_normal(6)
    sim.integrator = "leapfrog"
    sim.dt = 1e-300  # one step of negligible length: REBOUND's var accelerations at the start state
    sim.steps(1)
    pos = np.array([[p.x for p in sim.particles], [p.y for p in sim.particles], [p.z for p in sim.particles]])
    m = np.array([p.m for p in sim.particles])
    dpos = np.array([[p.x for p in var.particles], [p.y for p in var.particles], [p.z for p in var.particles]])
    ref = np.array([[p.ax for p in var.particles], [p.ay for p in var.particles], [p.az for p in var.particles]])
    dacc = np.zeros_like(pos)
    tangent_accelerations(pos, m, sim.G, 0.0, dpos, dacc, ALL_PAIRS)
    # same pair terms in the same order: round-off only
    assert np.allclose(dacc, ref, rtol=1e-13, atol=1e-15 * np.max(np.abs(ref)))
