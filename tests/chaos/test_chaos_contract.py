"""Every scheme's variational run through one contract (``run_chaos``): the registry, the refusals,
REBOUND's regular and chaotic MEGNO cases, the tangent map against finite differences of two runs,
bodies untouched by the tangent, and a run cut in two equal to one uninterrupted, bit for bit."""

from __future__ import annotations

import numpy as np
import pytest
import rebound
from suite_split import fast_only

from orbitsim.chaos.megno import megno_start, random_initial_variation
from orbitsim.chaos.run import chaos_run
from orbitsim.integrators.registry import RECORDS, chaos_refusal, chaos_schemes
from orbitsim.integrators.wisdom_holman.tangent import TANGENT_SCRATCH_ROWS, tangent_run
from orbitsim.physics.coordinates import jacobi_weights
from orbitsim.physics.force_context import make_force
from orbitsim.simulation import simulate

CHAOS = ("verlet", "leapfrog", "leapfrog4", "leapfrog6", "leapfrog8", "wisdom_holman", "ias15")
#: The cases of the contract tests below: IAS15's variational run compiles for ~15 s cold, so make test checks
#: the contract on the fixed-step schemes and Wisdom-Holman (tests/integrators/test_ias15_tangent.py keeps IAS15's
#: tangent step there), make test-slow on IAS15 too.
CHAOS_CASES = fast_only(CHAOS, [n for n in CHAOS if n != "ias15"])


