"""Energy behaviour: explicit Euler drifts secularly; symplectic schemes stay bounded for 10^4 orbits.

Two bodies, M = 1 and m = 1e-3 (a massive secondary, so the total energy is not zero), G = 1,
a = 1, started in the centre-of-mass frame.

* Negative control: explicit Euler on a circular orbit gains energy every step; the gain per orbit
  is, to leading order, 8 pi^2 / n_per_orbit (derivation in :func:`test_euler_energy_grows_secularly`).
* Symplectic schemes on an eccentric orbit (e = 0.5) for 10^4 orbits: the energy error oscillates
  around a fixed offset (the shadow Hamiltonian) with no secular trend. The test compares the
  largest |dE/E| of the last 10% of the run with that of the first 10%, and fits a line to dE/E
  against time: the drift it implies over the whole run must be a small fraction of the
  oscillation's peak-to-peak amplitude. RK4 (not symplectic) fails both criteria, which shows the
  criteria can fail.

Samples are taken every (steps per orbit + 1) steps so they walk through the orbital phase instead of
strobing one point of the orbit.

The bounded-energy test runs over every scheme whose record says ``symplectic`` but Wisdom-Holman:
on two bodies its map is the exact Kepler flow, so its energy error is round-off alone, below the
oscillation this test needs to see (:func:`test_two_body_exact_schemes_have_only_round_off`; its
bounded energy on a planetary system is tests/integrators/test_wisdom_holman.py's
``test_energy_is_bounded_without_drift``). :func:`test_symplectic_flags_match_this_list` holds the
lists to the registry.
"""

from __future__ import annotations

import numpy as np
import pytest

from orbitsim.integrators.registry import INTEGRATORS
from orbitsim.simulation import simulate

CENTRAL_MASS = 1.0
SECONDARY_MASS = 1e-3
MU = CENTRAL_MASS + SECONDARY_MASS
PERIOD = 2.0 * np.pi / np.sqrt(MU)  # a = 1
ORBITS = 10_000

#: Symplectic scheme -> steps per orbit for the 10^4-orbit run on the e = 0.5 orbit. Order 1-2: P/100
#: (10^6 steps, well inside the stable range). leapfrog6/8: P/70; at P/45 and coarser their large
#: negative substeps over-step the pericentre passage and the energy does drift (measured ratio 3.1
#: for leapfrog8 at P/45); at P/100 leapfrog8's amplitude (1e-11) is too close to round-off.
SYMPLECTIC_STEPS_PER_ORBIT = {
    "semi_implicit_euler": 100,
    "verlet": 100,
    "leapfrog": 100,
    "leapfrog4": 100,
    "leapfrog6": 70,
    "leapfrog8": 70,
}

#: Symplectic schemes exact on the two-body problem (Wisdom-Holman in its default Jacobi coordinates:
#: a Kepler drift and no interaction kick), whose energy error here is round-off alone.
TWO_BODY_EXACT = ("wisdom_holman",)

#: last-10% / first-10% max |dE/E| must stay below this (measured 1.000-1.006); a bounded
#: oscillation gives ~1, a secular drift grows it with time (rk4: 11).
MAX_GROWTH = 2.0

#: The linear trend over the whole run must stay below this fraction of the peak-to-peak
#: oscillation (measured 2.7e-4 .. 1.1e-3, and 4.9e-3 for leapfrog8 whose amplitude, 1.7e-10, is
#: nearest round-off; rk4: 1.0).
MAX_TREND_FRACTION = 0.02


