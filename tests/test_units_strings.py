"""Masses, lengths, speeds and angles written with a unit (``m: "1 Mjup"``), checked against astropy."""

from __future__ import annotations

import math
import subprocess
import sys

import pytest

from orbitsim.scenario import ScenarioError, scenario_from_dict
from orbitsim.scenario.quantities import UNIT_NAMES, QuantityReader, unit_factor
from orbitsim.units import GAUSSIAN_YEAR_DAYS

u = pytest.importorskip("astropy.units")
const = pytest.importorskip("astropy.constants")

#: astropy's base unit of each kind in each system (the time of au-yr-msun is the Gaussian year: days / 2 pi k).
_TARGETS = {"si": {"mass": "kg", "length": "m", "time": "s"},
            "au-day-msun": {"mass": "M_sun", "length": "au", "time": "day"},
            "au-yr-msun": {"mass": "M_sun", "length": "au", "time": "day"}}


def _doc(body: dict, units: str = "au-yr-msun", **top: object) -> dict:
    return {"units": units, "integrator": "verlet", "dt": 0.01, "steps": 1, **top,
            "bodies": [{"name": "star", "m": 1.0, "x": [0, 0, 0], "v": [0, 0, 0]}, {"name": "b", **body}]}


def test_one_jupiter_mass_is_the_iau_2015_nominal_ratio() -> None:
    """1 Mjup in au-yr-msun is GM_jup / GM_sun of IAU 2015 Resolution B3 (both exact nominal values)."""
    s = scenario_from_dict(_doc({"m": "1 Mjup", "x": [1, 0, 0], "v": [0, 6, 0]}))
    assert s.masses[1] == pytest.approx(1.2668653e17 / 1.3271244e20, rel=4e-16)  # one rounding of astropy's kg
    assert s.masses[1] == pytest.approx(9.545942e-4, abs=5e-11)  # the ratio to the 7 digits it is quoted with
    # The issue quotes 9.547919e-4 = 1 / 1047.348644: the IAU 2009 / DE421 mass of Jupiter's *system*
    # (with its satellites), not IAU 2015's planet. They differ by 2.1e-4 relative; both are pinned here so
    # that the choice is visible and cannot change silently.
    assert s.masses[1] / (1.0 / 1047.348644) == pytest.approx(1.0 - 2.07e-4, abs=1e-6)


@pytest.mark.parametrize("units", list(_TARGETS))
@pytest.mark.parametrize("name", sorted(UNIT_NAMES))
def test_every_unit_name_matches_astropy(name: str, units: str) -> None:
    kind, expr = UNIT_NAMES[name]
    expected = (1.0 * u.Unit(expr)).to_value(u.Unit(_TARGETS[units][kind]))
    if kind == "time" and units == "au-yr-msun":
        expected /= GAUSSIAN_YEAR_DAYS
    for spelling in (name, name.upper(), name.capitalize()):  # names are case-insensitive
        assert unit_factor(spelling.casefold(), kind, units, "k") == pytest.approx(expected, rel=1e-15)


@pytest.mark.parametrize(("text", "kind", "units", "expected"), [
    ("5.97e24 kg", "mass", "au-yr-msun", 5.97e24 / const.M_sun.value),
    ("1 Mearth", "mass", "si", const.M_earth.value),
    ("0.5 MSUN", "mass", "au-day-msun", 0.5),
    ("1 au", "length", "si", 149597870700.0),
    ("7000 km", "length", "si", 7.0e6),
    ("30 km/s", "speed", "si", 3.0e4),
    ("30 KM/S", "speed", "au-day-msun", 30e3 * 86400 / 149597870700.0),
    ("1 au/yr", "speed", "au-yr-msun", GAUSSIAN_YEAR_DAYS / 365.25),  # astropy's yr is Julian
])
def test_strings_convert_into_the_scenario_units(text: str, kind: str, units: str, expected: float) -> None:
    assert QuantityReader(units).number(text, "k", kind) == pytest.approx(expected, rel=1e-15)


