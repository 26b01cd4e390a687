"""Slow, obviously-correct references for the tests: plain numpy, (N, 3) arrays, no Numba.

Everything here is written from the formulas, independently of the engine's kernels:

* :func:`accelerations` is the O(N^2) double loop over ordered pairs (no Newton's-third-law trick,
  no blocks, no reassociation), so agreement with the engine tests the engine's pair bookkeeping;
* :func:`energy` is T + U with the Plummer-softened potential U = -G m_i m_j / sqrt(r^2 + eps^2);
* ``step_<scheme>`` takes one step of each registered fixed-step scheme built from kicks, drifts
  or RK stages, in its textbook form (REBOUND's schemes, Wisdom-Holman, IAS15 and TRACE, have
  REBOUND as their reference: tests/integrators/test_integrators_naive.py names the tests); the
  compositions are written as *unmerged* sequences of whole DKD leapfrog substeps (the engine
  merges neighbouring drifts), so they also test the merging;
* ``sample_steps_every`` / ``sample_steps_interval`` build a whole sampling plan in one array,
  as the engine did before its plans were produced block by block.

The fourth-order weights come from Yoshida's closed form, computed here. The sixth- and
eighth-order tables are imported from :mod:`orbitsim.integrators.leapfrog`; their identities
(sum, symmetry, order conditions) are tested on their own in ``tests/integrators/test_composition_tables.py``.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from orbitsim.integrators.leapfrog import LEAPFROG6_WEIGHTS, LEAPFROG8_WEIGHTS

#: Yoshida (1990), Phys. Lett. A 150, 262: the triple jump w1 = 1 / (2 - 2^(1/3)), w0 = 1 - 2 w1.
YOSHIDA_W1 = 1.0 / (2.0 - 2.0 ** (1.0 / 3.0))
YOSHIDA_W0 = 1.0 - 2.0 * YOSHIDA_W1
YOSHIDA4_WEIGHTS = np.array([YOSHIDA_W1, YOSHIDA_W0, YOSHIDA_W1])


def accelerations(pos: np.ndarray, m: np.ndarray, G: float, eps: float) -> np.ndarray:
    """a_i = G sum_{j != i} m_j (x_j - x_i) / (|x_j - x_i|^2 + eps^2)^(3/2), pos (N, 3)."""
    pos = np.asarray(pos, dtype=np.float64)
    n = pos.shape[0]
    acc = np.zeros((n, 3))
    for i in range(n):
        for j in range(n):
            if i == j:
                continue
            d = pos[j] - pos[i]
            r2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2] + eps * eps
            acc[i] += G * m[j] * d / r2**1.5
    return acc


def kinetic_energy(vel: np.ndarray, m: np.ndarray) -> float:
    """T = sum m |v|^2 / 2."""
    return float(0.5 * np.sum(m * np.sum(np.asarray(vel) ** 2, axis=1)))


def potential_energy(pos: np.ndarray, m: np.ndarray, G: float, eps: float) -> float:
    """U = -sum_{i<j} G m_i m_j / sqrt(|x_i - x_j|^2 + eps^2)."""
    pos = np.asarray(pos, dtype=np.float64)
    total = 0.0
    for i in range(pos.shape[0]):
        for j in range(i + 1, pos.shape[0]):
            d = pos[j] - pos[i]
            total -= G * m[i] * m[j] / np.sqrt(d @ d + eps * eps)
    return total


def energy(pos: np.ndarray, vel: np.ndarray, m: np.ndarray, G: float, eps: float) -> float:
    """Total energy T + U."""
    return kinetic_energy(vel, m) + potential_energy(pos, m, G, eps)


# --- one step of each scheme: (pos, vel, m, G, eps, dt) -> (new pos, new vel) -------------------

Step = Callable[[np.ndarray, np.ndarray, np.ndarray, float, float, float], tuple[np.ndarray, np.ndarray]]


def step_euler(pos, vel, m, G, eps, dt):
    """Explicit Euler: x' = x + dt v, v' = v + dt a(x) (both from the old state)."""
    a = accelerations(pos, m, G, eps)
    return pos + dt * vel, vel + dt * a


def step_semi_implicit_euler(pos, vel, m, G, eps, dt):
    """Kick then drift: v' = v + dt a(x), x' = x + dt v'."""
    v_new = vel + dt * accelerations(pos, m, G, eps)
    return pos + dt * v_new, v_new


def step_verlet(pos, vel, m, G, eps, dt):
    """Velocity Verlet, kick-drift-kick."""
    v_half = vel + 0.5 * dt * accelerations(pos, m, G, eps)
    x_new = pos + dt * v_half
    return x_new, v_half + 0.5 * dt * accelerations(x_new, m, G, eps)


