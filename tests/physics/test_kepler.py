"""The universal-variable Kepler drift: Stumpff functions, every kind of conic, long steps, failures.

References used here are independent of the solver: exact rational sums for the Stumpff
functions, :func:`orbitsim.initial_conditions.elements.elements_to_cartesian` (classical Kepler
equation in E or H) for ellipses and hyperbolas, and Barker's equation, solved in closed form,
for the parabola.
"""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pytest

from orbitsim.initial_conditions.elements import elements_to_cartesian
from orbitsim.physics import kepler_solver
from orbitsim.physics.kepler import (
    KEPLER_NOT_CONVERGED,
    KEPLER_OK,
    KEPLER_SCRATCH_ROWS,
    KEPLER_SINGULAR,
    KeplerConvergenceError,
    kepler_drift,
    kepler_drift_bodies,
    kepler_propagate,
    universal_anomaly,
)
from orbitsim.physics.kepler_solver import stumpff

ELLIPTIC = (0.0, 0.1, 0.5, 0.9, 0.99, 0.999)
HYPERBOLIC = (1.01, 1.5, 3.0, 10.0)
#: Starting mean anomalies (degrees). Exactly at pericentre an e = 0.999 state is ill-conditioned
#: (its energy cancels to 1 part in 2000), so the rounding of the start alone moves the orbit more
#: than the solver's error; that case is covered by the invariants test below.
STARTS = (45.0, 180.0, 300.0)
#: Steps in periods (ellipses) or in units of 1/n (hyperbolas): tiny, typical, long, many periods,
#: and backwards.
STEPS = (1e-3, 0.03, 0.3, 1.7, 10.3, -0.6)


def exact_stumpff(z: float, n: int) -> float:
    """c_n(z) as an exact rational sum of its series (80 terms: enough for |z| <= 60)."""
    zf = Fraction(z)
    total = Fraction(0)
    term = Fraction(1, math.factorial(n))
    for k in range(80):
        total += term
        term *= -zf / ((2 * k + n + 1) * (2 * k + n + 2))
    return float(total)


@pytest.mark.parametrize("z", [0.0, 1e-8, -3e-4, 0.07, -0.4, 0.99, 1.01, -2.5, 7.3, 39.0, -55.0])
def test_stumpff_functions_match_their_series(z: float) -> None:
    got = stumpff(z)
    for n in range(4):
        ref = exact_stumpff(z, n)
        # Series below |z| = 1; quartered and rebuilt above: a few ulps per quarter-argument
        # identity, 4 of them at most at |z| = 55, scaled by max(1, |c_n|) near zeros of cos.
        assert abs(got[n] - ref) <= 2e-14 * max(1.0, abs(ref)), (z, n, got[n], ref)


def test_stumpff_identities() -> None:
    for z in np.linspace(-30.0, 30.0, 121):
        c0, c1, c2, c3 = stumpff(z)
        # c0 + z c2 = 1 and c1 + z c3 = 1 hold exactly; rounding grows with |z| (products of O(|z|)).
        assert abs(c0 + z * c2 - 1.0) <= 1e-14 * max(1.0, abs(z))
        assert abs(c1 + z * c3 - 1.0) <= 1e-14 * max(1.0, abs(z))


def relative_error(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.linalg.norm(a - b) / np.linalg.norm(b))


@pytest.mark.parametrize("e", ELLIPTIC + HYPERBOLIC)
def test_drift_matches_the_classical_kepler_equation(e: float) -> None:
    gm = 1.0
    a = 1.0 if e < 1.0 else -1.0
    n = 1.0  # mean motion sqrt(gm / |a|^3)
    for M0 in STARTS:
        x0, v0 = elements_to_cartesian(gm, a, e, 20.0, 30.0, 40.0, M=M0)
        for steps in STEPS:
            dt = steps * (2.0 * math.pi if e < 1.0 else 1.0) / n
            x, v = kepler_propagate(x0, v0, gm, dt)
            M = M0 + math.degrees(n * dt)
            xr, vr = elements_to_cartesian(gm, a, e, 20.0, 30.0, 40.0, M=math.fmod(M, 360.0) if e < 1 else M)
            # Both sides round the same orbit differently; over <= 10 periods the phase error of
            # that rounding stays below 1e-12 relative (measured: <= 7e-14, e = 0.999 included).
            assert relative_error(x, xr) < 1e-12, (e, M0, steps)
            assert relative_error(v, vr) < 1e-12, (e, M0, steps)