def _system(*planets: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    sim = rebound.Simulation()
    sim.add(m=1.0)
    for planet in planets:
        sim.add(**planet)
    sim.move_to_com()
    m = np.array([p.m for p in sim.particles])
    return m, np.array([p.xyz for p in sim.particles]), np.array([p.vxyz for p in sim.particles]), sim.particles[1].P


def regular() -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """REBOUND's regular MEGNO case (rebound/tests/test_megno.py)."""
    return _system({"m": 1e-3, "a": 1.5, "e": 0.1, "inc": 0.1}, {"m": 1e-3, "a": 15.0, "e": 0.1, "inc": 0.1})


def chaotic() -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """REBOUND's chaotic case: two 1e-4 planets at periods 1 and 1.17."""
    return _system({"m": 1e-4, "P": 1.0}, {"m": 1e-4, "P": 1.17})


def test_registry_declares_which_schemes_have_variational_equations() -> None:
    assert chaos_schemes() == CHAOS
    for record in RECORDS:
        why = chaos_refusal(record.spec.name)
        if record.spec.name in CHAOS:
            assert callable(record.run_chaos) and why is None
        else:
            assert record.run_chaos is None
            assert why is not None and "\n" not in why and record.spec.name in why
            assert all(name in why for name in CHAOS)  # the line names the schemes that have them


@pytest.mark.parametrize(("settings", "key"), [({"coordinates": "democratic_heliocentric"}, "jacobi"),
                                               ({"corrector": 5}, "corrector")])
def test_wisdom_holman_settings_without_variational_equations_are_refused(settings: dict, key: str) -> None:
    m, x, v, _ = regular()
    with pytest.raises(ValueError, match=key):
        chaos_run(m, x, v, integrator="wisdom_holman", dt=0.1, steps=10, settings=settings)
    with pytest.raises(ValueError, match="no variational equations"):
        chaos_run(m, x, v, integrator="rk4", dt=0.1, steps=10)


def test_bad_variation_is_refused() -> None:
    m, x, v, _ = regular()
    with pytest.raises(ValueError, match="rows of 6"):
        chaos_run(m, x, v, integrator="verlet", dt=0.1, steps=1, variation=np.ones((2, 6)))
    with pytest.raises(ValueError, match="not all zero"):
        chaos_run(m, x, v, integrator="verlet", dt=0.1, steps=1, variation=np.zeros((3, 6)))


# dt per scheme: small enough that each scheme resolves the inner orbit (P ~ 1.84); higher orders afford more.
# ias15's dt is its output grid (it chooses its own steps between grid points): 10 periods.
STEP_FRACTION = {"verlet": 1 / 100, "leapfrog": 1 / 100, "leapfrog4": 1 / 30, "leapfrog6": 1 / 15,
                 "leapfrog8": 1 / 10, "wisdom_holman": 0.07, "ias15": 10.0}


@pytest.mark.parametrize("name", CHAOS_CASES)
def test_regular_orbit_megno_tends_to_two(name: str) -> None:
    # REBOUND's bounds for its regular case at t = 1e4: MEGNO = 2 +- 0.2 and mLCE = 0 +- 1e-3.
    m, x, v, P = regular()
    dt = P * STEP_FRACTION[name]
    result = chaos_run(m, x, v, integrator=name, dt=dt, steps=int(1e4 / dt), every=2000)
    assert result.finite
    assert abs(result.megno[-1] - 2.0) < 0.2
    assert abs(result.mlce[-1]) < 1e-3


@pytest.mark.parametrize(("name", "dt", "floor"), [("wisdom_holman", 0.001, 50.0), ("leapfrog4", 0.005, 50.0),
                                                   ("leapfrog", 0.001, 25.0), ("verlet", 0.001, 25.0),
                                                   ("ias15", 100.0, 50.0)])
def test_chaotic_pair_megno_grows_by_t_1000(name: str, dt: float, floor: float) -> None:
    # REBOUND's chaotic case: MEGNO > 50 by t = 1000 (its WHFast and IAS15). A chaotic MEGNO grows as
    # lambda t / 2 from an onset (t ~ 400 here) that each numerical trajectory places differently:
    # the second-order leapfrogs at dt = 1e-3 reach 40-48 by t = 1000 (50 by t ~ 1100), the
    # regular value being 2, so their floor is 25; WH and the fourth-order leapfrog pass REBOUND's 50.
    m, x, v, _ = chaotic()
    steps = round(1000 / dt)
    result = chaos_run(m, x, v, integrator=name, dt=dt, steps=steps, every=steps)
    assert result.finite and result.megno[-1] > floor
    assert result.mlce[-1] > 0.02  # a regular orbit's is < 1e-3 (test above)


@pytest.mark.parametrize("name", CHAOS_CASES)
def test_tangent_map_is_the_derivative_of_the_run(name: str) -> None:
    # (run(x + eps d) - run(x - eps d)) / (2 eps) = tangent(d) + O(eps^2 |d''|) + O(round-off / eps):
    # with eps = 1e-6 both are ~1e-10 of the state over 200 steps of the chaotic pair, 1e-6 keeps a margin.
    m, x, v, P = chaotic()
    d = np.concatenate(random_initial_variation(3, 11)).T  # (N, 6)
    eps, dt, steps = 1e-6, P / 50, 200
    ends = [chaos_run(m, x + s * eps * d[:, :3], v + s * eps * d[:, 3:], integrator=name, dt=dt, steps=steps,
                      every=steps) for s in (1.0, -1.0)]
    tangent = chaos_run(m, x, v, integrator=name, dt=dt, steps=steps, every=steps, variation=d)
    fd = np.concatenate([ends[0].positions - ends[1].positions, ends[0].velocities - ends[1].velocities]) / (2 * eps)
    ours = np.concatenate([tangent.dpos, tangent.dvel])
    assert np.abs(fd - ours).max() < 1e-6 * np.abs(ours).max()


@pytest.mark.parametrize("name", ["verlet", "leapfrog", "leapfrog4"])
def test_the_tangent_leaves_the_bodies_bits_alone(name: str) -> None:
    m, x, v, P = regular()
    dt, steps = P / 50, 500
    with_tangent = chaos_run(m, x, v, integrator=name, dt=dt, steps=steps, every=steps)
    plain = simulate(m, x, v, integrator=name, dt=dt, steps=steps, every=steps)
    assert np.array_equal(with_tangent.positions.T, plain.positions[-1])
    assert np.array_equal(with_tangent.velocities.T, plain.velocities[-1])


@pytest.mark.parametrize("name", CHAOS_CASES)
def test_a_run_cut_in_two_equals_one_uninterrupted_bit_for_bit(name: str) -> None:
    m, x, v, P = chaotic()
    dt = P / 40
    whole = chaos_run(m, x, v, integrator=name, dt=dt, steps=300, every=10)
    first = chaos_run(m, x, v, integrator=name, dt=dt, steps=170, every=10)
    rest = chaos_run(m, x, v, integrator=name, dt=dt, steps=130, every=10, resume=first)
    assert np.array_equal(np.concatenate([first.megno, rest.megno]), whole.megno)
    assert np.array_equal(np.concatenate([first.mlce, rest.mlce]), whole.mlce)
    assert rest.sums == whole.sums and rest.halvings == whole.halvings
    for field in ("positions", "velocities", "dpos", "dvel"):
        assert np.array_equal(getattr(rest, field), getattr(whole, field)), field


def test_wisdom_holman_contract_is_the_kernel_compared_with_rebound() -> None:
    # run_chaos is tangent_run (tested against REBOUND's WHFast in test_wh_tangent.py) under the sample loop.
    m, x, v, P = regular()
    dt = P * 0.07
    d = np.concatenate(random_initial_variation(3, 0)).T
    result = chaos_run(m, x, v, integrator="wisdom_holman", dt=dt, steps=1000, every=1000, variation=d)
    # C-ordered as a run's arrays (np.array(x.T) keeps x.T's F order): an F-ordered pair compiles tangent_run
    # a second time (15 CPU-s of the suite) for the same kernel.
    pos, vel = np.ascontiguousarray(x.T), np.ascontiguousarray(v.T)
    dpos, dvel = np.ascontiguousarray(d[:, :3].T), np.ascontiguousarray(d[:, 3:].T)
    _, _, _, sums, _ = tangent_run(pos, vel, dpos, dvel, m, make_force(1.0, 0.0, 3), dt, jacobi_weights(m),
                                   np.cumsum(m), np.zeros((TANGENT_SCRATCH_ROWS, 3, 3)), megno_start(0.0), 0.0, 0, 1000)
    assert sums == result.sums
    assert np.array_equal(dpos, result.dpos) and np.array_equal(pos, result.positions)


def test_rescaling_keeps_a_growing_tangent_finite_and_moves_no_indicator_bit() -> None:
    # A huge initial variation forces the 2^-200 rescaling at once: the same MEGNO bits as a unit one
    # scaled by 2^300 (exact), and a finite tangent state.
    m, x, v, P = chaotic()
    d = np.concatenate(random_initial_variation(3, 2)).T
    small = chaos_run(m, x, v, integrator="leapfrog", dt=P / 40, steps=100, every=100, variation=d)
    big = chaos_run(m, x, v, integrator="leapfrog", dt=P / 40, steps=100, every=100, variation=d * 2.0**300)
    assert big.halvings == 1 and small.halvings == 0
    assert big.sums == small.sums
    assert np.array_equal(big.dpos, small.dpos * 2.0**100)
