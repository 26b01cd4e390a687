"""Unit systems for the gravitational constant ``G``.

The integrators work in whatever units the caller picks; only the numerical
value of ``G`` changes.  This module names the systems the project supports
and records where each value of ``G`` comes from.

References
----------
.. [1] Hénon, M. (1971), "The Monte Carlo method", Ap&SS 14, 151
       (the N-body units with G = M = 1; see also Heggie & Mathieu 1986,
       in *The Use of Supercomputers in Stellar Dynamics*, LNP 267, 233).
.. [2] Gauss, C. F. (1809), *Theoria motus corporum coelestium*; the value of
       k is the defining constant of the astronomical unit before IAU 2012
       (IAU 1976 System of Astronomical Constants).
.. [3] Tiesinga, E. et al. (2021), "CODATA recommended values of the
       fundamental physical constants: 2018", Rev. Mod. Phys. 93, 025010.
.. [4] IAU 2012 Resolution B2 (the astronomical unit is exactly
       149 597 870 700 m).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = [
    "AU_M",
    "DAY_S",
    "GAUSSIAN_K",
    "GAUSSIAN_YEAR_DAYS",
    "JULIAN_YEAR_DAYS",
    "UNIT_SYSTEMS",
    "UnitSystem",
    "get_unit_system",
]

#: Astronomical unit in metres, exact by IAU 2012 Resolution B2 [4].
AU_M: float = 149_597_870_700.0
#: One day of 86400 SI seconds (the ephemeris/TDB day).
DAY_S: float = 86_400.0
#: Julian year in days (IAU definition, used for epochs such as J2000).
JULIAN_YEAR_DAYS: float = 365.25
#: Gaussian gravitational constant k in au^(3/2) Msun^(-1/2) day^(-1) [2].
GAUSSIAN_K: float = 0.01720209895
#: Gaussian year 2 pi / k in days: the Keplerian period of a massless body
#: at a = 1 au around one solar mass.  It is the time unit in which G = 4 pi^2
#: holds exactly, and it differs from the Julian year by about 6e-3 days.
GAUSSIAN_YEAR_DAYS: float = 2.0 * math.pi / GAUSSIAN_K


@dataclass(frozen=True)
class UnitSystem:
    """A consistent set of length, mass and time units and the value of G in them.

    Attributes
    ----------
    name : str
        Key of the system in :data:`UNIT_SYSTEMS`.
    G : float
        Gravitational constant in ``length**3 / (mass * time**2)``.
    length, mass, time : str
        Human-readable unit names.
    source : str
        Where the value of ``G`` comes from.
    """

    name: str
    G: float
    length: str
    mass: str
    time: str
    source: str


UNIT_SYSTEMS: dict[str, UnitSystem] = {
    "nbody": UnitSystem(
        name="nbody",
        G=1.0,
        length="N-body length",
        mass="N-body mass",
        time="N-body time",
        source="Hénon (1971) / Heggie & Mathieu (1986) N-body units: G = 1 by definition",
    ),
    "au-yr-msun": UnitSystem(
        name="au-yr-msun",
        G=4.0 * math.pi**2,
        length="au",
        mass="Msun",
        # G = 4 pi^2 is exact only for the Gaussian year; with the Julian year
        # it would be off by ~3e-5 relative, which matters for long runs.
        time=f"Gaussian year (2 pi / k = {GAUSSIAN_YEAR_DAYS:.7f} d)",
        source="Kepler's third law P^2 = a^3 for P in Gaussian years, a in au, M in Msun: G = 4 pi^2",
    ),
    "au-day-msun": UnitSystem(
        name="au-day-msun",
        G=GAUSSIAN_K**2,
        length="au",
        mass="Msun",
        time="day (86400 s)",
        source="Gaussian gravitational constant k = 0.01720209895 (IAU 1976): G = k^2",
    ),
    "si": UnitSystem(
        name="si",
        G=6.67430e-11,
        length="m",
        mass="kg",
        time="s",
        source="CODATA 2018 recommended value, G = 6.67430(15)e-11 m^3 kg^-1 s^-2",
    ),
}


def get_unit_system(name: str) -> UnitSystem:
    """Look up a unit system by name.

    Parameters
    ----------
    name : str
        One of the keys of :data:`UNIT_SYSTEMS` (``"nbody"``, ``"au-yr-msun"``,
        ``"au-day-msun"``, ``"si"``).

    Returns
    -------
    UnitSystem
        The matching unit system.

    Raises
    ------
    KeyError
        If ``name`` is not a known unit system; the message lists the valid names.
    """
    try:
        return UNIT_SYSTEMS[name]
    except KeyError:
        valid = ", ".join(sorted(UNIT_SYSTEMS))
        raise KeyError(f"unknown unit system {name!r}; valid names are: {valid}") from None