def barker_state(gm: float, q: float, t: float) -> tuple[np.ndarray, np.ndarray]:
    """Parabola with pericentre q on +x at t = 0, moving to +y: Barker's equation in closed form."""
    w = 1.5 * t * math.sqrt(gm / (2.0 * q**3))  # D + D^3/3 = 2w/3 ... written as D^3 + 3D - 2w = 0
    root = math.sqrt(w * w + 1.0)
    D = math.cbrt(w + root) - math.cbrt(root - w)
    r = q * (1.0 + D * D)
    pos = np.array([q * (1.0 - D * D), 2.0 * q * D, 0.0])
    dD = math.sqrt(gm / (2.0 * q**3)) / (1.0 + D * D)  # dD/dt from Barker's equation
    vel = np.array([-2.0 * q * D * dD, 2.0 * q * dD, 0.0])
    assert abs(np.linalg.norm(pos) - r) < 1e-12 * r
    return pos, vel


@pytest.mark.parametrize("t", [1e-3, 0.4, 3.0, 50.0, -7.0])
def test_drift_on_a_parabola(t: float) -> None:
    gm, q = 1.0, 0.5
    x0, v0 = barker_state(gm, q, 0.0)
    x, v = kepler_propagate(x0, v0, gm, t)
    xr, vr = barker_state(gm, q, t)
    # beta = 2 mu/r0 - v0^2 is zero to rounding; the cube roots and the drift each carry a few ulps.
    assert relative_error(x, xr) < 1e-12
    assert relative_error(v, vr) < 1e-12


