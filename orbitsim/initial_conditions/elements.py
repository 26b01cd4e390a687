"""Conversion between Keplerian orbital elements and Cartesian state vectors.

Conventions follow REBOUND (Rein & Liu 2012): ``gm = G (m_primary + m_body)``,
the state is that of the body *relative to its primary*, bound orbits have
``0 <= e < 1`` and ``a > 0``, unbound (hyperbolic) orbits have ``e > 1`` and
``a < 0``.  Angles at the public interface are in degrees.

The orientation of the orbit is the classical 3-1-3 rotation

.. math:: \\mathbf r = R_z(\\Omega)\\, R_x(i)\\, R_z(\\omega)\\, \\mathbf r_{\\rm pf},

where :math:`\\mathbf r_{\\rm pf}` lies in the perifocal plane with the
periapsis along +x (Murray & Dermott 1999, *Solar System Dynamics*, ch. 2).

References
----------
.. [1] Murray, C. D. & Dermott, S. F. (1999), *Solar System Dynamics*, CUP, ch. 2.
.. [2] Danby, J. M. A. (1988), *Fundamentals of Celestial Mechanics*, 2nd ed.,
       Willmann-Bell, ch. 6 (Kepler's equation, elliptic and hyperbolic).
.. [3] Rein, H. & Liu, S.-F. (2012), "REBOUND: an open-source multi-purpose
       N-body code for collisional dynamics", A&A 537, A128.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

__all__ = ["cartesian_to_elements", "elements_to_cartesian", "solve_kepler"]

_EPS = float(np.finfo(np.float64).eps)
#: Newton with a bisection fall-back on a bracket of width <= pi (elliptic) or a
#: few tens (hyperbolic) needs well under 100 steps even when every step bisects.
_MAX_KEPLER_ITER = 200
#: Largest hyperbolic anomaly used: sinh overflows a float64 just above H = 710.
_H_MAX = 700.0
#: Residuals below this multiple of the rounding scale cannot be improved on.
_RESIDUAL_FLOOR = 4.0 * _EPS
#: Relative size below which the node or eccentricity vector has no direction.
_DEGENERATE_TOL = 1e-13

KeplerEval = Callable[[float], tuple[float, float, float]]


def _newton_bisect(evaluate: KeplerEval, lo: float, hi: float, x0: float) -> float:
    """Root of an increasing function on ``[lo, hi]`` by safeguarded Newton iteration.

    ``evaluate(x)`` returns ``(g, x_newton, scale)``: the residual, the Newton
    iterate from ``x`` and the magnitude of the terms summed in ``g`` (so its
    rounding error is ~eps * scale).  Each evaluation shrinks the bracket and a
    Newton iterate that leaves it is replaced by bisection, so convergence is
    guaranteed (Press et al. 2007, *Numerical Recipes*, 3rd ed., §9.4 ``rtsafe``).
    """
    x = x0
    for _ in range(_MAX_KEPLER_ITER):
        g, x_new, scale = evaluate(x)
        # An overflowed g (huge hyperbolic H) is not converged: bisect instead.
        if math.isfinite(g) and abs(g) <= _RESIDUAL_FLOOR * scale:
            return x
        if g > 0.0:
            hi = x
        else:
            lo = x
        if not lo < x_new < hi:
            x_new = 0.5 * (lo + hi)
        if abs(x_new - x) <= 2.0 * _EPS * abs(x_new):
            return x_new
        x = x_new
    raise RuntimeError(f"Kepler solver did not converge in {_MAX_KEPLER_ITER} iterations")


def _eccentric_anomaly(M: float, e: float) -> float:
    """Solve E - e sin E = M for E (radians), 0 <= e < 1.

    By symmetry only M in (0, pi] is solved.  There (1-e) E <= E - e sin E <= (1+e) E
    brackets the root in [M/(1+e), M/(1-e)], and g(E) = E - e sin E - M is
    increasing and convex (g'' = e sin E >= 0), so Newton started at the upper
    end decreases monotonically onto the root (Danby 1988, ch. 6).  The Newton
    iterate is written E' = (M + e (sin E - E cos E)) / (1 - e cos E), which is
    free of the cancellation in E - g/g' when E is tiny.
    """
    M_wrapped = math.remainder(M, 2.0 * math.pi)  # in [-pi, pi]
    sign = 1.0 if M_wrapped >= 0.0 else -1.0
    M_abs = abs(M_wrapped)
    if e == 0.0 or M_abs == 0.0:
        return M  # E = M solves the equation exactly here

    def evaluate(E: float) -> tuple[float, float, float]:
        sin_E, cos_E = math.sin(E), math.cos(E)
        E_newton = (M_abs + e * (sin_E - E * cos_E)) / (1.0 - e * cos_E)
        return E - e * sin_E - M_abs, E_newton, E + e * abs(sin_E) + M_abs

    hi = min(M_abs / (1.0 - e), M_abs + e, math.pi)  # g >= 0 at each candidate
    E = _newton_bisect(evaluate, M_abs / (1.0 + e), hi, hi)
    # Undo the reduction so that E - e sin E reproduces the caller's M.
    return sign * E + (M - M_wrapped)


def _hyperbolic_anomaly(M: float, e: float) -> float:
    """Solve e sinh H - H = M for H, e > 1.

    For M >= 0 the root lies in [asinh(M/e), asinh(M/(e-1))] because
    (e-1) sinh H <= e sinh H - H <= e sinh H.  g is increasing and convex for
    H >= 0, so Newton from the upper end converges monotonically.  The upper
    end is taken as min(asinh(M/e) + ln(e/(e-1)), M/(e-1)), both >= asinh(M/(e-1)),
    which cannot overflow for e -> 1+.  The Newton iterate is written
    H' = (M + e (H cosh H - sinh H)) / (e cosh H - 1) to avoid cancellation.
    """
    sign = 1.0 if M >= 0.0 else -1.0
    M_abs = abs(M)
    if M_abs == 0.0:
        return 0.0

    def evaluate(H: float) -> tuple[float, float, float]:
        sinh_H, cosh_H = math.sinh(H), math.cosh(H)
        H_newton = (M_abs + e * (H * cosh_H - sinh_H)) / (e * cosh_H - 1.0)
        return e * sinh_H - H - M_abs, H_newton, e * sinh_H + H + M_abs

    lo = math.asinh(M_abs / e)
    hi = min(lo - math.log1p(-1.0 / e), M_abs / (e - 1.0), _H_MAX)
    if hi == _H_MAX and evaluate(hi)[0] < 0.0:
        raise ValueError(f"hyperbolic mean anomaly M={M} is too large: cosh H would overflow")
    return sign * _newton_bisect(evaluate, lo, hi, hi)


def solve_kepler(M: float, e: float) -> float:
    """Solve Kepler's equation for the eccentric or hyperbolic anomaly.

    Parameters
    ----------
    M : float
        Mean anomaly in radians (any real value).
    e : float
        Eccentricity, ``0 <= e < 1`` (elliptic) or ``e > 1`` (hyperbolic).

    Returns
    -------
    float
        ``E`` with :math:`E - e\\sin E = M` if ``e < 1``, otherwise ``H`` with
        :math:`e\\sinh H - H = M`, to the rounding level of the residual.
    """
    M, e = float(M), float(e)
    if not (math.isfinite(M) and math.isfinite(e)) or e < 0.0 or e == 1.0:
        raise ValueError(f"solve_kepler needs finite M and e >= 0, e != 1; got M={M}, e={e}")
    return _eccentric_anomaly(M, e) if e < 1.0 else _hyperbolic_anomaly(M, e)


def _check_shape(gm: float, a: float, e: float, angles: dict[str, float | None]) -> None:
    """Raise ValueError unless (gm, a, e, angles) describe a supported conic."""
    for name, value in {"gm": gm, "a": a, "e": e, **angles}.items():
        if value is not None and not math.isfinite(value):
            raise ValueError(f"{name} must be finite, got {value}")
    if gm <= 0.0:
        raise ValueError(f"gm = G (m_primary + m_body) must be positive, got {gm}")
    if e < 0.0:
        raise ValueError(f"eccentricity must be non-negative, got e={e}")
    if e == 1.0:
        raise ValueError("parabolic orbits (e == 1) are not supported; use e != 1")
    if a == 0.0:
        raise ValueError("semi-major axis must be non-zero")
    if e < 1.0 and a < 0.0:
        raise ValueError(f"bound orbit (e={e} < 1) needs a > 0, got a={a}")
    if e > 1.0 and a > 0.0:
        raise ValueError(f"hyperbolic orbit (e={e} > 1) needs a < 0 (REBOUND convention), got a={a}")


def _perifocal_from_mean(gm: float, a: float, e: float, M: float) -> tuple[np.ndarray, np.ndarray]:
    """Perifocal state from the mean anomaly via E or H (Murray & Dermott 1999, ch. 2).

    Working from E or H rather than f avoids 1 + e cos f -> 0 far out on a hyperbola.
    """
    a_abs = abs(a)
    n = math.sqrt(gm / a_abs**3)  # mean motion
    if e < 1.0:
        E = _eccentric_anomaly(M, e)
        cos_E, sin_E = math.cos(E), math.sin(E)
        b_over_a = math.sqrt((1.0 - e) * (1.0 + e))
        r = a * (1.0 - e * cos_E)
        pos = (a * (cos_E - e), a * b_over_a * sin_E)
        vel = (-(a * a) * n * sin_E / r, (a * a) * n * b_over_a * cos_E / r)
    else:
        H = _hyperbolic_anomaly(M, e)
        cosh_H, sinh_H = math.cosh(H), math.sinh(H)
        b_over_a = math.sqrt((e - 1.0) * (e + 1.0))
        r = a_abs * (e * cosh_H - 1.0)
        pos = (a_abs * (e - cosh_H), a_abs * b_over_a * sinh_H)
        vel = (-(a_abs * a_abs) * n * sinh_H / r, (a_abs * a_abs) * n * b_over_a * cosh_H / r)
    return np.array([pos[0], pos[1], 0.0]), np.array([vel[0], vel[1], 0.0])


def _perifocal_from_true(gm: float, a: float, e: float, f: float) -> tuple[np.ndarray, np.ndarray]:
    """Perifocal state from the true anomaly: r = p / (1 + e cos f), v = sqrt(gm/p) (-sin f, e + cos f)."""
    p = a * (1.0 - e) * (1.0 + e)  # semi-latus rectum, > 0 for both conics
    cos_f, sin_f = math.cos(f), math.sin(f)
    denominator = 1.0 + e * cos_f
    # At the rounding level of 1 + e cos f the body is at infinity: treat as on the asymptote.
    if denominator <= 4.0 * _EPS * (1.0 + e):
        f_inf = math.degrees(math.acos(-1.0 / e))
        raise ValueError(
            f"true anomaly {math.degrees(f):.6g} deg is on or beyond the asymptote of this "
            f"hyperbola (|f| must be < {f_inf:.6g} deg for e={e})"
        )
    r = p / denominator
    v_scale = math.sqrt(gm / p)
    return (
        np.array([r * cos_f, r * sin_f, 0.0]),
        np.array([-v_scale * sin_f, v_scale * (e + cos_f), 0.0]),
    )


def _perifocal_basis(inc: float, Omega: float, omega: float) -> tuple[np.ndarray, np.ndarray]:
    """Inertial unit vectors P (to periapsis) and Q (90 deg ahead in the orbit), radians in."""
    cO, sO = math.cos(Omega), math.sin(Omega)
    co, so = math.cos(omega), math.sin(omega)
    ci, si = math.cos(inc), math.sin(inc)
    P = np.array([cO * co - sO * so * ci, sO * co + cO * so * ci, so * si])
    Q = np.array([-cO * so - sO * co * ci, -sO * so + cO * co * ci, co * si])
    return P, Q


def elements_to_cartesian(
    gm: float,
    a: float,
    e: float,
    inc: float,
    Omega: float,
    omega: float,
    *,
    M: float | None = None,
    f: float | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Position and velocity of a body relative to its primary from Keplerian elements.

    Parameters
    ----------
    gm : float
        :math:`G (m_{\\rm primary} + m_{\\rm body})`, positive.
    a : float
        Semi-major axis; ``a > 0`` for ``0 <= e < 1``, ``a < 0`` for ``e > 1``.
    e : float
        Eccentricity, ``e >= 0`` and ``e != 1``.
    inc, Omega, omega : float
        Inclination, longitude of the ascending node and argument of
        periapsis, in degrees.
    M, f : float, optional
        Mean anomaly or true anomaly in degrees; exactly one must be given.
        For a hyperbola, :math:`|f| < \\arccos(-1/e)`.

    Returns
    -------
    position, velocity : numpy.ndarray
        Arrays of shape (3,) in the units implied by ``gm`` and ``a``.

    Raises
    ------
    ValueError
        For non-finite input, ``e < 0``, ``e == 1``, ``a == 0``, a sign of ``a``
        inconsistent with ``e``, ``gm <= 0``, both or neither of ``M`` and
        ``f``, or a hyperbolic true anomaly beyond the asymptote.

    Notes
    -----
    From ``M``, Kepler's equation :math:`E - e\\sin E = M` (or
    :math:`e\\sinh H - H = M`) is solved by safeguarded Newton iteration, and
    the perifocal state is built from ``E`` (``H``); from ``f`` the conic
    equation :math:`r = a(1-e^2)/(1+e\\cos f)` is used.  The perifocal state is
    rotated by :math:`R_z(\\Omega) R_x(i) R_z(\\omega)` (Murray & Dermott 1999, ch. 2).
    """
    if (M is None) == (f is None):
        raise ValueError("give exactly one of M (mean anomaly) or f (true anomaly)")
    gm, a, e = float(gm), float(a), float(e)
    anomaly = float(M if M is not None else f)  # type: ignore[arg-type]
    _check_shape(gm, a, e, {"inc": inc, "Omega": Omega, "omega": omega, "anomaly": anomaly})
    if M is not None:
        pos_pf, vel_pf = _perifocal_from_mean(gm, a, e, math.radians(anomaly))
    else:
        pos_pf, vel_pf = _perifocal_from_true(gm, a, e, math.radians(anomaly))
    P, Q = _perifocal_basis(math.radians(inc), math.radians(Omega), math.radians(omega))
    return pos_pf[0] * P + pos_pf[1] * Q, vel_pf[0] * P + vel_pf[1] * Q


