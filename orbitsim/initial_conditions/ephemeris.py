"""Solar-system initial conditions from the JPL DE421 ephemeris.

The Chebyshev coefficients ship offline in the ``de421`` PyPI package and are
evaluated by ``jplephem.ephem.Ephemeris``.  That reader returns positions in km
and velocities in km/day; planets, the Sun and the Earth-Moon barycentre (EMB)
are relative to the solar-system barycentre (SSB), while ``moon`` is geocentric.
The Earth and Moon follow from the EMB and the Earth/Moon mass ratio
:math:`\\mu = ` ``EMRAT``:

.. math::
    \\mathbf r_\\oplus = \\mathbf r_{\\rm EMB} - \\frac{1}{1+\\mu}\\,\\mathbf r_{\\rm geo},\\qquad
    \\mathbf r_{\\rm Moon} = \\mathbf r_{\\rm EMB} + \\frac{\\mu}{1+\\mu}\\,\\mathbf r_{\\rm geo},

with :math:`GM_\\oplus = GM_B\\,\\mu/(1+\\mu)` and :math:`GM_{\\rm Moon} = GM_B/(1+\\mu)`.
The header constants ``GMS``, ``GM1``..``GM9`` and ``GMB`` are already in
au^3/day^2, and ``AU`` is the number of km per au used by DE421.

References
----------
.. [1] Folkner, W. M., Williams, J. G. & Boggs, D. H. (2009), "The Planetary and
       Lunar Ephemeris DE 421", IPN Progress Report 42-178.
.. [2] Rhodes, B. (2011-), jplephem, https://github.com/brandon-rhodes/python-jplephem
"""

from __future__ import annotations

import datetime as _dt
import functools
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["EPHEMERIS_BODIES", "J2000_JD", "EphemerisStates", "de421_states", "epoch_to_jd"]

EPHEMERIS_BODIES: tuple[str, ...] = (
    "sun",
    "mercury",
    "venus",
    "earth",
    "moon",
    "earthmoon",
    "mars",
    "jupiter",
    "saturn",
    "uranus",
    "neptune",
    "pluto",
)

#: Julian date (TDB) of the J2000.0 epoch, 2000-01-01T12:00:00 TDB.
J2000_JD: float = 2451545.0
_J2000_DATETIME = _dt.datetime(2000, 1, 1, 12, 0, 0)

#: Header constant holding GM (au^3/day^2) of each body read directly from DE421.
_GM_CONSTANT = {
    "sun": "GMS",
    "mercury": "GM1",
    "venus": "GM2",
    "earthmoon": "GMB",
    "mars": "GM4",
    "jupiter": "GM5",
    "saturn": "GM6",
    "uranus": "GM7",
    "neptune": "GM8",
    "pluto": "GM9",
}


@dataclass(frozen=True)
class EphemerisStates:
    """Barycentric states of solar-system bodies at one epoch.

    Attributes
    ----------
    names : tuple of str
        Body names, in the order requested.
    gm : numpy.ndarray, shape (N,)
        :math:`G m` of each body in au^3/day^2.
    positions : numpy.ndarray, shape (N, 3)
        Positions relative to the solar-system barycentre in au, ICRF
        (equatorial) axes.
    velocities : numpy.ndarray, shape (N, 3)
        Velocities relative to the solar-system barycentre in au/day.
    jd : float
        Epoch as a Julian date in TDB.
    """

    names: tuple[str, ...]
    gm: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray
    jd: float


@functools.lru_cache(maxsize=1)
def _load_de421() -> Any:
    """Load the DE421 reader once per process (the coefficient files load lazily)."""
    import de421  # noqa: PLC0415 -- lazy: loads de421 (keeps ``import orbitsim`` free of the ephemeris packages)
    from jplephem.ephem import Ephemeris  # noqa: PLC0415 -- lazy: loads jplephem

    return Ephemeris(de421)


def _raw_state(ephemeris: Any, segment: str, jd: float) -> tuple[np.ndarray, np.ndarray]:
    """State of one DE421 segment in km and km/day (flattened from jplephem's (3, 1))."""
    position, velocity = ephemeris.position_and_velocity(segment, jd)
    return (
        np.asarray(position, dtype=np.float64).reshape(3),
        np.asarray(velocity, dtype=np.float64).reshape(3),
    )


def _body_state(ephemeris: Any, body: str, jd: float) -> tuple[float, np.ndarray, np.ndarray]:
    """GM (au^3/day^2) and barycentric state (km, km/day) of one named body."""
    if body not in ("earth", "moon"):
        r, v = _raw_state(ephemeris, body, jd)
        return float(getattr(ephemeris, _GM_CONSTANT[body])), r, v
    mass_ratio = float(ephemeris.EMRAT)  # M_earth / M_moon
    gm_emb = float(ephemeris.GMB)
    r_emb, v_emb = _raw_state(ephemeris, "earthmoon", jd)
    r_geo, v_geo = _raw_state(ephemeris, "moon", jd)  # Moon relative to Earth
    if body == "earth":
        share = -1.0 / (1.0 + mass_ratio)
        gm = gm_emb * mass_ratio / (1.0 + mass_ratio)
    else:
        share = mass_ratio / (1.0 + mass_ratio)
        gm = gm_emb / (1.0 + mass_ratio)
    return gm, r_emb + share * r_geo, v_emb + share * v_geo