@pytest.mark.parametrize("e", [0.0, 0.5, 0.999, 1.0, 3.0])
def test_invariants_are_kept_from_pericentre(e: float) -> None:
    """Energy, angular momentum and the eccentricity vector are constants of every drift."""
    gm, q = 1.0, 0.3
    x0 = np.array([q, 0.0, 0.0])
    v0 = np.array([0.0, math.sqrt(gm * (1.0 + e) / q), 0.0])

    def invariants(x: np.ndarray, v: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
        r = np.linalg.norm(x)
        h = np.cross(x, v)
        return 0.5 * v @ v - gm / r, h, np.cross(v, h) / gm - x / r

    e0, h0, ecc0 = invariants(x0, v0)
    scale_e = 0.5 * v0 @ v0 + gm / q  # |kinetic| + |potential|: the size of the rounding in E
    for dt in (0.01, 0.7, 13.0, -2.0):
        x, v = kepler_propagate(x0, v0, gm, dt)
        e1, h1, ecc1 = invariants(x, v)
        # A few ulps of each term of the invariants, at the scale of their largest term (far out
        # on a hyperbola |x||v| >> |h|, and the cross product rounds at the scale of |x||v|);
        # the energy's rounding grows with the turns covered in one drift (quartered Stumpff).
        turns = abs(dt) * math.sqrt(gm / q**3) / (2.0 * math.pi)
        assert abs(e1 - e0) < 1e-14 * scale_e * (1.0 + turns), (e, dt)
        h_scale = max(np.linalg.norm(h0), np.linalg.norm(x) * np.linalg.norm(v))
        assert np.linalg.norm(h1 - h0) < 1e-14 * h_scale * (1.0 + turns), (e, dt)
        assert np.linalg.norm(ecc1 - ecc0) < 1e-14 * max(1.0, e) * (1.0 + turns), (e, dt)


def test_round_trip_and_composition() -> None:
    x0, v0 = elements_to_cartesian(1.0, 1.3, 0.6, 10.0, 20.0, 30.0, M=100.0)
    for dt in (0.05, 2.0, 40.0):
        x1, v1 = kepler_propagate(x0, v0, 1.0, dt)
        xb, vb = kepler_propagate(x1, v1, 1.0, -dt)
        # Forward then back: a few ulps per drift, grown by the phase sensitivity over <= 4 periods.
        assert relative_error(xb, x0) < 1e-13 and relative_error(vb, v0) < 1e-13, dt
        xh, vh = kepler_propagate(*kepler_propagate(x0, v0, 1.0, 0.3 * dt), 1.0, 0.7 * dt)
        assert relative_error(xh, x1) < 1e-13 and relative_error(vh, v1) < 1e-13, dt


@pytest.mark.parametrize("e", [0.3, 0.999, 2.0])
@pytest.mark.parametrize("dt", [0.02, 1.0, 30.0])
def test_universal_anomaly_is_at_machine_precision(e: float, dt: float) -> None:
    """X agrees with the root found by plain bisection of K to a few ulps."""
    gm = 1.0
    a = 1.0 if e < 1.0 else -1.0
    x0, v0 = elements_to_cartesian(gm, a, e, 0.0, 0.0, 0.0, M=30.0)
    r0, v2, eta0 = float(np.linalg.norm(x0)), float(v0 @ v0), float(x0 @ v0)
    X, dt_eff, status = universal_anomaly(r0, v2, eta0, gm, dt)
    assert status == KEPLER_OK
    if e < 1.0:  # an ellipse's step is reduced by whole periods (2 pi here) to |dt_eff| <= pi
        assert abs(dt_eff) <= math.pi + 1e-12 and (dt - dt_eff) / (2.0 * math.pi) == pytest.approx(
            round((dt - dt_eff) / (2.0 * math.pi)), abs=1e-12
        )
    beta = 2.0 * gm / r0 - v2
    X_bisect, converged = kepler_solver._bisect(r0, eta0, gm - beta * r0, beta, dt_eff, X * 1.5)
    assert converged
    # The residual test accepts X within RESIDUAL_ULPS ulps of the rounding error of K itself.
    assert abs(X - X_bisect) <= 8.0 * np.spacing(abs(X_bisect)) * max(1.0, r0 * abs(X_bisect) / abs(dt_eff))


def test_zero_mu_is_a_straight_line_and_batch_equals_single() -> None:
    rng = np.random.default_rng(7)
    pos = rng.normal(size=(3, 6))
    vel = rng.normal(size=(3, 6)) * 0.5
    mu = np.array([0.0, 1.0, 1.0, 0.0, 2.5, 1e-8])
    single_pos, single_vel = pos.copy(), vel.copy()
    for i in range(1, 6):
        assert kepler_drift(single_pos, single_vel, i, mu[i], 0.37) == KEPLER_OK
    batch_pos, batch_vel = pos.copy(), vel.copy()
    ks = np.zeros((KEPLER_SCRATCH_ROWS, 6))
    stage = np.zeros(6, dtype=np.int64)
    assert kepler_drift_bodies(batch_pos, batch_vel, mu, 0.37, 1, ks, stage) == (KEPLER_OK, 0)
    np.testing.assert_array_equal(batch_pos, single_pos)
    np.testing.assert_array_equal(batch_vel, single_vel)
    np.testing.assert_array_equal(batch_pos[:, 0], pos[:, 0])  # before `start`: untouched
    np.testing.assert_array_equal(batch_pos[:, 3], pos[:, 3] + 0.37 * vel[:, 3])
    np.testing.assert_array_equal(batch_vel[:, 3], vel[:, 3])


def test_failures_are_reported_not_hidden() -> None:
    pos = np.array([[0.0, 1.0], [0.0, 0.0], [0.0, 0.0]])
    vel = np.array([[0.0, 0.0], [0.0, 30.0], [0.0, 0.0]])
    # A body on its centre cannot be drifted.
    assert kepler_drift(pos, vel, 0, 1.0, 0.1) == KEPLER_SINGULAR
    assert np.all(np.isnan(pos[:, 0])) and np.all(np.isnan(vel[:, 0]))
    # A strongly hyperbolic orbit over 1.7e308 time units: K(X) overflows before its root.
    assert kepler_drift(pos, vel, 1, 1.0, 1.7e308) == KEPLER_NOT_CONVERGED
    with pytest.raises(KeplerConvergenceError, match="did not converge"):
        kepler_propagate([1.0, 0.0, 0.0], [0.0, 30.0, 0.0], 1.0, 1.7e308)
    with pytest.raises(KeplerConvergenceError, match="sits on its centre"):
        kepler_propagate([0.0, 0.0, 0.0], [0.0, 1.0, 0.0], 1.0, 1.0)
    with pytest.raises(ValueError, match="finite"):
        kepler_propagate([np.nan, 0.0, 0.0], [0.0, 1.0, 0.0], 1.0, 1.0)
