"""Initial conditions: orbital elements, the DE421 ephemeris and random generators.

Importing this package pulls in numpy only; ``jplephem`` and ``de421`` are
imported on the first call to :func:`de421_states`.
"""

from orbitsim.initial_conditions.elements import cartesian_to_elements, elements_to_cartesian, solve_kepler
from orbitsim.initial_conditions.ephemeris import (
    EPHEMERIS_BODIES,
    J2000_JD,
    EphemerisStates,
    de421_states,
    epoch_to_jd,
)
from orbitsim.initial_conditions.generators import PLUMMER_HALF_MASS_RADIUS, disc, plummer

__all__ = [
    "EPHEMERIS_BODIES",
    "J2000_JD",
    "PLUMMER_HALF_MASS_RADIUS",
    "EphemerisStates",
    "cartesian_to_elements",
    "de421_states",
    "disc",
    "elements_to_cartesian",
    "epoch_to_jd",
    "plummer",
    "solve_kepler",
]