def _angle_in_plane(u: np.ndarray, w: np.ndarray, normal: np.ndarray) -> float:
    """Signed angle from u to w (radians), positive counter-clockwise about ``normal``."""
    return math.atan2(float(np.dot(np.cross(u, w), normal)), float(np.dot(u, w)))


def _mean_from_true(e: float, f: float) -> float:
    """Mean anomaly from true anomaly (radians) via E or H (Murray & Dermott 1999, ch. 2)."""
    if e < 1.0:
        E = 2.0 * math.atan2(math.sqrt(1.0 - e) * math.sin(0.5 * f), math.sqrt(1.0 + e) * math.cos(0.5 * f))
        return E - e * math.sin(E)
    if e > 1.0:
        H = 2.0 * math.atanh(math.sqrt((e - 1.0) / (e + 1.0)) * math.tan(0.5 * f))
        return e * math.sinh(H) - H
    return math.nan  # parabolic: no mean anomaly in this parametrisation


def _wrap_deg(angle_rad: float, lower: float) -> float:
    """Degrees in [lower, lower + 360)."""
    return (math.degrees(angle_rad) - lower) % 360.0 + lower


def cartesian_to_elements(gm: float, r: np.ndarray, v: np.ndarray) -> dict[str, float]:
    """Keplerian elements of a body from its state relative to its primary.

    Parameters
    ----------
    gm : float
        :math:`G (m_{\\rm primary} + m_{\\rm body})`, positive.
    r, v : array_like, shape (3,)
        Relative position and velocity.

    Returns
    -------
    dict
        ``a``, ``e``, ``inc`` (in [0, 180]), ``Omega`` and ``omega`` (in
        [0, 360)), ``f`` and ``M`` (in [-180, 180) for bound orbits; ``M`` is
        unbounded for hyperbolae and NaN for e == 1).  Angles in degrees.
        When the node is undefined (``inc`` = 0 or 180) ``Omega`` = 0; when the
        periapsis is undefined (``e`` = 0) ``omega`` = 0 and ``f`` is measured
        from the node.

    Notes
    -----
    :math:`\\mathbf h = \\mathbf r\\times\\mathbf v`,
    :math:`\\mathbf e = ((v^2 - gm/r)\\,\\mathbf r - (\\mathbf r\\cdot\\mathbf v)\\,\\mathbf v)/gm`,
    :math:`1/a = 2/r - v^2/gm` (vis-viva); Murray & Dermott (1999), ch. 2.
    """
    r = np.asarray(r, dtype=np.float64)
    v = np.asarray(v, dtype=np.float64)
    if r.shape != (3,) or v.shape != (3,):
        raise ValueError(f"r and v must have shape (3,), got {r.shape} and {v.shape}")
    if not (np.all(np.isfinite(r)) and np.all(np.isfinite(v)) and math.isfinite(gm) and gm > 0.0):
        raise ValueError("cartesian_to_elements needs finite r, v and gm > 0")
    r_norm = float(np.linalg.norm(r))
    v2 = float(np.dot(v, v))
    h = np.cross(r, v)
    h_norm = float(np.linalg.norm(h))
    if r_norm == 0.0 or h_norm == 0.0:
        raise ValueError("degenerate state: zero radius or radial (zero angular momentum) orbit")
    h_hat = h / h_norm
    e_vec = ((v2 - gm / r_norm) * r - float(np.dot(r, v)) * v) / gm
    e = float(np.linalg.norm(e_vec))
    inv_a = 2.0 / r_norm - v2 / gm
    node = np.array([-h[1], h[0], 0.0])  # z-hat x h
    node_norm = float(np.linalg.norm(node))
    node_hat = node / node_norm if node_norm > _DEGENERATE_TOL * h_norm else np.array([1.0, 0.0, 0.0])
    periapsis_hat = e_vec / e if e > _DEGENERATE_TOL else node_hat
    f = _angle_in_plane(periapsis_hat, r / r_norm, h_hat)
    M = _mean_from_true(e, f)
    return {
        "a": 1.0 / inv_a if inv_a != 0.0 else math.inf,
        "e": e,
        "inc": math.degrees(math.atan2(math.hypot(h[0], h[1]), h[2])),
        "Omega": _wrap_deg(math.atan2(node_hat[1], node_hat[0]), 0.0),
        "omega": _wrap_deg(_angle_in_plane(node_hat, periapsis_hat, h_hat), 0.0),
        "f": _wrap_deg(f, -180.0),
        "M": _wrap_deg(M, -180.0) if e < 1.0 else math.degrees(M),
    }
