"""Tests for orbitsim.units: the values of G and their provenance."""

from __future__ import annotations

import dataclasses
import math

import pytest

from orbitsim.units import (
    AU_M,
    DAY_S,
    GAUSSIAN_K,
    GAUSSIAN_YEAR_DAYS,
    JULIAN_YEAR_DAYS,
    UNIT_SYSTEMS,
    UnitSystem,
    get_unit_system,
)


def test_expected_systems_and_values() -> None:
    assert set(UNIT_SYSTEMS) == {"nbody", "au-yr-msun", "au-day-msun", "si"}
    assert get_unit_system("nbody").G == 1.0
    assert get_unit_system("au-yr-msun").G == 4.0 * math.pi**2
    assert get_unit_system("au-day-msun").G == 0.01720209895**2
    assert get_unit_system("si").G == 6.67430e-11


def test_every_system_is_named_and_sourced() -> None:
    for key, system in UNIT_SYSTEMS.items():
        assert isinstance(system, UnitSystem)
        assert system.name == key
        assert system.source.strip()
        assert system.length and system.mass and system.time


def test_unit_system_is_frozen() -> None:
    with pytest.raises(dataclasses.FrozenInstanceError):
        get_unit_system("nbody").G = 2.0  # type: ignore[misc]


def test_unknown_name_lists_valid_names() -> None:
    with pytest.raises(KeyError) as excinfo:
        get_unit_system("cgs")
    message = str(excinfo.value)
    for name in UNIT_SYSTEMS:
        assert name in message


def test_constants() -> None:
    assert AU_M == 149_597_870_700.0
    assert DAY_S == 86_400.0
    assert JULIAN_YEAR_DAYS == 365.25
    assert GAUSSIAN_K == 0.01720209895


def test_au_year_and_au_day_systems_agree_in_gaussian_years() -> None:
    g_day = get_unit_system("au-day-msun").G
    g_year = get_unit_system("au-yr-msun").G
    # Same physics, different time unit: only rounding of pi and k separates them.
    assert g_day * GAUSSIAN_YEAR_DAYS**2 == pytest.approx(g_year, rel=1e-14)
    # The Gaussian year is not the Julian year (about 6e-3 d longer).
    assert GAUSSIAN_YEAR_DAYS - JULIAN_YEAR_DAYS == pytest.approx(0.0069, abs=1e-3)


def test_gaussian_gm_sun_matches_si_value() -> None:
    gm_sun_si = GAUSSIAN_K**2 * AU_M**3 / DAY_S**2
    # IAU 2015 nominal GM_sun; k^2 au^3/d^2 agrees to ~3e-10 since the 2012 au redefinition.
    assert gm_sun_si == pytest.approx(1.3271244e20, rel=1e-8)
