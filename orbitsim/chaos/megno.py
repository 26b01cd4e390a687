"""MEGNO <Y> and the mean exponential growth factor, as REBOUND computes them.

For a tangent vector delta(t) = (dr, dv) carried along an orbit by the variational equations, the
MEGNO of Cincotta & Simo (2000) [1]_ is

    Y(t) = (2 / t) int_0^t  (delta'(s) . delta(s)) / (delta(s) . delta(s))  s ds,
    <Y>(t) = (1 / t) int_0^t Y(s) ds,

with delta' = (dv, da) (``deltad_delta`` is its integrand's ratio). <Y> tends to 2 for a quasi-periodic
orbit, to 0 for a stable periodic one, and grows as lambda t / 2 for a chaotic one whose maximal Lyapunov
exponent is lambda. REBOUND reports, as its ``lyapunov()``, the least-squares slope of <Y>(t) against t
(Eq. 24 of [1]), accumulated online with Welford-style running means: :func:`lyapunov` returns the same
number, so the Lyapunov time of a chaotic orbit is ``1 / lyapunov``.

:func:`megno_update` is REBOUND's ``reb_tools_megno_update`` (``src/tools.c``) step for step: each
integrator adds the step's integral increment ``dY`` (its quadrature of 2 s (delta'.delta)/(delta.delta) ds
over the step; WHFast's is ``2 dt (t - t0) deltad_delta`` at the step's end) and the step it took. The
state is a :class:`MegnoState` that jitted loops carry and return (a NamedTuple of scalars: it lives in
registers, and a checkpoint saves its fields by name).

Overflow: a chaotic orbit's tangent vector grows as exp(lambda t) and would reach inf within a long map.
Both indicators read only the ratio (delta'.delta)/(delta.delta), which a rescaling of delta by a power
of two leaves bit for bit unchanged (the variational equations are linear and such a product is exact),
so :func:`rescale_power_of_two` keeps |delta| near 1 without moving a bit of either indicator.

References
----------
.. [1] Cincotta, P. M. & Simo, C. (2000), "Simple tools to study global dynamics in non-axisymmetric
       galactic potentials - I", A&AS 147, 205.
.. [2] Rein, H. & Tamayo, D. (2016), "Second-order variational equations for N-body simulations",
       MNRAS 459, 2275 (REBOUND's variational particles).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from orbitsim._jit import jit, jit_inline


class MegnoState(NamedTuple):
    """REBOUND's MEGNO running sums (``megno_Ys``, ``megno_Yss``, ... in ``struct reb_simulation``)."""

    #: int_0^t 2 s (delta'.delta)/(delta.delta) ds: t times Y(t).
    ys: float
    #: int_0^t Y(s) ds: t times <Y>(t).
    yss: float
    #: Running co-moment of (t, <Y>) and second moment of t, and their running means.
    cov_yt: float
    var_t: float
    mean_t: float
    mean_y: float
    #: The time the indicators start from (REBOUND's ``megno_initial_t``).
    initial_t: float
    #: Number of updates (steps) so far.
    n: int


#: Field names in the order a checkpoint or a trace stores them.
MEGNO_FIELDS = MegnoState._fields


def megno_start(t0: float) -> MegnoState:
    """The state of REBOUND's ``init_megno`` at time ``t0``: every sum zero."""
    return MegnoState(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, float(t0), 0)


@jit_inline
def megno_value(state, t):
    """<Y>(t); 0 at the start time, as REBOUND's ``megno()``."""
    if t == state.initial_t:
        return 0.0
    return state.yss / (t - state.initial_t)


@jit_inline
def lyapunov(state):
    """The slope of <Y> against t (REBOUND's ``lyapunov()``): the maximal Lyapunov exponent's estimate."""
    if state.var_t == 0.0:
        return 0.0
    return state.cov_yt / state.var_t


@jit_inline
def megno_update(state, t, dY, dt_done):
    """The sums after a step that ended at time ``t``, took ``dt_done`` and added ``dY`` to t Y(t)."""
    ys = state.ys + dY
    elapsed = t - state.initial_t
    y = ys / elapsed
    yss = state.yss + y * dt_done
    n = state.n + 1
    mean_t = state.mean_t + (elapsed - state.mean_t) / n
    megno_now = yss / elapsed
    mean_y = state.mean_y + (megno_now - state.mean_y) / n
    weight = (n - 1.0) / n
    cov_yt = state.cov_yt + weight * (elapsed - mean_t) * (megno_now - mean_y)
    var_t = state.var_t + weight * (elapsed - mean_t) * (elapsed - mean_t)
    return MegnoState(ys, yss, cov_yt, var_t, mean_t, mean_y, state.initial_t, n)


