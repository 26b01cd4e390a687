"""TRACE's Kepler drift: REBOUND's WHFast universal-variable solver, operation for operation.

TRACE drifts every body about the star alone, ``mu = G m_0``, with the heliocentric position and
the barycentric (democratic heliocentric) velocity. In universal variables, with
``r0 = |x0|``, ``beta = 2 mu / r0 - |v0|^2``, ``eta0 = x0 . v0``, ``zeta0 = mu - beta r0`` and
Stiefel's functions ``G_n(X) = X^n c_n(beta X^2)``, the anomaly X of a step dt solves

    r0 X + eta0 G2(X) + zeta0 G3(X) = dt,

and the state moves by the increments ``dx = f x0 + g v0``, ``dv = fd x0 + gd v0`` with
``f = -mu G2 / r0``, ``g = dt - mu G3``, ``fd = -mu G1 / (r0 r)``, ``gd = -mu G2 / r``.

Why not :mod:`orbitsim.physics.kepler` (its solver is :mod:`orbitsim.physics.kepler_solver`): that
solver starts from a fourth-order series, stops on a residual test, reduces long steps by whole
periods and sums the Stumpff series up to ``|z| = 1``; each of these changes the last bits, and
TRACE's switching turns last-bit differences into different step histories. This module follows
``reb_integrator_whfast_kepler_solver`` (REBOUND ``integrator_whfast.c``) instead: the same
second-order start, one Newton step, then Laguerre-Conway (Conway 1986) if that step moved X by
more than 1% of a period, else Newton to a fixed point or a two-cycle, bisection as the last
resort, and the increment form. The Stumpff series is REBOUND's ``stumpff_cs3`` (quarter z to
``|z| <= 0.1``, 13 terms, double back up).

References
----------
.. [1] Rein, H. & Tamayo, D. (2015), MNRAS 452, 376 (WHFast).
.. [2] Conway, B. A. (1986), Celest. Mech. 39, 199 (Laguerre-Conway).
"""

from __future__ import annotations

import math

import numpy as np

from orbitsim._jit import jit, jit_inline

#: 1/n! for n = 0..13, as REBOUND's ``invfactorial`` table (each entry the correctly rounded
#: quotient of 1 by the correctly rounded n!, which is what its C literals compile to).
INV_FACTORIAL = np.array([1.0 / float(math.factorial(n)) for n in range(14)])
#: Highest term of the Stumpff series (REBOUND's ``nmax`` in ``stumpff_cs3``).
STUMPFF_NMAX = 13
#: Quartering bound: 4^520 exceeds the largest double, so any finite z is reduced before it; the
#: bound only keeps an infinite z from looping forever (REBOUND would hang there).
STUMPFF_MAX_QUARTERINGS = 520
#: Iteration caps of REBOUND's solver (``WHFAST_NMAX_QUART``, ``WHFAST_NMAX_NEWT``).
LAGUERRE_MAX = 64
NEWTON_MAX = 32
#: Bisection cap: REBOUND's loop has none; halving a finite bracket reaches the 1e-15 relative
#: width within ~2100 halvings even from the full double range.
BISECTION_MAX = 2200
#: Length of the scratch array that holds the Laguerre-Conway iterates (``prevX[64 + 1]``).
PREV_X_LENGTH = LAGUERRE_MAX + 1


@jit_inline
def stumpff_cs3(z):
    """Stumpff functions ``(c0, c1, c2, c3)`` at z (REBOUND's ``stumpff_cs3``)."""
    n = 0
    while abs(z) > 0.1 and n < STUMPFF_MAX_QUARTERINGS:
        z = z / 4.0
        n += 1
    c_odd = INV_FACTORIAL[STUMPFF_NMAX]
    c_even = INV_FACTORIAL[STUMPFF_NMAX - 1]
    for k in range(STUMPFF_NMAX - 2, 2, -2):
        c_odd = INV_FACTORIAL[k] - z * c_odd
        c_even = INV_FACTORIAL[k - 1] - z * c_even
    c3 = c_odd
    c2 = c_even
    c1 = INV_FACTORIAL[1] - z * c_odd
    c0 = INV_FACTORIAL[0] - z * c_even
    for _ in range(n):
        # The quarter-argument identities, each from the values at the smaller argument.
        c3 = (c2 + c0 * c3) * 0.25
        c2 = c1 * c1 * 0.5
        c1 = c0 * c1
        c0 = 2.0 * c0 * c0 - 1.0
    return c0, c1, c2, c3


@jit_inline
def stiefel_gs3(beta, X):
    """Stiefel's ``(G0, G1, G2, G3)`` at X (G0 left as c0, as REBOUND's ``stiefel_Gs3``)."""
    X2 = X * X
    c0, c1, c2, c3 = stumpff_cs3(beta * X2)
    return c0, c1 * X, c2 * X2, c3 * (X2 * X)


