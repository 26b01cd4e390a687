"""Tests for orbitsim.physics.orbital_elements: the vectorised osculating elements of a whole run.

Checked against the scalar :func:`cartesian_to_elements` body by body, by round trip through
:func:`elements_to_cartesian`, and against REBOUND's ``sim.orbits()`` (Jacobi) and
``p.orbit(primary=...)``. Warnings are errors here: the function promises none.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from orbitsim.initial_conditions.elements import cartesian_to_elements, elements_to_cartesian
from orbitsim.physics.orbital_elements import ELEMENT_NAMES, osculating_elements

pytestmark = pytest.mark.filterwarnings("error")

ANGLES = ("inc", "Omega", "omega", "f")
G = 1.0


def _angle_diff_deg(x: np.ndarray | float, y: np.ndarray | float) -> np.ndarray:
    """|x - y| in degrees modulo 360: 359.9999 and 0 are neighbours, not 360 apart."""
    return np.abs(np.mod(np.asarray(x) - np.asarray(y) + 180.0, 360.0) - 180.0)


def _random_orbits(rng: np.random.Generator, n: int) -> list[tuple[float, ...]]:
    """(a, e, inc, Omega, omega, M) in degrees: elliptic, hyperbolic, inclined and near-degenerate."""
    orbits = []
    for i in range(n):
        kind = i % 4
        Omega, omega = rng.uniform(0.0, 360.0, 2)
        if kind == 0:  # elliptic, any inclination, up to e = 0.999
            orbit = (rng.uniform(0.1, 10.0), rng.uniform(0.0, 0.999), rng.uniform(0.0, 180.0))
        elif kind == 1:  # hyperbolic, a < 0
            orbit = (-rng.uniform(0.1, 10.0), rng.uniform(1.001, 5.0), rng.uniform(0.0, 180.0))
        elif kind == 2:  # circular or nearly so, equatorial (prograde or retrograde) or nearly so
            orbit = (rng.uniform(0.1, 10.0), float(rng.choice([0.0, 1e-15, 1e-11, 1e-8])),
                     float(rng.choice([0.0, 180.0, 1e-9, 179.9999999])))
        else:  # moderately eccentric, equatorial or inclined
            orbit = (rng.uniform(0.1, 10.0), rng.uniform(0.0, 0.9), float(rng.choice([0.0, 180.0, 63.4])))
        M = rng.uniform(-180.0, 180.0) if orbit[1] < 1.0 else rng.uniform(-50.0, 50.0)
        orbits.append((*orbit, Omega, omega, M))
    return orbits


def _system(rng: np.random.Generator, n_bodies: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, list]:
    """A star (index 0, moving, off the origin) and bodies on random orbits about it; every 5th massless."""
    m = np.concatenate([[1.0], rng.uniform(0.0, 1e-3, n_bodies - 1)])
    m[1::5] = 0.0
    orbits = _random_orbits(rng, n_bodies - 1)
    pos = np.zeros((n_bodies, 3))
    vel = np.zeros((n_bodies, 3))
    pos[0], vel[0] = rng.normal(size=3), 0.1 * rng.normal(size=3)
    for i, (a, e, inc, Omega, omega, M) in enumerate(orbits, start=1):
        r, v = elements_to_cartesian(G * (m[0] + m[i]), a, e, inc, Omega, omega, M=M)
        pos[i], vel[i] = pos[0] + r, vel[0] + v
    return m, pos, vel, orbits


def test_agrees_with_the_scalar_function_body_by_body() -> None:
    rng = np.random.default_rng(20240615)
    samples = [_system(rng, 201) for _ in range(3)]
    m = samples[0][0]
    pos = np.stack([s[1] for s in samples])
    vel = np.stack([s[2] for s in samples])
    el = osculating_elements(m, pos, vel, G, primary=0)
    for s in range(pos.shape[0]):
        for i in range(1, pos.shape[1]):
            ref = cartesian_to_elements(G * (m[0] + m[i]), pos[s, i] - pos[s, 0], vel[s, i] - vel[s, 0])
            got = {name: float(el[name][s, i]) for name in ELEMENT_NAMES}
            # Same formulas on the same numbers: only the summation order of norms differs (a few ulps).
            assert got["a"] == pytest.approx(ref["a"], rel=1e-14)
            assert got["e"] == pytest.approx(ref["e"], rel=1e-13, abs=1e-14)
            assert _angle_diff_deg(got["inc"], ref["inc"]) < 1e-12
            assert _angle_diff_deg(got["Omega"], ref["Omega"]) < 1e-12
            # Below e ~ 1e-6 the periapsis direction is rounding noise (eps / e radians) in both codes:
            # compare the argument of latitude omega + f, which is defined, and omega to that noise.
            noise = 1e-11 + math.degrees(1e-15 / max(ref["e"], 1e-300))
            assert _angle_diff_deg(got["omega"] + got["f"], ref["omega"] + ref["f"]) < 1e-10
            assert _angle_diff_deg(got["omega"], ref["omega"]) < noise
            if ref["e"] < 1.0:
                assert _angle_diff_deg(got["M"], ref["M"]) < noise
            else:  # unbounded hyperbolic M: a relative tolerance, rounding only
                assert got["M"] == pytest.approx(ref["M"], rel=1e-12, abs=1e-12)
            assert -180.0 <= got["f"] < 180.0 and 0.0 <= got["Omega"] <= 360.0 and 0.0 <= got["inc"] <= 180.0


def test_round_trip_through_elements_to_cartesian() -> None:
    rng = np.random.default_rng(7)
    m, pos, vel, orbits = _system(rng, 101)
    el = osculating_elements(m, pos, vel, G, primary="heaviest")
    for i, (a, e, inc, Omega, omega, M) in enumerate(orbits, start=1):
        # a from vis-viva and e from the Laplace vector lose a few digits to cancellation; 1e-10 covers e = 0.999.
        assert el["a"][i] == pytest.approx(a, rel=1e-10)
        assert el["e"][i] == pytest.approx(e, abs=1e-10)
        assert _angle_diff_deg(el["inc"][i], inc) < 1e-7  # degrees; atan2 of h, a few ulps of 1/sin(inc)
        if 1e-6 < e and 1e-6 < inc < 180.0 - 1e-6:  # node and periapsis both well defined
            assert _angle_diff_deg(el["Omega"][i], Omega) < 1e-7
            assert _angle_diff_deg(el["omega"][i], omega) < 1e-7
        # The true longitude Omega + omega + f (retrograde: Omega - omega - f) is defined in every case.
        sign = 1.0 if el["inc"][i] < 90.0 else -1.0
        longitude = el["Omega"][i] + sign * (el["omega"][i] + el["f"][i])
        if e < 1e-6:  # circular: f is the anomaly from the node, M equals it
            r, _ = elements_to_cartesian(1.0, a, e, inc, Omega, omega, M=M)
            assert _angle_diff_deg(longitude, math.degrees(math.atan2(r[1], r[0]))) < 1e-6
        elif e < 1.0:
            assert _angle_diff_deg(el["M"][i], M) < 1e-7
        else:
            assert el["M"][i] == pytest.approx(M, rel=1e-9)  # rounding of e sinh H - H, amplified by cosh H


@pytest.mark.parametrize("M", [1e3, -1e5, 3e6])
def test_far_out_on_a_hyperbola(M: float) -> None:
    """A body far beyond periapsis (r up to ~1e6 |a|): finite elements, M to rounding."""
    r, v = elements_to_cartesian(1.0, -2.0, 1.3, 20.0, 30.0, 40.0, M=M)
    el = osculating_elements(np.array([1.0, 0.0]), np.array([[0, 0, 0], r]), np.array([[0, 0, 0], v]), G, 0)
    assert el["a"][1] == pytest.approx(-2.0, rel=1e-9)  # vis-viva: 2/r - v^2 loses ~log10(r/|a|) digits
    assert el["e"][1] == pytest.approx(1.3, rel=1e-9)
    # From r.v, a and e (not from f, within rounding of the asymptote): the digits a and e lost.
    assert el["M"][1] == pytest.approx(M, rel=1e-9)


# REBOUND ------------------------------------------------------------------------------------------


def _rebound_system() -> tuple[object, np.ndarray]:
    """Star, two planets and a massless particle, integrated with IAS15 and sampled 5 times."""
    rebound = pytest.importorskip("rebound")
    sim = rebound.Simulation()  # G = 1
    sim.add(m=1.0)
    sim.add(m=1e-3, a=1.0, e=0.05, inc=0.1, Omega=0.3, omega=1.0, M=2.0)
    sim.add(m=3e-4, a=1.7, e=0.2, inc=0.4, Omega=1.3, omega=2.0, M=-2.0)
    sim.add(m=0.0, a=-3.0, e=1.5, inc=2.5, Omega=4.3, omega=5.0, f=0.5)  # hyperbolic, retrograde
    sim.move_to_com()
    return sim, np.linspace(0.0, 7.0, 5)


def _states(sim: object) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    ps = sim.particles  # type: ignore[attr-defined]
    return (np.array([p.m for p in ps]), np.array([p.xyz for p in ps]), np.array([p.vxyz for p in ps]))


def _assert_matches_rebound(el: dict, s: int, i: int, orbit: object) -> dict[str, float]:
    """Differences (a, e relative; angles in radians) between our row and a REBOUND Orbit."""
    diffs = {"a": abs(el["a"][s, i] / orbit.a - 1.0), "e": abs(el["e"][s, i] / orbit.e - 1.0)}  # type: ignore[attr-defined]
    for name in (*ANGLES, "M"):
        ours, theirs = el[name][s, i], math.degrees(getattr(orbit, name))
        # REBOUND keeps f and M in [0, 2 pi), hyperbolic M too; ours are in [-180, 180), hyperbolic M
        # unbounded, so compare modulo 360 and relative to |M| (its ulp grows with it).
        scale = max(1.0, abs(math.radians(ours))) if name == "M" else 1.0
        diffs[name] = math.radians(float(_angle_diff_deg(ours, theirs))) / scale
    # Both are double precision on the same states: rounding only (REBOUND sums the Jacobi
    # centre of mass pair by pair, we by prefix sums), amplified by < 10 in the angles.
    assert max(diffs.values()) < 1e-12, diffs
    return diffs


def test_jacobi_matches_rebound_orbits() -> None:
    sim, times = _rebound_system()
    states = []
    orbits = []
    for t in times:
        sim.integrate(t)  # type: ignore[attr-defined]
        states.append(_states(sim))
        orbits.append(sim.orbits())  # type: ignore[attr-defined]  # default: Jacobi, jacobi_masses=False
    m = states[0][0]
    el = osculating_elements(m, np.stack([s[1] for s in states]), np.stack([s[2] for s in states]), G, "jacobi")
    assert el["a"].shape == (len(times), 4)
    assert np.all(np.isnan([el[name][:, 0] for name in ELEMENT_NAMES]))  # body 0 has no Jacobi orbit
    for s, sample_orbits in enumerate(orbits):
        for i, orbit in enumerate(sample_orbits, start=1):
            _assert_matches_rebound(el, s, i, orbit)


@pytest.mark.parametrize("primary", ["heaviest", 0, 2])
def test_about_one_body_matches_rebound_orbit_with_primary(primary: str | int) -> None:
    sim, times = _rebound_system()
    k = 0 if primary == "heaviest" else primary
    states, orbits = [], []
    for t in times:
        sim.integrate(t)  # type: ignore[attr-defined]
        states.append(_states(sim))
        ps = sim.particles  # type: ignore[attr-defined]
        orbits.append({i: ps[i].orbit(primary=ps[k]) for i in range(4) if i != k})
    m = states[0][0]
    el = osculating_elements(m, np.stack([s[1] for s in states]), np.stack([s[2] for s in states]), G, primary)
    assert np.all(np.isnan([el[name][:, k] for name in ELEMENT_NAMES]))  # the primary itself
    for s, sample_orbits in enumerate(orbits):
        for i, orbit in sample_orbits.items():
            _assert_matches_rebound(el, s, i, orbit)


# Shapes, NaN rows, degenerate states --------------------------------------------------------------


def test_shapes_dtype_and_keys() -> None:
    rng = np.random.default_rng(3)
    m, pos, vel, _ = _system(rng, 6)
    one = osculating_elements(m, pos, vel, G, "jacobi")
    assert tuple(one) == ELEMENT_NAMES
    assert all(v.shape == (6,) and v.dtype == np.float64 for v in one.values())
    many = osculating_elements(m, np.stack([pos] * 4), np.stack([vel] * 4), G, "jacobi")
    assert all(v.shape == (4, 6) for v in many.values())
    for name in ELEMENT_NAMES:
        np.testing.assert_array_equal(many[name][2], one[name])  # samples are independent
    per_sample = osculating_elements(np.stack([m] * 4), np.stack([pos] * 4), np.stack([vel] * 4), G, "jacobi")
    for name in ELEMENT_NAMES:
        np.testing.assert_array_equal(per_sample[name], many[name])


def test_nan_body_gives_nan_for_that_body_only() -> None:
    rng = np.random.default_rng(5)
    m, pos, vel, _ = _system(rng, 6)
    pos_s, vel_s = np.stack([pos] * 3), np.stack([vel] * 3)
    pos_s[1, 2] = np.nan  # body 2 removed from sample 1 on (position and velocity stored as NaN)
    vel_s[1, 2] = np.nan
    pos_s[2, 4, 0] = np.nan  # one NaN coordinate is enough
    clean = osculating_elements(m, pos, vel, G, "heaviest")
    el = osculating_elements(m, pos_s, vel_s, G, "heaviest")
    for name in ELEMENT_NAMES:
        assert np.isnan(el[name][1, 2]) and np.isnan(el[name][2, 4])
        np.testing.assert_array_equal(el[name][0], clean[name])
        np.testing.assert_array_equal(np.delete(el[name][1], 2), np.delete(clean[name], 2))
    # Jacobi: a removed body leaves the interior centre of mass, as in REBOUND after sim.remove().
    jac = osculating_elements(m, pos_s, vel_s, G, "jacobi")
    without = osculating_elements(np.delete(m, 2), np.delete(pos, 2, axis=0), np.delete(vel, 2, axis=0), G, "jacobi")
    for name in ELEMENT_NAMES:
        assert np.isnan(jac[name][1, 2])
        np.testing.assert_allclose(np.delete(jac[name][1], 2), without[name], rtol=1e-13, atol=1e-12)  # rounding


def test_nan_mass_and_removed_heaviest_body() -> None:
    m = np.array([[1.0, 0.5, 0.0], [np.nan, 0.5, 0.0]])  # the star gone at sample 1 (NaN mass)
    pos = np.array([[[0.0, 0, 0], [2.0, 0, 0], [3.0, 0, 0]]] * 2)
    vel = np.array([[[0.0, 0, 0], [0.0, 0.8, 0], [0.0, 0.6, 0]]] * 2)
    el = osculating_elements(m, pos, vel, G, "heaviest")
    assert np.isnan(el["a"][0, 0]) and np.isnan(el["a"][1, 0]) and np.isnan(el["a"][1, 1])
    # Sample 1: the heaviest body present is body 1, so body 2 orbits it (mu = 0.5, r = 1, v = 0.2).
    assert el["a"][1, 2] == pytest.approx(1.0 / (2.0 - 0.2**2 / 0.5), rel=1e-14)
    assert el["a"][0, 2] == pytest.approx(1.0 / (2.0 / 3.0 - 0.36 / 1.0), rel=1e-14)  # sample 0: about the star


def test_primary_rows_and_ties() -> None:
    m = np.array([0.5, 1.0, 1.0, 0.0])  # a tie: body 1 is the heaviest, the first of the largest
    pos = np.array([[0.0, 0, 0], [5.0, 0, 0], [-5.0, 0, 0], [6.0, 0, 0]])
    vel = np.array([[0.0, 0, 0], [0.0, 0.1, 0], [0.0, -0.1, 0], [0.0, 1.1, 0]])
    el = osculating_elements(m, pos, vel, G, "heaviest")
    assert np.isnan(el["e"][1]) and not np.isnan(el["e"][2])
    assert el["a"][3] == pytest.approx(1.0 / (2.0 - 1.0 / 1.0), rel=1e-15)  # about body 1: r = 1, v = 1, mu = 1
    assert el["e"][3] == pytest.approx(0.0, abs=1e-15)
    by_index = osculating_elements(m, pos, vel, G, 2)
    assert np.isnan(by_index["a"][2]) and np.count_nonzero(np.isnan(by_index["a"])) == 1


def test_degenerate_states_give_values_or_nan_without_warnings() -> None:
    m = np.array([1.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    pos = np.array([[0.0, 0, 0], [1.0, 0, 0], [2.0, 0, 0], [0.0, 0, 0], [-2.0, 0, 0], [0.0, 2.0, 0]])
    # Speeds chosen so that v^2, 2 mu / r and the rest are exact in binary.
    vel = np.array([[0.0, 0, 0], [0.0, 1.0, 0], [0.3, 0, 0], [0.0, 1.0, 0], [0.0, -1.0, 0], [1.0000001, 0, 0]])
    el = osculating_elements(m, pos, vel, G, "heaviest")
    # Body 1: circular and equatorial: Omega = omega = 0, f from x-hat (the scalar's conventions).
    assert (el["e"][1], el["inc"][1], el["Omega"][1], el["omega"][1], el["f"][1], el["M"][1]) == (
        0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    # Body 2: radial (h = 0): a and e from the energy and the Laplace vector; no plane, so no angles.
    assert el["a"][2] == pytest.approx(1.0 / (2.0 / 2.0 - 0.09), rel=1e-15)
    assert el["e"][2] == pytest.approx(1.0, abs=1e-15)
    assert all(np.isnan(el[name][2]) for name in (*ANGLES, "M"))
    # Body 3: on its primary (r = 0): nothing is defined.
    assert all(np.isnan(el[name][3]) for name in ELEMENT_NAMES)
    # Body 4: exactly parabolic (v^2 = 2 mu / r = 1): a = inf and M = NaN, as the scalar function.
    assert el["a"][4] == math.inf and el["e"][4] == 1.0 and np.isnan(el["M"][4])
    assert el["f"][4] == 0.0
    # Body 5: barely hyperbolic, at periapsis and retrograde: a < 0, e just above 1, finite angles.
    assert el["a"][5] < 0.0 and 1.0 < el["e"][5] < 1.0 + 1e-6 and el["inc"][5] == 180.0
    assert all(np.isfinite(el[name][5]) for name in ELEMENT_NAMES)


def test_massless_primary_and_body_give_nan() -> None:
    m = np.array([0.0, 0.0])  # mu = G (0 + 0): no Kepler orbit
    el = osculating_elements(m, np.array([[0.0, 0, 0], [1.0, 0, 0]]), np.array([[0.0, 0, 0], [0.0, 1, 0]]), G, 0)
    assert all(np.isnan(el[name]).all() for name in ELEMENT_NAMES)
    jac = osculating_elements(np.array([0.0, 1.0, 0.0]), np.array([[0.0, 0, 0], [1.0, 0, 0], [3.0, 0, 0]]),
                              np.array([[0.0, 0, 0], [0.0, 1, 0], [0.0, 1.5, 0]]), G, "jacobi")
    # Body 1 has only a massless body inside it (no centre of mass); body 2 orbits body 1 alone
    # (mu = 1, r = 2, v = 0.5).
    assert np.isnan(jac["a"][1]) and jac["a"][2] == pytest.approx(1.0 / (2.0 / 2.0 - 0.25), rel=1e-15)


@pytest.mark.parametrize(("args", "match"), [
    ((np.ones(2), np.zeros((2, 3)), np.zeros((2, 2)), 1.0, 0), "shape"),
    ((np.ones(2), np.zeros((2, 2)), np.zeros((2, 2)), 1.0, 0), "shape"),
    ((np.ones(3), np.zeros((2, 3)), np.zeros((2, 3)), 1.0, 0), "masses must have shape"),
    ((np.array([1.0, -1.0]), np.zeros((2, 3)), np.zeros((2, 3)), 1.0, 0), ">= 0"),
    ((np.ones(2), np.zeros((2, 3)), np.zeros((2, 3)), 0.0, 0), "G must be"),
    ((np.ones(2), np.zeros((2, 3)), np.zeros((2, 3)), math.nan, 0), "G must be"),
    ((np.ones(2), np.zeros((2, 3)), np.zeros((2, 3)), 1.0, "sun"), "heaviest, jacobi"),
    ((np.ones(2), np.zeros((2, 3)), np.zeros((2, 3)), 1.0, 2), "from 0 to 1"),
    ((np.ones(2), np.zeros((2, 3)), np.zeros((2, 3)), 1.0, -1), "from 0 to 1"),
    ((np.ones(2), np.zeros((2, 3)), np.zeros((2, 3)), 1.0, True), "body index"),
])
def test_bad_input_is_refused(args: tuple, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        osculating_elements(*args)


def test_blocks_of_samples_change_nothing(monkeypatch: pytest.MonkeyPatch) -> None:
    """Samples are converted in blocks to bound memory; block edges must not show in the result."""
    import orbitsim.physics.orbital_elements as module

    rng = np.random.default_rng(11)
    m, pos, vel, _ = _system(rng, 9)
    pos_s = pos + 0.01 * rng.normal(size=(50, 9, 3))
    vel_s = vel + 0.01 * rng.normal(size=(50, 9, 3))
    pos_s[17:33, 4] = np.nan  # a removal that straddles block edges
    whole = {mode: osculating_elements(m, pos_s, vel_s, G, mode) for mode in ("heaviest", "jacobi")}
    monkeypatch.setattr(module, "_BLOCK_BODY_SAMPLES", 7 * 9)  # 7 samples per block, the last one short
    for mode, expected in whole.items():
        blocked = osculating_elements(m, pos_s, vel_s, G, mode)
        for name in ELEMENT_NAMES:
            np.testing.assert_array_equal(blocked[name], expected[name])