def two_body(e: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Masses, positions, velocities (N, 3) of the two-body orbit, at pericentre, CoM frame."""
    r_peri = 1.0 - e
    v_peri = np.sqrt(MU * (1.0 + e) / r_peri)  # vis-viva, a = 1
    x_rel = np.array([r_peri, 0.0, 0.0])
    v_rel = np.array([0.0, v_peri, 0.0])
    m = np.array([CENTRAL_MASS, SECONDARY_MASS])
    x = np.array([-SECONDARY_MASS / MU * x_rel, CENTRAL_MASS / MU * x_rel])
    v = np.array([-SECONDARY_MASS / MU * v_rel, CENTRAL_MASS / MU * v_rel])
    return m, x, v


def drift_statistics(name: str, steps_per_orbit: int, orbits: int) -> tuple[float, float, float]:
    """(max |dE/E| last 10% / first 10%, |trend over the run| / peak-to-peak, peak-to-peak)."""
    m, x, v = two_body(0.5)
    result = simulate(
        m, x, v, integrator=name, dt=PERIOD / steps_per_orbit, steps=steps_per_orbit * orbits,
        every=steps_per_orbit + 1, record_positions=False,
    )
    assert result.status == "complete"
    de = result.energy_error
    tenth = de.size // 10
    first = np.max(np.abs(de[1 : tenth + 1]))  # sample 0 is exactly zero
    last = np.max(np.abs(de[-tenth:]))
    slope = np.polyfit(result.time, de, 1)[0]
    peak_to_peak = float(de.max() - de.min())
    return float(last / first), float(abs(slope) * result.time[-1] / peak_to_peak), peak_to_peak


def test_euler_energy_grows_secularly() -> None:
    """Circular orbit, dt = P/10^4, 30 orbits, sampled once per orbit.

    One Euler step changes the energy by dt^2 (|a|^2 + v.H.v) / 2 + O(dt^3), where H is the
    Hessian of the potential: both terms are positive, so E rises every step. On the circle
    (reduced problem, E = -mu/2) that is 2 mu dt^2 relative per step, 8 pi^2 / n per orbit.
    """
    n_per_orbit = 10_000
    m, x, v = two_body(0.0)
    result = simulate(
        m, x, v, integrator="euler", dt=PERIOD / n_per_orbit, steps=30 * n_per_orbit,
        every=n_per_orbit, record_positions=False,
    )
    de = result.energy_error
    assert de.size == 31
    assert np.all(np.diff(de) > 0.0), "Euler's energy must rise monotonically on a circular orbit"
    assert de[-1] > 10.0 * de[1]  # measured 21x after 30 orbits
    # The first orbit's gain matches the leading-order rate; O(dt) terms and the orbit's own
    # expansion during that orbit change it by ~2% (measured 7.77e-3 vs 7.90e-3).
    assert de[1] == pytest.approx(8.0 * np.pi**2 / n_per_orbit, rel=0.05)


@pytest.mark.parametrize("name", SYMPLECTIC_STEPS_PER_ORBIT)
def test_symplectic_energy_is_bounded(name: str) -> None:
    growth, trend, peak_to_peak = drift_statistics(name, SYMPLECTIC_STEPS_PER_ORBIT[name], ORBITS)
    # The oscillation must dwarf the round-off random walk (~1e-13 after 10^6 steps) or the test
    # would measure round-off, not the integrator.
    assert peak_to_peak > 1e-11
    assert growth < MAX_GROWTH, f"{name}: max |dE/E| grew {growth:.3f}x from the first to the last 10%"
    assert trend < MAX_TREND_FRACTION, f"{name}: linear trend is {trend:.2e} of the oscillation"


def test_criteria_catch_a_non_symplectic_drift() -> None:
    """Negative control for the two criteria: RK4's slow energy drift fails both."""
    growth, trend, _ = drift_statistics("rk4", 100, ORBITS)
    # Measured growth 11.4 and trend 1.0: far outside the symplectic bounds.
    assert growth > 2.0 * MAX_GROWTH
    assert trend > 10.0 * MAX_TREND_FRACTION


@pytest.mark.parametrize("name", TWO_BODY_EXACT)
def test_two_body_exact_schemes_have_only_round_off(name: str) -> None:
    """Why TWO_BODY_EXACT is outside the bounded-energy test: 10 orbits at P/100 on the e = 0.5 orbit
    leave |dE/E| at round-off, not the oscillation of a symplectic scheme's shadow energy."""
    m, x, v = two_body(0.5)
    steps_per_orbit = 100  # as the order 1-2 schemes above
    result = simulate(m, x, v, integrator=name, dt=PERIOD / steps_per_orbit, steps=10 * steps_per_orbit,
                      every=steps_per_orbit + 1, record_positions=False)
    # Measured 8.7e-15; the bounded-energy test needs an oscillation above 1e-11, 10x this bound.
    assert np.max(np.abs(result.energy_error)) < 1e-12


def test_symplectic_flags_match_this_list() -> None:
    """Every scheme the registry calls symplectic is tested here, in the bounded-energy test or as
    exact on two bodies, and only those; the negative controls are not symplectic."""
    by_name = {spec.name: spec for spec in INTEGRATORS}
    symplectic = {name for name, spec in by_name.items() if spec.symplectic}
    assert symplectic == set(SYMPLECTIC_STEPS_PER_ORBIT) | set(TWO_BODY_EXACT)
    assert not set(SYMPLECTIC_STEPS_PER_ORBIT) & set(TWO_BODY_EXACT)
    assert not by_name["euler"].symplectic and not by_name["rk4"].symplectic


@pytest.mark.slow
@pytest.mark.parametrize("name", ["verlet", "leapfrog", "leapfrog4"])
def test_symplectic_energy_is_bounded_for_1e5_orbits(name: str) -> None:
    """The same criteria over ten times as many orbits (10^7 steps; ~10 s per scheme)."""
    growth, trend, peak_to_peak = drift_statistics(name, SYMPLECTIC_STEPS_PER_ORBIT[name], 10 * ORBITS)
    assert peak_to_peak > 1e-11  # as above: the oscillation must dwarf round-off
    assert growth < MAX_GROWTH
    assert trend < MAX_TREND_FRACTION
