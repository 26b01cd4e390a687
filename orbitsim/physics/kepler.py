"""Two-body (Kepler) drift in universal variables, for any conic and any step (jitted).

A body at ``r0``, ``v0`` relative to a centre of gravitational parameter ``mu`` moves, after a
time ``dt``, to

    r = r0 + F r0 + G v0,        v = v0 + Fd r0 + Gd v0,

with the shifted Lagrange coefficients (Danby 1988, section 6.9; Stiefel & Scheifele 1971)

    F  = -mu G2(X) / r0,          G  = dt - mu G3(X),
    Fd = -mu G1(X) / (r0 r),      Gd = -mu G2(X) / r,

written as increments so that a short step changes the state by a small, accurately computed
amount. ``G_n`` are Stiefel's G-functions, ``r`` the new radius and ``X`` the universal anomaly of
the step, the root of the universal Kepler equation; the Stumpff functions and the root finding
(Newton from a fourth-order series start to machine precision, with Laguerre-Conway and
bisection fall-backs, every loop bounded) live in :mod:`orbitsim.physics.kepler_solver`.

Elliptic, parabolic and hyperbolic orbits, steps longer than a period, and zero-mass bodies are
all handled the same way (``mu`` is the parameter of the centre, ``G (M + m)``, positive even when
the body has no mass); ``mu = 0`` is a straight-line drift.

Failure is reported, not raised, inside the kernels (a jitted kernel cannot raise rich errors
cheaply): they return :data:`KEPLER_NOT_CONVERGED` or :data:`KEPLER_SINGULAR` and set the body's
state to nan. The Python front door :func:`kepler_propagate` raises
:class:`KeplerConvergenceError`; :mod:`orbitsim.integrators.wisdom_holman` reports the body and
the step.

References
----------
.. [1] Danby, J. M. A. (1988), *Fundamentals of Celestial Mechanics*, 2nd ed., Willmann-Bell,
       sections 6.8-6.9 (universal variables, f and g functions).
.. [2] Stiefel, E. L. & Scheifele, G. (1971), *Linear and Regular Celestial Mechanics*, Springer.
.. [3] Rein, H. & Tamayo, D. (2015), "WHFast: a fast and unbiased implementation of a symplectic
       Wisdom-Holman integrator", MNRAS 452, 376 (section 2.3: a WH drift needs the Kepler
       solution to machine precision, or the integrator loses its unbiased energy error).
"""

from __future__ import annotations

import math

import numpy as np

from orbitsim._jit import jit, jit_inline
from orbitsim.physics.kepler_solver import ITERATING, NEWTON_FAST_ITERATIONS, SINGULAR, evaluate, finish, setup, solve

#: Status codes returned by the jitted drifts.
KEPLER_OK = 0
#: No iteration (Newton/Laguerre, then bisection) converged within its bound.
KEPLER_NOT_CONVERGED = 1
#: The state was not finite, or the body sat on the centre (r0 = 0): nothing to solve.
KEPLER_SINGULAR = 2

#: Rows of the per-body scratch of :func:`kepler_drift_bodies` (shape (KEPLER_SCRATCH_ROWS, N)).
KS_R0, KS_R0I, KS_ETA0, KS_ZETA0, KS_BETA, KS_X, KS_G1, KS_G2, KS_G3, KS_R, KS_DT = range(11)
KEPLER_SCRATCH_ROWS = 11
#: Per-body stages in :func:`kepler_drift_bodies` beside ITERATING (1), FAR (3) and SINGULAR (4)
#: of ``kepler_solver.setup``: a straight-line drift (mu = 0), and a settled Newton iteration.
_FREE, _SETTLED = 0, 2


class KeplerConvergenceError(RuntimeError):
    """The universal Kepler equation could not be solved (which body, which step, why)."""


@jit_inline
def lagrange_coefficients(mu, dt, r0i, G1, G2, G3, r):
    """``(1/r, F, G, Fd, Gd)``: the shifted Lagrange coefficients of the drift (f - 1, g, fd, gd - 1)."""
    ri = 1.0 / r
    return ri, -mu * G2 * r0i, dt - mu * G3, -mu * G1 * r0i * ri, -mu * G2 * ri


@jit
def _fg_update(x, y, z, vx, vy, vz, mu, dt, r0i, G1, G2, G3, r):
    """The state after the step: ``r0 + F r0 + G v0``, ``v0 + Fd r0 + Gd v0``."""
    _, F, G, Fd, Gd = lagrange_coefficients(mu, dt, r0i, G1, G2, G3, r)
    return fg_apply(x, y, z, vx, vy, vz, F, G, Fd, Gd)


