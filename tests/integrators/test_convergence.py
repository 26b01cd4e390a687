"""Measured convergence order of every scheme on the Kepler problem, against its analytic solution.

A test particle (mass 0) orbits a unit mass with G = 1, a = 1, e = 0.5, starting at pericentre, so
the exact motion is the Kepler ellipse with mu = G (M + m) = 1, computed in the test by solving
Kepler's equation. The position error is taken at t = 1.3 P: at a whole number of periods
semi-implicit Euler's first-order error term vanishes and it looks second order
(:func:`test_whole_period_hides_semi_implicit_euler_order` shows the trap).

For each scheme the step count n (dt = t / n) runs up a ladder; the slope of log(error) against
log(dt) is fitted with ``np.polyfit`` and must lie within 0.3 of the declared order. The ladders
were chosen by measurement so every error lies in the asymptotic regime and above ~3e-12 (the
float64 round-off floor of this run is ~5e-14 .. 1e-13).

Three schemes are exact on this problem, at round-off for any dt
(:func:`test_kepler_problem_is_exact_for`): Wisdom-Holman and TRACE drift the particle along the
exact Kepler orbit and a massless particle gets no kick, so their ladders run on a two-planet system
instead, against REBOUND's IAS15 (:func:`test_measured_order_on_a_planetary_system`); IAS15 is
adaptive (``spec.adaptive``): its dt is the output grid, not a step, and it keeps its error at
round-off whatever dt is, so there is no order in dt to measure.
:func:`test_every_scheme_has_a_ladder_or_a_reason` holds the lists to the registry.
"""

from __future__ import annotations

import naive
import numpy as np
import pytest
import rebound

from orbitsim.initial_conditions.elements import elements_to_cartesian
from orbitsim.integrators.registry import INTEGRATORS, get_spec
from orbitsim.simulation import simulate

SEMI_MAJOR_AXIS = 1.0
ECCENTRICITY = 0.5
PERIOD = 2.0 * np.pi  # G (M + m) = 1, a = 1
T_COMPARE = 1.3 * PERIOD

#: scheme -> (first step count, ratio between rungs, number of rungs). Five halvings of dt (ratio 2,
#: six rungs) where float64 leaves room. leapfrog8 cannot: five halvings span 2^40 ~ 1e12 in error,
#: more than double precision offers between the end of its pre-asymptotic regime (~4e-8 at
#: n = 52; local slopes below n = 52 wander between 7.2 and 7.8) and the round-off floor (~5e-14 at
#: n ~ 300), so it uses 2^(1/4) rungs over 1.75 halvings of dt.
LADDERS: dict[str, tuple[int, float, int]] = {
    "euler": (4000, 2.0, 6),  # errors 0.29 .. 9e-3
    "semi_implicit_euler": (2000, 2.0, 6),  # 1.5e-2 .. 5e-4
    "verlet": (200, 2.0, 6),  # 4.4e-2 .. 4.3e-5
    "leapfrog": (200, 2.0, 6),  # 2.0e-2 .. 2.0e-5
    "rk4": (200, 2.0, 6),  # 6.3e-5 .. 4.5e-11
    "leapfrog4": (100, 2.0, 6),  # 6.2e-3 .. 6.5e-9
    "leapfrog6": (26, 2.0, 6),  # 5.2e-3 .. 7.4e-12
    "leapfrog8": (52, 2.0**0.25, 8),  # 4.3e-8 .. 2.8e-12
}

#: Fixed-step schemes exact on the Kepler problem: scheme -> ladder on the two-planet system, as in
#: LADDERS (errors against REBOUND's IAS15, whose own error there is ~5e-13).
PLANETARY_LADDERS: dict[str, tuple[int, float, int]] = {
    "wisdom_holman": (80, 2.0, 6),  # 2.1e-5 .. 2.0e-8
    "trace": (80, 2.0, 6),  # 1.5e-5 .. 1.5e-8 (no close encounter, no pericentre switch)
}

#: Adaptive schemes (``spec.adaptive``): no order in dt to measure.
ADAPTIVE = ("ias15",)

