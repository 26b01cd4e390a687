"""Random initial conditions: a Plummer sphere and a Keplerian test-particle disc.

Both generators draw every random number from ``numpy.random.default_rng(seed)``
in a fixed order, so the same arguments give bit-identical arrays.

References
----------
.. [1] Plummer, H. C. (1911), "On the problem of distribution in globular star
       clusters", MNRAS 71, 460.
.. [2] Aarseth, S. J., Hénon, M. & Wielen, R. (1974), "A comparison of numerical
       methods for the study of star cluster dynamics", A&A 37, 183 (appendix:
       sampling the Plummer model).
.. [3] Binney, J. & Tremaine, S. (2008), *Galactic Dynamics*, 2nd ed., ch. 2 and 4
       (Plummer potential and distribution function).
"""

from __future__ import annotations

import math

import numpy as np

from orbitsim.initial_conditions.elements import elements_to_cartesian

__all__ = ["PLUMMER_HALF_MASS_RADIUS", "disc", "plummer"]

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
) -> Arrays:
    """A central star plus ``n`` massless test bodies on Keplerian orbits.

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

    Returns
    -------
    masses : numpy.ndarray, shape (n + 1,)
        ``central_mass`` followed by ``n`` zeros.
    positions, velocities : numpy.ndarray, shape (n + 1, 3)
        Star first, then the test bodies relative to it.

    Notes
    -----
    Semi-major axes are uniform in area, :math:`a = \\sqrt{r_{\\min}^2 + u\\,
    (r_{\\max}^2 - r_{\\min}^2)}` with ``u`` uniform in [0, 1), so the surface
    density is constant.  Mean anomaly, node and argument of periapsis are
    uniform in [0, 360) degrees.  Each body's state comes from
    :func:`~orbitsim.initial_conditions.elements.elements_to_cartesian` with
    :math:`gm = G M_\\star` (massless bodies), so its specific energy is
    :math:`-G M_\\star / (2a)`.
    """
    _check_disc_arguments(n, central_mass, r_min, r_max, G, e_max, inc_max_deg)
    rng = np.random.default_rng(seed)
    # All element arrays are drawn even when e_max or inc_max_deg is 0 so that
    # the random stream, and hence the radii and phases, do not depend on them.
    a = np.sqrt(r_min**2 + rng.random(n) * (r_max**2 - r_min**2))
    mean_anomaly = rng.uniform(0.0, 360.0, n)
    e = e_max * rng.random(n)
    inc = inc_max_deg * rng.random(n)
    node = rng.uniform(0.0, 360.0, n)
    periapsis = rng.uniform(0.0, 360.0, n)
    gm = G * central_mass
    positions = np.zeros((n + 1, 3))
    velocities = np.zeros((n + 1, 3))
    for i in range(n):
        positions[i + 1], velocities[i + 1] = elements_to_cartesian(
            gm, a[i], e[i], inc[i], node[i], periapsis[i], M=mean_anomaly[i]
        )
    masses = np.zeros(n + 1)
    masses[0] = central_mass
    return masses, positions, velocities


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
