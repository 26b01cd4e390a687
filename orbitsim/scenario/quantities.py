"""Numbers a user writes with a unit: ``m: "1 Mjup"``, ``a: "7000 km"``, ``inc: "90 deg"``, ``dt: "1 day"``,
a disc's ``density: "3 g/cm3"``.

A plain number is returned as it is (the same bits, so existing scenarios resolve unchanged).
A string ``"<number> <unit>"`` is converted into the scenario's unit system with
``astropy.units``, whose solar-system masses and radii are the IAU 2015 Resolution B3 nominal
values (``M_jup = GM_jup / G`` etc.) and whose G is CODATA's. astropy.units costs 0.8-1.1 s to import
(measured with -X importtime), so it is imported only here, and only when a string with a unit
is met: the CLI's start-up and every all-numbers scenario never pay for it.

Unit names are case-insensitive, so they are looked up in :data:`UNIT_NAMES`, an explicit table
from the lower-cased name to astropy's (astropy itself is case-sensitive, and a blind
lower-casing would confuse ``Mm`` with ``mm``: the table simply has no such pairs).
"""

from __future__ import annotations

import math
import re
from typing import Any

from orbitsim.scenario.errors import ScenarioError
from orbitsim.scenario.fields import check_number, describe
from orbitsim.units import GAUSSIAN_YEAR_DAYS, UNIT_SYSTEMS

__all__ = ["ANGLE_UNITS", "UNIT_NAMES", "QuantityReader", "parse_angle", "scenario_time", "unit_factor",
           "wall_seconds"]

#: Lower-cased unit name -> (kind, astropy unit expression). Kinds: mass, length, time.
UNIT_NAMES: dict[str, tuple[str, str]] = {
    "kg": ("mass", "kg"), "g": ("mass", "g"),
    "msun": ("mass", "M_sun"), "msol": ("mass", "M_sun"), "m_sun": ("mass", "M_sun"),
    "mjup": ("mass", "M_jup"), "mjupiter": ("mass", "M_jup"), "m_jup": ("mass", "M_jup"),
    "mearth": ("mass", "M_earth"), "m_earth": ("mass", "M_earth"),
    "m": ("length", "m"), "cm": ("length", "cm"), "km": ("length", "km"), "au": ("length", "au"),
    "pc": ("length", "pc"), "kpc": ("length", "kpc"), "ly": ("length", "lyr"), "lyr": ("length", "lyr"),
    "rsun": ("length", "R_sun"), "rjup": ("length", "R_jup"), "rearth": ("length", "R_earth"),
    "s": ("time", "s"), "min": ("time", "min"), "h": ("time", "h"), "hr": ("time", "h"),
    "d": ("time", "day"), "day": ("time", "day"), "days": ("time", "day"),
    # astropy's yr is the Julian year (365.25 d); orbitsim's own time unit in au-yr-msun is the
    # Gaussian year, which a user never writes by name.
    "yr": ("time", "yr"), "year": ("time", "yr"), "years": ("time", "yr"), "kyr": ("time", "kyr"),
    "myr": ("time", "Myr"),
}
#: What each kind of key accepts, for error messages.
_KIND_UNITS = {"mass": "kg, Msun, Mjup, Mearth", "length": "m, km, au, Rsun, Rjup, Rearth, pc",
               "speed": "km/s, m/s, au/day, au/yr", "time": "s, min, h, day, yr, kyr, Myr",
               "density": "g/cm3, kg/m3, Msun/au3"}
ANGLE_UNITS = ("deg", "rad")
_ANGLE_NAMES = {"deg": "deg", "degree": "deg", "degrees": "deg", "rad": "rad", "radian": "rad", "radians": "rad"}
# The unit starts with a letter; digits, ^ and * follow only for a density's cube (g/cm3, kg/m^3).
_QUANTITY_RE = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*([A-Za-z_][A-Za-z0-9_/^* ]*?)\s*$")
#: The cube of a length in a density's unit: ``cm3``, ``cm^3``, ``cm**3``.
_CUBE_RE = re.compile(r"^([a-z_]+)(?:3|\^3|\*\*3)$")
#: Base units of each system: (length, mass, time in astropy's expressions, time factor).
#: au-yr-msun's year is the Gaussian year 2 pi / k days (orbitsim.units), in which G = 4 pi^2.
_SYSTEM_BASES = {"au-yr-msun": ("au", "M_sun", "day", "gaussian_year"), "au-day-msun": ("au", "M_sun", "day", None),
                 "si": ("m", "kg", "s", None)}


#: An example of a number with a unit of each kind, for error messages.
_EXAMPLES = {"mass": '"1 Mjup"', "length": '"7000 km"', "speed": '"30 km/s"', "time": '"10 yr" or "1 day"',
             "density": '"2 g/cm3"', "angle": '"90 deg"'}


def _split(text: str, key: str, kind: str | None = None) -> tuple[float, str]:
    """``"1.5 Mjup"`` -> (1.5, "mjup"); anything else is an error naming ``key``."""
    match = _QUANTITY_RE.match(text)
    if not match:
        example = _EXAMPLES.get(kind or "", '"1 Mjup" or "7000 km"')
        raise ScenarioError(f"expected a number or a number with a unit such as {example}, got "
                            f"{describe(text)}", key=key)
    return float(match.group(1)), "".join(match.group(2).split()).casefold()


