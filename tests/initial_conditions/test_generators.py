"""Tests for orbitsim.initial_conditions.generators: Plummer sphere and Keplerian disc."""

from __future__ import annotations

import math

import numpy as np
import pytest

from orbitsim.initial_conditions.elements import cartesian_to_elements
from orbitsim.initial_conditions.generators import (
    PLUMMER_HALF_MASS_RADIUS,
    disc,
    plummer,
    power_law_masses,
    sphere_radii,
)


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


# -- a disc of planetesimals: power-law masses, radii from a density (issue 27, item 16) -------------------------

def _power_law_cdf(m: np.ndarray, m_min: float, m_max: float, index: float) -> np.ndarray:
    """The cumulative fraction of dN/dm ∝ m^index below m, written the plain way (a reference)."""
    p = index + 1.0
    if p == 0.0:
        return np.log(m / m_min) / math.log(m_max / m_min)
    return (m**p - m_min**p) / (m_max**p - m_min**p)


@pytest.mark.parametrize("index", [-11.0 / 6.0, -1.0, -2.5, 0.0, 0.5, 3.0])
def test_power_law_masses_invert_the_cumulative_distribution(index: float) -> None:
    """Mass k is the quantile u_k of dN/dm ∝ m^index: F(m_k) = u_k, so the masses follow the law exactly."""
    u = np.random.default_rng(11).random(20_000)
    m = power_law_masses(u, 1e-3, 1.0, index)
    assert m.min() >= 1e-3 and m.max() <= 1.0
    # The plain F loses a few digits to m^p - m_min^p over a range of 10^3 in m: 1e-12 is ~1e4 ulps of u.
    np.testing.assert_allclose(_power_law_cdf(m, 1e-3, 1.0, index), u, rtol=0, atol=1e-12)
    order = np.argsort(u)
    assert np.all(np.diff(m[order]) >= 0.0)  # a quantile function: larger u, larger mass


def test_power_law_masses_near_index_minus_one_and_steep() -> None:
    u = np.linspace(0.0, 0.999, 1000)
    log_uniform = power_law_masses(u, 1e-6, 1.0, -1.0)
    near = power_law_masses(u, 1e-6, 1.0, -1.0 + 1e-12)
    # p = 1e-12 is a log-uniform law to O(p ln(1e6)) = 1.4e-11 relative: expm1/log1p keep that, not 1e-4.
    np.testing.assert_allclose(near, log_uniform, rtol=1e-10)
    for index in (-400.0, 400.0):  # m^p alone would overflow float64 here
        steep = power_law_masses(u, 1.0, 1e6, index)
        assert np.isfinite(steep).all() and steep.min() >= 1.0 and steep.max() <= 1e6
        median = steep[500]  # u = 0.5: the bodies crowd at one end of the range
        assert median < 1.01 if index < 0 else median > 0.99e6
    assert np.array_equal(power_law_masses(u, 2.0, 2.0, 5.0), np.full(1000, 2.0))


def test_sphere_radii_give_the_earth_from_its_mass_and_density() -> None:
    # Earth: 5.9722e24 kg, mean density 5513.4 kg/m^3, mean radius 6371.0 km; the quoted values are rounded
    # to ~1e-4, so the radius agrees to that.
    assert sphere_radii(np.array([5.9722e24]), 5513.4)[0] == pytest.approx(6.3710e6, rel=2e-4)
    r = sphere_radii(np.array([1.0, 8.0]), 3.0 / (4.0 * math.pi))
    np.testing.assert_allclose(r, [1.0, 2.0], rtol=1e-15)  # r^3 = 3 m / (4 pi rho): unit sphere, twice the radius


def test_massive_disc_keeps_the_orbits_of_the_test_disc() -> None:
    """Masses are drawn after the orbits: same positions, to the bit, and velocities scaled by
    sqrt((M + m) / M), the two-body gm of each body."""
    kwargs = {"seed": 5, "central_mass": 2.0, "r_min": 1.0, "r_max": 3.0, "e_max": 0.2, "inc_max_deg": 5.0}
    m0, x0, v0 = disc(300, **kwargs)
    m, x, v = disc(300, m_min=1e-6, m_max=1e-2, mass_index=-2.0, **kwargs)
    assert np.array_equal(x, x0) and m[0] == 2.0 and not m0[1:].any()
    assert m[1:].min() >= 1e-6 and m[1:].max() <= 1e-2
    scale = np.sqrt((2.0 + m[1:]) / 2.0)
    # A few roundings apart, relative to each body's speed (a small component carries a cancellation of P and Q).
    error = np.abs(v[1:] - v0[1:] * scale[:, None]).max(axis=1) / np.linalg.norm(v[1:], axis=1)
    assert error.max() <= 1e-14
    again = disc(300, m_min=1e-6, m_max=1e-2, mass_index=-2.0, **kwargs)
    assert all(a.tobytes() == b.tobytes() for a, b in zip((m, x, v), again, strict=True))  # the seed fixes the bits
    other = disc(300, m_min=1e-6, m_max=1e-2, mass_index=-2.0, **{**kwargs, "seed": 6})
    assert not np.array_equal(other[0], m)
    for el, gm in ((cartesian_to_elements(2.0 + m[k], x[k], v[k]), 2.0 + m[k]) for k in (1, 100, 299)):
        assert el["a"] >= 1.0 - 1e-12 and el["e"] <= 0.2 + 1e-12, gm  # the drawn orbit, about M + m