def step_leapfrog(pos, vel, m, G, eps, dt):
    """Drift-kick-drift leapfrog."""
    x_half = pos + 0.5 * dt * vel
    v_new = vel + dt * accelerations(x_half, m, G, eps)
    return x_half + 0.5 * dt * v_new, v_new


def step_rk4(pos, vel, m, G, eps, dt):
    """Classical Runge-Kutta on y = (x, v), y' = (v, a(x))."""
    k1x, k1v = vel, accelerations(pos, m, G, eps)
    k2x, k2v = vel + 0.5 * dt * k1v, accelerations(pos + 0.5 * dt * k1x, m, G, eps)
    k3x, k3v = vel + 0.5 * dt * k2v, accelerations(pos + 0.5 * dt * k2x, m, G, eps)
    k4x, k4v = vel + dt * k3v, accelerations(pos + dt * k3x, m, G, eps)
    x_new = pos + dt / 6.0 * (k1x + 2.0 * k2x + 2.0 * k3x + k4x)
    v_new = vel + dt / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v)
    return x_new, v_new


def compose_leapfrog(weights: np.ndarray) -> Step:
    """A step that applies whole DKD leapfrog substeps of sizes w_1 dt, ..., w_s dt in turn."""

    def step(pos, vel, m, G, eps, dt):
        for w in weights:
            pos, vel = step_leapfrog(pos, vel, m, G, eps, w * dt)
        return pos, vel

    return step


step_leapfrog4 = compose_leapfrog(YOSHIDA4_WEIGHTS)
step_leapfrog6 = compose_leapfrog(np.asarray(LEAPFROG6_WEIGHTS))
step_leapfrog8 = compose_leapfrog(np.asarray(LEAPFROG8_WEIGHTS))

#: Reference step of every scheme that has one, by registry name.
STEPS: dict[str, Step] = {
    "euler": step_euler,
    "semi_implicit_euler": step_semi_implicit_euler,
    "verlet": step_verlet,
    "leapfrog": step_leapfrog,
    "rk4": step_rk4,
    "leapfrog4": step_leapfrog4,
    "leapfrog6": step_leapfrog6,
    "leapfrog8": step_leapfrog8,
}


def run(name: str, pos, vel, m, G: float, eps: float, dt: float, steps: int) -> tuple[np.ndarray, np.ndarray]:
    """``steps`` reference steps of scheme ``name`` from (pos, vel), both (N, 3)."""
    pos = np.array(pos, dtype=np.float64)
    vel = np.array(vel, dtype=np.float64)
    m = np.asarray(m, dtype=np.float64)
    for _ in range(steps):
        pos, vel = STEPS[name](pos, vel, m, G, eps, dt)
    return pos, vel


# --- the Kepler problem, analytically --------------------------------------------------------


def solve_kepler(mean_anomaly: float, e: float) -> float:
    """Eccentric anomaly E with E - e sin E = M (Newton's method to machine precision)."""
    M = float(np.remainder(mean_anomaly, 2.0 * np.pi))
    E = M if e < 0.8 else np.pi
    for _ in range(100):
        delta = (E - e * np.sin(E) - M) / (1.0 - e * np.cos(E))
        E -= delta
        if abs(delta) < 1e-16:
            break
    return E


def kepler_state(t: float, a: float, e: float, mu: float) -> tuple[np.ndarray, np.ndarray]:
    """Relative position and velocity (3,) at time t; orbit in the xy-plane, pericentre on +x at t = 0."""
    n = np.sqrt(mu / a**3)
    E = solve_kepler(n * t, e)
    b = a * np.sqrt(1.0 - e * e)
    edot = n / (1.0 - e * np.cos(E))
    x = np.array([a * (np.cos(E) - e), b * np.sin(E), 0.0])
    v = np.array([-a * np.sin(E) * edot, b * np.cos(E) * edot, 0.0])
    return x, v


# --- sampling plans, built whole -------------------------------------------------------------


def sample_steps_every(n_steps: int, every: int) -> np.ndarray:
    """0, K, 2K, ... and always the last step, in one array."""
    steps = np.arange(0, n_steps + 1, every, dtype=np.int64)
    if steps[-1] != n_steps:
        steps = np.append(steps, np.int64(n_steps))
    return steps


def sample_steps_interval(n_steps: int, dt: float, interval: float) -> np.ndarray:
    """The last whole step at or before each k * interval, and the last step, in one array."""
    t_end = n_steps * dt
    k = np.arange(0, math.floor(t_end / interval) + 1, dtype=np.float64)
    wanted = k * interval
    steps = np.floor(wanted / dt).astype(np.int64)
    steps -= (steps * dt > wanted).astype(np.int64)
    steps += ((steps + 1) * dt <= wanted).astype(np.int64)
    steps = np.unique(np.clip(steps, 0, n_steps))
    if steps[-1] != n_steps:
        steps = np.append(steps, np.int64(n_steps))
    return steps