def unit_factor(unit: str, kind: str, units: str, key: str) -> float:
    """How many of the scenario's ``units`` one ``unit`` (a lower-cased name) of ``kind`` is."""
    if kind == "speed":
        length, _, time = unit.partition("/")
        if not time:
            raise ScenarioError(f"a speed needs a unit such as km/s, got {unit!r}", key=key)
        return unit_factor(length, "length", units, key) / unit_factor(time, "time", units, key)
    if kind == "density":
        mass, _, volume = unit.partition("/")
        cube = _CUBE_RE.match(volume)
        if cube is None:
            raise ScenarioError(f"a density needs a mass over a length cubed, such as g/cm3 or kg/m3, got {unit!r}",
                                key=key)
        return unit_factor(mass, "mass", units, key) / unit_factor(cube.group(1), "length", units, key) ** 3
    found = UNIT_NAMES.get(unit)
    if found is None or found[0] != kind:
        what = "unknown unit" if found is None else f"{unit!r} is a {found[0]}, not a"
        raise ScenarioError(f"{what} {kind if found else repr(unit)}; {kind} units: {_KIND_UNITS[kind]} (any case)",
                            key=key)
    if units not in _SYSTEM_BASES:
        raise ScenarioError(f"units: {units} has no physical scale, so {unit!r} cannot be converted: give a number "
                            "or use units au-yr-msun, au-day-msun or si", key=key)
    import astropy.units as u  # noqa: PLC0415 -- lazy: loads astropy (~1 s, paid only by scenarios that write units)

    length, mass, time, time_scale = _SYSTEM_BASES[units]
    target = {"mass": mass, "length": length, "time": time}[kind]
    factor = float((1.0 * u.Unit(found[1])).to_value(u.Unit(target)))
    if kind == "time" and time_scale == "gaussian_year":
        factor /= GAUSSIAN_YEAR_DAYS
    return factor


class QuantityReader:
    """Reads numbers that may carry a unit, for one scenario's unit system and angle unit.

    Parameters
    ----------
    units : str
        The scenario's unit system (a key of :data:`orbitsim.units.UNIT_SYSTEMS`).
    angles : str
        ``"deg"`` or ``"rad"``: the unit of angles written as plain numbers.
    own_G : bool
        Whether the scenario overrides G: its time unit is then not the one ``units`` names, so
        speeds and times with a unit are refused (masses and lengths still convert).
    """

    def __init__(self, units: str, angles: str = "deg", own_G: bool = False) -> None:
        self.units = units
        self.angles = angles
        self.own_G = own_G

    def number(self, value: Any, key: str, kind: str, *, minimum: float | None = None,
               positive: bool = False) -> float:
        """``value`` in the scenario's units: a number as is, or ``"<number> <unit>"`` converted."""
        if not isinstance(value, str):
            return check_number(value, key, minimum=minimum, positive=positive)
        number, unit = _split(value, key, kind)
        if self.own_G and kind in ("speed", "time"):
            raise ScenarioError(f"this scenario sets its own G, so its time unit is not the one units: {self.units} "
                                f"names and {value!r} cannot be converted: give a number", key=key)
        converted = number * unit_factor(unit, kind, self.units, key)
        if not math.isfinite(converted):
            raise ScenarioError(f"{value!r} overflows float64 in units {self.units}", key=key)
        return check_number(converted, key, minimum=minimum, positive=positive)

    @property
    def angle_words(self) -> str:
        """The angle unit for messages: ``"angles in degrees (angles: deg)"``."""
        return f"angles in {'degrees' if self.angles == 'deg' else 'radians'} (angles: {self.angles})"

    def angle(self, value: Any, key: str) -> float:
        """An angle in degrees (what the elements code takes): see :func:`parse_angle`."""
        return parse_angle(value, key, self.angles)


def parse_angle(value: Any, key: str, angles: str) -> float:
    """An angle in degrees from a number in the scenario's ``angles`` unit or ``"90 deg"``/``"1.57 rad"``.

    A number in degrees is returned as it is (same bits); radians are converted with
    :func:`math.degrees` (the elements code converts back with :func:`math.radians`).
    """
    if isinstance(value, str):
        number, unit = _split(value, key, "angle")
        unit = _ANGLE_NAMES.get(unit, "")
        if not unit:
            raise ScenarioError(f"unknown angle unit in {value!r}; use deg or rad (any case)", key=key)
        return number if unit == "deg" else math.degrees(number)
    number = check_number(value, key)
    return number if angles == "deg" else math.degrees(number)


def scenario_time(value: Any, units: str, G: float, key: str) -> float:
    """A time in a scenario's units: a number as it is (same bits), ``"10 yr"`` converted.

    ``units`` and ``G`` are the scenario's: a ``G`` other than the unit system's makes its time
    unit another one, so a time with a unit is then refused (as for :class:`QuantityReader`).
    """
    own_G = units in UNIT_SYSTEMS and G != UNIT_SYSTEMS[units].G
    return QuantityReader(units, own_G=own_G).number(value, key, "time")


def wall_seconds(value: Any, key: str) -> float:
    """A wall-clock duration in seconds (> 0): a number of seconds, or ``"10 min"``, ``"2 h"``.

    Wall time is SI seconds whatever the scenario's units, so this converts even in ``nbody``.
    """
    return QuantityReader("si").number(value, key, "time", positive=True)