def test_units_in_a_scenario_file_convert_every_key() -> None:
    s = scenario_from_dict(_doc({"m": "1 Mearth", "x": ["1 au", 0, 0], "v": [0, "29.78 km/s", 0], "r": "6371 km"},
                                units="au-day-msun"))
    assert s.masses[1] == pytest.approx(const.M_earth.value / const.M_sun.value, rel=1e-15)
    assert s.positions[1, 0] == 1.0
    assert s.velocities[1, 1] == pytest.approx(29.78e3 * 86400 / 149597870700.0, rel=1e-15)
    assert s.radii[1] == pytest.approx(6371e3 / 149597870700.0, rel=1e-15)


def test_numbers_keep_their_bits() -> None:
    s = scenario_from_dict(_doc({"m": 0.1 + 0.2, "x": [1.1, 0, 0], "v": [0, 6.2, 0]}))
    assert s.masses[1] == 0.1 + 0.2 and s.positions[1, 0] == 1.1


@pytest.mark.parametrize(("body", "units", "key", "words"), [
    ({"m": "1 Mjup", "x": [1, 0, 0], "v": [0, 1, 0]}, "nbody", "bodies[1].m", "no physical scale"),
    ({"m": "1 km", "x": [1, 0, 0], "v": [0, 1, 0]}, "si", "bodies[1].m", "'km' is a length, not a mass"),
    ({"m": "1 furlong", "x": [1, 0, 0], "v": [0, 1, 0]}, "si", "bodies[1].m", "unknown unit"),
    ({"m": "heavy", "x": [1, 0, 0], "v": [0, 1, 0]}, "si", "bodies[1].m", "expected a number"),
    ({"m": 1, "x": [1, 0, 0], "v": [0, "3 km", 0]}, "si", "bodies[1].v[1]", "a speed needs a unit"),
    ({"m": "-1 kg", "x": [1, 0, 0], "v": [0, 1, 0]}, "si", "bodies[1].m", "mass must be >= 0"),
])
def test_bad_units_name_the_key(body: dict, units: str, key: str, words: str) -> None:
    with pytest.raises(ScenarioError) as err:
        scenario_from_dict(_doc(body, units=units), source="f.yaml")
    text = str(err.value)
    assert text.startswith(f"f.yaml: {key}: ") and words in text and "\n" not in text


def test_a_scenario_with_its_own_g_refuses_speeds_with_units() -> None:
    with pytest.raises(ScenarioError, match=r"bodies\[1\]\.v\[1\]: this scenario sets its own G"):
        scenario_from_dict(_doc({"m": 1e-3, "x": [1, 0, 0], "v": [0, "30 km/s", 0]}, G=1.0))


def test_astropy_is_imported_only_for_strings_with_units() -> None:
    code = ("import sys; from orbitsim.scenario import scenario_from_dict; "
            "scenario_from_dict({'integrator': 'verlet', 'dt': 0.1, 'steps': 1, 'bodies': ["
            "{'name': 'a', 'm': 1, 'x': [0, 0, 0], 'v': [0, 0, 0]}, {'name': 'b', 'm': 1, 'primary': 'a', "
            "'a': 1, 'inc': '90 deg', 'M': 0}]}); print('astropy' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "False"
    cli = subprocess.run([sys.executable, "-c", "import sys, orbitsim.cli.main; print('astropy' in sys.modules)"],
                         capture_output=True, text=True, check=True).stdout
    assert cli.strip() == "False"


def test_angle_strings_and_radians() -> None:
    base = {"m": 0.0, "primary": "star", "a": 1.0, "M": 0}
    deg = scenario_from_dict(_doc({**base, "inc": 90}))
    rad = scenario_from_dict(_doc({**base, "inc": math.pi / 2}, angles="rad"))
    text = scenario_from_dict(_doc({**base, "inc": "1.5707963267948966 RAD"}))
    for s in (rad, text):  # pi/2 -> 90 deg -> pi/2 again: at most an ulp or two apart
        assert s.velocities[1] == pytest.approx(deg.velocities[1], abs=1e-14)
    assert abs(deg.velocities[1, 1]) < 1e-14  # inc = 90 deg: the orbit is in the x-z plane