#: The comparison time on the two-planet system: 3.3 inner periods, a whole number of neither orbit.
T_PLANETARY = 20.7

#: A fitted slope within this margin of the declared order passes: the pre-asymptotic end of each
#: ladder bends the fit by up to ~0.15 (measured: rk4 4.08, leapfrog6 5.89); a wrong order is >= 1 off.
ORDER_MARGIN = 0.3

#: Errors below this are round-off, not truncation, and would flatten the fit.
ROUND_OFF_FLOOR = 1e-12


def kepler_initial_state() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    r_peri = SEMI_MAJOR_AXIS * (1.0 - ECCENTRICITY)
    v_peri = np.sqrt((1.0 + ECCENTRICITY) / r_peri)  # vis-viva at pericentre with mu = 1, a = 1
    m = np.array([1.0, 0.0])
    x = np.array([[0.0, 0.0, 0.0], [r_peri, 0.0, 0.0]])
    v = np.array([[0.0, 0.0, 0.0], [0.0, v_peri, 0.0]])
    return m, x, v


def position_error(name: str, n: int, t_end: float) -> float:
    """|x_numeric - x_exact| of the particle relative to the central mass after n steps to t_end."""
    m, x0, v0 = kepler_initial_state()
    result = simulate(m, x0, v0, integrator=name, dt=t_end / n, steps=n, every=n)
    x_rel = result.final_positions[1] - result.final_positions[0]
    x_exact, _ = naive.kepler_state(t_end, SEMI_MAJOR_AXIS, ECCENTRICITY, 1.0)
    return float(np.linalg.norm(x_rel - x_exact))


def fitted_order(name: str, n0: int, ratio: float, rungs: int, t_end: float) -> tuple[float, np.ndarray]:
    steps = np.array([round(n0 * ratio**k) for k in range(rungs)])
    errors = np.array([position_error(name, int(n), t_end) for n in steps])
    slope = np.polyfit(np.log(t_end / steps), np.log(errors), 1)[0]
    return float(slope), errors


def test_analytic_solution_is_right() -> None:
    """The reference itself: back at pericentre after one period, and energy/angular momentum of
    the analytic state match the orbit's (a check of naive.kepler_state, not of the engine)."""
    x, v = naive.kepler_state(PERIOD, SEMI_MAJOR_AXIS, ECCENTRICITY, 1.0)
    # Kepler's equation is solved by Newton's method to ~1 ulp of 2 pi.
    assert np.allclose(x, [0.5, 0.0, 0.0], rtol=0, atol=1e-14)
    x, v = naive.kepler_state(0.37 * PERIOD, SEMI_MAJOR_AXIS, ECCENTRICITY, 1.0)
    # Energy -mu / (2a) and |L| = sqrt(mu a (1 - e^2)) hold to round-off of a few operations.
    assert 0.5 * v @ v - 1.0 / np.linalg.norm(x) == pytest.approx(-0.5, abs=1e-14)
    assert np.cross(x, v)[2] == pytest.approx(np.sqrt(1.0 - ECCENTRICITY**2), abs=1e-14)


@pytest.mark.parametrize("name", LADDERS)
def test_measured_order_matches_declared(name: str) -> None:
    n0, ratio, rungs = LADDERS[name]
    assert rungs >= 6  # at least five refinements of dt
    slope, errors = fitted_order(name, n0, ratio, rungs, T_COMPARE)
    declared = get_spec(name).order
    assert np.all(errors > ROUND_OFF_FLOOR), f"{name}: ladder reaches the round-off floor: {errors}"
    assert np.all(np.diff(errors) < 0), f"{name}: errors do not decrease along the ladder: {errors}"
    assert abs(slope - declared) < ORDER_MARGIN, f"{name}: fitted order {slope:.3f}, declared {declared}"


