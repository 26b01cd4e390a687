"""Tests for orbitsim.initial_conditions.generators: Plummer sphere and Keplerian disc."""

from __future__ import annotations

import math

import numpy as np
import pytest

from orbitsim.initial_conditions.elements import cartesian_to_elements
from orbitsim.initial_conditions.generators import PLUMMER_HALF_MASS_RADIUS, disc, plummer


def _kinetic_and_potential(masses, positions, velocities, G):
    kinetic = 0.5 * float(np.sum(masses * np.sum(velocities**2, axis=1)))
    i, j = np.triu_indices(len(masses), k=1)
    separations = np.linalg.norm(positions[i] - positions[j], axis=1)
    potential = -G * float(np.sum(masses[i] * masses[j] / separations))
    return kinetic, potential


def test_plummer_half_mass_radius_constant() -> None:
    assert PLUMMER_HALF_MASS_RADIUS == pytest.approx(1.3048, abs=1e-4)  # 1/sqrt(2^(2/3) - 1)


@pytest.mark.parametrize(("G", "total_mass", "scale_radius"), [(1.0, 1.0, 1.0), (4 * math.pi**2, 3.0, 0.2)])
def test_plummer_virial_equilibrium(G, total_mass, scale_radius) -> None:
    masses, positions, velocities = plummer(
        2000, seed=11, total_mass=total_mass, scale_radius=scale_radius, G=G
    )
    kinetic, potential = _kinetic_and_potential(masses, positions, velocities, G)
    # Over 200 seeds at n = 2000, 2K/|W| has standard deviation 0.018 (sampling noise); 0.1 is ~5.5 sigma.
    assert 2.0 * kinetic / abs(potential) == pytest.approx(1.0, abs=0.1)
    # W = -3 pi G M^2 / (32 a) for the model; over 100 seeds W/W_model has sd 0.017, so 0.1 is ~6 sigma.
    assert potential == pytest.approx(-3 * math.pi * G * total_mass**2 / (32 * scale_radius), rel=0.1)


def test_plummer_centre_of_mass_frame_and_masses() -> None:
    masses, positions, velocities = plummer(500, seed=3, total_mass=2.0)
    assert masses.shape == (500,) and positions.shape == (500, 3) and velocities.shape == (500, 3)
    np.testing.assert_array_equal(masses, np.full(500, 2.0 / 500))
    # Mean subtraction leaves only rounding of sums of O(1) numbers.
    np.testing.assert_allclose(masses @ positions, 0.0, atol=1e-13)
    np.testing.assert_allclose(masses @ velocities, 0.0, atol=1e-13)


def test_plummer_half_mass_radius() -> None:
    _, positions, _ = plummer(20_000, seed=5, scale_radius=2.0)
    half_mass_radius = np.median(np.linalg.norm(positions, axis=1))
    # Sample-median noise at n = 20000 is ~0.7 % (2.2 % at n = 2000 over 200 seeds); 4 % is ~5.5 sigma.
    assert half_mass_radius == pytest.approx(PLUMMER_HALF_MASS_RADIUS * 2.0, rel=0.04)


def test_plummer_truncation_caps_radius() -> None:
    _, positions, _ = plummer(20_000, seed=9)
    # m < 0.999 means r < 0.999^(1/3) / sqrt(1 - 0.999^(2/3)) ~= 38.7; the COM shift is ~0.01.
    assert np.linalg.norm(positions, axis=1).max() < 38.8


def test_plummer_is_bound() -> None:
    masses, positions, velocities = plummer(1000, seed=2)
    kinetic, potential = _kinetic_and_potential(masses, positions, velocities, 1.0)
    assert kinetic + potential < 0.0


def test_plummer_reproducible() -> None:
    first = plummer(300, seed=42)
    second = plummer(300, seed=42)
    other = plummer(300, seed=43)
    for a, b in zip(first, second, strict=True):
        assert a.tobytes() == b.tobytes()  # identical bits
    assert not np.array_equal(first[1], other[1])
    assert not np.array_equal(first[2], other[2])


