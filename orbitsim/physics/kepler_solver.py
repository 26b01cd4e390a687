"""Stumpff functions and the root of the universal Kepler equation (jitted, scalar, no allocation).

The drift kernels of :mod:`orbitsim.physics.kepler` are built on these. With Stiefel's
G-functions ``G_n(X) = X^n c_n(beta X^2)`` and the Stumpff functions

    c_n(z) = sum_k (-z)^k / (2k + n)!      (c0 = cos sqrt z, c1 = sin sqrt z / sqrt z, ...),

the universal anomaly X of a step dt solves

    K(X) = r0 X + eta0 G2(X) + zeta0 G3(X) - dt = 0,    eta0 = r0 . v0,  zeta0 = mu - beta r0,

``beta = 2 mu / r0 - v0^2``. ``K'(X) = r0 + eta0 G1 + zeta0 G2 = r(X) > 0``: K increases, so the
root is unique for every conic and every dt (Danby 1988, section 6.9).

Root finding, all loops bounded:

1. A short step (``(dt / t_dyn)^2 <`` :data:`NEWTON_MAX_STEP2`, ``t_dyn = min(r0/|v0|,
   sqrt(r0^3/mu))``) starts from the reversion of the series ``dt/r0 = X + a X^2 + b X^3 + d X^4``,
   ``a = eta0/(2 r0)``, ``b = zeta0/(6 r0)``, ``d = -eta0 beta/(24 r0)``:
   ``X ~ tau (1 - a tau + (2a^2 - b) tau^2 + (5ab - 5a^3 - d) tau^3)``, ``tau = dt/r0``, and
   iterates Newton until the residual K(X) is within its own rounding error
   (:data:`RESIDUAL_ULPS`): X then cannot be improved in float64 (:func:`evaluate`).
2. Otherwise (or if 1 did not settle) :func:`finish`: Newton to a fixed point or a two-cycle of
   neighbouring floats, or, for a long step, Laguerre-Conway (Conway 1986) from a mean-motion
   (ellipse) or logarithmic (hyperbola) start; then, if still unsettled, bisection of the
   monotone K on a bracket found by doubling (always converges unless K overflows).

Stumpff functions: for ``|z| <=`` :data:`STUMPFF_SERIES_MAX_Z` the series is summed directly (9
terms each; the first omitted term is below 1e-18 of the sum), the case of every Wisdom-Holman
step shorter than a sixth of an orbit; this short path is a separate straight-line function so
that LLVM inlines it into the Newton loop. For z > 1 (ellipses; at most pi^2, since :func:`setup`
reduces a step by whole periods) the argument is quartered into the series range and brought
back with the quarter-argument identities

    c0(4z) = 2 c0(z)^2 - 1,  c1(4z) = c0 c1,  c2(4z) = c1^2 / 2,  c3(4z) = (c2 + c0 c3) / 4;

for z < -1 (hyperbolas) the closed forms in cosh and sinh are used.

References
----------
.. [1] Danby, J. M. A. (1988), *Fundamentals of Celestial Mechanics*, 2nd ed., Willmann-Bell,
       sections 6.8-6.9.
.. [2] Stiefel, E. L. & Scheifele, G. (1971), *Linear and Regular Celestial Mechanics*, Springer.
.. [3] Conway, B. A. (1986), "An improved algorithm due to Laguerre for the solution of Kepler's
       equation", Celest. Mech. 39, 199.
"""

from __future__ import annotations

import math

import numpy as np

from orbitsim._jit import jit, jit_inline

#: Largest |z| at which the Stumpff series is summed directly.
STUMPFF_SERIES_MAX_Z = 1.0
#: Bound on the quartering loop: 4^520 exceeds the largest float64, so any finite z fits.
STUMPFF_MAX_QUARTERINGS = 520
#: 1/n! for n = 0..19: the series for c2 and c3 run to z^8/18! and z^8/19!.
INV_FACTORIAL = np.array([1.0 / math.factorial(n) for n in range(20)])

#: Newton from the series start when (dt / t_dyn)^2 is below this: the start is then accurate to
#: about (dt / t_dyn)^5 / 120 and Newton settles in 1-4 iterations.
NEWTON_MAX_STEP2 = 0.5
#: Newton stops when |K(X)| <= RESIDUAL_ULPS * eps * (|r0 X| + |eta0 G2| + |zeta0 G3| + |dt|):
#: the residual is then within the rounding error of its own evaluation (each of the four terms
#: carries a few ulps: the Stumpff sums, one product, the additions), so X cannot be improved.
RESIDUAL_ULPS = 4.0
EPS = float(np.finfo(np.float64).eps)
#: Iteration bounds. Newton from the series start needs <= 5 (1e-2 -> 1e-4 -> 1e-8 -> 1e-16);
#: Laguerre-Conway <= ~20 even for hundreds of periods or a strongly hyperbolic step; bisection
#: ~64 + log2 of the bracket ratio; doubling the bracket log2 of (root / start).
NEWTON_FAST_ITERATIONS = 8
NEWTON_MAX_ITERATIONS = 16
LAGUERRE_MAX_ITERATIONS = 50
BRACKET_MAX_DOUBLINGS = 200
BISECTION_MAX_ITERATIONS = 300

