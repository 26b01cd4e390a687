"""A body given by orbital elements: the keys a user may write and the checks on them.

One of each group must be given (or takes its default):

- size: ``a`` (semi-major axis), ``P`` (period, bound orbits only: a^3 = G (m_p + m) P^2 / 4 pi^2)
  or ``q`` (pericentre distance, a = q / (1 - e); the only choice for a parabola, e = 1);
- orientation of the pericentre: ``omega`` (argument) or ``pomega`` (longitude, pomega = Omega + omega;
  on a retrograde orbit, cos(inc) <= 0, pomega = Omega - omega, REBOUND's convention);
- position on the orbit: ``M`` or ``f`` (mean or true anomaly) or ``l`` or ``theta`` (mean or true
  longitude, l = pomega + M, theta = pomega + f; retrograde: l = pomega - M, theta = pomega - f);
  none of them means f = 0, at pericentre, REBOUND's rule (``rebound.Particle``, f = 0 when no
  anomaly or longitude is passed), and ``orbitsim validate`` says so.

Angles are in the scenario's ``angles`` unit (degrees unless ``angles: rad``), or strings
``"90 deg"``/``"1.57 rad"``; every error about an element names that unit, since a radian value
read as degrees (or the reverse) is the mistake most likely behind it. ``frame: ecliptic |
equatorial`` says which plane the elements refer to; the state is rotated into the scenario's axes.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from orbitsim.initial_conditions.elements import elements_to_cartesian
from orbitsim.scenario.body_set import BodySet
from orbitsim.scenario.errors import ScenarioError
from orbitsim.scenario.frames import AXES, rotate

if TYPE_CHECKING:
    from orbitsim.scenario.fields import Fields
    from orbitsim.scenario.quantities import QuantityReader

__all__ = ["ELEMENT_ONLY_KEYS", "elements_state"]

#: Keys that make a body an orbital-elements body.
ELEMENT_ONLY_KEYS = ("primary", "a", "P", "q", "e", "inc", "Omega", "omega", "pomega", "M", "f", "l", "theta",
                     "frame")


def elements_state(body: Fields, m: float, G: float, bodies: BodySet) -> tuple[np.ndarray, np.ndarray]:
    """The body's position and velocity in the scenario's axes: its primary's state plus the
    relative Keplerian state. Any error names the key and the scenario's angle unit."""
    words = bodies.reader.angle_words
    if words not in bodies.notes:
        bodies.notes.append(words)
    try:
        return _elements_state(body, m, G, bodies)
    except ScenarioError as err:
        raise ScenarioError(f"{err.reason} [orbital elements: {words}]", key=err.key) from None