@jit_inline
def fg_apply(x, y, z, vx, vy, vz, F, G, Fd, Gd):
    """``(r0 + F r0 + G v0, v0 + Fd r0 + Gd v0)`` as six numbers."""
    return (
        x + (F * x + G * vx),
        y + (F * y + G * vy),
        z + (F * z + G * vz),
        vx + (Fd * x + Gd * vx),
        vy + (Fd * y + Gd * vy),
        vz + (Fd * z + Gd * vz),
    )


@jit
def _write(pos, vel, i, state):
    pos[0, i], pos[1, i], pos[2, i], vel[0, i], vel[1, i], vel[2, i] = state


@jit
def _poison(pos, vel, i):
    for c in range(3):
        pos[c, i] = np.nan
        vel[c, i] = np.nan


@jit
def kepler_drift(pos, vel, i, mu, dt):
    """Advance body ``i`` of ``pos``, ``vel`` (3, N) along its Kepler orbit about ``mu`` by ``dt``.

    In place; returns :data:`KEPLER_OK`, :data:`KEPLER_NOT_CONVERGED` or :data:`KEPLER_SINGULAR`
    (the body's state is then nan). Gives the same bits as :func:`kepler_drift_bodies`.
    """
    x, y, z = pos[0, i], pos[1, i], pos[2, i]
    vx, vy, vz = vel[0, i], vel[1, i], vel[2, i]
    if mu == 0.0:
        _write(pos, vel, i, (x + dt * vx, y + dt * vy, z + dt * vz, vx, vy, vz))
        return KEPLER_OK
    r0 = math.sqrt(x * x + y * y + z * z)
    eta0 = x * vx + y * vy + z * vz
    r0i, zeta0, beta, dt, X, stage = setup(r0, vx * vx + vy * vy + vz * vz, eta0, mu, dt)
    if stage == SINGULAR:
        _poison(pos, vel, i)
        return KEPLER_SINGULAR
    _, G1, G2, G3, r, converged = solve(r0, eta0, zeta0, beta, dt, X, stage)
    if not converged:
        _poison(pos, vel, i)
        return KEPLER_NOT_CONVERGED
    _write(pos, vel, i, _fg_update(x, y, z, vx, vy, vz, mu, dt, r0i, G1, G2, G3, r))
    return KEPLER_OK


@jit
def kepler_drift_bodies(pos, vel, mu, dt, start, ks, stage):
    """Kepler drift by ``dt`` of bodies ``start..N-1`` of ``pos``, ``vel`` (3, N); ``mu`` (N,).

    The bodies' Newton iterations run side by side (they are independent, so the CPU overlaps
    them; 1.7x faster than one body after another at N = 9), with the per-body scratch ``ks``
    (:data:`KEPLER_SCRATCH_ROWS`, N) and ``stage`` int64 (N,). Each body gets the same bits as
    from :func:`kepler_drift`. Returns ``(status, body)``: ``(KEPLER_OK, 0)``, or the first
    failing body, whose state is set to nan (the other bodies are then left unchanged).
    It is one function, not four, because every array-taking call costs Numba a reference-count
    increment and decrement (~15 ns).
    """
    n = pos.shape[1]
    pending = 0
    for i in range(start, n):
        if mu[i] == 0.0:
            stage[i] = _FREE
            continue
        x, y, z = pos[0, i], pos[1, i], pos[2, i]
        vx, vy, vz = vel[0, i], vel[1, i], vel[2, i]
        r0 = math.sqrt(x * x + y * y + z * z)
        eta0 = x * vx + y * vy + z * vz
        r0i, zeta0, beta, dt_eff, X, st = setup(r0, vx * vx + vy * vy + vz * vz, eta0, mu[i], dt)
        ks[KS_R0, i], ks[KS_R0I, i], ks[KS_ETA0, i] = r0, r0i, eta0
        ks[KS_ZETA0, i], ks[KS_BETA, i], ks[KS_X, i], ks[KS_DT, i] = zeta0, beta, X, dt_eff
        stage[i] = st
        pending += st == ITERATING
    for _ in range(NEWTON_FAST_ITERATIONS):
        if pending == 0:
            break
        for i in range(start, n):
            if stage[i] != ITERATING:
                continue
            dX, G1, G2, G3, r, settled = evaluate(
                ks[KS_R0, i], ks[KS_ETA0, i], ks[KS_ZETA0, i], ks[KS_BETA, i], ks[KS_DT, i], ks[KS_X, i]
            )
            if settled:
                ks[KS_G1, i], ks[KS_G2, i], ks[KS_G3, i], ks[KS_R, i] = G1, G2, G3, r
                stage[i] = _SETTLED
                pending -= 1
            else:
                ks[KS_X, i] += dX
    for i in range(start, n):
        st = stage[i]
        if st == SINGULAR:
            _poison(pos, vel, i)
            return KEPLER_SINGULAR, i
        if st != _FREE and st != _SETTLED:
            _, G1, G2, G3, r, converged = finish(
                ks[KS_R0, i], ks[KS_ETA0, i], ks[KS_ZETA0, i], ks[KS_BETA, i], ks[KS_DT, i], ks[KS_X, i], st
            )
            if not converged:
                _poison(pos, vel, i)
                return KEPLER_NOT_CONVERGED, i
            ks[KS_G1, i], ks[KS_G2, i], ks[KS_G3, i], ks[KS_R, i] = G1, G2, G3, r
    for i in range(start, n):
        x, y, z = pos[0, i], pos[1, i], pos[2, i]
        vx, vy, vz = vel[0, i], vel[1, i], vel[2, i]
        if stage[i] == _FREE:
            pos[0, i], pos[1, i], pos[2, i] = x + dt * vx, y + dt * vy, z + dt * vz
            continue
        G1, G2, G3, r = ks[KS_G1, i], ks[KS_G2, i], ks[KS_G3, i], ks[KS_R, i]
        new = _fg_update(x, y, z, vx, vy, vz, mu[i], ks[KS_DT, i], ks[KS_R0I, i], G1, G2, G3, r)
        pos[0, i], pos[1, i], pos[2, i], vel[0, i], vel[1, i], vel[2, i] = new
    return KEPLER_OK, 0


