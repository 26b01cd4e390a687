"""Osculating orbital elements of many bodies at many samples, from Cartesian states.

The vectorised counterpart of :func:`orbitsim.initial_conditions.elements.cartesian_to_elements`:
the same formulas, units, angle ranges and degenerate-case conventions, applied to arrays of
shape (S, N) at once, with the choice of primary (heliocentric, Jacobi, or about one body) made
here. Pure numpy: every step is a whole-array expression over S N bodies, so the cost is a few
dozen passes over memory and there is no loop for Numba to speed up.

Conventions (REBOUND's, Rein & Liu 2012, as in the scalar function)
-------------------------------------------------------------------
For a body of relative position :math:`\\mathbf r` and velocity :math:`\\mathbf v` about a
primary, with :math:`\\mu = G (m_{\\rm primary} + m)`:

.. math::

    \\mathbf h = \\mathbf r \\times \\mathbf v, \\qquad
    \\mathbf e = \\frac{(v^2 - \\mu / r)\\, \\mathbf r - (\\mathbf r \\cdot \\mathbf v)\\, \\mathbf v}{\\mu}, \\qquad
    \\frac{1}{a} = \\frac{2}{r} - \\frac{v^2}{\\mu},

:math:`i = \\operatorname{atan2}(\\sqrt{h_x^2 + h_y^2}, h_z)`, the node along
:math:`\\hat{\\mathbf z} \\times \\mathbf h`, :math:`\\Omega`, :math:`\\omega` and :math:`f` the
angles from x-hat to the node, from the node to the periapsis and from the periapsis to the body,
counter-clockwise about :math:`\\mathbf h`. The mean anomaly of an ellipse comes from f through
the eccentric anomaly, :math:`\\tan(E/2) = \\sqrt{(1-e)/(1+e)} \\tan(f/2)`,
:math:`M = E - e \\sin E`; that of a hyperbola from the state through the hyperbolic anomaly,
:math:`e \\sinh H = \\mathbf r \\cdot \\mathbf v / \\sqrt{\\mu |a|}`, :math:`M = e \\sinh H - H`
(Murray & Dermott 1999, ch. 2; Danby 1988, ch. 6).

References
----------
.. [1] Murray, C. D. & Dermott, S. F. (1999), *Solar System Dynamics*, CUP, ch. 2.
.. [2] Rein, H. & Liu, S.-F. (2012), "REBOUND: an open-source multi-purpose N-body code for
       collisional dynamics", A&A 537, A128; ``Simulation.orbits()`` for the Jacobi convention.
.. [3] Danby, J. M. A. (1988), *Fundamentals of Celestial Mechanics*, 2nd ed., Willmann-Bell, ch. 6.
.. [4] Wisdom, J. & Holman, M. (1991), "Symplectic maps for the N-body problem", AJ 102, 1528
       (Jacobi coordinates: each body about the centre of mass of those before it).
"""

from __future__ import annotations

import math
import numbers

import numpy as np

# The scalar function's threshold, shared so that both call the same states degenerate.
from orbitsim.initial_conditions.elements import _DEGENERATE_TOL

__all__ = ["ELEMENT_NAMES", "PRIMARY_MODES", "osculating_elements"]

#: The elements returned, in the order a trace stores them.
ELEMENT_NAMES = ("a", "e", "inc", "Omega", "omega", "f", "M")
#: The named choices of primary; an integer body index is the third kind.
PRIMARY_MODES = ("heaviest", "jacobi")
#: Body-samples converted at a time. The temporaries of a block then hold ~25 MB whatever S N is
#: (one pass over 10^6 body-samples held ~40 floats each at once), and ran 1.1-2x faster than
#: such a pass (0.8-1.1 against 0.9-2.1 us per body-sample on this 2-core machine).
_BLOCK_BODY_SAMPLES = 2**16


def _norm(x: np.ndarray) -> np.ndarray:
    return np.sqrt(np.einsum("...k,...k->...", x, x))