def test_whole_period_hides_semi_implicit_euler_order() -> None:
    """Why the comparison time is 1.3 P: at exactly one period, started at pericentre, semi-implicit
    Euler's first-order error cancels and the fit reports ~2, not 1."""
    slope_whole, _ = fitted_order("semi_implicit_euler", 2000, 2.0, 6, PERIOD)
    slope_off, _ = fitted_order("semi_implicit_euler", 2000, 2.0, 6, T_COMPARE)
    # Measured 2.00 at t = P and 0.99 at t = 1.3 P; 0.5 separates the two cleanly.
    assert slope_whole > 1.5
    assert slope_off < 1.5


@pytest.mark.parametrize("name", [*PLANETARY_LADDERS, *ADAPTIVE])
def test_kepler_problem_is_exact_for(name: str) -> None:
    """Why these schemes have no ladder on the Kepler problem: ten steps (or output intervals) of
    0.13 P already land on the analytic position to round-off."""
    # Measured 2.0e-14 (trace), 7.5e-15 (wisdom_holman), 8.9e-16 (ias15); any ladder rung of the
    # other schemes is above the round-off floor.
    assert position_error(name, 10, T_COMPARE) < ROUND_OFF_FLOOR


def two_planets() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A star (m = 1, G = 1) and two 1e-3 planets at a = 1 and 1.6 (e = 0.05, 0.1), barycentric."""
    m = np.array([1.0, 1e-3, 1e-3])
    x1, v1 = elements_to_cartesian(1.001, 1.0, 0.05, 1.0, 10.0, 20.0, M=30.0)
    x2, v2 = elements_to_cartesian(1.002, 1.6, 0.1, 3.0, 50.0, 80.0, M=200.0)
    x = np.array([np.zeros(3), x1, x2])
    v = np.array([np.zeros(3), v1, v2])
    return m, x - m @ x / m.sum(), v - m @ v / m.sum()


@pytest.mark.parametrize("name", PLANETARY_LADDERS)
def test_measured_order_on_a_planetary_system(name: str) -> None:
    """The ladder of a scheme exact on Kepler: the largest position error of the three bodies at
    T_PLANETARY, against REBOUND's IAS15, with the criteria of the Kepler ladders."""
    m, x, v = two_planets()
    sim = rebound.Simulation()
    sim.G, sim.integrator = 1.0, "ias15"
    for mi, xi, vi in zip(m, x, v, strict=True):
        sim.add(m=mi, x=xi[0], y=xi[1], z=xi[2], vx=vi[0], vy=vi[1], vz=vi[2])
    sim.integrate(T_PLANETARY)
    reference = np.array([[p.x, p.y, p.z] for p in sim.particles])

    n0, ratio, rungs = PLANETARY_LADDERS[name]
    assert rungs >= 6  # at least five refinements of dt
    steps = np.array([round(n0 * ratio**k) for k in range(rungs)])
    errors = np.array([
        np.max(np.linalg.norm(simulate(m, x, v, integrator=name, dt=T_PLANETARY / n, steps=int(n), every=int(n))
                              .final_positions - reference, axis=1))
        for n in steps
    ])
    slope = np.polyfit(np.log(T_PLANETARY / steps), np.log(errors), 1)[0]
    declared = get_spec(name).order
    assert np.all(errors > ROUND_OFF_FLOOR), f"{name}: ladder reaches the round-off floor: {errors}"
    assert np.all(np.diff(errors) < 0), f"{name}: errors do not decrease along the ladder: {errors}"
    # Measured 1.999 for both.
    assert abs(slope - declared) < ORDER_MARGIN, f"{name}: fitted order {slope:.3f}, declared {declared}"


def test_every_scheme_has_a_ladder_or_a_reason() -> None:
    """Every registered scheme has a ladder here or is adaptive, and only the adaptive ones go
    without: a new scheme fails here until its order is measured."""
    by_name = {spec.name: spec for spec in INTEGRATORS}
    lists = (set(LADDERS), set(PLANETARY_LADDERS), set(ADAPTIVE))
    assert set().union(*lists) == set(by_name)
    assert sum(len(names) for names in lists) == len(by_name)  # no scheme in two lists
    assert set(ADAPTIVE) == {name for name, spec in by_name.items() if spec.adaptive}