#: How a body's solve proceeds (:func:`setup`): Newton from the series start, the long-step
#: path of :func:`finish`, or nothing to solve (non-finite state, r0 = 0, mu not in (0, inf)).
ITERATING, FAR, SINGULAR = 1, 3, 4


@jit_inline
def _stumpff_series(z):
    """``(c0, c1, c2, c3)`` by their series, for ``|z| <= STUMPFF_SERIES_MAX_Z``. Inlined: called, it kept
    the SIMD lanes' Newton loops (:mod:`orbitsim.ensemble.lanes`, :mod:`orbitsim.ensemble.system_lanes`) scalar,
    a call in a loop being something LLVM cannot vectorise."""
    c2 = INV_FACTORIAL[18]
    c3 = INV_FACTORIAL[19]
    for k in range(7, -1, -1):
        c2 = INV_FACTORIAL[2 * k + 2] - z * c2
        c3 = INV_FACTORIAL[2 * k + 3] - z * c3
    return 1.0 - z * c2, 1.0 - z * c3, c2, c3


@jit
def _stumpff_large(z):
    """``(c0, c1, c2, c3)`` for ``|z| > STUMPFF_SERIES_MAX_Z``.

    z < -1 (hyperbolic): closed forms in cosh and sinh, accurate to a few ulps (s > 1, so
    cosh s - 1 and sinh s - s lose at most 3 bits). z > 1 (elliptic; at most pi^2 after the
    period reduction of :func:`setup`, i.e. two quarterings): quartered series and the identities.
    """
    if not math.isfinite(z):  # math, not np: numba-cuda lacks the numpy ufunc (the GPU ensemble calls this)
        return np.nan, np.nan, np.nan, np.nan
    if z < 0.0:
        s = math.sqrt(-z)
        ch = math.cosh(s)
        sh = math.sinh(s)
        return ch, sh / s, (ch - 1.0) / (-z), (sh - s) / (s * (-z))
    quarterings = 0
    while z > STUMPFF_SERIES_MAX_Z and quarterings < STUMPFF_MAX_QUARTERINGS:
        z *= 0.25
        quarterings += 1
    c0, c1, c2, c3 = _stumpff_series(z)
    for _ in range(quarterings):
        # Each identity uses the values at the smaller argument.
        c3 = (c2 + c0 * c3) * 0.25
        c2 = 0.5 * c1 * c1
        c1 = c0 * c1
        c0 = 2.0 * c0 * c0 - 1.0
    return c0, c1, c2, c3


@jit
def stumpff(z):
    """Stumpff functions ``(c0, c1, c2, c3)`` at ``z`` (non-finite ``z`` gives nan)."""
    if abs(z) <= STUMPFF_SERIES_MAX_Z:
        return _stumpff_series(z)
    return _stumpff_large(z)


@jit
def stiefel(beta, X):
    """Stiefel's G-functions ``(G0, G1, G2, G3)``, ``G_n = X^n c_n(beta X^2)``."""
    X2 = X * X
    c0, c1, c2, c3 = stumpff(beta * X2)
    return c0, X * c1, X2 * c2, X2 * X * c3


@jit_inline
def stiefel_short(beta, X):
    """:func:`stiefel` by the series alone, branch free (the same bits where ``|beta X^2| <=``
    :data:`STUMPFF_SERIES_MAX_Z`), and ``z = beta X^2`` for the caller to check that it was."""
    X2 = X * X
    z = beta * X2
    c0, c1, c2, c3 = _stumpff_series(z)
    return c0, X * c1, X2 * c2, X2 * X * c3, z


@jit_inline
def newton_terms(r0, eta0, zeta0, dt, X, G1, G2, G3):
    """``(dX, r, settled)`` from the G-functions at X: the Newton correction, the radius, and whether
    K(X) is within its own rounding error."""
    t1 = r0 * X
    t2 = eta0 * G2
    t3 = zeta0 * G3
    K = (t1 + t2 + t3) - dt
    r = r0 + eta0 * G1 + zeta0 * G2
    settled = abs(K) <= RESIDUAL_ULPS * EPS * (abs(t1) + abs(t2) + abs(t3) + abs(dt))
    return -K / r, r, settled


