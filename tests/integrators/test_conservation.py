"""Conservation laws that hold to round-off whatever the step size.

* Total momentum: pair forces are equal and opposite, so every kick changes sum m v by round-off
  only, for every scheme (each is a sequence of drifts and kicks, or RK stages built from them).
* Centre of mass: with P conserved, X_com(t) = X_com(0) + P t / M.
* Angular momentum on the two-body (central-force) problem: drifts and kicks each conserve
  m x cross v exactly when the force is along the line of centres, so every scheme built from
  whole kicks and drifts conserves it: semi-implicit Euler, Verlet, leapfrog and its compositions.
  Explicit Euler and RK4 mix old and new states and do not: the negative controls.
"""

from __future__ import annotations

import numpy as np
import pytest

from orbitsim.integrators.registry import INTEGRATORS
from orbitsim.simulation import simulate

#: Every scheme whose momentum/CoM conservation this file checks (all of them at present).
ALL_SCHEMES = (
    "euler", "semi_implicit_euler", "verlet", "leapfrog", "rk4", "leapfrog4", "leapfrog6", "leapfrog8",
)
#: Schemes that are sequences of exact kicks and drifts: L conserved on a central force.
ANGULAR_MOMENTUM_SCHEMES = ("semi_implicit_euler", "verlet", "leapfrog", "leapfrog4", "leapfrog6", "leapfrog8")

#: 1000 steps of up to 17 kicks: each adds terms m_i a_i dt that cancel only to a rounding; the
#: measured drift is 1e-15 .. 5e-15 of sum m |v|, and a missing reaction term would give ~1e-3.
MOMENTUM_TOL = 1e-13
#: Same reason; measured 6.5e-16 .. 9e-15 of the mass-weighted mean distance.
COM_TOL = 1e-13
#: 1000 steps, measured 2e-15 .. 1.2e-14 relative (it grows with the run: ~6e-14 after 10^5).
ANGULAR_MOMENTUM_TOL = 1e-13


def six_bodies() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(7)
    m = np.array([1.0, 0.5, 0.2, 0.05, 1e-3, 0.3])
    x = rng.normal(size=(6, 3))
    v = 0.5 * rng.normal(size=(6, 3))
    return m, x, v


def two_body_eccentric() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """M = 1, m = 1e-3, a = 1, e = 0.5, at pericentre, centre-of-mass frame."""
    big, small = 1.0, 1e-3
    mu = big + small
    x_rel = np.array([0.5, 0.0, 0.0])
    v_rel = np.array([0.0, np.sqrt(mu * 1.5 / 0.5), 0.0])  # vis-viva at r = a (1 - e)
    m = np.array([big, small])
    x = np.array([-small / mu * x_rel, big / mu * x_rel])
    v = np.array([-small / mu * v_rel, big / mu * v_rel])
    return m, x, v


def registry_names() -> list[str]:
    return [spec.name for spec in INTEGRATORS]


@pytest.mark.parametrize("name", registry_names())
def test_momentum_and_centre_of_mass(name: str) -> None:
    if name not in ALL_SCHEMES:
        pytest.skip(f"{name}: not in this test's list")
    m, x, v = six_bodies()
    dt, steps = 1e-3, 1000
    result = simulate(m, x, v, integrator=name, dt=dt, steps=steps, every=100, softening=0.05)
    assert result.status == "complete"
    assert np.max(np.abs(result.final_positions - x)) > 0.1  # the bodies interacted and moved

    scale = np.sum(m * np.linalg.norm(v, axis=1))
    p0 = (m[:, None] * v).sum(axis=0)
    p_end = (m[:, None] * result.final_velocities).sum(axis=0)  # independent of the engine's diagnostic
    assert np.linalg.norm(p_end - p0) / scale < MOMENTUM_TOL
    # The engine's own momentum samples agree.
    drift = np.linalg.norm(result.momentum - result.momentum[0], axis=1).max() / scale
    assert drift < MOMENTUM_TOL

    total = m.sum()
    com0 = (m[:, None] * x).sum(axis=0) / total
    com_end = (m[:, None] * result.final_positions).sum(axis=0) / total
    expected = com0 + p0 / total * (steps * dt)
    length = np.sum(m * np.linalg.norm(x, axis=1)) / total
    assert np.linalg.norm(com_end - expected) / length < COM_TOL


@pytest.mark.parametrize("name", registry_names())
def test_angular_momentum_on_kepler(name: str) -> None:
    if name not in ANGULAR_MOMENTUM_SCHEMES:
        pytest.skip(f"{name}: not in this test's list of L-conserving schemes")
    m, x, v = two_body_eccentric()
    result = simulate(m, x, v, integrator=name, dt=2 * np.pi / 200, steps=1000, every=10)
    L = result.angular_momentum
    assert np.max(np.linalg.norm(L - L[0], axis=1)) / np.linalg.norm(L[0]) < ANGULAR_MOMENTUM_TOL
    # The engine's L matches m x cross v computed here from the final state.
    L_end = (m[:, None] * np.cross(result.final_positions, result.final_velocities)).sum(axis=0)
    assert np.linalg.norm(L_end - L[-1]) / np.linalg.norm(L[0]) < 1e-14  # same sum, other order


@pytest.mark.parametrize("name", ["euler", "rk4"])
def test_angular_momentum_not_conserved_by_mixed_updates(name: str) -> None:
    """Negative control: Euler (dt^2 v x a per step) and RK4 change L by far more than round-off."""
    m, x, v = two_body_eccentric()
    result = simulate(m, x, v, integrator=name, dt=2 * np.pi / 200, steps=1000, every=1000)
    L = result.angular_momentum
    # Measured 0.34 (euler) and 7e-7 (rk4).
    assert np.linalg.norm(L[-1] - L[0]) / np.linalg.norm(L[0]) > 1e3 * ANGULAR_MOMENTUM_TOL
