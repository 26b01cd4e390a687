"""The systems a benchmark integrates: generated ones of any N, or bundled/file scenarios.

Three generators keep the benchmark independent of the scenario files:

* ``plummer``: an equal-mass Plummer sphere in virial equilibrium
  (:func:`orbitsim.initial_conditions.generators.plummer`), G = 1, the load for large N;
* ``planets``: a unit-mass star and N - 1 planets of Jupiter-like mass ratio (~1e-3) on
  near-circular, slightly inclined orbits at a = 1.6^k, the load for small N (N = 9 is a
  Solar-System-sized problem);
* ``planetesimals``: a unit-mass star, two planets (1e-4 and 5e-5 at a = 1 and 1.6) and N - 3
  planetesimals of 1e-8 to 1e-7 on orbits that cross the planets' (a from 0.8 to 1.8, e < 0.05):
  a disc with close encounters every few orbits, the load for TRACE (``kind: trace``).

Any other name goes to :func:`orbitsim.scenario.load_scenario`, when that module exists; a
scenario brings its own G, softening and dt, and fixes N.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from orbitsim.initial_conditions.elements import elements_to_cartesian
from orbitsim.initial_conditions.generators import plummer

__all__ = ["System", "build_system", "planetesimals", "planets", "scenario_size"]

#: Spacing of the planets' semi-major axes: wide enough (ratio 1.6 > the ~1.3 Hill-stability
#: limit for 1e-3 masses) that nothing goes unstable during a benchmark.
PLANET_SPACING = 1.6


@dataclass(frozen=True)
class System:
    """Initial state of a benchmark run: (N,), (N, 3), (N, 3) float64 arrays and constants.

    ``dt`` and ``softening`` are None for generated systems (the matrix group sets them).
    """

    name: str
    masses: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray
    G: float
    dt: float | None = None
    softening: float | None = None

    @property
    def n(self) -> int:
        """Number of bodies."""
        return int(self.masses.shape[0])


def planets(n: int, *, seed: int = 1, G: float = 1.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A star of unit mass and ``n - 1`` planets on near-circular orbits, barycentric frame.

    Parameters
    ----------
    n : int
        Number of bodies (>= 1).
    seed : int
        Seed of the phases, masses and inclinations (same seed, same bits).
    G : float
        Gravitational constant; circular speeds are sqrt(G M / a).

    Returns
    -------
    masses, positions, velocities : numpy.ndarray
        (n,), (n, 3), (n, 3), C-contiguous and writable.
    """
    rng = np.random.default_rng(seed)
    k = n - 1
    masses = np.concatenate(([1.0], 1e-3 * rng.uniform(0.1, 1.0, k)))
    a = PLANET_SPACING ** np.arange(k)
    phase = rng.uniform(0.0, 2.0 * math.pi, k)
    inc = rng.uniform(0.0, 0.02, k)  # a few degrees at most: a genuinely 3-D problem
    speed = np.sqrt(G * 1.0 / a)
    pos = np.zeros((n, 3))
    vel = np.zeros((n, 3))
    pos[1:, 0] = a * np.cos(phase)
    pos[1:, 1] = a * np.sin(phase) * np.cos(inc)
    pos[1:, 2] = a * np.sin(phase) * np.sin(inc)
    vel[1:, 0] = -speed * np.sin(phase)
    vel[1:, 1] = speed * np.cos(phase) * np.cos(inc)
    vel[1:, 2] = speed * np.cos(phase) * np.sin(inc)
    total = masses.sum()
    pos -= (masses[:, None] * pos).sum(axis=0) / total
    vel -= (masses[:, None] * vel).sum(axis=0) / total
    return masses, np.ascontiguousarray(pos), np.ascontiguousarray(vel)


#: The planets of the ``planetesimals`` disc: (mass, semi-major axis), star mass 1, e = 0.02. 12
#: mutual Hill radii apart: they stay on their orbits while the planetesimals between and around
#: them pass inside their Hill spheres, the encounters TRACE hands to Bulirsch-Stoer.
DISC_PLANETS = ((1e-4, 1.0), (5e-5, 1.6))
#: The planetesimals: semi-major axes uniform in area over this range (across both planets'
#: orbits), masses log-uniform over this range (massive: their mutual encounters count too, and
#: their Hill radii, 3e-3 to 6e-3 at a = 1, make them), eccentricities up to E_MAX, inclinations
#: up to INC_MAX_DEG.
DISC_A = (0.8, 1.8)
DISC_MASS = (1e-8, 1e-7)
DISC_E_MAX = 0.05
DISC_INC_MAX_DEG = 1.0


def planetesimals(n: int, *, seed: int = 1, G: float = 1.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A star of unit mass, the planets of :data:`DISC_PLANETS` and ``n - 3`` planetesimals,
    barycentric frame; fewer than 3 bodies keep the first ``n - 1`` planets.

    Returns (n,), (n, 3), (n, 3) C-contiguous, writable arrays; the same seed gives the same bits.
    """
    rng = np.random.default_rng(seed)
    planets = DISC_PLANETS[: max(0, n - 1)]
    k = n - 1 - len(planets)
    lo, hi = DISC_A
    masses = np.concatenate(([1.0], [p[0] for p in planets],
                             np.exp(rng.uniform(math.log(DISC_MASS[0]), math.log(DISC_MASS[1]), k))))
    a = np.concatenate(([p[1] for p in planets], np.sqrt(lo**2 + rng.random(k) * (hi**2 - lo**2))))
    e = np.concatenate((np.full(len(planets), 0.02), DISC_E_MAX * rng.random(k)))
    inc = DISC_INC_MAX_DEG * rng.random(n - 1)
    node, peri, mean = (rng.uniform(0.0, 360.0, n - 1) for _ in range(3))
    pos = np.zeros((n, 3))
    vel = np.zeros((n, 3))
    for i in range(1, n):
        pos[i], vel[i] = elements_to_cartesian(G * (1.0 + masses[i]), a[i - 1], e[i - 1], inc[i - 1], node[i - 1],
                                               peri[i - 1], M=mean[i - 1])
    total = masses.sum()
    pos -= (masses[:, None] * pos).sum(axis=0) / total
    vel -= (masses[:, None] * vel).sum(axis=0) / total
    return masses, np.ascontiguousarray(pos), np.ascontiguousarray(vel)


def _load_scenario(name: str) -> Any:
    from orbitsim.scenario import load_scenario  # noqa: PLC0415 -- lazy: loads yaml

    return load_scenario(name)


def scenario_size(name: str) -> int:
    """Number of bodies of a bundled or file scenario (raises if it cannot be loaded)."""
    return int(np.asarray(_load_scenario(name).masses).shape[0])


def build_system(name: str, n: int, *, seed: int = 1) -> System:
    """The initial state of system ``name`` with ``n`` bodies (``n`` is ignored for a scenario)."""
    if name == "plummer":
        m, x, v = plummer(int(n), seed=seed)
        return System(name, m, np.ascontiguousarray(x), np.ascontiguousarray(v), 1.0)
    if name == "planets":
        m, x, v = planets(int(n), seed=seed)
        return System(name, m, x, v, 1.0)
    if name == "planetesimals":
        m, x, v = planetesimals(int(n), seed=seed)
        return System(name, m, x, v, 1.0)
    sc = _load_scenario(name)
    # Copies: Numba compiles a separate, uncached specialisation for read-only arrays.
    return System(sc.name, np.array(sc.masses, dtype=np.float64), np.array(sc.positions, dtype=np.float64),
                  np.array(sc.velocities, dtype=np.float64), float(sc.G), float(sc.dt), float(sc.softening))