@jit
def evaluate(r0, eta0, zeta0, beta, dt, X):
    """``(dX, G1, G2, G3, r, settled)`` at X: the Newton correction, the G-functions, the radius,
    and whether K(X) is within its own rounding error."""
    _, G1, G2, G3 = stiefel(beta, X)
    dX, r, settled = newton_terms(r0, eta0, zeta0, dt, X, G1, G2, G3)
    return dX, G1, G2, G3, r, settled


@jit
def _far_start(r0, eta0, zeta0, beta, mu, dt):
    """Start of Laguerre-Conway for a step that is long compared with the dynamical time."""
    if beta > 0.0:
        return beta * dt / mu  # the orbit-averaged 1/r is 1/a = beta/mu
    # Hyperbola/parabola: X grows like ln(t)/v_inf far out; L is a length scale of the orbit.
    s = math.sqrt(-beta)
    L = max(r0, mu / (-beta)) if beta < 0.0 else r0
    if s * abs(dt) < L:
        return dt / L
    return math.copysign(math.log1p(s * abs(dt) / L) / s, dt)


@jit_inline
def solvable(r0, v2, eta0, mu):
    """Whether a body's drift has anything to solve: finite state, r0 > 0, mu in (0, inf)."""
    return (r0 > 0.0) & (r0 < np.inf) & (v2 < np.inf) & (eta0 == eta0) & (mu > 0.0) & (mu < np.inf)


@jit_inline
def orbit_terms(r0, v2, mu):
    """``(1/r0, beta, zeta0)``: ``beta = 2 mu / r0 - v0^2`` and ``zeta0 = mu - beta r0``."""
    r0i = 1.0 / r0
    beta = 2.0 * mu * r0i - v2
    return r0i, beta, mu - beta * r0


@jit_inline
def longer_than_half_period(beta, mu, dt):
    """Whether ``|dt|`` exceeds half the period of an ellipse (beta > 0), which :func:`setup` reduces."""
    # (pi mu)^2 as a product, the value ``** 2`` gives (1.0 times it): inlined where mu differs from lane to
    # lane (orbitsim.ensemble.system_lanes), Numba's ``** 2`` became a loop that kept the lane loop scalar
    pi_mu = math.pi * mu
    return beta > 0.0 and dt * dt * (beta * beta * beta) > pi_mu * pi_mu


@jit_inline
def short_step(v2, mu, r0i, dt):
    """Whether Newton starts from the series: ``(dt / t_dyn)^2 <`` :data:`NEWTON_MAX_STEP2`."""
    # max(v2, mu / r0) written as the select Python's max makes (the later argument where it is greater): the
    # builtin stayed a call, which kept a lane loop with per-lane mu scalar (orbitsim.ensemble.system_lanes)
    mu_r0 = mu * r0i
    return dt * dt * (mu_r0 if mu_r0 > v2 else v2) * (r0i * r0i) < NEWTON_MAX_STEP2


@jit_inline
def series_start(r0i, eta0, zeta0, beta, dt):
    """The reversion of the series ``dt/r0 = X + a X^2 + b X^3 + d X^4`` (module docstring)."""
    tau = dt * r0i
    a = 0.5 * eta0 * r0i
    b = zeta0 * r0i / 6.0
    d = -eta0 * beta * r0i / 24.0
    return tau * (1.0 + tau * (-a + tau * ((2.0 * a * a - b) + tau * (5.0 * a * (b - a * a) - d))))


@jit
def setup(r0, v2, eta0, mu, dt):
    """``(1/r0, zeta0, beta, dt_eff, X_start, stage)`` of one body (stage ITERATING, FAR, SINGULAR).

    On an ellipse a step longer than half a period is reduced by whole periods P = 2 pi mu /
    beta^(3/2): K(X + 2 pi / sqrt(beta)) = K(X) + P, and the drift is periodic, so the body moves
    by ``dt_eff = dt - k P`` instead (exactly the same orbit point). This keeps the Stumpff
    argument within pi^2: the quarter-argument identities amplify rounding by up to 4 per
    quartering, which over a step of 8 periods cost ~400 ulps of energy per step unreduced.
    A step shorter than P/2 is not touched (``dt_eff = dt``, same bits).
    """
    if not solvable(r0, v2, eta0, mu):
        return 0.0, 0.0, 0.0, dt, 0.0, SINGULAR
    r0i, beta, zeta0 = orbit_terms(r0, v2, mu)
    if longer_than_half_period(beta, mu, dt):
        period = 2.0 * math.pi * mu / (beta * math.sqrt(beta))
        dt = dt - round(dt / period) * period
    if short_step(v2, mu, r0i, dt):
        return r0i, zeta0, beta, dt, series_start(r0i, eta0, zeta0, beta, dt), ITERATING
    return r0i, zeta0, beta, dt, _far_start(r0, eta0, zeta0, beta, mu, dt), FAR


