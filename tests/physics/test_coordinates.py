"""Jacobi and democratic heliocentric coordinates against their definitions and their identities.

The references below are written from the definitions (interior centres of mass, heliocentric
positions, barycentric velocities) in plain numpy, independently of the recurrences in
:mod:`orbitsim.physics.coordinates`.
"""

from __future__ import annotations

import numpy as np
import pytest

from orbitsim.physics.coordinates import (
    democratic_heliocentric_to_inertial_pos,
    democratic_heliocentric_to_inertial_vel,
    inertial_to_democratic_heliocentric,
    inertial_to_jacobi,
    jacobi_to_inertial,
    jacobi_weights,
)

#: Round-off of a few additions and products on O(1) values, accumulated over at most N terms.
ROUND_OFF = 1e-14


def planetary_system(n: int = 7, seed: int = 3) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A star, planets of very different masses, and a zero-mass test body; (3, N) arrays."""
    rng = np.random.default_rng(seed)
    m = np.concatenate([[1.0], 10.0 ** rng.uniform(-9, -3, n - 2), [0.0]])
    x = rng.normal(size=(3, n)) * np.arange(1, n + 1)
    v = rng.normal(size=(3, n)) * 0.3
    return m, np.ascontiguousarray(x), np.ascontiguousarray(v)


def jacobi_reference(u: np.ndarray, m: np.ndarray) -> np.ndarray:
    """r'_i = u_i - (centre of mass of bodies 0..i-1); r'_0 = centre of mass of all bodies."""
    out = np.empty_like(u)
    for i in range(1, m.size):
        out[:, i] = u[:, i] - (u[:, :i] @ m[:i]) / m[:i].sum()
    out[:, 0] = (u @ m) / m.sum()
    return out


def test_jacobi_matches_its_definition() -> None:
    m, x, _ = planetary_system()
    out = np.empty_like(x)
    inertial_to_jacobi(x, jacobi_weights(m), out)
    np.testing.assert_allclose(out, jacobi_reference(x, m), rtol=0, atol=ROUND_OFF * np.abs(x).max())


def test_jacobi_round_trip_and_in_place() -> None:
    m, x, _ = planetary_system()
    w = jacobi_weights(m)
    jac = np.empty_like(x)
    inertial_to_jacobi(x, w, jac)
    back = np.empty_like(x)
    jacobi_to_inertial(jac, w, back)
    np.testing.assert_allclose(back, x, rtol=0, atol=ROUND_OFF * np.abs(x).max())
    # In place (output aliasing input) gives the same bits as out of place.
    alias = x.copy()
    inertial_to_jacobi(alias, w, alias)
    np.testing.assert_array_equal(alias, jac)
    jacobi_to_inertial(alias, w, alias)
    np.testing.assert_array_equal(alias, back)


def test_jacobi_kinetic_energy_splits_into_centre_of_mass_and_jacobi_terms() -> None:
    """sum m v^2/2 = M V^2/2 + sum_i m'_i v'_i^2/2 with m'_i = m_i M_{i-1} / M_i (Jacobi masses)."""
    m, _, v = planetary_system()
    jv = np.empty_like(v)
    inertial_to_jacobi(v, jacobi_weights(m), jv)
    interior = np.cumsum(m)
    jacobi_mass = m[1:] * interior[:-1] / interior[1:]
    t_inertial = 0.5 * np.sum(m * np.sum(v * v, axis=0))
    t_jacobi = 0.5 * interior[-1] * jv[:, 0] @ jv[:, 0] + 0.5 * np.sum(jacobi_mass * np.sum(jv[:, 1:] ** 2, axis=0))
    assert t_jacobi == pytest.approx(t_inertial, rel=ROUND_OFF)


def test_jacobi_weights_need_a_massive_centre() -> None:
    with pytest.raises(ValueError, match=r"m\[0\] > 0"):
        jacobi_weights(np.array([0.0, 1.0]))


def test_democratic_heliocentric_matches_its_definition() -> None:
    m, x, v = planetary_system()
    hx, hv = np.empty_like(x), np.empty_like(v)
    inertial_to_democratic_heliocentric(x, v, m, hx, hv)
    vcom = (v @ m) / m.sum()
    scale_x, scale_v = np.abs(x).max(), np.abs(v).max()
    np.testing.assert_allclose(hx[:, 1:], x[:, 1:] - x[:, :1], rtol=0, atol=ROUND_OFF * scale_x)
    np.testing.assert_allclose(hv[:, 1:], v[:, 1:] - vcom[:, None], rtol=0, atol=ROUND_OFF * scale_v)
    np.testing.assert_allclose(hx[:, 0], (x @ m) / m.sum(), rtol=0, atol=ROUND_OFF * scale_x)
    np.testing.assert_allclose(hv[:, 0], vcom, rtol=0, atol=ROUND_OFF * scale_v)


def test_democratic_heliocentric_round_trip_and_in_place() -> None:
    m, x, v = planetary_system()
    hx, hv = np.empty_like(x), np.empty_like(v)
    inertial_to_democratic_heliocentric(x, v, m, hx, hv)
    bx, bv = np.empty_like(x), np.empty_like(v)
    democratic_heliocentric_to_inertial_pos(hx, m, bx)
    democratic_heliocentric_to_inertial_vel(hv, m, bv)
    np.testing.assert_allclose(bx, x, rtol=0, atol=ROUND_OFF * np.abs(x).max())
    np.testing.assert_allclose(bv, v, rtol=0, atol=ROUND_OFF * np.abs(v).max())
    ax, av = x.copy(), v.copy()
    inertial_to_democratic_heliocentric(ax, av, m, ax, av)
    np.testing.assert_array_equal(ax, hx)
    np.testing.assert_array_equal(av, hv)
    democratic_heliocentric_to_inertial_pos(ax, m, ax)
    democratic_heliocentric_to_inertial_vel(av, m, av)
    np.testing.assert_array_equal(ax, bx)
    np.testing.assert_array_equal(av, bv)


def test_zero_mass_body_does_not_move_the_interior_centre_of_mass() -> None:
    """A test body (m = 0) inserted anywhere leaves every other Jacobi vector unchanged."""
    m, x, _ = planetary_system()
    w = jacobi_weights(m)
    base = np.empty_like(x)
    inertial_to_jacobi(x, w, base)
    m2 = np.insert(m, 3, 0.0)
    x2 = np.ascontiguousarray(np.insert(x, 3, [5.0, -2.0, 1.0], axis=1))
    out = np.empty_like(x2)
    inertial_to_jacobi(x2, jacobi_weights(m2), out)
    np.testing.assert_array_equal(np.delete(out, 3, axis=1), base)
