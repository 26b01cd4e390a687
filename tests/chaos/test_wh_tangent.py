"""The Wisdom-Holman tangent map: REBOUND's WHFast variational particles and MEGNO, and the
linearisation of the map itself (finite differences of two nearby runs)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import rebound

from orbitsim.chaos.megno import lyapunov, megno_start, megno_value, random_initial_variation
from orbitsim.integrators.wisdom_holman.tangent import (
    TANGENT_SCRATCH_ROWS,
    kepler_drift_tangent_at,
    stiefel_g6_at,
    tangent_run,
)
from orbitsim.physics.coordinates import jacobi_weights
from orbitsim.physics.force_context import make_force
from orbitsim.physics.kepler import KEPLER_OK


def _regular_sim() -> rebound.Simulation:
    """REBOUND's own regular MEGNO case (rebound/tests/test_megno.py, test_whfast)."""
    sim = rebound.Simulation()
    sim.integrator = "whfast"
    sim.add(m=1.0)
    sim.add(m=1e-3, a=1.5, e=0.1, inc=0.1)
    sim.add(m=1e-3, a=15.0, e=0.1, inc=0.1)
    sim.init_megno(seed=0)
    sim.dt = sim.particles[1].P * 0.07
    sim.integrator.safe_mode = 1  # REBOUND's MEGNO demands it; orbitsim's variational WH is the same arrangement
    sim.exact_finish_time = 0
    return sim


def _state(particles, n: int) -> tuple[np.ndarray, np.ndarray]:
    pos = np.array([[particles[i].x, particles[i].y, particles[i].z] for i in range(n)]).T.copy()
    vel = np.array([[particles[i].vx, particles[i].vy, particles[i].vz] for i in range(n)]).T.copy()
    return pos, vel


def _system(m: np.ndarray, G: float = 1.0):
    n = m.shape[0]
    return make_force(G, 0.0, n), jacobi_weights(m), G * np.cumsum(m), np.zeros((TANGENT_SCRATCH_ROWS, 3, n))


def test_megno_and_variational_particle_agree_with_rebound_whfast() -> None:
    sim = _regular_sim()
    n = sim.N
    pos, vel = _state(sim.particles, n)
    dpos, dvel = _state(sim.var_config[0].particles, n)
    m = np.array([p.m for p in sim.particles])
    force, weights, mu, scratch = _system(m, sim.G)
    megno = megno_start(0.0)
    every = 100
    n_samples = int(1e4 / sim.dt) // every
    ours = np.zeros((n_samples, 2))
    theirs = np.zeros((n_samples, 2))
    n_done = 0
    for k in range(n_samples):
        n_done, status, _, megno, halvings = tangent_run(pos, vel, dpos, dvel, m, force, sim.dt, weights, mu,
                                                          scratch, megno, 0.0, n_done, n_done + every)
        assert status == KEPLER_OK and halvings == 0
        ours[k] = megno_value(megno, n_done * sim.dt), lyapunov(megno)
        sim.steps(every)
        theirs[k] = sim.megno(), sim.lyapunov()
    assert n_done * sim.dt > 9900.0
    # Two codes' round-off (different Kepler solvers, transforms) moves the orbits apart linearly;
    # over 1e4 time units that reached 1e-12 in MEGNO and 2e-11 in the slope.
    assert np.all(np.abs(ours - theirs) <= 1e-10 * np.abs(theirs))
    assert abs(ours[-1, 0] - 2.0) < 0.2 and abs(ours[-1, 1]) < 1e-3  # REBOUND's regular-case bounds
    ref_dpos, ref_dvel = _state(sim.var_config[0].particles, n)
    # The variational particle itself: the same linear round-off growth, 1.1e-10 of its norm seen.
    scale = max(np.abs(ref_dpos).max(), np.abs(ref_dvel).max())
    assert np.abs(dpos - ref_dpos).max() < 1e-9 * scale
    assert np.abs(dvel - ref_dvel).max() < 1e-9 * scale


def _chaotic_system() -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    sim = rebound.Simulation()
    sim.add(m=1.0)
    sim.add(m=1e-4, P=1.0)
    sim.add(m=1e-4, P=1.17)
    sim.move_to_com()
    pos, vel = _state(sim.particles, 3)
    return np.array([p.m for p in sim.particles]), pos, vel, sim.G