def _check_request(bodies: Sequence[str], jd: float, ephemeris: Any) -> tuple[str, ...]:
    """Validate body names and the epoch; return the names as a tuple."""
    if isinstance(bodies, str):
        raise TypeError(f"bodies must be a sequence of names, not the string {bodies!r}")
    names = tuple(bodies)
    unknown = [name for name in names if name not in EPHEMERIS_BODIES]
    if unknown:
        raise ValueError(f"unknown body {unknown}; valid names are: {', '.join(EPHEMERIS_BODIES)}")
    first, last = float(ephemeris.jalpha), float(ephemeris.jomega)
    if not np.isfinite(jd) or not first <= jd <= last:
        raise ValueError(
            f"jd={jd} is outside the DE421 span {first} to {last} "
            f"({_jd_to_iso(first)} to {_jd_to_iso(last)} TDB)"
        )
    return names


def de421_states(bodies: Sequence[str], jd: float) -> EphemerisStates:
    """Barycentric positions, velocities and GM of solar-system bodies from DE421.

    Parameters
    ----------
    bodies : sequence of str
        Names from :data:`EPHEMERIS_BODIES`.  ``earthmoon`` is the Earth-Moon
        barycentre with :math:`GM = GM_B`; do not combine it with ``earth`` or
        ``moon`` in one simulation, which would count that mass twice.
    jd : float
        Julian date in TDB, within the span of the coefficient files (read from
        them: JD 2414992.5 to 2524624.5, i.e. 1899-12-04 to 2200-02-01, for the
        ``de421`` package).

    Returns
    -------
    EphemerisStates
        ``gm`` in au^3/day^2, positions in au and velocities in au/day relative
        to the solar-system barycentre, ICRF axes.

    Raises
    ------
    ValueError
        For an unknown body name (the message lists the valid ones) or a
        ``jd`` outside the ephemeris span.
    TypeError
        If ``bodies`` is a single string.

    Notes
    -----
    Kilometres are converted with DE421's own ``AU`` constant
    (149 597 870.6996262 km), so that positions and the header GM values,
    both fitted in au, stay mutually consistent (Folkner et al. 2009).
    """
    ephemeris = _load_de421()
    jd = float(jd)
    names = _check_request(bodies, jd, ephemeris)
    km_per_au = float(ephemeris.AU)
    gm = np.empty(len(names))
    positions = np.empty((len(names), 3))
    velocities = np.empty((len(names), 3))
    for i, name in enumerate(names):
        gm[i], r_km, v_km_per_day = _body_state(ephemeris, name, jd)
        positions[i] = r_km / km_per_au
        velocities[i] = v_km_per_day / km_per_au
    for array in (gm, positions, velocities):
        array.setflags(write=False)  # the dataclass is frozen; keep its arrays so too
    return EphemerisStates(names=names, gm=gm, positions=positions, velocities=velocities, jd=jd)


def epoch_to_jd(epoch: str) -> float:
    """Julian date of an ISO 8601 calendar date or date-time read as TDB.

    Parameters
    ----------
    epoch : str
        ``"YYYY-MM-DD"`` or ``"YYYY-MM-DDTHH:MM[:SS[.ffffff]]"`` (a space may
        replace ``T``).  No time-zone designator: the value is a TDB reading.

    Returns
    -------
    float
        Julian date, :math:`JD = 2451545.0 + \\Delta t / 86400\\,{\\rm s}` with
        :math:`\\Delta t` the elapsed time since 2000-01-01T12:00:00 (J2000.0)
        on the proleptic Gregorian calendar with 86400-s days (TDB has no leap
        seconds).

    Raises
    ------
    ValueError
        If the string is not an ISO date/date-time or carries a time zone.
    """
    if not isinstance(epoch, str):
        raise TypeError(f"epoch must be a string, got {type(epoch).__name__}")
    try:
        moment = _dt.datetime.fromisoformat(epoch.strip())
    except ValueError:
        raise ValueError(
            f"cannot parse epoch {epoch!r}: expected ISO 8601 such as '2000-01-01' or '2000-01-01T12:00:00'"
        ) from None
    if moment.tzinfo is not None:
        raise ValueError(f"epoch {epoch!r} has a time zone; epochs are TDB readings, give none")
    elapsed = moment - _J2000_DATETIME
    # Integral days add exactly; only the sub-day fraction is rounded (to ~40 us at JD ~2.5e6).
    return J2000_JD + elapsed.days + (elapsed.seconds + elapsed.microseconds * 1e-6) / 86400.0


def _jd_to_iso(jd: float) -> str:
    """ISO date-time (TDB) of a Julian date, for error messages."""
    moment = _J2000_DATETIME + _dt.timedelta(days=jd - J2000_JD)
    return moment.isoformat(timespec="seconds")