@pytest.mark.parametrize(
    "kwargs",
    [{"m_min": 1e-6}, {"m_max": 1e-6}, {"m_min": 0.0, "m_max": 1.0, "mass_index": -2.0},
     {"m_min": 2.0, "m_max": 1.0, "mass_index": -2.0}, {"m_min": 1e-6, "m_max": 1.0},
     {"m_min": 1e-6, "m_max": 1.0, "mass_index": math.inf}],
)
def test_disc_rejects_a_bad_mass_distribution(kwargs) -> None:
    with pytest.raises(ValueError):
        disc(10, seed=0, r_min=1.0, r_max=2.0, **kwargs)


def test_planetesimal_disc_in_a_scenario_converts_units_and_gives_radii() -> None:
    u = pytest.importorskip("astropy.units")
    from orbitsim.scenario import scenario_from_dict

    generator = {"kind": "disc", "n": 400, "seed": 2, "r_min": 1, "r_max": 2, "m_min": "1e-3 Mearth",
                 "m_max": "1 Mearth", "mass_index": -11 / 6, "density": "3 g/cm3", "star_r": "1 Rsun"}
    s = scenario_from_dict({"units": "au-yr-msun", "integrator": "verlet", "dt": 0.01, "steps": 1,
                            "generator": generator})
    mearth = (1.0 * u.M_earth).to_value(u.M_sun)
    rho = (3.0 * u.g / u.cm**3).to_value(u.M_sun / u.au**3)
    assert s.masses[1:].min() >= 1e-3 * mearth and s.masses[1:].max() <= mearth
    np.testing.assert_allclose(s.radii[1:], sphere_radii(s.masses[1:], rho), rtol=1e-15)  # rho is astropy's
    assert s.radii[0] == pytest.approx((1.0 * u.R_sun).to_value(u.au), rel=1e-15)
    # A 1 Mearth rock of 3 g/cm^3 is 7800 km across its radius: the units are right end to end.
    r_earth_mass = sphere_radii(np.array([mearth]), rho)[0] * (1.0 * u.au).to_value(u.km)
    assert r_earth_mass == pytest.approx(7.80e3, rel=1e-3)
    from orbitsim.scenario.yamlio import parse_yaml

    again = scenario_from_dict(parse_yaml(s.to_yaml(), "resolved")[0])  # the resolved text keeps masses and radii
    assert again.sha256 == s.sha256 and np.array_equal(again.radii, s.radii) and np.array_equal(again.masses, s.masses)


def test_generated_radii_collide_with_events(tmp_path) -> None:
    """A crowded ring of planetesimals whose radii come from a density: ``events.collisions`` merges them."""
    import h5py
    from click.testing import CliRunner

    from orbitsim.cli.main import cli

    path = tmp_path / "ring.yaml"
    # 30 bodies of 1e-5 on a ring 1.02 wide; density 0.0884 gives r = 0.03 each, so neighbours touch.
    path.write_text("""\
name: ring
integrator: verlet
dt: 0.001
steps: 200
events: {collisions: {detect: line, resolve: merge}}
generator: {kind: disc, n: 30, seed: 4, r_min: 1.0, r_max: 1.02, m_min: 1.0e-5, m_max: 1.0e-5, density: 0.0884}
""", encoding="utf-8")
    out = tmp_path / "ring.h5"
    result = CliRunner().invoke(cli, ["run", str(path), "-o", str(out)])
    assert result.exit_code == 0, result.output
    assert "collisions (disc" in result.output and "merged at t = " in result.output
    with h5py.File(out, "r") as f:
        kinds = [k.decode() if isinstance(k, bytes) else k for k in f["events"]["kind"][()]]
    assert len(kinds) >= 1 and set(kinds) == {"collision"}, kinds