@pytest.mark.parametrize("n_steps", [1, 50])
def test_tangent_map_is_the_derivative_of_the_map(n_steps: int) -> None:
    # (map(x + eps d) - map(x - eps d)) / (2 eps) = tangent map(d) + O(eps^2) + O(round-off / eps):
    # eps = 1e-6 makes both about 1e-10 of the state, so 1e-6 relative leaves a wide margin.
    m, pos, vel, G = _chaotic_system()
    dt = 0.05
    rng = np.random.default_rng(3)
    dpos, dvel = rng.standard_normal((3, 3)), rng.standard_normal((3, 3))
    force, weights, mu, scratch = _system(m, G)
    eps = 1e-6
    ends = []
    for sign in (1.0, -1.0):
        p, v = pos + sign * eps * dpos, vel + sign * eps * dvel
        tangent_run(p, v, np.zeros((3, 3)), np.ones((3, 3)), m, force, dt, weights, mu, scratch, megno_start(0.0),
                    0.0, 0, n_steps)
        ends.append((p, v))
    p, v = pos.copy(), vel.copy()
    tangent_run(p, v, dpos, dvel, m, force, dt, weights, mu, scratch, megno_start(0.0), 0.0, 0, n_steps)
    fd_pos = (ends[0][0] - ends[1][0]) / (2 * eps)
    fd_vel = (ends[0][1] - ends[1][1]) / (2 * eps)
    scale = max(np.abs(dpos).max(), np.abs(dvel).max())
    assert np.abs(fd_pos - dpos).max() < 1e-6 * scale
    assert np.abs(fd_vel - dvel).max() < 1e-6 * scale


@pytest.mark.parametrize("dt", [0.3, -0.2, 2.6, 7.9])  # the last two are longer than a period (2 pi)
def test_kepler_drift_tangent_is_its_derivative(dt: float) -> None:
    # One body about mu = 1 on an e = 0.3 ellipse; steps beyond a period exercise the solver's
    # whole-period reduction, whose secular shear the tangent must keep. Central difference as above.
    x0 = np.array([[0.7], [0.1], [0.05]])
    v0 = np.array([[-0.2], [1.3], [0.1]])
    rng = np.random.default_rng(8)
    d0, dv0 = rng.standard_normal((3, 1)), rng.standard_normal((3, 1))
    eps = 1e-7
    ends = []
    for sign in (1.0, -1.0):
        p, v = x0 + sign * eps * d0, v0 + sign * eps * dv0
        assert kepler_drift_tangent_at(p, v, np.zeros((3, 1)), np.zeros((3, 1)), 0, 1.0, dt) == KEPLER_OK
        ends.append((p, v))
    p, v, dp, dv = x0.copy(), v0.copy(), d0.copy(), dv0.copy()
    assert kepler_drift_tangent_at(p, v, dp, dv, 0, 1.0, dt) == KEPLER_OK
    fd = np.concatenate([(ends[0][0] - ends[1][0]) / (2 * eps), (ends[0][1] - ends[1][1]) / (2 * eps)])
    ours = np.concatenate([dp, dv])
    assert np.abs(fd - ours).max() < 1e-6 * np.abs(ours).max()


@pytest.mark.parametrize(("beta", "X"), [(1.0, 0.01), (0.7, 1.3), (2.0, 2.9), (-1.5, 2.0), (0.0, 0.5)])
def test_stiefel_g6_against_closed_forms(beta: float, X: float) -> None:
    # G_n = X^n c_n(beta X^2), c_n(z) = sum_k (-z)^k / (2k + n)!: summed in exact rationals' float image.
    z = beta * X * X
    expected = [X**n * sum((-z) ** k / math.factorial(2 * k + n) for k in range(40)) for n in range(6)]
    got = stiefel_g6_at(beta, X)
    # The quarter-argument identities amplify rounding by ~4 per quartering: 1e-13 relative covers three.
    for n in range(6):
        assert abs(got[n] - expected[n]) <= 1e-13 * abs(expected[n]) + 1e-300


def test_megno_of_chaotic_pair_grows() -> None:
    # REBOUND's chaotic case (m = 1e-4 at P = 1 and 1.17): MEGNO > 50 by t = 1000.
    m, pos, vel, G = _chaotic_system()
    force, weights, mu, scratch = _system(m, G)
    dpos, dvel = random_initial_variation(3, 0)  # not a uniform shift: that is a symmetry, and stays regular
    dt = 0.001  # REBOUND's default step, which its test uses
    n_done, status, _, megno, _ = tangent_run(pos, vel, dpos, dvel, m, force, dt, weights, mu, scratch,
                                              megno_start(0.0), 0.0, 0, 1000000)
    assert status == KEPLER_OK
    assert megno_value(megno, n_done * dt) > 50.0
