"""orbitsim's TRACE kernels (:mod:`orbitsim.integrators.trace.core`) against REBOUND's TRACE.

Both run in this process from the same initial state (read from a ``rebound.Simulation``, set up
as REBOUND's own ``test_trace.py`` does), to the same end time with REBOUND's exact finish (whole
steps, then one step of ``t_end - t``). The port keeps REBOUND 5.2.2's order of floating-point
operations everywhere (non-OpenMP loop orders, no FMA), so the comparisons are bit for bit: every
coordinate of every body ``==``, not a tolerance. The step counters (steps redone, BS sub-steps)
are REBOUND 5.2.2's over the same spans, measured with an instrumented reference that reproduced it
bit for bit.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest

from orbitsim.integrators.trace.core import active_count, advance, counts_of, make_work

rebound = pytest.importorskip("rebound")

#: Bit-for-bit agreement is what the port was checked for; another REBOUND may round differently.
bitwise = pytest.mark.skipif(rebound.__version__ != "5.2.2", reason="bitwise parity is with REBOUND 5.2.2")

PERI_MODE_IDS = {"partial_bs": 0, "full_bs": 1, "full_ias15": 2}


def state_of(sim: rebound.Simulation) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Inertial (3, N) positions and velocities and the masses of a REBOUND simulation."""
    ps = sim.particles
    pos = np.array([[p.x for p in ps], [p.y for p in ps], [p.z for p in ps]])
    vel = np.array([[p.vx for p in ps], [p.vy for p in ps], [p.vz for p in ps]])
    return pos, vel, np.array([p.m for p in ps])


def energy(pos: np.ndarray, vel: np.ndarray, m: np.ndarray, G: float) -> float:
    """Newtonian energy of the massive bodies (what REBOUND's ``sim.energy()`` reports for TRACE)."""
    massive = m > 0.0
    pos, vel, m = pos[:, massive], vel[:, massive], m[massive]
    kinetic = 0.5 * float(np.sum(m * np.sum(vel * vel, axis=0)))
    potential = 0.0
    for i in range(m.size):
        r = np.sqrt(np.sum((pos[:, i + 1:] - pos[:, i:i + 1]) ** 2, axis=0))
        potential -= G * m[i] * float(np.sum(m[i + 1:] / r))
    return kinetic + potential


def integrate(pos: np.ndarray, vel: np.ndarray, m: np.ndarray, G: float, dt: float, t0: float, t_end: float,
              **settings: object) -> tuple[float, dict[str, int]]:
    """REBOUND's ``integrate(t_end)`` with exact finish: whole steps while t + dt < t_end (t summed
    as REBOUND sums it), then one step of t_end - t. Returns the final time and the counters."""
    n_steps, t = 0, t0
    while t + dt < t_end:
        t += dt
        n_steps += 1
    work = make_work(pos.shape[1])
    t, _ = advance(pos, vel, m, G, dt, t0, n_steps, work=work, **settings)
    if t != t_end:
        t, _ = advance(pos, vel, m, G, t_end - t, t, 1, work=work, dt_last_done=dt if n_steps else 0.0, **settings)
    return t, counts_of(work)


def run_both(make_sim: Callable[[], rebound.Simulation], t_end: float, peri_mode: str = "full_bs",
             r_crit_hill: float = 3.0, softening: float = 0.0
             ) -> tuple[tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray], dict[str, int], float]:
    """The same set-up integrated by REBOUND and by orbitsim: (REBOUND state, orbitsim state,
    orbitsim's counters, orbitsim's |dE/E|)."""
    sim = make_sim()
    sim.integrator = "trace"
    sim.integrator.peri_mode = PERI_MODE_IDS[peri_mode]
    sim.integrator.r_crit_hill = r_crit_hill
    sim.softening = softening
    pos, vel, m = state_of(sim)
    e0 = energy(pos, vel, m, sim.G)
    t, counts = integrate(pos, vel, m, sim.G, sim.dt, sim.t, t_end, peri_mode=peri_mode, r_crit_hill=r_crit_hill,
                          peri_crit_eta=sim.integrator.peri_crit_eta, softening=softening)
    sim.integrate(t_end)
    assert t == sim.t
    rb_pos, rb_vel, _ = state_of(sim)
    return (rb_pos, rb_vel), (pos, vel), counts, abs((energy(pos, vel, m, sim.G) - e0) / e0)


def assert_bitwise(rebound_state: tuple[np.ndarray, np.ndarray], ours: tuple[np.ndarray, np.ndarray]) -> None:
    """Every coordinate equal (the port performs REBOUND's operations in REBOUND's order)."""
    for label, a, b in (("positions", rebound_state[0], ours[0]), ("velocities", rebound_state[1], ours[1])):
        scale = np.max(np.abs(a))
        assert np.array_equal(a, b), f"{label} differ, max relative {np.max(np.abs(a - b)) / scale:.3e}"


