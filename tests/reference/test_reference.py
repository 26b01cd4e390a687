"""The REBOUND bridge (orbitsim.reference) and the comparison metrics it feeds.

REBOUND 5.2 behaviour relied on, each checked here: ``sim.integrator = "leapfrog"`` then
``sim.integrator.order = n``; ``sim.steps(k)`` takes k whole steps; IAS15 with
``exact_finish_time=1`` stops exactly on the requested time; ``serialize_particle_data`` returns
(N, 3) states.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from orbitsim.compare.metrics import energy_drift_slope, pair_verdict, relative_position_difference
from orbitsim.integrators.registry import INTEGRATORS, get_spec
from orbitsim.reference.bridge import (
    ReboundScheme,
    ReboundSchemeError,
    parse_rebound_scheme,
    read_state,
    rebound_simulation,
)
from orbitsim.reference.pairs import (
    BASE_TOLERANCE,
    MATCHED_PAIRS,
    TWIN_MARGIN,
    allowed_difference,
    available_pairs,
    nominal_tolerance,
    parse_pair,
)
from orbitsim.reference.sampling import run_rebound, run_reference

rebound = pytest.importorskip("rebound")

#: Sun, a Jupiter, a massless test particle (REBOUND treats m = 0 as any other particle).
MASSES = np.array([1.0, 1e-3, 0.0])
POSITIONS = np.array([[0.0, 0.0, 0.0], [5.2, 0.0, 0.05], [0.0, 2.0, 0.0]])
VELOCITIES = np.array([[0.0, -1e-3 * math.sqrt(1 / 5.2), 0.0], [0.0, math.sqrt(1 / 5.2), 0.0],
                       [-math.sqrt(0.5), 0.0, 0.0]])


def test_parse_rebound_scheme_names_and_defaults() -> None:
    assert parse_rebound_scheme("leapfrog") == ReboundScheme("leapfrog", "2")
    assert parse_rebound_scheme("leapfrog:4") == ReboundScheme("leapfrog", "4")
    assert parse_rebound_scheme("LeapFrog6") == ReboundScheme("leapfrog", "6")
    assert parse_rebound_scheme("saba:10_6_4").options == {"type": "10_6_4"}
    assert parse_rebound_scheme("whfast").key == "whfast"
    assert not parse_rebound_scheme("ias15").fixed_step
    assert parse_rebound_scheme("leapfrog:8").order == 8


@pytest.mark.parametrize("text", ["leapfrog:3", "rk4", "whfast:1", "leapfrog:x"])
def test_parse_rebound_scheme_rejects_with_valid_names(text: str) -> None:
    with pytest.raises(ReboundSchemeError, match=r"leapfrog|option"):
        parse_rebound_scheme(text)


def test_rebound_simulation_matches_every_setting() -> None:
    sim = rebound_simulation(MASSES, POSITIONS, VELOCITIES, G=0.5, softening=0.01, dt=0.02, scheme="leapfrog:4")
    assert (sim.G, sim.softening, sim.dt, sim.N) == (0.5, 0.01, 0.02, 3)
    # REBOUND accepts an unsupported order silently, so read the configured one back.
    assert str(sim.integrator) == "leapfrog" and sim.integrator.order == 4
    pos, vel = read_state(sim)
    np.testing.assert_array_equal(pos, POSITIONS)
    np.testing.assert_array_equal(vel, VELOCITIES)
    assert [p.m for p in sim.particles] == list(MASSES)


def test_fixed_step_samples_land_on_step_times() -> None:
    plan = np.array([0, 7, 100, 1001])
    rec = run_rebound(MASSES, POSITIONS, VELOCITIES, G=1.0, softening=0.0, dt=0.05, scheme="leapfrog",
                      sample_steps=plan)
    assert rec.status == "complete" and rec.steps_done == 1001
    np.testing.assert_array_equal(rec.step, plan)
    # Labelled with step * dt, the float orbitsim uses, not REBOUND's accumulated sim.t.
    np.testing.assert_array_equal(rec.time, plan * 0.05)
    assert rec.positions.shape == (4, 3, 3) and np.all(np.isfinite(rec.energy))


def test_reference_lands_exactly_on_sample_times_and_is_accurate() -> None:
    """Circular two-body orbit: the separation rotates at omega = sqrt(G M / a^3)."""
    masses = np.array([1.0, 1e-3])
    v = math.sqrt(1.001)
    pos = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    vel = np.array([[0.0, 0.0, 0.0], [0.0, v, 0.0]])
    plan = np.array([0, 333, 1000])
    ref = run_reference(masses, pos, vel, G=1.0, softening=0.0, dt=0.01, sample_steps=plan)
    np.testing.assert_array_equal(ref.time, plan * 0.01)
    sep = ref.positions[:, 1] - ref.positions[:, 0]
    angle = v * ref.time
    expected = np.stack([np.cos(angle), np.sin(angle), np.zeros_like(angle)], axis=-1)
    assert np.max(np.abs(sep - expected)) < 1e-12


def test_leapfrog4_pair_agrees_to_round_off() -> None:
    from orbitsim.simulation import simulate

    plan = np.arange(0, 2001, 200)
    ours = simulate(MASSES, POSITIONS, VELOCITIES, integrator="leapfrog4", dt=0.05, steps=2000, sample_steps=plan)
    theirs = run_rebound(MASSES, POSITIONS, VELOCITIES, G=1.0, softening=0.0, dt=0.05, scheme="leapfrog:4",
                         sample_steps=plan)
    assert np.max(relative_position_difference(ours.positions, theirs.positions)) < 1e-12


def test_pair_table_is_consistent_with_the_registry() -> None:
    registered = {spec.name for spec in INTEGRATORS}
    for pair in MATCHED_PAIRS:
        assert pair.rebound.fixed_step and pair.reason
        if pair.rebound.name == "leapfrog" and pair.orbitsim in registered:
            assert get_spec(pair.orbitsim).order == pair.rebound.order
    assert {p.orbitsim for p in available_pairs()} <= registered
    assert {"leapfrog", "leapfrog4", "leapfrog6", "leapfrog8"} <= {p.orbitsim for p in available_pairs()}
    if "wisdom_holman" in registered:
        assert any(p.rebound.name == "whfast" for p in available_pairs())


def test_tolerances_are_below_one_and_grow_as_documented() -> None:
    assert 0 < BASE_TOLERANCE < 1
    assert nominal_tolerance(100) == BASE_TOLERANCE
    assert nominal_tolerance(40_000) == pytest.approx(8 * BASE_TOLERANCE)
    allowed = allowed_difference(np.array([10, 20, 30]), np.array([1e-15, 1e-9, np.nan]))
    np.testing.assert_allclose(allowed, [BASE_TOLERANCE, TWIN_MARGIN * 1e-9, BASE_TOLERANCE])


def test_parse_pair() -> None:
    pair = parse_pair("kdk=leapfrog:4")
    assert pair.orbitsim == "verlet" and pair.rebound.order == 4 and not pair.builtin
    for bad in ("verlet", "verlet=ias15", "nope=leapfrog"):
        with pytest.raises(ValueError):
            parse_pair(bad)


def test_mismatched_pair_disagrees_and_matched_agrees() -> None:
    from orbitsim.compare.run import run_orbitsim

    class Tiny:
        G, softening, dt, integrator, integrator_settings = 1.0, 0.0, 0.05, "verlet", {}
        masses, positions, velocities = MASSES, POSITIONS, VELOCITIES

    plan = np.arange(0, 401, 40)
    kw = dict(G=1.0, softening=0.0, dt=0.05, sample_steps=plan)
    theirs = run_rebound(MASSES, POSITIONS, VELOCITIES, scheme="leapfrog:4", **kw)
    twin = run_rebound(MASSES, POSITIONS * (1 + 2.0**-50), VELOCITIES, scheme="leapfrog:4", **kw)
    good = pair_verdict(parse_pair("leapfrog4=leapfrog:4"), run_orbitsim(Tiny, "leapfrog4", plan), theirs, twin)
    bad = pair_verdict(parse_pair("verlet=leapfrog:4"), run_orbitsim(Tiny, "verlet", plan), theirs, twin)
    assert good.agree and good.max_difference < 1e-12
    assert not bad.agree and bad.max_difference > 1e-8 and bad.worst_ratio > 1


def test_energy_drift_slope_recovers_a_line() -> None:
    t = np.linspace(0.0, 10.0, 50)
    assert energy_drift_slope(t, 3e-9 * t + 1e-3 + 1e-12 * np.sin(t)) == pytest.approx(3e-9, rel=1e-2)
    assert math.isnan(energy_drift_slope(t[:2], t[:2]))


def test_relative_position_difference_scales_by_system_size() -> None:
    ref = np.array([[[0.0, 0.0, 0.0], [10.0, 0.0, 0.0]]])
    moved = ref.copy()
    moved[0, 0, 1] = 0.5  # the central body moves by 0.5 in a system of size 10
    np.testing.assert_allclose(relative_position_difference(moved, ref), [0.05])


def test_whfast_is_configured_like_wisdom_holman() -> None:
    from orbitsim.reference.bridge import whfast_configurator

    sim = rebound_simulation(MASSES[:2], POSITIONS[:2], VELOCITIES[:2], G=1.0, softening=0.0, dt=0.1,
                             scheme="whfast")
    assert str(sim.integrator) == "whfast" and sim.dt == 0.1
    assert str(sim.integrator.coordinates).upper() == "JACOBI"
    if whfast_configurator() is not None:
        # orbitsim's map keeps its Jacobi state between steps: REBOUND without safe mode.
        assert sim.integrator.safe_mode == 0 and sim.integrator.keep_unsynchronized == 1


def test_wisdom_holman_pair_agrees_to_round_off() -> None:
    from orbitsim.integrators.registry import UnknownIntegratorError
    from orbitsim.simulation import simulate

    try:
        get_spec("wisdom_holman")
    except UnknownIntegratorError:
        pytest.skip("wisdom_holman is not registered in this build")
    plan = np.arange(0, 1001, 100)
    ours = simulate(MASSES, POSITIONS, VELOCITIES, integrator="wisdom_holman", dt=0.05, steps=1000,
                    sample_steps=plan)
    theirs = run_rebound(MASSES, POSITIONS, VELOCITIES, G=1.0, softening=0.0, dt=0.05, scheme="whfast",
                         sample_steps=plan)
    assert np.max(relative_position_difference(ours.positions, theirs.positions)) < 1e-11
