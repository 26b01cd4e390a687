"""Random initial conditions: a Plummer sphere and a Keplerian disc (test bodies or planetesimals).

Both generators draw every random number from ``numpy.random.default_rng(seed)``
in a fixed order, so the same arguments give bit-identical arrays. A disc's masses, when it has
any, are drawn after everything else, so the orbits of a disc do not depend on its masses being
asked for (the test-body disc of a seed keeps its bits).

References
----------
.. [1] Plummer, H. C. (1911), "On the problem of distribution in globular star
       clusters", MNRAS 71, 460.
.. [2] Aarseth, S. J., Hénon, M. & Wielen, R. (1974), "A comparison of numerical
       methods for the study of star cluster dynamics", A&A 37, 183 (appendix:
       sampling the Plummer model).
.. [3] Binney, J. & Tremaine, S. (2008), *Galactic Dynamics*, 2nd ed., ch. 2 and 4
       (Plummer potential and distribution function).
.. [4] Devroye, L. (1986), *Non-Uniform Random Variate Generation*, Springer, ch. II.2
       (sampling by inverting the cumulative distribution).
"""

from __future__ import annotations

import math

import numpy as np

from orbitsim.initial_conditions.elements import elements_to_cartesian

__all__ = ["PLUMMER_HALF_MASS_RADIUS", "disc", "plummer", "power_law_masses", "sphere_radii"]

#: Half-mass radius of a Plummer sphere in units of its scale radius, 1/sqrt(2^(2/3) - 1).
PLUMMER_HALF_MASS_RADIUS: float = 1.0 / math.sqrt(2.0 ** (2.0 / 3.0) - 1.0)

#: Envelope for von Neumann rejection of g(q) = q^2 (1 - q^2)^(7/2), whose maximum
#: is (2/9)(7/9)^(7/2) ~= 0.0922 at q^2 = 2/9; AHW (1974) use 0.1.
_SPEED_ENVELOPE = 0.1
#: Fraction of proposals accepted: (1/2) B(3/2, 9/2) / 0.1 ~= 0.43; used to size batches.
_SPEED_ACCEPTANCE = 0.5 * math.gamma(1.5) * math.gamma(4.5) / math.gamma(6.0) / _SPEED_ENVELOPE

Arrays = tuple[np.ndarray, np.ndarray, np.ndarray]


def _isotropic_unit_vectors(rng: np.random.Generator, n: int) -> np.ndarray:
    """Unit vectors uniform on the sphere: cos(theta) uniform in [-1, 1], phi in [0, 2 pi)."""
    cos_theta = rng.uniform(-1.0, 1.0, n)
    phi = rng.uniform(0.0, 2.0 * math.pi, n)
    sin_theta = np.sqrt(1.0 - cos_theta**2)
    return np.column_stack((sin_theta * np.cos(phi), sin_theta * np.sin(phi), cos_theta))


def _plummer_radii(rng: np.random.Generator, n: int, max_mass_fraction: float) -> np.ndarray:
    """Radii in units of the scale radius by inverting the cumulative mass.

    M(<r)/M = r^3 / (1 + r^2)^(3/2)  =>  r = m^(1/3) / sqrt(1 - m^(2/3))
    for m uniform in [0, max_mass_fraction) (AHW 1974, appendix).
    """
    m = max_mass_fraction * rng.random(n)
    m_one_third = np.cbrt(m)
    return m_one_third / np.sqrt(1.0 - m_one_third**2)


def _plummer_speed_fractions(rng: np.random.Generator, n: int) -> np.ndarray:
    """Speeds q = v / v_esc drawn from g(q) ∝ q^2 (1 - q^2)^(7/2) by von Neumann rejection.

    g follows from the Plummer distribution function f(E) ∝ (-E)^(7/2)
    (Binney & Tremaine 2008, ch. 4) at fixed radius (AHW 1974, appendix).
    """
    accepted: list[np.ndarray] = []
    remaining = n
    while remaining > 0:
        # Oversize the batch so one round almost always suffices; the batch size
        # depends only on n, so the random stream stays reproducible.
        batch = int(remaining / _SPEED_ACCEPTANCE * 1.2) + 16
        q = rng.random(batch)
        height = _SPEED_ENVELOPE * rng.random(batch)
        keep = q[height < q**2 * (1.0 - q**2) ** 3.5][:remaining]
        accepted.append(keep)
        remaining -= keep.size
    return np.concatenate(accepted)


