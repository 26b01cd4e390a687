"""Tests for orbitsim.initial_conditions.elements: Kepler solver, conversions, REBOUND cross-check."""

from __future__ import annotations

import math

import numpy as np
import pytest

from orbitsim.initial_conditions.elements import cartesian_to_elements, elements_to_cartesian, solve_kepler

rebound = pytest.importorskip("rebound")

GM = 1.001  # G (m_primary + m_body) for the REBOUND setup below: G = 1, masses 1 and 1e-3

# (a, e, inc, Omega, omega, anomaly) in degrees; elliptic then hyperbolic (a < 0).
ORBITS = [
    (1.0, 0.1, 10.0, 20.0, 30.0, 40.0),
    (2.5, 0.9, 100.0, 200.0, 300.0, -60.0),
    (0.7, 0.0, 0.0, 0.0, 0.0, 123.0),
    (1.3, 0.99, 45.0, 10.0, 270.0, 1.0),
    (5.2, 0.5, 179.0, 359.0, 90.0, 180.0),
    (-1.0, 1.5, 30.0, 40.0, 50.0, 2.0),
    (-0.3, 3.0, 170.0, 10.0, 20.0, -5.0),
    (-2.0, 1.01, 5.0, 5.0, 5.0, 30.0),
]


def _rebound_relative_state(a, e, inc, Omega, omega, **anomaly_rad):
    sim = rebound.Simulation()  # G = 1
    sim.add(m=1.0)
    sim.add(
        m=1e-3,
        a=a,
        e=e,
        inc=math.radians(inc),
        Omega=math.radians(Omega),
        omega=math.radians(omega),
        primary=sim.particles[0],
        **anomaly_rad,
    )
    body, primary = sim.particles[1], sim.particles[0]
    return (
        np.array(body.xyz) - np.array(primary.xyz),
        np.array(body.vxyz) - np.array(primary.vxyz),
    )


def _rel_err(x: np.ndarray, ref: np.ndarray) -> float:
    return float(np.linalg.norm(x - ref) / np.linalg.norm(ref))


def _angle_diff_deg(x: float, y: float) -> float:
    return abs((x - y + 180.0) % 360.0 - 180.0)


@pytest.mark.parametrize("orbit", ORBITS)
@pytest.mark.parametrize("anomaly_kind", ["M", "f"])
def test_matches_rebound(orbit, anomaly_kind) -> None:
    a, e, inc, Omega, omega, anomaly = orbit
    r, v = elements_to_cartesian(GM, a, e, inc, Omega, omega, **{anomaly_kind: anomaly})
    r_ref, v_ref = _rebound_relative_state(a, e, inc, Omega, omega, **{anomaly_kind: math.radians(anomaly)})
    # Both codes are double precision; e = 0.99 amplifies rounding in E by 1/(1 - e cos E) ~ 100.
    assert _rel_err(r, r_ref) < 1e-12
    assert _rel_err(v, v_ref) < 1e-12


@pytest.mark.parametrize("orbit", ORBITS)
def test_elements_round_trip(orbit) -> None:
    a, e, inc, Omega, omega, M = orbit
    r, v = elements_to_cartesian(GM, a, e, inc, Omega, omega, M=M)
    el = cartesian_to_elements(GM, r, v)
    # a and e come from vis-viva and the Laplace vector: a few ulps of cancellation.
    assert el["a"] == pytest.approx(a, rel=1e-12)
    assert el["e"] == pytest.approx(e, abs=1e-12)
    assert el["inc"] == pytest.approx(inc, abs=1e-10)  # degrees; acos-free atan2 keeps this tight
    if e == 0.0 and inc == 0.0:
        # Node and periapsis undefined: both reported as 0, f is the true longitude.
        assert el["Omega"] == 0.0 and el["omega"] == 0.0
        assert _angle_diff_deg(el["f"], Omega + omega + M) < 1e-10  # degrees, rounding only
        return
    # Angles near-degenerate at e = 0.99 or inc = 179 deg lose a few digits; still far below 1e-6 deg.
    assert _angle_diff_deg(el["Omega"], Omega) < 1e-8
    assert _angle_diff_deg(el["omega"], omega) < 1e-8
    assert _angle_diff_deg(el["M"], M) < 1e-8


@pytest.mark.parametrize("seed", range(5))
def test_cartesian_round_trip_random_states(seed) -> None:
    rng = np.random.default_rng(seed)
    for _ in range(20):
        r = rng.normal(size=3)
        v = rng.normal(size=3)  # both bound and unbound states occur
        el = cartesian_to_elements(GM, r, v)
        r2, v2 = elements_to_cartesian(
            GM, el["a"], el["e"], el["inc"], el["Omega"], el["omega"], f=el["f"]
        )
        # Unit-scale states; errors are a few ulps amplified by the conversions.
        assert _rel_err(r2, r) < 1e-11
        assert _rel_err(v2, v) < 1e-11


@pytest.mark.parametrize("orbit", ORBITS)
def test_mean_and_true_anomaly_inputs_agree(orbit) -> None:
    a, e, inc, Omega, omega, M = orbit
    r, v = elements_to_cartesian(GM, a, e, inc, Omega, omega, M=M)
    f = cartesian_to_elements(GM, r, v)["f"]
    r_f, v_f = elements_to_cartesian(GM, a, e, inc, Omega, omega, f=f)
    # Two formulations of the same conic (via E/H versus via f) agree to rounding.
    assert _rel_err(r_f, r) < 1e-11
    assert _rel_err(v_f, v) < 1e-11