def _dot(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    return np.einsum("...k,...k->...", x, y)


def _wrap_deg(angle_rad: np.ndarray, lower: float) -> np.ndarray:
    """Degrees in [lower, lower + 360), as the scalar ``_wrap_deg`` (same floating-point steps)."""
    return np.mod(np.degrees(angle_rad) - lower, 360.0) + lower


def _angle_in_plane(u: np.ndarray, w: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """Signed angle from u to w (radians), counter-clockwise about ``normal``; shapes (..., 3)."""
    return np.arctan2(_dot(np.cross(u, w), normal), _dot(u, w))


def _mean_anomaly(e: np.ndarray, f: np.ndarray, rv: np.ndarray, mu: np.ndarray, a: np.ndarray) -> np.ndarray:
    """Mean anomaly (radians, unwrapped): via E for e < 1, H for e > 1, NaN at e = 1.

    Elliptic: from f by the half-angle formula, as the scalar function. Hyperbolic: from the
    state, :math:`e \\sinh H = \\mathbf r \\cdot \\mathbf v / \\sqrt{\\mu |a|}` (Danby 1988,
    ch. 6), which keeps M to rounding far out on the branch, where f is within rounding of the
    asymptote and the half-angle formula loses ~e^H ulps (at M = 3e6 it was off by 1.7).
    Where e > 1 but rounding gave a >= 0 (parabolic to ~1e-16) the half-angle formula stands in.
    Every branch is evaluated on arguments kept in its domain and the right one selected.
    """
    half = 0.5 * f
    below, above = np.maximum(1.0 - e, 0.0), np.maximum(e - 1.0, 0.0)
    E = 2.0 * np.arctan2(np.sqrt(below) * np.sin(half), np.sqrt(1.0 + e) * np.cos(half))
    e_sinh_H = rv / np.sqrt(mu * np.abs(a))
    H_state = np.arcsinh(e_sinh_H / e)
    H_true = 2.0 * np.arctanh(np.sqrt(above / (e + 1.0)) * np.tan(half))
    hyperbolic = np.where(a < 0.0, e_sinh_H - H_state, e * np.sinh(H_true) - H_true)
    return np.where(e < 1.0, E - e * np.sin(E), np.where(e > 1.0, hyperbolic, np.nan))


def _nan_where(values: np.ndarray, mask: np.ndarray) -> np.ndarray:
    return np.where(mask, np.nan, values)


def _elements_from_relative(mu: np.ndarray, r: np.ndarray, v: np.ndarray) -> dict[str, np.ndarray]:
    """Elements of states ``r``, ``v`` (..., 3) relative to their primaries, ``mu`` (...,).

    Follows :func:`~orbitsim.initial_conditions.elements.cartesian_to_elements` step by step.
    Where that function raises (non-finite input, mu <= 0, r = 0) every element is NaN here;
    where it raises for a radial orbit (h = 0 exactly) a and e are kept and the angles, which
    need an orbital plane, are NaN.
    """
    r_norm, v2 = _norm(r), _dot(v, v)
    h = np.cross(r, v)
    h_norm = _norm(h)
    h_hat = h / h_norm[..., None]
    rv = _dot(r, v)
    e_vec = ((v2 - mu / r_norm)[..., None] * r - rv[..., None] * v) / mu[..., None]
    e = _norm(e_vec)
    inv_a = 2.0 / r_norm - v2 / mu
    a = np.where(inv_a != 0.0, 1.0 / inv_a, np.inf)  # exactly parabolic: a = inf, as the scalar

    node = np.stack([-h[..., 1], h[..., 0], np.zeros_like(h_norm)], axis=-1)  # z-hat x h
    node_norm = np.hypot(h[..., 0], h[..., 1])
    # No node for an equatorial orbit: x-hat stands in, so Omega = 0 (the scalar's choice).
    has_node = node_norm > _DEGENERATE_TOL * h_norm
    node_hat = np.where(has_node[..., None], node / node_norm[..., None], np.array([1.0, 0.0, 0.0]))
    # No periapsis for a circular orbit: the node stands in, so omega = 0 and f is from the node.
    periapsis_hat = np.where((e > _DEGENERATE_TOL)[..., None], e_vec / e[..., None], node_hat)
    f = _angle_in_plane(periapsis_hat, r / r_norm[..., None], h_hat)
    M = _mean_anomaly(e, f, rv, mu, a)

    out = {
        "a": a,
        "e": e,
        "inc": np.degrees(np.arctan2(node_norm, h[..., 2])),
        "Omega": _wrap_deg(np.arctan2(node_hat[..., 1], node_hat[..., 0]), 0.0),
        "omega": _wrap_deg(_angle_in_plane(node_hat, periapsis_hat, h_hat), 0.0),
        "f": _wrap_deg(f, -180.0),
        "M": np.where(e < 1.0, _wrap_deg(M, -180.0), np.degrees(M)),
    }
    finite = np.isfinite(r).all(axis=-1) & np.isfinite(v).all(axis=-1) & np.isfinite(mu)
    undefined = ~(finite & (mu > 0.0) & (r_norm > 0.0))
    no_plane = undefined | ~(h_norm > 0.0)
    return {name: _nan_where(value, no_plane if name not in ("a", "e") else undefined)
            for name, value in out.items()}


def _relative_to_bodies(masses: np.ndarray, pos: np.ndarray, vel: np.ndarray, G: float,
                        index: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(mu, r, v) of every body about body ``index[s]`` at sample s; that body's own row is NaN."""
    rows = np.arange(pos.shape[0])
    r = pos - pos[rows, index][:, None, :]
    v = vel - vel[rows, index][:, None, :]
    mu = G * (masses[rows, index][:, None] + masses)
    mu[rows, index] = np.nan  # the primary has no orbit about itself
    return mu, r, v


def _jacobi(masses: np.ndarray, pos: np.ndarray, vel: np.ndarray, G: float,
            present: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(mu, r, v) of body i about the centre of mass of the present bodies before it.

    Absent bodies (a NaN state or mass) weigh nothing, so a removed body drops out of the interior
    centre of mass as it drops out of a REBOUND simulation. A body with no massive interior (body
    0, or one after only massless or removed bodies) has no Jacobi orbit: its mu is NaN.
    """
    weight = np.where(present, masses, 0.0)
    weighted_pos = np.where(present[..., None], pos, 0.0) * weight[..., None]
    weighted_vel = np.where(present[..., None], vel, 0.0) * weight[..., None]
    interior_mass = np.zeros_like(weight)
    interior_pos = np.zeros_like(pos)
    interior_vel = np.zeros_like(vel)
    # Exclusive prefix sums over the body axis: bodies 0..i-1 for body i.
    np.cumsum(weight[:, :-1], axis=1, out=interior_mass[:, 1:])
    np.cumsum(weighted_pos[:, :-1], axis=1, out=interior_pos[:, 1:])
    np.cumsum(weighted_vel[:, :-1], axis=1, out=interior_vel[:, 1:])
    has_interior = interior_mass > 0.0
    safe_mass = np.where(has_interior, interior_mass, 1.0)[..., None]
    r = pos - interior_pos / safe_mass
    v = vel - interior_vel / safe_mass
    mu = np.where(has_interior, G * (interior_mass + masses), np.nan)
    return mu, r, v


def _validated(masses: object, positions: object, velocities: object, G: float,
               primary: object) -> tuple[np.ndarray, np.ndarray, np.ndarray, bool]:
    """Arrays as (S, N) masses and (S, N, 3) states, and whether the input was one sample."""
    G = float(G)
    pos = np.asarray(positions, dtype=np.float64)
    vel = np.asarray(velocities, dtype=np.float64)
    m = np.asarray(masses, dtype=np.float64)
    if pos.shape != vel.shape or pos.ndim not in (2, 3) or pos.shape[-1] != 3:
        raise ValueError(f"positions and velocities must both have shape (S, N, 3) or (N, 3); "
                         f"got {pos.shape} and {vel.shape}")
    single = pos.ndim == 2
    if single:
        pos, vel = pos[None], vel[None]
    n_samples, n_bodies = pos.shape[:2]
    if m.shape not in ((n_bodies,), (n_samples, n_bodies)):
        raise ValueError(f"masses must have shape ({n_bodies},) or ({n_samples}, {n_bodies}); got {m.shape}")
    with np.errstate(invalid="ignore"):
        if np.any(m < 0.0):  # NaN compares False: a removed body's NaN mass passes
            raise ValueError("masses must be >= 0")
    if not (math.isfinite(G) and G > 0.0):
        raise ValueError(f"G must be finite and > 0; got {G}")
    if isinstance(primary, str):
        if primary not in PRIMARY_MODES:
            raise ValueError(f"primary must be one of {', '.join(PRIMARY_MODES)} or a body index; got {primary!r}")
    elif not isinstance(primary, numbers.Integral) or isinstance(primary, bool) or not 0 <= primary < n_bodies:
        raise ValueError(f"primary must be one of {', '.join(PRIMARY_MODES)} or a body index from 0 to "
                         f"{n_bodies - 1}; got {primary!r}")
    return np.broadcast_to(m, (n_samples, n_bodies)), pos, vel, single


def osculating_elements(masses: np.ndarray, positions: np.ndarray, velocities: np.ndarray, G: float,
                        primary: str | int) -> dict[str, np.ndarray]:
    """Osculating Keplerian elements of every body at every sample.

    Parameters
    ----------
    masses : numpy.ndarray, shape (N,) or (S, N)
        Body masses (>= 0; zero for test particles). Per-sample masses follow merges; NaN marks a
        removed body.
    positions, velocities : numpy.ndarray, shape (S, N, 3) or (N, 3)
        Inertial states at S samples (or one). A body whose row holds a NaN is absent at that
        sample (removed): its elements are NaN there, and it does not take part as a primary.
    G : float
        Gravitational constant, > 0, in the units of the states.
    primary : {"heaviest", "jacobi"} or int
        * ``"heaviest"``: every body about the heaviest body present at that sample (the first
          index of the largest mass on ties), :math:`\\mu = G (m_p + m_i)`; heliocentric when the
          star is the heaviest body. As REBOUND's ``p.orbit(primary=sim.particles[k])``.
        * ``"jacobi"``: Jacobi elements, REBOUND's ``sim.orbits()`` default
          (``jacobi_masses=False``): body i about the centre of mass of the present bodies
          0..i-1, in index order, with :math:`\\mu = G \\sum_{j \\le i} m_j` (the interior
          mass plus its own).
        * an integer k, ``0 <= k < N``: every body about body k, :math:`\\mu = G (m_k + m_i)`.

    Returns
    -------
    dict of str to numpy.ndarray
        ``a, e, inc, Omega, omega, f, M``, float64 arrays of shape (S, N), or (N,) for states of
        shape (N, 3). Units and ranges as
        :func:`~orbitsim.initial_conditions.elements.cartesian_to_elements`: ``a`` in length
        units (> 0 bound, < 0 hyperbolic, ``inf`` when exactly parabolic); angles in degrees,
        ``inc`` in [0, 180], ``Omega`` and ``omega`` in [0, 360), ``f`` in [-180, 180), ``M`` in
        [-180, 180) for e < 1, the unbounded hyperbolic mean anomaly :math:`e \\sinh H - H` for
        e > 1 and NaN for e == 1.

    Raises
    ------
    ValueError
        For shapes that do not fit, a negative mass, G not finite and positive, or an unknown
        primary.

    Notes
    -----
    Degenerate states follow the scalar function: with no node (``inc`` = 0 or 180, to
    1e-13 relative) ``Omega`` = 0; with no periapsis (``e`` <= 1e-13) ``omega`` = 0 and ``f``
    (and ``M``) are measured from the node, or from x-hat when both are missing. Where the scalar
    function raises, a value stands in and nothing is raised or warned:

    * the primary itself, a body with no massive interior (``jacobi``: body 0), an absent body,
      every body at a sample where an integer primary is absent, mu = 0 (a massless body about a
      massless primary) and r = 0 (a body on its primary): every element NaN;
    * a radial orbit (h = 0 exactly): ``a`` and ``e`` (= 1 to rounding) from the formulas above,
      ``inc``, ``Omega``, ``omega``, ``f`` and ``M`` NaN, since no orbital plane exists.

    Examples
    --------
    >>> import numpy as np
    >>> m = np.array([1.0, 0.0])
    >>> x = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    >>> v = np.array([[0.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    >>> el = osculating_elements(m, x, v, G=1.0, primary="heaviest")
    >>> float(el["a"][1]), float(el["e"][1]), bool(np.isnan(el["a"][0]))
    (1.0, 0.0, True)
    """
    m, pos, vel, single = _validated(masses, positions, velocities, G, primary)
    n_samples, n_bodies = pos.shape[:2]
    out = {name: np.empty((n_samples, n_bodies)) for name in ELEMENT_NAMES}
    block = max(1, _BLOCK_BODY_SAMPLES // max(n_bodies, 1))
    with np.errstate(all="ignore"):  # NaN rows and degenerate states are masked explicitly
        for start in range(0, n_samples, block):
            rows = slice(start, start + block)
            for name, values in _block_elements(m[rows], pos[rows], vel[rows], float(G), primary).items():
                out[name][rows] = values
    return {name: out[name][0] if single else out[name] for name in ELEMENT_NAMES}


def _block_elements(m: np.ndarray, pos: np.ndarray, vel: np.ndarray, G: float,
                    primary: str | int) -> dict[str, np.ndarray]:
    """Elements of validated (S, N) masses and (S, N, 3) states about the chosen primaries."""
    present = np.isfinite(pos).all(axis=-1) & np.isfinite(vel).all(axis=-1) & np.isfinite(m)
    if isinstance(primary, str) and primary == "jacobi":
        mu, r, v = _jacobi(m, pos, vel, G, present)
    else:
        if isinstance(primary, str):  # "heaviest"; _validated refused any other string
            index = np.argmax(np.where(present, m, -np.inf), axis=1)  # first on ties
        else:
            index = np.full(pos.shape[0], int(primary))
        mu, r, v = _relative_to_bodies(m, pos, vel, G, index)
    return _elements_from_relative(mu, r, v)
