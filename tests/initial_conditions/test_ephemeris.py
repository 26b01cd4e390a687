"""Tests for orbitsim.initial_conditions.ephemeris (JPL DE421 via jplephem, offline)."""

from __future__ import annotations

import dataclasses
import subprocess
import sys

import numpy as np
import pytest

pytest.importorskip("jplephem")
pytest.importorskip("de421")

from orbitsim.initial_conditions.ephemeris import (
    EPHEMERIS_BODIES,
    J2000_JD,
    de421_states,
    epoch_to_jd,
)

MAJOR_BODIES = (
    "sun", "mercury", "venus", "earthmoon", "mars", "jupiter", "saturn", "uranus", "neptune", "pluto",
)
KM_PER_AU = 149_597_870.7  # for order-of-magnitude checks only


def test_sun_earth_distance_at_j2000() -> None:
    states = de421_states(["sun", "earth"], J2000_JD)
    distance = np.linalg.norm(states.positions[1] - states.positions[0])
    # Earth is two days before perihelion (0.98329 au) at J2000; published value 0.98333 au.
    assert distance == pytest.approx(0.98333, abs=1e-4)


def test_major_bodies_are_barycentric() -> None:
    states = de421_states(MAJOR_BODIES, J2000_JD)
    total_gm = states.gm.sum()
    centre = (states.gm[:, None] * states.positions).sum(axis=0) / total_gm
    drift = (states.gm[:, None] * states.velocities).sum(axis=0) / total_gm
    # Asteroid masses and relativistic mass terms left out of this sum shift it by ~1e-9 au.
    assert np.linalg.norm(centre) < 1e-6
    assert np.linalg.norm(drift) < 1e-8  # au/day, same reason (Sun moves ~1e-5 au/day)


def test_earth_and_moon_reproduce_the_earth_moon_barycentre() -> None:
    states = de421_states(["earth", "moon", "earthmoon"], J2000_JD)
    gm_earth, gm_moon, gm_emb = states.gm
    # GM_earth + GM_moon = GMB exactly up to rounding.
    assert gm_earth + gm_moon == pytest.approx(gm_emb, rel=1e-15)
    # EMRAT = M_earth / M_moon ~ 81.30 for DE421.
    assert gm_earth / gm_moon == pytest.approx(81.3005690699153, rel=1e-12)
    for arrays in (states.positions, states.velocities):
        barycentre = (gm_earth * arrays[0] + gm_moon * arrays[1]) / gm_emb
        # Linear recombination of the same numbers: rounding only.
        np.testing.assert_allclose(barycentre, arrays[2], rtol=0, atol=1e-14)
    separation_km = np.linalg.norm(states.positions[1] - states.positions[0]) * KM_PER_AU
    assert 356_000 < separation_km < 407_000  # lunar perigee/apogee bounds


def test_units_are_au_and_au_per_day() -> None:
    states = de421_states(["earth"], J2000_JD)
    speed_km_s = np.linalg.norm(states.velocities[0]) * KM_PER_AU / 86_400.0
    # Earth's barycentric speed is 29.3-30.3 km/s over the year.
    assert 29.0 < speed_km_s < 31.0


def test_gm_sun_is_gaussian_constant_squared() -> None:
    states = de421_states(["sun"], J2000_JD)
    # DE421 adopts GMS = k^2 exactly in au^3/d^2; only the printed digits differ.
    assert states.gm[0] == pytest.approx(0.01720209895**2, rel=1e-9)


def test_all_bodies_and_output_layout() -> None:
    states = de421_states(EPHEMERIS_BODIES, J2000_JD)
    n = len(EPHEMERIS_BODIES)
    assert states.names == EPHEMERIS_BODIES
    assert states.gm.shape == (n,) and states.positions.shape == (n, 3) and states.velocities.shape == (n, 3)
    assert np.all(states.gm > 0) and np.all(np.isfinite(states.positions))
    assert states.jd == J2000_JD
    with pytest.raises(dataclasses.FrozenInstanceError):
        states.jd = 0.0  # type: ignore[misc]
    with pytest.raises(ValueError):
        states.positions[0, 0] = 1.0  # arrays are read-only


def test_order_follows_request() -> None:
    forward = de421_states(["jupiter", "sun"], J2000_JD)
    backward = de421_states(["sun", "jupiter"], J2000_JD)
    np.testing.assert_array_equal(forward.positions[::-1], backward.positions)


def test_unknown_body_lists_valid_names() -> None:
    with pytest.raises(ValueError, match="valid names are: sun, mercury"):
        de421_states(["sun", "vulcan"], J2000_JD)
    with pytest.raises(TypeError):
        de421_states("sun", J2000_JD)


@pytest.mark.parametrize("jd", [2_400_000.5, 2_600_000.5, float("nan")])
def test_epoch_outside_span_raises(jd) -> None:
    with pytest.raises(ValueError, match="outside the DE421 span"):
        de421_states(["sun"], jd)


@pytest.mark.parametrize(
    ("epoch", "jd"),
    [
        ("2000-01-01T12:00:00", 2451545.0),
        ("2000-01-01", 2451544.5),
        ("2000-01-01 18:00", 2451545.25),
        ("1999-12-31T12:00:00.000000", 2451544.0),
        ("2024-03-01T00:00:00", 2460370.5),
        ("1900-01-01T12:00:00", 2415021.0),
    ],
)
def test_epoch_to_jd(epoch, jd) -> None:
    assert epoch_to_jd(epoch) == jd


@pytest.mark.parametrize(
    "bad", ["", "yesterday", "2000-13-01", "2000-01-01T25:00:00", "2000-01-01T00:00:00+01:00"]
)
def test_epoch_to_jd_rejects_bad_strings(bad) -> None:
    with pytest.raises(ValueError):
        epoch_to_jd(bad)


def test_import_does_not_load_numba_or_jplephem() -> None:
    code = (
        "import sys, orbitsim.initial_conditions, orbitsim.units;"
        "print(sorted(m for m in sys.modules if m.split('.')[0] in ('numba', 'jplephem', 'de421')))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"