@pytest.mark.parametrize("orbit", ORBITS)
def test_vis_viva_and_angular_momentum(orbit) -> None:
    a, e, inc, Omega, omega, M = orbit
    r, v = elements_to_cartesian(GM, a, e, inc, Omega, omega, M=M)
    r_norm = np.linalg.norm(r)
    # Specific energy v^2/2 - gm/r = -gm/(2a) and |h| = sqrt(gm a (1 - e^2)), to rounding.
    assert 0.5 * v @ v - GM / r_norm == pytest.approx(-GM / (2.0 * a), rel=1e-12)
    assert np.linalg.norm(np.cross(r, v)) == pytest.approx(math.sqrt(GM * a * (1 - e * e)), rel=1e-12)


@pytest.mark.parametrize("e", [0.0, 1e-9, 0.3, 0.9, 0.99, 0.999999])
def test_elliptic_kepler_residual(e) -> None:
    for M in np.concatenate([np.geomspace(1e-12, math.pi, 40), np.linspace(-20.0, 20.0, 81)]):
        E = solve_kepler(M, e)
        scale = abs(E) + e * abs(math.sin(E)) + abs(M)
        # Solved to the rounding level of the residual's terms.
        assert abs(E - e * math.sin(E) - M) <= 1e-15 * scale


@pytest.mark.parametrize("e", [1.0 + 1e-9, 1.000001, 1.5, 10.0, 1e6])
def test_hyperbolic_kepler_residual(e) -> None:
    for M in np.concatenate([np.geomspace(1e-12, 1e12, 49), -np.geomspace(1e-3, 1e6, 10)]):
        H = solve_kepler(M, e)
        scale = e * abs(math.sinh(H)) + abs(H) + abs(M)
        # Rounding of H itself (eps * |H| with |H| up to ~30) bounds the attainable residual.
        assert abs(e * math.sinh(H) - H - M) <= 1e-14 * scale


def test_kepler_reduces_mean_anomaly_consistently() -> None:
    e = 0.7
    E0 = solve_kepler(1.0, e)
    # E(M + 2 pi k) = E(M) + 2 pi k; the reduction costs only the rounding of 2 pi k.
    assert solve_kepler(1.0 + 2 * math.pi * 3, e) == pytest.approx(E0 + 2 * math.pi * 3, abs=1e-13)
    assert solve_kepler(-1.0, e) == -E0


def test_large_hyperbolic_mean_anomaly() -> None:
    r, v = elements_to_cartesian(1.0, -1.0, 1.2, 0.0, 0.0, 0.0, M=math.degrees(1e8))
    # Far out on the asymptote: r ~ |a| e cosh H ~ 1e8, speed -> v_inf = sqrt(gm/|a|) = 1.
    assert np.linalg.norm(r) > 1e7
    assert np.linalg.norm(v) == pytest.approx(1.0, rel=1e-6)  # residual gm/r correction ~1e-8


@pytest.mark.parametrize(
    ("args", "kwargs", "match"),
    [
        ((1.0, 1.0, -0.1, 0, 0, 0), {"M": 0.0}, "non-negative"),
        ((1.0, 1.0, 1.0, 0, 0, 0), {"M": 0.0}, "e != 1"),
        ((1.0, 0.0, 0.5, 0, 0, 0), {"M": 0.0}, "non-zero"),
        ((1.0, -1.0, 0.5, 0, 0, 0), {"M": 0.0}, "a > 0"),
        ((1.0, 1.0, 1.5, 0, 0, 0), {"M": 0.0}, "a < 0"),
        ((0.0, 1.0, 0.5, 0, 0, 0), {"M": 0.0}, "gm"),
        ((1.0, math.nan, 0.5, 0, 0, 0), {"M": 0.0}, "finite"),
        ((1.0, 1.0, 0.5, math.inf, 0, 0), {"M": 0.0}, "finite"),
        ((1.0, 1.0, 0.5, 0, 0, 0), {"M": math.nan}, "finite"),
        ((1.0, 1.0, 0.5, 0, 0, 0), {}, "exactly one"),
        ((1.0, 1.0, 0.5, 0, 0, 0), {"M": 0.0, "f": 0.0}, "exactly one"),
        ((1.0, -1.0, 2.0, 0, 0, 0), {"f": 120.0}, "asymptote"),  # f_inf = 120 deg for e = 2
        ((1.0, -1.0, 2.0, 0, 0, 0), {"f": -150.0}, "asymptote"),
    ],
)
def test_invalid_input_raises(args, kwargs, match) -> None:
    with pytest.raises(ValueError, match=match):
        elements_to_cartesian(*args, **kwargs)


def test_cartesian_to_elements_rejects_degenerate_states() -> None:
    with pytest.raises(ValueError, match="radial"):
        cartesian_to_elements(1.0, np.array([1.0, 0.0, 0.0]), np.array([2.0, 0.0, 0.0]))
    with pytest.raises(ValueError, match="shape"):
        cartesian_to_elements(1.0, np.zeros(2), np.zeros(3))
