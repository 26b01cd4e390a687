"""The forces in the variational equations (orbitsim/forces/tangent.py): each position force's
derivative against central differences of its own acceleration, a variational run with forces
against the difference of two nearby runs, the size of what leaving the derivative out would cost,
and the one-line refusal of every force whose derivative is not built."""

from __future__ import annotations

import numpy as np
import pytest
import rebound
from forces_helpers import make_forces
from numba.core.errors import TypingError
from suite_split import fast_only

from orbitsim.chaos.megno import random_initial_variation
from orbitsim.chaos.run import chaos_run
from orbitsim.forces.compat import CHAOS_FORCE_SCHEMES, TANGENT_BUILT, check_chaos_forces
from orbitsim.forces.kernels import add_position_forces
from orbitsim.forces.table import (
    FORCE_IDS,
    GR,
    GR_FULL,
    GR_POTENTIAL,
    HARMONICS,
    MIGRATION,
    P_C,
    P_J2,
    P_J4,
    P_R_EQ,
    P_SPIN,
    empty_force_set,
)
from orbitsim.forces.tangent import add_tangent_forces
from orbitsim.forces.terms import terms_of
from orbitsim.integrators.registry import chaos_refusal, chaos_schemes
from orbitsim.physics.gravity import all_pairs_accelerations
from orbitsim.physics.tangent import ALL_PAIRS, tangent_accelerations

SPIN = np.array([0.3, -0.2, 0.9]) / np.linalg.norm([0.3, -0.2, 0.9])


def _harmonics(src: int, J2: float, J4: float, spin: np.ndarray = SPIN) -> tuple:
    return (HARMONICS, src, {P_J2: J2, P_J4: J4, P_R_EQ: 0.3, P_SPIN: spin[0], P_SPIN + 1: spin[1],
                             P_SPIN + 2: spin[2]}, None)


#: Every position force's derivative, in each branch of its kernel: J2 alone, J4 alone, both, a spin
#: along z (the basis's special case), a source that is not body 0.
DERIVATIVE_CASES = {
    "gr_potential": [(GR_POTENTIAL, 0, {P_C: 10.0}, None)],
    "gr_potential_source_2": [(GR_POTENTIAL, 2, {P_C: 7.0}, None)],
    "harmonics_J2": [_harmonics(0, 0.05, 0.0)],
    "harmonics_J4": [_harmonics(0, 0.0, -0.02)],
    "harmonics_J2_J4_spin_z": [_harmonics(0, 0.05, -0.02, np.array([0.0, 0.0, 1.0]))],
    "harmonics_source_3": [_harmonics(3, 0.05, 0.01)],
    "both": [(GR_POTENTIAL, 0, {P_C: 10.0}, None), _harmonics(0, 0.05, -0.02)],
}


