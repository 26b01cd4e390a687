"""Each body's shortest orbital timescale ahead, from one state: the check a run without ``events:``
makes at its samples (:mod:`orbitsim.events.sampled`).

The events watch judges every step against the timescale tau of the orbit the body is on *then*
(:func:`orbitsim.events.bodies.check_unresolved`). A check that looks only at a few states must
instead ask what the orbit will demand: the osculating two-body orbit about the dominant
attractor has its tightest point at its pericentre, which a bound orbit passes every period and
an approaching one is about to pass. So tau is the smaller of its value now and at that pericentre
(Pham, Rein & Spiegel 2024, eq. 16, as the watch evaluates it), and one state of an e = 0.99
comet at aphelion shows that dt = P / 200 is far too long for its perihelion.
"""

from __future__ import annotations

import math
import types
from collections.abc import Callable

import numpy as np

from orbitsim._jit import jit
from orbitsim.events.bodies import two_body_tau2

__all__ = ["PYTHON_MAX_N", "orbit_timescales", "orbit_timescales_python", "timescales_of"]

#: Up to this many bodies :func:`timescales_of` runs the check's code in the interpreter: at N = 32
#: about a millisecond a look, where compiling it costs a first run 1-2 s (a third of a 10-step run).
PYTHON_MAX_N = 32


@jit
def orbit_timescales(pos, vel, m, G, eps2, tau, attractor, closest):
    """Fill ``tau`` (N,) with each body's shortest timescale ahead about its dominant attractor
    ``attractor`` (N,) int64 (the body pulling it hardest, G m_j / r^2; -1 for none), and
    ``closest`` (N,) with the separation where it is reached: the pericentre of the osculating
    orbit when that orbit is bound or the pair approaches, else the separation now.

    ``pos``, ``vel``: (3, N); ``m``: (N,); O(N^2) for the attractors, O(N) for the rest. A pair
    whose bodies attract each other most is judged once, under the lighter body (the heavier
    gets ``tau = inf``), as the events watch does. With softening eps (``eps2`` = eps^2) no
    timescale is shorter than a circular orbit's at r = eps, sqrt(eps^3 / G m): the softened force
    is smooth inside eps, and two bodies passing within it are resolved at that timescale.
    """
    n = pos.shape[1]
    best = np.zeros(n)
    for i in range(n):
        attractor[i] = -1
        tau[i] = np.inf
        closest[i] = np.nan
    for i in range(n):
        for j in range(i + 1, n):
            dx = pos[0, i] - pos[0, j]
            dy = pos[1, i] - pos[1, j]
            dz = pos[2, i] - pos[2, j]
            r2 = dx * dx + dy * dy + dz * dz
            if r2 > 0.0:
                if G * m[j] / r2 > best[i]:
                    best[i] = G * m[j] / r2
                    attractor[i] = j
                if G * m[i] / r2 > best[j]:
                    best[j] = G * m[i] / r2
                    attractor[j] = i
    for i in range(n):
        k = attractor[i]
        if k < 0 or (attractor[k] == i and (m[i] > m[k] or (m[i] == m[k] and i > k))):
            continue
        x, y, z = pos[0, i] - pos[0, k], pos[1, i] - pos[1, k], pos[2, i] - pos[2, k]
        vx, vy, vz = vel[0, i] - vel[0, k], vel[1, i] - vel[1, k], vel[2, i] - vel[2, k]
        gm = G * (m[i] + m[k])
        tau2 = two_body_tau2(x, y, z, vx, vy, vz, gm)
        r = math.sqrt(x * x + y * y + z * z)
        where = r
        hx, hy, hz = y * vz - z * vy, z * vx - x * vz, x * vy - y * vx
        h2 = hx * hx + hy * hy + hz * hz
        energy = 0.5 * (vx * vx + vy * vy + vz * vz) - gm / r
        if h2 > 0.0 and (energy < 0.0 or x * vx + y * vy + z * vz < 0.0):
            e = math.sqrt(max(0.0, 1.0 + 2.0 * energy * h2 / (gm * gm)))
            rp = h2 / (gm * (1.0 + e))
            peri2 = two_body_tau2(rp, 0.0, 0.0, 0.0, math.sqrt(h2) / rp, 0.0, gm)
            if peri2 < tau2:
                tau2, where = peri2, rp
        if eps2 > 0.0:
            tau2 = max(tau2, eps2 * math.sqrt(eps2) / gm)
        tau[i] = math.sqrt(tau2)
        closest[i] = where


def _interpreted() -> Callable[..., None]:
    """:func:`orbit_timescales`'s own code, for the interpreter: the Python functions behind the
    jitted one and its ``two_body_tau2`` (plain functions under ``NUMBA_DISABLE_JIT``)."""
    body = getattr(orbit_timescales, "py_func", orbit_timescales)
    tau2 = getattr(two_body_tau2, "py_func", two_body_tau2)
    return types.FunctionType(body.__code__, {**body.__globals__, "two_body_tau2": tau2}, body.__name__)


_orbit_timescales_python = _interpreted()


def orbit_timescales_python(pos: np.ndarray, vel: np.ndarray, m: np.ndarray, G: float, eps2: float, tau: np.ndarray,
                            attractor: np.ndarray, closest: np.ndarray) -> None:
    """:func:`orbit_timescales` run by the interpreter, nothing compiled. Every operation is the
    same IEEE double operation in the same order on numpy float64 scalars (no fastmath, no
    contraction in the compiled one), so the outputs are the same bits (tested). Division by zero
    gives inf or nan as compiled (``error_model="numpy"``), not an exception."""
    with np.errstate(all="ignore"):
        _orbit_timescales_python(pos, vel, m, G, eps2, tau, attractor, closest)


def timescales_of(pos: np.ndarray, vel: np.ndarray, m: np.ndarray, G: float, eps2: float, tau: np.ndarray,
                  attractor: np.ndarray, closest: np.ndarray) -> None:
    """:func:`orbit_timescales`, interpreted for a finite state of at most :data:`PYTHON_MAX_N`
    bodies (a run's first look then compiles nothing), compiled otherwise. A state that is not
    finite goes to the compiled code, where ``math.sqrt`` of a nan cannot raise."""
    if pos.shape[1] <= PYTHON_MAX_N and np.isfinite(pos).all() and np.isfinite(vel).all():
        orbit_timescales_python(pos, vel, m, G, eps2, tau, attractor, closest)
    else:
        orbit_timescales(pos, vel, m, G, eps2, tau, attractor, closest)