# REBOUND's test_trace.py set-ups -----------------------------------------------------------------

def outer_solar_system() -> rebound.Simulation:
    """test_outer_solar: the Sun and the giant planets (REBOUND's built-in data), dt = P_Jupiter / 1000."""
    sim = rebound.Simulation()
    sim.add("outer solar system")
    sim.dt = 1e-3 * sim.particles[1].P
    return sim


def many_encounters() -> rebound.Simulation:
    """test_many_encounters: six 1e-4 planets on crossing orbits, dt = 0.034."""
    sim = rebound.Simulation()
    sim.add(m=1)
    for x, y, vx, vy in ((0.90000, 0.00000, 0.00000, 1.10360), (-1.17676, -0.05212, 0.22535, -0.90102),
                         (-1.66025, -0.69852, 0.18932, -0.60030), (0.57904, 1.03836, -0.69267, 0.75995),
                         (-0.41683, 0.83128, -1.03478, -0.72482), (1.83969, 0.32938, -0.55114, 0.51646)):
        sim.add(m=0.0001, x=x, y=y, vx=vx, vy=vy)
    sim.move_to_com()
    sim.dt = 0.034
    return sim


def pericenter() -> rebound.Simulation:
    """test_pericenter: Jupiter, and a Saturn-mass body on a polar e = 0.99 orbit, dt = 0.15 * 2 pi."""
    sim = rebound.Simulation()
    sun = rebound.Particle(m=1.0)
    sim.add(sun)
    sim.add(primary=sun, m=9.55e-4, a=5.2)
    sim.add(primary=sun, m=2.857e-4, a=9.58, e=0.99, inc=math.pi / 2.0)
    sim.move_to_com()
    sim.dt = 0.15 * 2.0 * math.pi
    return sim


def chaotic_exchange() -> rebound.Simulation:
    """test_chaotic_exchange: a test particle scattered by a 0.01 solar-mass planet, with
    N_active = 2 (orbitsim's test particles are REBOUND's N_active ones)."""
    star_m, jup_m, jup_a = 1.0, 0.01 / 0.99, 5.2
    star_x = -(jup_m / (star_m + jup_m)) * jup_a
    star_vy = -(jup_m / (star_m + jup_m)) * np.sqrt((star_m + jup_m) / jup_a)
    sim = rebound.Simulation()
    sim.add(m=star_m, x=star_x, vy=star_vy)
    jup_x = (star_m / (star_m + jup_m)) * jup_a
    jup_vy = (star_m / (star_m + jup_m)) * np.sqrt((star_m + jup_m) / jup_a)
    sim.add(m=jup_m, x=jup_x, vy=jup_vy)
    sim.add(m=0.0, x=4.42 + star_x, vy=0.0072 * 365.25 / (2.0 * np.pi) + star_vy)
    sim.N_active = 2
    sim.dt = (8.0 / 365.0) * 2.0 * math.pi
    return sim


# agreement with REBOUND --------------------------------------------------------------------------

@bitwise
def test_outer_solar_system_is_bit_identical_to_rebound_and_conserves_energy() -> None:
    rb, ours, counts, de = run_both(outer_solar_system, 1000.0)
    assert_bitwise(rb, ours)
    assert counts["steps"] == 13414 and counts["redone"] == 0 and counts["encounter_bs_substeps"] == 0
    assert de < 3e-10  # REBOUND's bound; measured 2.41e-10


@bitwise
def test_many_encounters_is_bit_identical_to_rebound_with_its_redone_and_full_bs_steps() -> None:
    rb, ours, counts, de = run_both(many_encounters, 2000.0)
    assert_bitwise(rb, ours)
    # Counters of the notes' reference (bit-identical to REBOUND 5.2.2) over the same span.
    assert counts["steps"] == 58824
    assert counts["redone"] == 85
    assert counts["encounter_bs_substeps"] == 1400 and counts["encounter_bs_rejected"] == 54
    assert counts["full_bs_steps"] == 34
    assert de < 5e-5  # REBOUND's bound; measured 5.68e-6


@bitwise
def test_many_encounters_partial_bs_is_bit_identical_to_rebound() -> None:
    rb, ours, counts, de = run_both(many_encounters, 2000.0, "partial_bs")
    assert_bitwise(rb, ours)
    assert counts["redone"] > 0 and counts["full_bs_steps"] == 0
    assert de < 5e-5  # measured 1.86e-5


@bitwise
def test_pericentre_passages_in_full_bs_are_bit_identical_to_rebound() -> None:
    rb, ours, counts, de = run_both(pericenter, 10 * 2 * math.pi * 29.4, "full_bs")
    assert_bitwise(rb, ours)
    assert counts["full_bs_steps"] > 0 and counts["redone"] > 0
    assert de < 1e-4  # REBOUND's bound; measured 5.69e-6


