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
import time
import types
from collections.abc import Callable

import numpy as np

from orbitsim._jit import jit, jit_inline
from orbitsim.events.bodies import two_body_tau2

__all__ = ["INTERPRETED_BUDGET_S", "INTERPRETED_MAX_N", "orbit_timescales", "orbit_timescales_python",
           "timescales_of"]

#: Up to this many bodies :func:`timescales_of` can look without compiling anything: the O(N^2) search
#: for attractors in numpy, the O(N) rest in the interpreter (~40 us a body: 8 ms a look at N = 201,
#: up to ~150 ms at this N). Compiling :func:`orbit_timescales` costs a first run more than a second, a
#: sixth of a 10-step run of 200 bodies.
INTERPRETED_MAX_N = 1024

#: Seconds of interpreted looks a process may spend before :func:`timescales_of` compiles: about what
#: the compile costs, so a run that looks often pays at most twice the cheaper of the two ways (and a
#: short run, nothing to compile).
INTERPRETED_BUDGET_S = 1.0

#: Pairs the numpy search holds at once (a few arrays of this many doubles: 8 MiB each).
_PAIRS_PER_BLOCK = 2**20


@jit_inline
def dominant_attractors(pos, m, G, attractor):
    """``attractor`` (N,) int64: the body pulling each body hardest, G m_j / r^2 (-1 for none), the
    first such j where two pull equally; pairs at r = 0 are left out."""
    n = pos.shape[1]
    best = np.zeros(n)
    for i in range(n):
        attractor[i] = -1
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


@jit_inline
def timescales_about(pos, vel, m, G, eps2, attractor, tau, closest):
    """``tau`` and ``closest`` (N,) of every body about its ``attractor`` (:func:`orbit_timescales`)."""
    n = pos.shape[1]
    for i in range(n):
        tau[i] = np.inf
        closest[i] = np.nan
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

    Its two halves are inlined (one compilation); :func:`orbit_timescales_python` runs them uncompiled.
    """
    dominant_attractors(pos, m, G, attractor)
    timescales_about(pos, vel, m, G, eps2, attractor, tau, closest)


def _attractors_numpy(pos: np.ndarray, m: np.ndarray, G: float, attractor: np.ndarray) -> None:
    """:func:`dominant_attractors` in numpy, a block of rows at a time: the same pull G m_j / r^2 of
    every pair (the same IEEE operations: r^2 is the same for i, j and j, i, a difference only
    changing sign), and the first largest one above 0 (``argmax`` keeps the first, as the loop's
    strict ``>`` does)."""
    n = pos.shape[1]
    rows = max(1, _PAIRS_PER_BLOCK // max(n, 1))
    pull_of = G * m
    for first in range(0, n, rows):
        last = min(n, first + rows)
        dx = pos[0, first:last, None] - pos[0, None, :]
        dy = pos[1, first:last, None] - pos[1, None, :]
        dz = pos[2, first:last, None] - pos[2, None, :]
        r2 = dx * dx + dy * dy + dz * dz
        pull = pull_of[None, :] / r2
        pull[~(r2 > 0.0)] = -np.inf
        best = pull.argmax(axis=1)
        attractor[first:last] = np.where(pull[np.arange(last - first), best] > 0.0, best, -1)


def _interpreted() -> Callable[..., None]:
    """:func:`timescales_about`'s own code, for the interpreter: the Python functions behind the
    jitted one and its ``two_body_tau2`` (plain functions under ``NUMBA_DISABLE_JIT``)."""
    body = getattr(timescales_about, "py_func", timescales_about)
    tau2 = getattr(two_body_tau2, "py_func", two_body_tau2)
    return types.FunctionType(body.__code__, {**body.__globals__, "two_body_tau2": tau2}, body.__name__)


_timescales_about_python = _interpreted()


def orbit_timescales_python(pos: np.ndarray, vel: np.ndarray, m: np.ndarray, G: float, eps2: float, tau: np.ndarray,
                            attractor: np.ndarray, closest: np.ndarray) -> None:
    """:func:`orbit_timescales` with nothing compiled: the attractors in numpy, the rest run by the
    interpreter. Every operation is the same IEEE double operation in the same order on numpy float64
    values (no fastmath, no contraction in the compiled one), so the outputs are the same bits
    (tested). Division by zero gives inf or nan as compiled (``error_model="numpy"``), not an exception."""
    with np.errstate(all="ignore"):
        _attractors_numpy(pos, m, np.float64(G), attractor)
        _timescales_about_python(pos, vel, m, np.float64(G), np.float64(eps2), attractor, tau, closest)


#: Seconds this process has spent in :func:`orbit_timescales_python` (against :data:`INTERPRETED_BUDGET_S`).
_interpreted_seconds = [0.0]


def _compiled_at_hand() -> bool:
    """Whether :func:`orbit_timescales` runs without compiling: compiled in this process already, or in
    Numba's on-disk cache (its index, read through Numba's private cache object: where that fails, False,
    and the looks are interpreted until the budget is spent, as on a cold cache)."""
    if getattr(orbit_timescales, "signatures", None):
        return True
    try:
        return bool(orbit_timescales._cache._cache_file._load_index())
    except Exception:  # any change in Numba's internals (or NUMBA_DISABLE_JIT) means "not known to be cached"
        return False


def timescales_of(pos: np.ndarray, vel: np.ndarray, m: np.ndarray, G: float, eps2: float, tau: np.ndarray,
                  attractor: np.ndarray, closest: np.ndarray) -> None:
    """:func:`orbit_timescales`, compiled where that costs no compilation (:func:`_compiled_at_hand`),
    else interpreted (:func:`orbit_timescales_python`: a run's looks then compile nothing) for a finite
    state of at most :data:`INTERPRETED_MAX_N` bodies until the process has spent
    :data:`INTERPRETED_BUDGET_S` on them, and compiled after that. A state that is not finite goes to
    the compiled code, where ``math.sqrt`` of a nan cannot raise."""
    if (pos.shape[1] <= INTERPRETED_MAX_N and _interpreted_seconds[0] < INTERPRETED_BUDGET_S
            and np.isfinite(pos).all() and np.isfinite(vel).all() and not _compiled_at_hand()):
        started = time.perf_counter()
        orbit_timescales_python(pos, vel, m, G, eps2, tau, attractor, closest)
        _interpreted_seconds[0] += time.perf_counter() - started
    else:
        orbit_timescales(pos, vel, m, G, eps2, tau, attractor, closest)