@pytest.mark.parametrize(
    "kwargs",
    [{"n": 0}, {"n": 10, "total_mass": -1.0}, {"n": 10, "scale_radius": 0.0}, {"n": 10, "G": math.nan},
     {"n": 10, "max_mass_fraction": 1.5}, {"n": 10, "max_mass_fraction": 0.0}],
)
def test_plummer_rejects_bad_input(kwargs) -> None:
    with pytest.raises(ValueError):
        plummer(seed=0, **kwargs)


def test_disc_layout() -> None:
    masses, positions, velocities = disc(200, seed=1, central_mass=2.0, r_min=1.0, r_max=3.0)
    assert masses.shape == (201,) and positions.shape == (201, 3) and velocities.shape == (201, 3)
    assert masses[0] == 2.0 and np.all(masses[1:] == 0.0)
    assert np.all(positions[0] == 0.0) and np.all(velocities[0] == 0.0)
    radii = np.linalg.norm(positions[1:], axis=1)
    assert radii.min() >= 1.0 and radii.max() <= 3.0
    # Flat and circular when e_max = inc_max_deg = 0: z = 0 exactly, v perpendicular to r to rounding.
    assert np.all(positions[1:, 2] == 0.0)
    np.testing.assert_allclose(np.sum(positions[1:] * velocities[1:], axis=1), 0.0, atol=1e-14)


def test_disc_circular_energy() -> None:
    G, mass = 4 * math.pi**2, 1.0
    _, positions, velocities = disc(500, seed=4, central_mass=mass, r_min=0.5, r_max=5.0, G=G)
    r = np.linalg.norm(positions[1:], axis=1)
    energy = 0.5 * np.sum(velocities[1:] ** 2, axis=1) - G * mass / r
    # Circular: a = r, and E = -GM/(2a) holds to rounding.
    np.testing.assert_allclose(energy, -G * mass / (2.0 * r), rtol=1e-13)


def test_disc_eccentric_inclined_elements() -> None:
    G, mass, r_min, r_max = 1.0, 1.5, 1.0, 2.0
    _, positions, velocities = disc(
        300, seed=8, central_mass=mass, r_min=r_min, r_max=r_max, G=G, e_max=0.2, inc_max_deg=10.0
    )
    for r, v in zip(positions[1:], velocities[1:], strict=True):
        energy = 0.5 * v @ v - G * mass / np.linalg.norm(r)
        semi_major_axis = -G * mass / (2.0 * energy)
        el = cartesian_to_elements(G * mass, r, v)
        # E = -GM/(2a) with a the drawn semi-major axis; recovered to rounding (margins 1e-12).
        assert r_min - 1e-12 <= semi_major_axis <= r_max + 1e-12
        assert el["a"] == pytest.approx(semi_major_axis, rel=1e-12)
        assert el["e"] <= 0.2 + 1e-12
        assert el["inc"] <= 10.0 + 1e-9  # degrees


def test_disc_uniform_in_area() -> None:
    _, positions, _ = disc(20_000, seed=6, r_min=1.0, r_max=3.0)
    r_squared = np.sum(positions[1:] ** 2, axis=1)
    # r^2 is uniform on [1, 9]: mean 5, sd 2.31; the sample mean's sd is 0.016, tolerance 0.1 is ~6 sigma.
    assert r_squared.mean() == pytest.approx(5.0, abs=0.1)


def test_disc_reproducible() -> None:
    first = disc(100, seed=7, r_min=1.0, r_max=2.0, e_max=0.1, inc_max_deg=5.0)
    second = disc(100, seed=7, r_min=1.0, r_max=2.0, e_max=0.1, inc_max_deg=5.0)
    other = disc(100, seed=8, r_min=1.0, r_max=2.0, e_max=0.1, inc_max_deg=5.0)
    for a, b in zip(first, second, strict=True):
        assert a.tobytes() == b.tobytes()  # identical bits
    assert not np.array_equal(first[1], other[1])


@pytest.mark.parametrize(
    "kwargs",
    [{"n": 0}, {"r_min": 0.0}, {"r_min": 3.0, "r_max": 2.0}, {"e_max": 1.0}, {"e_max": -0.1},
     {"inc_max_deg": 190.0}, {"central_mass": 0.0}],
)
def test_disc_rejects_bad_input(kwargs) -> None:
    arguments = {"n": 10, "r_min": 1.0, "r_max": 2.0} | kwargs
    with pytest.raises(ValueError):
        disc(seed=0, **arguments)