@jit_inline
def deltad_delta_body(deltad, delta2, dpx, dpy, dpz, dvx, dvy, dvz, dax, day, daz):
    """One body's terms of :func:`deltad_delta`'s two running sums: ``deltad`` (delta' . delta) plus
    dv . dr and da . dv, ``delta2`` (delta . delta) plus |dr|^2 and |dv|^2, each term added alone, x, y, z
    (REBOUND's order: Python adds left to right, one rounding a term). Shared by :func:`deltad_delta_sums` and
    the ensembles' SIMD lanes, one lane a call."""
    deltad = deltad + dvx * dpx + dvy * dpy + dvz * dpz + dax * dvx + day * dvy + daz * dvz
    delta2 = delta2 + dpx * dpx + dpy * dpy + dpz * dpz + dvx * dvx + dvy * dvy + dvz * dvz
    return deltad, delta2


@jit_inline
def deltad_delta_sums(dpos, dvel, dacc, deltad, delta2):
    """:func:`deltad_delta`'s two running sums, delta' . delta and delta . delta, continued from
    ``deltad``, ``delta2`` over the bodies (columns) of ``dpos``, ``dvel``, ``dacc``, body by body.

    A caller that holds the bodies in two parts (orbitsim.ensemble.restricted) continues the sums
    from one part to the next and gets the bits of one call over all of them.
    """
    for i in range(dpos.shape[1]):
        deltad, delta2 = deltad_delta_body(deltad, delta2, dpos[0, i], dpos[1, i], dpos[2, i], dvel[0, i], dvel[1, i],
                                           dvel[2, i], dacc[0, i], dacc[1, i], dacc[2, i])
    return deltad, delta2


@jit_inline
def deltad_delta(dpos, dvel, dacc):
    """(delta' . delta) / (delta . delta) for a tangent state (dr, dv) with da = J dr (each (3, N)).

    Summed body by body in REBOUND's order (``reb_tools_megno_deltad_delta``).
    """
    deltad, delta2 = deltad_delta_sums(dpos, dvel, dacc, 0.0, 0.0)
    return deltad / delta2


@jit_inline
def tangent_norm2(dpos, dvel):
    """|delta|^2 of a tangent state, components outermost (the sum :func:`rescale_power_of_two` tests)."""
    norm2 = 0.0
    for c in range(3):
        for i in range(dpos.shape[1]):
            norm2 += dpos[c, i] * dpos[c, i] + dvel[c, i] * dvel[c, i]
    return norm2


#: |delta|^2 beyond which :func:`rescale_power_of_two` scales the tangent state down (2^200 in |delta|).
RESCALE_ABOVE = 2.0 ** 400


@jit
def rescale_power_of_two(dpos, dvel):
    """Scale (dr, dv) by 2^-200 while |delta|^2 > 2^400; return the number of halvings by 200 done.

    Exact: a power-of-two factor changes only exponents, so every ratio the indicators read is the
    same bits. The count lets a caller recover |delta| (log |delta| = log |delta_scaled| + 200 k ln 2).
    """
    count = 0
    while True:
        if not tangent_norm2(dpos, dvel) > RESCALE_ABOVE:
            return count
        for c in range(3):
            for i in range(dpos.shape[1]):
                dpos[c, i] *= 2.0 ** -200
                dvel[c, i] *= 2.0 ** -200
        count += 1


def random_initial_variation(n_bodies: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """A tangent state of unit norm per body, drawn from N(0, 1) with numpy's PCG64 and ``seed``.

    As REBOUND's ``init_megno(seed)`` does, each body's six components are normalised to length 1; the
    draws are numpy's, not REBOUND's own generator's, so to reproduce a REBOUND run give its variational
    particle explicitly (``output.chaos.variation``).
    """
    rng = np.random.default_rng(seed)
    draws = rng.standard_normal((n_bodies, 6))
    draws /= np.sqrt(np.sum(draws * draws, axis=1))[:, None]
    return np.ascontiguousarray(draws[:, :3].T), np.ascontiguousarray(draws[:, 3:].T)
