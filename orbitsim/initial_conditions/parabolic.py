"""The parabolic orbit (e = 1): state from the pericentre distance q and an anomaly.

A parabola has no finite semi-major axis, so it is described by q. With D = tan(f / 2),
Barker's equation gives the time from pericentre passage T (Murray & Dermott 1999, §2.6;
Danby 1988, §6.5):

.. math:: D + D^3 / 3 = \\sqrt{G M / (2 q^3)}\\,(t - T) \\equiv M,

which defines the parabolic "mean anomaly" M used here (radians; degrees at the interface, as for
the other conics). The cubic has the closed-form root D = 2 sinh(asinh(3 M / 2) / 3), since
(2/3) sinh 3y = 2 sinh y + (8/3) sinh^3 y. In the perifocal plane, with p = 2 q,

.. math:: r = p / (1 + \\cos f), \\quad \\mathbf v = \\sqrt{G M / p}\\,(-\\sin f, 1 + \\cos f),

so the energy v^2 / 2 - G M / r is zero at every f.
"""

from __future__ import annotations

import math

import numpy as np

from orbitsim.initial_conditions.elements import _perifocal_basis

__all__ = ["parabolic_to_cartesian", "parabolic_true_anomaly"]


def parabolic_true_anomaly(M: float) -> float:
    """True anomaly f (radians) from the parabolic mean anomaly M (radians) by Barker's equation."""
    D = 2.0 * math.sinh(math.asinh(1.5 * M) / 3.0)
    return 2.0 * math.atan(D)


def parabolic_to_cartesian(gm: float, q: float, inc: float, Omega: float, omega: float, *,
                           M: float | None = None, f: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Position and velocity relative to the primary on a parabola.

    Parameters
    ----------
    gm : float
        G (m_primary + m_body) > 0.
    q : float
        Pericentre distance > 0.
    inc, Omega, omega : float
        Orientation in degrees (as :func:`~orbitsim.initial_conditions.elements.elements_to_cartesian`).
    M, f : float, optional
        Parabolic mean anomaly (Barker's equation) or true anomaly in degrees, |f| < 180; exactly one.

    Raises
    ------
    ValueError
        For gm <= 0, q <= 0, both or neither anomaly, or |f| >= 180 deg (the body would be at infinity).
    """
    if (M is None) == (f is None):
        raise ValueError("give exactly one of M (mean anomaly) or f (true anomaly)")
    if not (gm > 0.0 and q > 0.0):
        raise ValueError(f"a parabola needs G (m_primary + m) > 0 and q > 0, got {gm:g} and q = {q:g}")
    if f is not None:
        wrapped = math.remainder(float(f), 360.0)
        if abs(wrapped) >= 180.0:
            raise ValueError(f"true anomaly {f:g} deg is at infinity on a parabola: |f| must be < 180 deg")
        f_rad = math.radians(wrapped)
    else:
        f_rad = parabolic_true_anomaly(math.radians(float(M)))  # type: ignore[arg-type]
    p = 2.0 * q
    cos_f, sin_f = math.cos(f_rad), math.sin(f_rad)
    # 1 + cos f written as 2 cos^2(f / 2): no cancellation as f -> 180 deg, far out on the parabola.
    one_plus_cos = 2.0 * math.cos(0.5 * f_rad) ** 2
    r = p / one_plus_cos
    speed = math.sqrt(gm / p)
    P, Q = _perifocal_basis(math.radians(inc), math.radians(Omega), math.radians(omega))
    position = r * cos_f * P + r * sin_f * Q
    velocity = -speed * sin_f * P + speed * one_plus_cos * Q
    return position, velocity