@np.errstate(all="ignore")  # an overflow is reported as an error naming the key, not as a RuntimeWarning
def _elements_state(body: Fields, m: float, G: float, bodies: BodySet) -> tuple[np.ndarray, np.ndarray]:
    primary_name = body.string("primary")
    primary = bodies.find(primary_name)
    if primary is None:
        known = ", ".join(bodies.names[:12]) or "none yet"
        raise body.error("primary", f"unknown primary {primary_name!r}: it must be a body defined before this "
                         f"one (known: {known})")
    m_primary, x_primary, v_primary = primary
    gm = G * (m_primary + m)
    if not math.isfinite(gm):
        raise body.error("m", f"G (m_primary + m) = {G:g} * ({m_primary:g} + {m:g}) overflows float64: use units in "
                         "which the masses are smaller")
    if gm <= 0.0:
        raise body.error("m", f"{primary_name!r} and this body are both massless: orbital elements need "
                         "G (m_primary + m) > 0")
    frame = body.string("frame", bodies.axes, choices=AXES)
    size = body.one_of("a", "P", "q")
    e = body.number("e", 0.0, minimum=0.0)
    reader = bodies.reader
    angles = {k: reader.angle(body.raw(k), body.key(k)) if body.has(k) else 0.0 for k in ("inc", "Omega")}
    # Longitudes (pomega, l, theta) are measured along the orbit's direction of motion, which on a
    # retrograde orbit (cos i <= 0) runs against Omega: there pomega = Omega - omega, as in REBOUND's
    # rebound.Particle (and its reb_orbit), where a prograde orbit has pomega = Omega + omega.
    prograde = math.cos(math.radians(angles["inc"])) > 0.0  # REBOUND's test, on inc in radians
    if body.one_of("omega", "pomega", required=False) == "pomega":
        pomega = reader.angle(body.raw("pomega"), body.key("pomega"))
        angles["omega"] = pomega - angles["Omega"] if prograde else angles["Omega"] - pomega
    else:
        angles["omega"] = reader.angle(body.raw("omega"), body.key("omega")) if body.has("omega") else 0.0
    anomaly_key = body.one_of("M", "f", "l", "theta", required=False)
    if anomaly_key is None:  # REBOUND's rule: no anomaly or longitude means f = 0, at pericentre
        bodies.no_anomaly.append(f"{body.path} ({body.data.get('name')})")
        anomaly_key, anomaly = "f", 0.0
    else:
        anomaly = reader.angle(body.raw(anomaly_key), body.key(anomaly_key))
    if anomaly_key in ("l", "theta"):  # a longitude: l = Omega + omega + M (retrograde: Omega - omega - M)
        if prograde:
            anomaly -= angles["Omega"] + angles["omega"]
        else:
            anomaly = angles["Omega"] - angles["omega"] - anomaly
    kind = {"l": "M", "theta": "f"}.get(anomaly_key, anomaly_key)
    a_key = body.key(size)
    if e == 1.0:
        r, v = _parabola(body, reader, size, gm, angles, (kind, anomaly_key), anomaly)
    else:
        a = _semi_major_axis(body, reader, size, gm, e)
        try:
            r, v = elements_to_cartesian(gm, a, e, angles["inc"], angles["Omega"], angles["omega"],
                                         **{kind: anomaly})
        except ValueError as err:
            raise ScenarioError(str(err), key=body.key(anomaly_key)) from None
        except ArithmeticError:  # e.g. a = 1e-300: the state is not representable, reported below
            r = v = np.array([math.nan])
    if not (np.isfinite(r).all() and np.isfinite(v).all()):
        raise ScenarioError(f"the orbit's position or velocity overflows float64 (G (m_primary + m) = {gm:g}, "
                            f"{size} = {body.raw(size)}): use units in which these numbers are closer to 1",
                            key=a_key)
    r, v = rotate(r, frame, bodies.axes), rotate(v, frame, bodies.axes)
    return x_primary + r, v_primary + v


def _semi_major_axis(body: Fields, reader: QuantityReader, size: str, gm: float, e: float) -> float:
    """a from whichever of a, P, q was given, with the sign REBOUND uses (a < 0 for a hyperbola)."""
    if size == "a":
        a = reader.number(body.raw("a"), body.key("a"), "length")
        if (e < 1.0) != (a > 0.0):
            sign = "positive for an elliptic orbit (e < 1)" if e < 1.0 else "negative for a hyperbolic orbit (e > 1)"
            raise body.error("a", f"a must be {sign}, got a = {a:g} with e = {e:g}")
        return a
    if size == "P":
        if e >= 1.0:
            raise body.error("P", f"only a bound orbit (e < 1) has a period; give a or q for e = {e:g}")
        period = reader.number(body.raw("P"), body.key("P"), "time", positive=True)
        return (gm * period * period / (4.0 * math.pi**2)) ** (1.0 / 3.0)
    q = reader.number(body.raw("q"), body.key("q"), "length", positive=True)
    return q / (1.0 - e)  # negative for e > 1, as REBOUND's hyperbolae


def _parabola(body: Fields, reader: QuantityReader, size: str, gm: float, angles: dict[str, float],
              kinds: tuple[str, str], anomaly: float) -> tuple[np.ndarray, np.ndarray]:
    """A parabola (e = 1) from q; ``kinds`` is (M or f, the key the anomaly came from)."""
    from orbitsim.initial_conditions.parabolic import parabolic_to_cartesian  # noqa: PLC0415 -- lazy: off `orbitsim run`/`validate`

    if size != "q":
        raise body.error(size, "a parabolic orbit (e = 1) has no finite a or period: give q (the pericentre "
                         "distance) instead")
    q = reader.number(body.raw("q"), body.key("q"), "length", positive=True)
    try:
        return parabolic_to_cartesian(gm, q, angles["inc"], angles["Omega"], angles["omega"],
                                      **{kinds[0]: anomaly})
    except ValueError as err:
        raise ScenarioError(str(err), key=body.key(kinds[1])) from None