@bitwise
def test_pericentre_passages_in_full_ias15_are_bit_identical_to_rebound() -> None:
    rb, ours, counts, de = run_both(pericenter, 10 * 2 * math.pi * 29.4, "full_ias15")
    assert_bitwise(rb, ours)
    assert counts["full_bs_steps"] > 0 and counts["full_ias15_steps"] > 0 and counts["full_bs_substeps"] == 0
    assert de < 1e-4  # REBOUND's bound (test_trace_full_ias15.py has no pericentre test; FULL_BS's is used)


@bitwise
def test_pericentre_passages_in_partial_bs_are_bit_identical_to_rebound() -> None:
    # PARTIAL_BS puts every body in BS with the jump term in its equations; its energy error
    # (8.1e-4, REBOUND's too) is why FULL_BS is the default, so only agreement is checked.
    rb, ours, counts, _ = run_both(pericenter, 10 * 2 * math.pi * 29.4, "partial_bs")
    assert_bitwise(rb, ours)
    assert counts["full_bs_steps"] == 0 and counts["encounter_bs_substeps"] > 0


@bitwise
def test_test_particle_scattering_is_bit_identical_to_rebound() -> None:
    rb, ours, counts, _ = run_both(chaotic_exchange, 2000.0, r_crit_hill=3.0 * 1.21)
    assert_bitwise(rb, ours)
    assert counts["encounter_bs_substeps"] > 0


@bitwise
def test_a_moving_centre_of_mass_agrees_with_rebound_through_redone_steps() -> None:
    """REBOUND does not roll the centre of mass back when it redoes a step, so each redo moves the
    system on by dt * v_com once more: with v_com = 0.5, rolling it back would differ by ~1e-3."""
    def drifting() -> rebound.Simulation:
        sim = many_encounters()
        for p in sim.particles:
            p.vx += 0.5
        return sim

    rb, ours, counts, _ = run_both(drifting, 500.0)
    assert_bitwise(rb, ours)
    assert counts["redone"] > 0


@bitwise
def test_softened_pair_forces_agree_with_rebound() -> None:
    rb, ours, counts, _ = run_both(many_encounters, 500.0, softening=0.01)
    assert_bitwise(rb, ours)
    assert counts["encounter_bs_substeps"] > 0


# properties --------------------------------------------------------------------------------------

def test_a_test_particle_encounter_leaves_the_massive_bodies_bit_identical() -> None:
    """REBOUND's test_no_effect_tp: a test particle 0.01 from a Jupiter-mass planet, at rest relative
    to it, falls onto it within the first step (a near-singular plunge, integrated by BS together
    with the planet); the planet is then put back on its exact Kepler drift, so nothing leaks."""
    sim = rebound.Simulation()
    sim.add(m=1.0)
    sim.add(m=1e-3, a=1.0)
    sim.move_to_com()
    sim.dt = 0.1
    pos, vel, m = state_of(sim)
    tp = sim.particles[1].copy()
    tp.x += 0.01
    tp.m = 0.0
    sim.add(tp)
    pos_tp, vel_tp, m_tp = state_of(sim)
    _, counts = advance(pos_tp, vel_tp, m_tp, sim.G, sim.dt, 0.0, 10)
    advance(pos, vel, m, sim.G, sim.dt, 0.0, 10)
    assert counts["encounter_bs_substeps"] > 0  # the encounter was integrated
    assert np.array_equal(pos_tp[:, :2], pos) and np.array_equal(vel_tp[:, :2], vel)


def test_advance_rejects_bad_input() -> None:
    pos, vel, m = np.zeros((3, 3)), np.zeros((3, 3)), np.array([1.0, 1e-3, 0.0])
    assert active_count(m) == 2
    with pytest.raises(ValueError, match="peri_mode"):
        advance(pos, vel, m, 1.0, 0.1, 0.0, 1, peri_mode="full_ias16")
    with pytest.raises(ValueError, match="after every massive body"):
        advance(pos, vel, np.array([1.0, 0.0, 1e-3]), 1.0, 0.1, 0.0, 1)
    with pytest.raises(ValueError, match="central body"):
        advance(pos, vel, np.array([0.0, 1e-3, 1e-3]), 1.0, 0.1, 0.0, 1)
    with pytest.raises(ValueError, match="shape"):
        advance(np.zeros((2, 3)), vel, m, 1.0, 0.1, 0.0, 1)
    with pytest.raises(ValueError, match="same N bodies"):
        advance(pos, vel, m[:2], 1.0, 0.1, 0.0, 1)
    with pytest.raises(ValueError, match="dt"):
        advance(pos, vel, m, 1.0, 0.0, 0.0, 1)