def _bodies(seed: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Four bodies at random places of order 1 (no two closer than 0.66), masses 1 and smaller."""
    rng = np.random.default_rng(seed)
    return rng.normal(size=(3, 4)), np.array([1.0, 1e-3, 3e-4, 2e-3])


def _force_acc(pos: np.ndarray, m: np.ndarray, terms: tuple) -> np.ndarray:
    acc = np.zeros_like(pos)
    add_position_forces(pos, m, 1.0, terms, acc)
    return acc


# "both" (GR and harmonics in one force set) compiles a derivative of its own (~20 s cold): `make test-slow`.
@pytest.mark.parametrize("case", fast_only(DERIVATIVE_CASES, [c for c in DERIVATIVE_CASES if c != "both"]))
def test_each_derivative_is_the_central_difference_of_its_force(case: str) -> None:
    pos, m = _bodies()
    terms = terms_of(*make_forces(4, DERIVATIVE_CASES[case]).arrays)
    rng = np.random.default_rng(7)
    for _ in range(3):
        d = rng.normal(size=(3, 4))
        dacc = np.zeros((3, 4))
        add_tangent_forces(pos, m, 1.0, terms, d, dacc)
        h = 1e-5
        fd = (_force_acc(pos + h * d, m, terms) - _force_acc(pos - h * d, m, terms)) / (2 * h)
        # central differences: truncation h^2 |a'''| / |a'| ~ h^2 / r^2 ~ 1e-9 (r >= 0.66 here, the J4
        # term goes as r^-7) plus round-off eps / h ~ 1e-11; measured <= 7e-9, 1e-7 leaves a margin
        assert np.abs(fd - dacc).max() < 1e-7 * np.abs(dacc).max()
        assert np.abs(dacc).max() > 0.0


@pytest.mark.parametrize("case", ["gr_potential_source_2", "harmonics_source_3"])
def test_the_derivative_keeps_the_reaction_on_the_source(case: str) -> None:
    # The forces keep the total momentum (the source takes -(m_i / M) a_i), so their derivatives do:
    # sum_i m_i da_i = 0 to round-off of the largest term.
    pos, m = _bodies(3)
    terms = terms_of(*make_forces(4, DERIVATIVE_CASES[case]).arrays)
    d = np.random.default_rng(5).normal(size=(3, 4))
    dacc = np.zeros((3, 4))
    add_tangent_forces(pos, m, 1.0, terms, d, dacc)
    assert np.abs(dacc @ m).max() < 1e-14 * np.abs(dacc * m).max()
    assert np.abs(dacc[:, 1:]).max() > 0.0 and np.abs(dacc[:, 0]).max() + np.abs(dacc[:, 2]).max() > 0.0


def test_a_force_without_a_derivative_does_not_compile_into_a_variational_kick() -> None:
    # The safety net behind the front door: a velocity-dependent record in the tangent walk is a
    # typing error naming the force, never a silent zero.
    pos, m = _bodies()
    terms = terms_of(*make_forces(4, [(GR, 0, {P_C: 10.0}, None)]).arrays)
    with pytest.raises(TypingError, match="force gr are not built"):
        add_tangent_forces(pos, m, 1.0, terms, pos.copy(), np.zeros((3, 4)))


# -- a variational run with forces ---------------------------------------------------------------

def _chaotic_pair() -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """REBOUND's chaotic MEGNO case (two 1e-4 planets at periods 1 and 1.17), built as
    tests/chaos/test_chaos_contract.py builds it."""
    sim = rebound.Simulation()
    sim.add(m=1.0)
    sim.add(m=1e-4, P=1.0)
    sim.add(m=1e-4, P=1.17)
    sim.move_to_com()
    m = np.array([p.m for p in sim.particles])
    return m, np.array([p.xyz for p in sim.particles]), np.array([p.vxyz for p in sim.particles]), 1.0


#: Strong forces about the star: gr_potential at c = 10 (6 GM / (c^2 r) ~ 6% of gravity at r ~ 1) and
#: a J2, J4 about a tilted axis; both in one run, so one variational kernel is compiled for both.
STRONG = [(GR_POTENTIAL, 0, {P_C: 10.0}, None), _harmonics(0, 0.05, -0.01)]


def _naive_verlet(pos: np.ndarray, vel: np.ndarray, dpos: np.ndarray, dvel: np.ndarray, m: np.ndarray,
                  terms: tuple, dt: float, steps: int, with_derivative: bool) -> tuple[np.ndarray, ...]:
    """KDK steps of the forced bodies and their tangent vector, one Python loop, (3, N) arrays: the
    tangent's kicks take Newtonian tangent gravity plus (when ``with_derivative``) the forces'."""
    pos, vel, dpos, dvel = pos.copy(), vel.copy(), dpos.copy(), dvel.copy()

    def acc_at(p: np.ndarray) -> np.ndarray:
        a = np.zeros_like(p)
        all_pairs_accelerations(p, m, 1.0, 0.0, a)
        add_position_forces(p, m, 1.0, terms, a)
        return a

    def dacc_at(p: np.ndarray, dp: np.ndarray) -> np.ndarray:
        da = np.zeros_like(p)
        tangent_accelerations(p, m, 1.0, 0.0, dp, da, ALL_PAIRS)
        if with_derivative:
            add_tangent_forces(p, m, 1.0, terms, dp, da)
        return da

    a, da = acc_at(pos), dacc_at(pos, dpos)
    for _ in range(steps):
        vel += 0.5 * dt * a
        dvel += 0.5 * dt * da
        pos += dt * vel
        dpos += dt * dvel
        a, da = acc_at(pos), dacc_at(pos, dpos)
        vel += 0.5 * dt * a
        dvel += 0.5 * dt * da
    return pos, vel, dpos, dvel


def test_leaving_the_forces_derivative_out_is_measurable() -> None:
    # In the system and over the span of the run tests below, the tangent vector with the forces'
    # derivative matches the difference of two nearby forced runs; without it (Newtonian variations
    # along the forced orbit, what REBOUND's MEGNO integrates beside REBOUNDx forces) it misses by
    # far more than those tests' tolerance of 1e-6, so they would fail if the derivative were lost.
    m, x, v, P = _chaotic_pair()
    terms = terms_of(*make_forces(3, STRONG).arrays)
    d = np.concatenate(random_initial_variation(3, 11))  # (6, N)
    pos, vel = np.ascontiguousarray(x.T), np.ascontiguousarray(v.T)
    eps, dt, steps = 1e-6, P / 50, 200
    ends = [_naive_verlet(pos + s * eps * d[:3], vel + s * eps * d[3:], d[:3], d[3:], m, terms, dt, steps, True)
            for s in (1.0, -1.0)]
    fd = np.concatenate([ends[0][0] - ends[1][0], ends[0][1] - ends[1][1]]) / (2 * eps)
    forced = np.concatenate(_naive_verlet(pos, vel, d[:3], d[3:], m, terms, dt, steps, True)[2:])
    newtonian = np.concatenate(_naive_verlet(pos, vel, d[:3], d[3:], m, terms, dt, steps, False)[2:])
    scale = np.abs(forced).max()
    # O(eps^2) and round-off / eps, both ~1e-10 of the state here (measured 4e-8): 1e-6 as in the run tests
    assert np.abs(fd - forced).max() < 1e-6 * scale
    # measured 3e3 times the tangent vector's largest component: Newtonian variations along the forced
    # orbit are the linearisation of another flow; 1e-2 is a floor four orders above the run tests' 1e-6
    assert np.abs(fd - newtonian).max() > 1e-2 * scale


def _fd_check(name: str) -> None:
    m, x, v, P = _chaotic_pair()
    forces = make_forces(3, STRONG)
    d = np.concatenate(random_initial_variation(3, 11)).T  # (N, 6)
    eps, dt, steps = 1e-6, P / 50, 200
    # IAS15 at fixed steps: adaptive runs 1e-6 apart would choose steps that differ by round-off
    settings = {"adaptive": False} if name == "ias15" else None
    ends = [chaos_run(m, x + s * eps * d[:, :3], v + s * eps * d[:, 3:], integrator=name, dt=dt, steps=steps,
                      every=steps, forces=forces, settings=settings) for s in (1.0, -1.0)]
    tangent = chaos_run(m, x, v, integrator=name, dt=dt, steps=steps, every=steps, variation=d, forces=forces,
                        settings=settings)
    assert tangent.finite
    fd = np.concatenate([ends[0].positions - ends[1].positions, ends[0].velocities - ends[1].velocities]) / (2 * eps)
    ours = np.concatenate([tangent.dpos, tangent.dvel])
    # (run(x + eps d) - run(x - eps d)) / (2 eps) = tangent(d) + O(eps^2) + O(round-off / eps), both ~1e-10
    # of the state over 200 steps (measured 2e-8 to 4e-8 relative); leaving the forces' derivative out
    # costs 3e3 (test above), so 1e-6 separates the two by nine orders of magnitude
    assert np.abs(fd - ours).max() < 1e-6 * np.abs(ours).max()
    plain = chaos_run(m, x, v, integrator=name, dt=dt, steps=steps, every=steps, variation=d, settings=settings)
    assert not np.array_equal(plain.positions, tangent.positions)  # the forces acted on the bodies


@pytest.mark.slow  # compiles Wisdom-Holman's tangent run with forces (~2 min cold)
def test_wisdom_holman_variational_run_with_forces_is_the_derivative_of_two_nearby_runs() -> None:
    # Wisdom-Holman kicks the forces (and their derivatives) in its interaction step and in MEGNO's read.
    _fd_check("wisdom_holman")


# Every other scheme, IAS15 among them (the forces at every node, their derivatives in the tangent's node
# accelerations). Slow: each compiles its own forced variational loop (~1-3 minutes on 2 cores); the
# Wisdom-Holman case above keeps the property in make test.
@pytest.mark.slow
@pytest.mark.parametrize("name", [s for s in CHAOS_FORCE_SCHEMES if s != "wisdom_holman"])
def test_every_scheme_variational_run_with_forces_is_the_derivative_of_two_nearby_runs(name: str) -> None:
    _fd_check(name)


def test_an_empty_force_set_is_a_run_without_forces_bit_for_bit() -> None:
    m, x, v, P = _chaotic_pair()
    plain = chaos_run(m, x, v, integrator="verlet", dt=P / 40, steps=50, every=10)
    empty = chaos_run(m, x, v, integrator="verlet", dt=P / 40, steps=50, every=10, forces=empty_force_set(3))
    assert np.array_equal(plain.megno, empty.megno) and np.array_equal(plain.dpos, empty.dpos)


# -- refusals ------------------------------------------------------------------------------------

REFUSED = sorted(set(FORCE_IDS) - set(TANGENT_BUILT))


def test_the_forces_refused_are_exactly_the_velocity_dependent_ones() -> None:
    assert REFUSED == ["gr", "gr_full", "migration"]
    assert set(TANGENT_BUILT) | set(REFUSED) == set(FORCE_IDS)
    assert set(CHAOS_FORCE_SCHEMES) <= set(chaos_schemes())


@pytest.mark.parametrize("force", REFUSED)
@pytest.mark.parametrize("name", CHAOS_FORCE_SCHEMES)
def test_every_force_without_a_derivative_is_refused_in_one_line(force: str, name: str) -> None:
    why = chaos_refusal(name, None, ("gr_potential", force))
    assert why is not None and "\n" not in why
    assert f"force {force}:" in why and "derivative" in why and "not built" in why
    assert all(built in why for built in TANGENT_BUILT)  # names the forces that do enter


@pytest.mark.parametrize(("fid", "per_body"), [(GR, None), (GR_FULL, None),
                                               (MIGRATION, np.array([[np.inf, -1e3, np.inf]] * 3).T)])
def test_chaos_run_refuses_a_force_without_a_derivative_before_anything_runs(fid: int, per_body: object) -> None:
    m, x, v, P = _chaotic_pair()
    forces = make_forces(3, [(fid, 0 if fid == GR else -1, {P_C: 10.0}, per_body)])
    name = forces.names[0]
    with pytest.raises(ValueError, match=f"force {name}: its derivative in the variational equations is not built"):
        chaos_run(m, x, v, integrator="wisdom_holman", dt=P / 40, steps=10, forces=forces)


def test_every_scheme_with_variational_equations_takes_forces() -> None:
    assert set(CHAOS_FORCE_SCHEMES) == set(chaos_schemes())


def test_a_scheme_whose_variational_kernel_takes_no_forces_is_refused_in_one_line() -> None:
    # Every scheme with variational equations takes forces today (test above); the refusal stands for one
    # added without them, and says so for any name outside the list (rk4 has no variational equations).
    why = check_chaos_forces(("harmonics",), "rk4")
    assert why is not None and "\n" not in why and "force harmonics" in why and "rk4" in why
    assert all(name in why for name in CHAOS_FORCE_SCHEMES)
    assert check_chaos_forces((), "rk4") is None
    # a scheme with no variational equations at all is refused for that first
    assert "no variational equations" in chaos_refusal("rk4", None, ("gr_potential",))


def test_position_forces_are_accepted() -> None:
    for name in CHAOS_FORCE_SCHEMES:
        assert chaos_refusal(name, None, TANGENT_BUILT) is None