@jit
def _bisect_anomaly(r0, v2, eta0, zeta0, beta, mu, dt, invperiod, X_per_period):
    """X by bisection of the monotone Kepler equation on REBOUND's bracket; ``(X, G1, G2, G3)``."""
    if beta > 0.0:
        X_min = X_per_period * math.floor(dt * invperiod)
        X_max = X_min + X_per_period
    else:
        # Hyperbola: X lies between dt / r_max (r_max = r0 + |v_q dt|) and dt / q (pericentre q).
        h2 = r0 * r0 * v2 - eta0 * eta0
        q = h2 / mu / (1.0 + math.sqrt(1.0 - h2 * beta / (mu * mu)))
        vq = math.copysign(math.sqrt(h2) / q, dt)
        X_min = dt / (abs(vq * dt) + r0)
        X_max = dt / q
        if dt < 0.0:
            X_min, X_max = X_max, X_min
    X = (X_max + X_min) / 2.0
    G1 = G2 = G3 = 0.0
    for _ in range(BISECTION_MAX):
        _, G1, G2, G3 = stiefel_gs3(beta, X)
        s = r0 * X + eta0 * G2 + zeta0 * G3 - dt
        if s >= 0.0:
            X_max = X
        else:
            X_min = X
        X = (X_max + X_min) / 2.0
        if not abs(X_max - X_min) > abs((X_max + X_min) * 1e-15):
            break
    return X, G1, G2, G3


@jit
def _laguerre_conway(r0, eta0, zeta0, beta, mu, dt, prev_x):
    """Laguerre-Conway from the mean-motion start until an iterate repeats an earlier one.

    Returns ``(converged, G1, G2, G3)`` with the G-functions of the last iterate evaluated (not
    of the final X, which REBOUND does not use either).
    """
    X = beta * dt / mu
    G1 = G2 = G3 = 0.0
    for n_lag in range(1, LAGUERRE_MAX):
        G0, G1, G2, G3 = stiefel_gs3(beta, X)
        f = r0 * X + eta0 * G2 + zeta0 * G3 - dt
        fp = r0 + eta0 * G1 + zeta0 * G2
        fpp = eta0 * G0 + zeta0 * G1
        denom = fp + math.sqrt(abs(16.0 * fp * fp - 20.0 * f * fpp))
        X = (X * denom - 5.0 * f) / denom
        for k in range(1, n_lag):
            if X == prev_x[k]:
                return True, G1, G2, G3
        prev_x[n_lag] = X
    return False, G1, G2, G3


@jit_inline
def kepler_drift(x, y, z, vx, vy, vz, mu, dt, prev_x):
    """The state ``(x, y, z, vx, vy, vz)`` after a Kepler drift of dt about ``mu``.

    ``prev_x`` (:data:`PREV_X_LENGTH`,) is scratch for the Laguerre-Conway iterates. Scalars in
    and out: an array argument costs a reference-count round trip per call (measured).
    """
    r0 = math.sqrt(x * x + y * y + z * z)
    r0i = 1.0 / r0
    v2 = vx * vx + vy * vy + vz * vz
    beta = 2.0 * mu * r0i - v2
    eta0 = x * vx + y * vy + z * vz
    zeta0 = mu - beta * r0
    invperiod = 0.0
    # nan makes the Laguerre test below false, so hyperbolic orbits always take Newton.
    X_per_period = np.nan
    if beta > 0.0:
        sqrt_beta = math.sqrt(beta)
        invperiod = sqrt_beta * beta / (2.0 * math.pi * mu)
        X_per_period = 2.0 * math.pi / sqrt_beta
        dtr0i = dt * r0i
        X = dtr0i * (1.0 - dtr0i * eta0 * 0.5 * r0i)  # second-order start
    else:
        X = 0.0
    converged = False
    oldX = X
    _, G1, G2, G3 = stiefel_gs3(beta, X)
    eG = eta0 * G1 + zeta0 * G2
    ri = 1.0 / (r0 + eG)
    X = ri * (X * eG - eta0 * G2 - zeta0 * G3 + dt)
    if abs(X - oldX) > 0.01 * X_per_period:
        # A long step (more than 1% of a period off after one Newton step).
        converged, G1, G2, G3 = _laguerre_conway(r0, eta0, zeta0, beta, mu, dt, prev_x)
        ri = 1.0 / (r0 + (eta0 * G1 + zeta0 * G2))
    else:
        oldX2 = np.nan
        for _ in range(1, NEWTON_MAX):
            oldX2 = oldX
            oldX = X
            _, G1, G2, G3 = stiefel_gs3(beta, X)
            eG = eta0 * G1 + zeta0 * G2
            ri = 1.0 / (r0 + eG)
            X = ri * (X * eG - eta0 * G2 - zeta0 * G3 + dt)
            if X == oldX or X == oldX2:
                converged = True
                break
    if not converged:
        X, G1, G2, G3 = _bisect_anomaly(r0, v2, eta0, zeta0, beta, mu, dt, invperiod, X_per_period)
        ri = 1.0 / (r0 + (eta0 * G1 + zeta0 * G2))
    if math.isnan(ri):
        # (Almost) straight-line hyperbolic motion: REBOUND drops the Kepler terms.
        ri = 0.0
        G1 = G2 = G3 = 0.0
    f = -mu * G2 * r0i
    g = dt - mu * G3
    fd = -mu * G1 * r0i * ri
    gd = -mu * G2 * ri
    return (x + (f * x + g * vx), y + (f * y + g * vy), z + (f * z + g * vz),
            vx + (fd * x + gd * vx), vy + (fd * y + gd * vy), vz + (fd * z + gd * vz))