def plummer(
    n: int,
    *,
    seed: int,
    total_mass: float = 1.0,
    scale_radius: float = 1.0,
    G: float = 1.0,
    max_mass_fraction: float = 0.999,
) -> Arrays:
    """Equal-mass Plummer sphere in virial equilibrium.

    Parameters
    ----------
    n : int
        Number of bodies, ``n >= 1``.
    seed : int
        Seed for ``numpy.random.default_rng``; equal seeds give identical bits.
    total_mass, scale_radius, G : float
        Model mass M, Plummer scale radius a and gravitational constant.
    max_mass_fraction : float
        Radii are drawn from the innermost fraction of the mass, which removes
        the rare far outliers (0.999 caps r at ~38.7 a); ``1.0`` disables it.

    Returns
    -------
    masses : numpy.ndarray, shape (n,)
        Each ``total_mass / n``.
    positions, velocities : numpy.ndarray, shape (n, 3)
        Centre-of-mass frame (mean position and velocity exactly removed).

    Notes
    -----
    Density :math:`\\rho \\propto (1 + r^2/a^2)^{-5/2}`, potential
    :math:`\\Phi = -GM/\\sqrt{r^2 + a^2}`.  Radii invert the cumulative mass; the
    speed is :math:`q\\,v_{\\rm esc}` with :math:`v_{\\rm esc} = \\sqrt{-2\\Phi}` and
    ``q`` drawn from :math:`q^2 (1-q^2)^{7/2}`; directions are isotropic
    (Aarseth, Hénon & Wielen 1974).  The expected energies obey the virial
    theorem :math:`2K = -W` with :math:`W = -3\\pi G M^2 / (32 a)`, and the
    half-mass radius is :math:`a / \\sqrt{2^{2/3} - 1} \\approx 1.305\\,a`.
    """
    _require(isinstance(n, int | np.integer) and n >= 1, f"n must be a positive integer, got {n}")
    for name, value in (("total_mass", total_mass), ("scale_radius", scale_radius), ("G", G)):
        _require(math.isfinite(value) and value > 0.0, f"{name} must be positive and finite, got {value}")
    _require(0.0 < max_mass_fraction <= 1.0, f"max_mass_fraction must be in (0, 1], got {max_mass_fraction}")
    rng = np.random.default_rng(seed)
    r = _plummer_radii(rng, n, max_mass_fraction)
    positions = r[:, None] * _isotropic_unit_vectors(rng, n)
    v_escape = np.sqrt(2.0) * (1.0 + r**2) ** -0.25  # in units of sqrt(G M / a)
    speeds = _plummer_speed_fractions(rng, n) * v_escape
    velocities = speeds[:, None] * _isotropic_unit_vectors(rng, n)
    # Equal masses: the centre of mass is the plain mean.
    positions -= positions.mean(axis=0)
    velocities -= velocities.mean(axis=0)
    masses = np.full(n, total_mass / n)
    return masses, positions * scale_radius, velocities * math.sqrt(G * total_mass / scale_radius)


def power_law_masses(u: np.ndarray, m_min: float, m_max: float, index: float) -> np.ndarray:
    """Masses distributed as dN/dm ∝ m^index on [m_min, m_max], from uniform numbers ``u`` in [0, 1).

    Inverts the cumulative distribution (Devroye 1986, ch. II.2): with p = index + 1 and
    L = ln(m_max / m_min), m^p = m_min^p + u (m_max^p - m_min^p), that is

        m = m_min exp(log1p(u expm1(p L)) / p)          for p < 0,
        m = m_max exp(log1p((1 - u) expm1(-p L)) / p)   for p > 0,

    and m = m_min exp(u L) for p = 0 (index -1: uniform in log m). ``expm1`` of a negative argument stays
    in (-1, 0], so nothing overflows however steep the power law, and with ``log1p`` no digits are lost
    as p -> 0.
    ``m_min == m_max`` gives every body that mass. The results are clipped to [m_min, m_max]
    against round-off.
    """
    u = np.asarray(u, dtype=np.float64)
    if m_min == m_max:
        return np.full(u.shape, float(m_min))
    p = float(index) + 1.0
    span = math.log(m_max / m_min)
    if p == 0.0:
        masses = m_min * np.exp(u * span)
    elif p < 0.0:
        masses = m_min * np.exp(np.log1p(u * math.expm1(p * span)) / p)
    else:
        with np.errstate(divide="ignore"):  # log1p(-1) = -inf at u = 0 of a steep law: m = m_min, exactly right
            masses = m_max * np.exp(np.log1p((1.0 - u) * math.expm1(-p * span)) / p)
    return np.clip(masses, m_min, m_max)


def sphere_radii(masses: np.ndarray, density: float) -> np.ndarray:
    """Radii of uniform spheres of ``masses`` and bulk ``density``: r = (3 m / (4 pi rho))^(1/3).

    ``density`` is in the scenario's mass per length cubed, so the radii come out in its length unit.
    """
    return np.cbrt(3.0 * np.asarray(masses, dtype=np.float64) / (4.0 * math.pi * density))