@jit_inline
def setup_short(r0, v2, eta0, mu, dt):
    """:func:`setup` for a lane of a vector loop, branch free: ``(1/r0, zeta0, beta, X_start, short)``,
    where ``short`` says that :func:`setup` would return these same bits with stage ITERATING and
    ``dt_eff = dt`` (a solvable body, a step under half a period and short enough for the series start)."""
    r0i, beta, zeta0 = orbit_terms(r0, v2, mu)
    short = solvable(r0, v2, eta0, mu) & (not longer_than_half_period(beta, mu, dt)) & short_step(v2, mu, r0i, dt)
    return r0i, zeta0, beta, series_start(r0i, eta0, zeta0, beta, dt), short


@jit
def _newton(r0, eta0, zeta0, beta, dt, X):
    """Newton to a fixed point or a two-cycle of neighbouring floats; ``(X, converged)``."""
    X_before = np.nan
    for _ in range(NEWTON_MAX_ITERATIONS):
        dX, _, _, _, _, _ = evaluate(r0, eta0, zeta0, beta, dt, X)
        X_next = X + dX
        if X_next == X or X_next == X_before:
            return X, True
        X_before = X
        X = X_next
    return X, False


@jit
def _laguerre_conway(r0, eta0, zeta0, beta, dt, X):
    """Laguerre-Conway (degree 5) from ``X``; ``(X, converged)``."""
    X_before = np.nan
    for _ in range(LAGUERRE_MAX_ITERATIONS):
        G0, G1, G2, G3 = stiefel(beta, X)
        K = r0 * X + eta0 * G2 + zeta0 * G3 - dt
        K1 = r0 + eta0 * G1 + zeta0 * G2
        K2 = eta0 * G0 + zeta0 * G1
        # K1 = r > 0, so the root of larger magnitude in the denominator has K1's sign.
        X_next = X - 5.0 * K / (K1 + math.sqrt(abs(16.0 * K1 * K1 - 20.0 * K * K2)))
        if X_next == X or X_next == X_before:
            return X, True
        X_before = X
        X = X_next
    return X, False


@jit
def _residual(r0, eta0, zeta0, beta, dt, X):
    _, _, G2, G3 = stiefel(beta, X)
    return r0 * X + eta0 * G2 + zeta0 * G3 - dt


@jit
def _bisect(r0, eta0, zeta0, beta, dt, X_start):
    """Bisection of the increasing K on [0, X] or [X, 0], X found by doubling; ``(X, converged)``."""
    if dt == 0.0:
        return 0.0, True
    step = abs(X_start) if abs(X_start) > 0.0 else abs(dt) / r0
    far = math.copysign(step, dt)
    found = False
    for _ in range(BRACKET_MAX_DOUBLINGS):
        K = _residual(r0, eta0, zeta0, beta, dt, far)
        if (K >= 0.0) if dt > 0.0 else (K <= 0.0):
            found = True
            break
        far *= 2.0
    if not found:
        return far, False
    lo, hi = (0.0, far) if dt > 0.0 else (far, 0.0)
    for _ in range(BISECTION_MAX_ITERATIONS):
        mid = 0.5 * (lo + hi)
        if mid == lo or mid == hi:
            return mid, True
        if _residual(r0, eta0, zeta0, beta, dt, mid) >= 0.0:
            hi = mid
        else:
            lo = mid
    return 0.5 * (lo + hi), False


@jit
def finish(r0, eta0, zeta0, beta, dt, X, stage):
    """The robust path from X; ``(X, G1, G2, G3, r, converged)`` at the solution."""
    if stage == ITERATING:
        X, converged = _newton(r0, eta0, zeta0, beta, dt, X)
    else:
        X, converged = _laguerre_conway(r0, eta0, zeta0, beta, dt, X)
    if not converged:
        X, converged = _bisect(r0, eta0, zeta0, beta, dt, X)
    _, G1, G2, G3, r, _ = evaluate(r0, eta0, zeta0, beta, dt, X)
    return X, G1, G2, G3, r, converged


@jit
def solve(r0, eta0, zeta0, beta, dt, X, stage):
    """One body: Newton from the series start until settled, else :func:`finish`.

    Returns ``(X, G1, G2, G3, r, converged)``.
    """
    if stage == ITERATING:
        for _ in range(NEWTON_FAST_ITERATIONS):
            dX, G1, G2, G3, r, settled = evaluate(r0, eta0, zeta0, beta, dt, X)
            if settled:
                return X, G1, G2, G3, r, True
            X += dX
    return finish(r0, eta0, zeta0, beta, dt, X, stage)
