"""Reference planes: the Earth's mean equator (ICRF, DE421's axes) and the J2000 mean ecliptic.

Both frames share the x axis (the equinox); the ecliptic one is the equatorial one rotated about
x by the obliquity of the ecliptic at J2000, taken as the IAU 2006 value
epsilon_0 = 84381.406 arcsec (IAU 2006 Resolution B1; Hilton et al. 2006, Celest. Mech. 94, 351):

    x_ecl = R_x(epsilon_0) x_equ,   R_x(e) = [[1, 0, 0], [0, cos e, sin e], [0, -sin e, cos e]].

(DE421's axes are ICRF, which differ from the J2000 mean equator by ~20 mas: far below what an
element catalogue resolves, so no frame bias is applied.)
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["AXES", "OBLIQUITY_ARCSEC", "rotate"]

#: The planes a scenario's x-y plane, an ephemeris or a body's elements may refer to.
AXES = ("equatorial", "ecliptic")
#: Obliquity of the ecliptic at J2000 in arcseconds (IAU 2006 Resolution B1).
OBLIQUITY_ARCSEC = 84381.406
_EPS = math.radians(OBLIQUITY_ARCSEC / 3600.0)
_EQU_TO_ECL = np.array([[1.0, 0.0, 0.0],
                        [0.0, math.cos(_EPS), math.sin(_EPS)],
                        [0.0, -math.sin(_EPS), math.cos(_EPS)]])


def rotate(vectors: np.ndarray, source: str, target: str) -> np.ndarray:
    """``vectors`` (..., 3) given in ``source`` axes, expressed in ``target`` axes (a copy when they differ;
    the same array when they agree, so a scenario that rotates nothing keeps its bits)."""
    if source == target:
        return vectors
    matrix = _EQU_TO_ECL if source == "equatorial" else _EQU_TO_ECL.T
    return np.asarray(vectors, dtype=np.float64) @ matrix.T