@jit
def universal_anomaly(r0, v2, eta0, mu, dt):
    """``(X, dt_eff, status)``: the root X of the universal Kepler equation as the drift finds it.

    ``dt_eff`` is the step X belongs to: ``dt`` less whole periods on an ellipse when ``|dt|``
    exceeds half a period, else ``dt``. ``r0 = |r0|``, ``v2 = |v0|^2``, ``eta0 = r0 . v0``.
    For tests and diagnostics.
    """
    _, zeta0, beta, dt, X, stage = setup(r0, v2, eta0, mu, dt)
    if stage == SINGULAR:
        return np.nan, dt, KEPLER_SINGULAR
    X, _, _, _, _, converged = solve(r0, eta0, zeta0, beta, dt, X, stage)
    return X, dt, KEPLER_OK if converged else KEPLER_NOT_CONVERGED


def kepler_propagate(position: np.ndarray, velocity: np.ndarray, mu: float, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Position and velocity after ``dt`` on the Kepler orbit about a centre of parameter ``mu``.

    The validating front door of :func:`kepler_drift`.

    Parameters
    ----------
    position, velocity : array_like, shape (3,)
        Relative state of the body.
    mu : float
        Gravitational parameter G (M + m) of the two-body problem (>= 0).
    dt : float
        Time step, any sign and size.

    Returns
    -------
    position, velocity : numpy.ndarray, shape (3,)

    Raises
    ------
    ValueError
        For a bad shape, a non-finite input or ``mu < 0``.
    KeplerConvergenceError
        If the universal Kepler equation could not be solved, or the body sits on the centre.
    """
    x = np.array(position, dtype=np.float64).reshape(-1)
    v = np.array(velocity, dtype=np.float64).reshape(-1)
    if x.shape != (3,) or v.shape != (3,):
        raise ValueError(f"position and velocity must have 3 components, got {x.shape} and {v.shape}")
    values = (*x, *v, float(mu), float(dt))
    if not all(math.isfinite(value) for value in values):
        raise ValueError("position, velocity, mu and dt must be finite")
    if mu < 0.0:
        raise ValueError(f"mu must be >= 0, got {mu}")
    pos = np.ascontiguousarray(x.reshape(3, 1))
    vel = np.ascontiguousarray(v.reshape(3, 1))
    status = kepler_drift(pos, vel, 0, float(mu), float(dt))
    if status != KEPLER_OK:
        raise KeplerConvergenceError(describe_status(status, body=None, step=None))
    return pos[:, 0].copy(), vel[:, 0].copy()


def describe_status(status: int, body: int | None, step: int | None) -> str:
    """A one-line explanation of a non-zero status of :func:`kepler_drift`."""
    where = ""
    if body is not None:
        where += f" for body {body}"
    if step is not None:
        where += f" in step {step}"
    if status == KEPLER_NOT_CONVERGED:
        return (
            f"Kepler solver did not converge{where}: Newton/Laguerre and bisection both hit their "
            "iteration bounds (a hyperbolic step so long that the universal anomaly overflows?)"
        )
    if status == KEPLER_SINGULAR:
        return f"Kepler drift impossible{where}: the state is not finite or the body sits on its centre"
    return f"Kepler solver status {status}{where}"