def disc(
    n: int,
    *,
    seed: int,
    central_mass: float = 1.0,
    r_min: float,
    r_max: float,
    G: float = 1.0,
    e_max: float = 0.0,
    inc_max_deg: float = 0.0,
    m_min: float | None = None,
    m_max: float | None = None,
    mass_index: float | None = None,
) -> Arrays:
    """A central star plus ``n`` bodies on Keplerian orbits: massless test bodies, or planetesimals
    whose masses follow a power law.

    Parameters
    ----------
    n : int
        Number of test bodies, ``n >= 1``.
    seed : int
        Seed for ``numpy.random.default_rng``; equal seeds give identical bits.
    central_mass : float
        Mass of the star at index 0, placed at the origin at rest.
    r_min, r_max : float
        Range of semi-major axes, ``0 < r_min <= r_max``.
    G : float
        Gravitational constant.
    e_max : float
        Eccentricities are uniform in ``[0, e_max]``, ``0 <= e_max < 1``.
    inc_max_deg : float
        Inclinations are uniform in ``[0, inc_max_deg]`` degrees, at most 180.
    m_min, m_max, mass_index : float, optional
        The bodies' masses, dN/dm ∝ m^mass_index on ``[m_min, m_max]``
        (:func:`power_law_masses`; ``mass_index`` may be left out when ``m_min == m_max``).
        Without them the bodies are massless.

    Returns
    -------
    masses : numpy.ndarray, shape (n + 1,)
        ``central_mass`` followed by the ``n`` bodies' masses (zeros for test bodies).
    positions, velocities : numpy.ndarray, shape (n + 1, 3)
        Star first, then the bodies relative to it.

    Notes
    -----
    Semi-major axes are uniform in area, :math:`a = \\sqrt{r_{\\min}^2 + u\\,
    (r_{\\max}^2 - r_{\\min}^2)}` with ``u`` uniform in [0, 1), so the surface
    density is constant.  Mean anomaly, node and argument of periapsis are
    uniform in [0, 360) degrees.  Each body's state comes from
    :func:`~orbitsim.initial_conditions.elements.elements_to_cartesian` with
    :math:`gm = G (M_\\star + m)`, the two-body value a scenario's orbital elements use
    (:math:`G M_\\star` for a test body), so its specific energy relative to the star is
    :math:`-gm / (2a)`.  The star stays at the origin at rest: with massive bodies the centre of
    mass is not there (``frame: barycentric`` moves the system to it).  Masses are drawn last, one
    uniform number per body, so the orbits are the same with or without them.
    """
    _check_disc_arguments(n, central_mass, r_min, r_max, G, e_max, inc_max_deg)
    massive = m_min is not None or m_max is not None
    if massive:
        _check_disc_masses(m_min, m_max, mass_index)
    rng = np.random.default_rng(seed)
    # All element arrays are drawn even when e_max or inc_max_deg is 0 so that
    # the random stream, and hence the radii and phases, do not depend on them.
    a = np.sqrt(r_min**2 + rng.random(n) * (r_max**2 - r_min**2))
    mean_anomaly = rng.uniform(0.0, 360.0, n)
    e = e_max * rng.random(n)
    inc = inc_max_deg * rng.random(n)
    node = rng.uniform(0.0, 360.0, n)
    periapsis = rng.uniform(0.0, 360.0, n)
    masses = np.zeros(n + 1)
    masses[0] = central_mass
    if massive:
        masses[1:] = power_law_masses(rng.random(n), float(m_min), float(m_max),  # type: ignore[arg-type]
                                      0.0 if mass_index is None else float(mass_index))
        gm = G * (central_mass + masses[1:])
    else:
        gm = np.full(n, G * central_mass)  # the test-body disc: the same gm, to the bit, as before masses
    positions = np.zeros((n + 1, 3))
    velocities = np.zeros((n + 1, 3))
    for i in range(n):
        positions[i + 1], velocities[i + 1] = elements_to_cartesian(
            gm[i], a[i], e[i], inc[i], node[i], periapsis[i], M=mean_anomaly[i]
        )
    return masses, positions, velocities


def _check_disc_masses(m_min: float | None, m_max: float | None, mass_index: float | None) -> None:
    """Raise ValueError for a mass distribution :func:`power_law_masses` cannot draw from."""
    _require(m_min is not None and m_max is not None, "give both m_min and m_max (or neither, for test bodies)")
    for name, value in (("m_min", m_min), ("m_max", m_max)):
        _require(math.isfinite(value) and value > 0.0, f"{name} must be positive and finite, got {value}")
    _require(m_min <= m_max, f"need m_min <= m_max, got {m_min} > {m_max}")
    if m_min < m_max:
        _require(mass_index is not None, "m_min < m_max needs mass_index (dN/dm ∝ m^mass_index)")
        _require(math.isfinite(mass_index), f"mass_index must be finite, got {mass_index}")


def _check_disc_arguments(
    n: int, central_mass: float, r_min: float, r_max: float, G: float, e_max: float, inc_max_deg: float
) -> None:
    """Raise ValueError for arguments :func:`disc` cannot honour."""
    _require(isinstance(n, int | np.integer) and n >= 1, f"n must be a positive integer, got {n}")
    for name, value in (("central_mass", central_mass), ("G", G), ("r_min", r_min), ("r_max", r_max)):
        _require(math.isfinite(value) and value > 0.0, f"{name} must be positive and finite, got {value}")
    _require(r_min <= r_max, f"need r_min <= r_max, got {r_min} > {r_max}")
    _require(0.0 <= e_max < 1.0, f"e_max must be in [0, 1), got {e_max}")
    _require(0.0 <= inc_max_deg <= 180.0, f"inc_max_deg must be in [0, 180], got {inc_max_deg}")


def _require(condition: bool, message: str) -> None:
    """Raise ValueError with ``message`` unless ``condition`` holds."""
    if not condition:
        raise ValueError(message)
