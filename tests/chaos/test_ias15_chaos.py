"""IAS15 behind the variational run contract (``chaos_run(..., integrator="ias15")``): REBOUND 5.2.2's
MEGNO and mLCE at every sample, REBOUND's regular and chaotic cases, a run stopped at a sample and
resumed with every output array the same bytes, the fixed-step mode, a failed run, and the refusals."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import pytest
import rebound

from orbitsim.chaos.megno import megno_start
from orbitsim.chaos.run import ChaosResult, chaos_run
from orbitsim.forces.table import GR, N_PARAMS, P_C, ForceSet
from orbitsim.integrators.ias15.core import COUNT_ACCEPTED, IAS15Work
from orbitsim.integrators.ias15.tangent import IAS15Tangent
from orbitsim.integrators.registry import chaos_refusal, get_integrator


class Case(NamedTuple):
    sim: rebound.Simulation  # REBOUND's IAS15, init_megno(seed=0) done
    m: np.ndarray  # (N,)
    x: np.ndarray  # (N, 3)
    v: np.ndarray  # (N, 3)
    variation: np.ndarray  # (N, 6): REBOUND's variational particle


def _case(chaotic: bool, t0: float = 0.0) -> Case:
    """REBOUND's test_megno.py systems. Regular (test_ias15, test_initial_t_ias15): star m = 1;
    m = 1e-3 at a = 1.5 and 15, e = 0.1, i = 0.1. Chaotic (test_chaotic): m = 1e-4 at P = 1 and 1.17."""
    sim = rebound.Simulation()
    sim.integrator = "ias15"
    sim.t = t0
    sim.add(m=1.0)
    if chaotic:
        sim.add(m=1e-4, P=1.0)
        sim.add(m=1e-4, P=1.17)
    else:
        sim.add(m=1e-3, a=1.5, e=0.1, inc=0.1)
        sim.add(m=1e-3, a=15.0, e=0.1, inc=0.1)
    sim.init_megno(seed=0)
    if chaotic:
        sim.move_to_com()
    ps = sim.particles
    return Case(sim, np.array([p.m for p in ps]), np.array([p.xyz for p in ps]), np.array([p.vxyz for p in ps]),
                np.array([[*p.xyz, *p.vxyz] for p in sim.particles_var]))


def _ours(case: Case, dt: float, steps: int, t0: float = 0.0, **kwargs) -> ChaosResult:
    # first_dt: REBOUND's first trial step (sim.dt), so both codes choose the same steps
    settings = {"first_dt": case.sim.dt, **kwargs.pop("settings", {})}
    return chaos_run(case.m, case.x, case.v, integrator="ias15", dt=dt, steps=steps, every=1, t0=t0,
                     variation=case.variation, settings=settings, **kwargs)


def _rebound(case: Case, times: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """REBOUND integrated to each time in turn: megno(), lyapunov(), and the final variational particle (6, N)."""
    megno, mlce = [], []
    for t in times:
        case.sim.integrate(t)
        megno.append(case.sim.megno())
        mlce.append(case.sim.lyapunov())
    var = np.array([[getattr(p, k) for p in case.sim.particles_var] for k in ("x", "y", "z", "vx", "vy", "vz")])
    return np.array(megno), np.array(mlce), var


def test_regular_case_agrees_with_rebound_at_every_sample_over_1e4() -> None:
    case = _case(chaotic=False)
    ours = _ours(case, dt=200.0, steps=50)
    assert ours.finite and np.array_equal(ours.times, np.arange(51) * 200.0)  # samples land exactly on the grid
    megno, mlce, var = _rebound(case, ours.times)
    assert ours.megno[0] == megno[0] == 0.0 and ours.mlce[0] == mlce[0] == 0.0
    # The bound, 1e-10 relative: the codes differ only in the Newtonian force sum's order
    # (round-off), which a regular orbit carries linearly (measured: MEGNO 3.3e-13, mLCE 5.5e-12).
    assert np.all(np.abs(ours.megno[1:] - megno[1:]) <= 1e-10 * np.abs(megno[1:]))
    assert np.all(np.abs(ours.mlce[1:] - mlce[1:]) <= 1e-10 * np.abs(mlce[1:]))
    # the final variational particle: measured 3e-11 of its largest component
    assert np.max(np.abs(np.vstack([ours.dpos, ours.dvel]) - var)) <= 1e-10 * np.max(np.abs(var))
    assert ours.work.counts[COUNT_ACCEPTED] == case.sim.steps_done  # the same steps
    assert ours.sums.n == case.sim.steps_done  # one MEGNO update per accepted step
    # REBOUND's own bounds for this case at t = 1e4
    assert abs(ours.megno[-1] - 2.0) < 0.2 and abs(ours.mlce[-1]) < 1e-3


def test_regular_case_from_t0_1e6_agrees_with_rebound() -> None:
    # REBOUND's test_initial_t_ias15: the grid starts at t0, MEGNO's clock too. From t0 = 1e6 the clock's
    # resolution (ulp 1.2e-10) is the floor: each interval's last step, t_target - t, differs between the
    # codes by that much, and so do the bodies (measured over 1e3: MEGNO 1e-12, mLCE 3e-11), hence 1e-9.
    case = _case(chaotic=False, t0=1e6)
    ours = _ours(case, dt=50.0, steps=20, t0=1e6)
    assert ours.finite and ours.times[0] == 1e6 and ours.times[-1] == 1e6 + 1e3
    megno, mlce, _ = _rebound(case, ours.times)
    assert np.all(np.abs(ours.megno[1:] - megno[1:]) <= 1e-9 * np.abs(megno[1:]))
    assert np.all(np.abs(ours.mlce[1:] - mlce[1:]) <= 1e-9 * np.abs(mlce[1:]))


def test_chaotic_case_agrees_early_and_megno_passes_50_by_t_1000() -> None:
    case = _case(chaotic=True)
    early = _ours(case, dt=2.0, steps=10)
    megno, mlce, var = _rebound(case, early.times)
    # over 20 periods the force sums' round-off has grown by e^(lambda t) ~ 10: still far below 1e-10
    assert np.all(np.abs(early.megno[1:] - megno[1:]) <= 1e-10 * np.abs(megno[1:]))
    assert np.all(np.abs(early.mlce[1:] - mlce[1:]) <= 1e-10 * np.abs(mlce[1:]))
    assert np.max(np.abs(np.vstack([early.dpos, early.dvel]) - var)) <= 1e-10 * np.max(np.abs(var))
    late = _ours(_case(chaotic=True), dt=100.0, steps=10)
    case.sim.integrate(1000.0)
    # REBOUND's bound for its chaotic case (the regular value is 2); both codes pass it
    assert late.finite and late.times[-1] == 1000.0
    assert late.megno[-1] > 50.0 and case.sim.megno() > 50.0
    assert late.mlce[-1] > 0.02  # a regular orbit's is < 1e-3 (above)


def _assert_same_bytes(a: object, b: object, name: str) -> None:
    if isinstance(a, np.ndarray):
        assert a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes(), name
    else:
        assert type(a) is type(b) and a == b, name


@pytest.mark.parametrize("settings", [{}, {"adaptive": False}], ids=["adaptive", "fixed-step"])
@pytest.mark.parametrize("cut", [7, 23])
def test_stop_at_a_sample_and_resume_is_byte_equal(settings: dict, cut: int) -> None:
    """A run stopped at sample ``cut`` and resumed from its result: every output array, the MEGNO
    sums, the bodies' adaptive state (clock, b, e, compensations) and the tangent's polynomial are
    the bytes of the straight run. The chaotic pair, where any round-off difference would grow."""
    case = _case(chaotic=True)
    dt = 0.37 if not settings else 0.005  # fixed step: dt is the step, small enough for the pair
    steps = 40
    whole = _ours(case, dt=dt, steps=steps, settings=settings)
    first = _ours(case, dt=dt, steps=cut, settings=settings)
    rest = chaos_run(case.m, case.x, case.v, integrator="ias15", dt=dt, steps=steps - cut, every=1, resume=first)
    assert whole.finite and first.finite and rest.finite
    for name in ("times", "megno", "mlce"):
        _assert_same_bytes(np.concatenate([getattr(first, name), getattr(rest, name)]), getattr(whole, name), name)
    for name in ("positions", "velocities", "dpos", "dvel", "halvings", "sums", "steps_done"):
        _assert_same_bytes(getattr(rest, name), getattr(whole, name), name)
    assert isinstance(rest.work, IAS15Work) and isinstance(rest.tangent, IAS15Tangent)
    for name, a, b in zip(IAS15Work._fields, rest.work, whole.work, strict=True):
        _assert_same_bytes(a, b, f"work.{name}")
    for name, a, b in zip(IAS15Tangent._fields, rest.tangent, whole.tangent, strict=True):
        _assert_same_bytes(a, b, f"tangent.{name}")
    # resuming read `first` and did not move it: a second resume gives the same bytes again
    again = chaos_run(case.m, case.x, case.v, integrator="ias15", dt=dt, steps=steps - cut, every=1, resume=first)
    _assert_same_bytes(again.megno, rest.megno, "megno of a second resume")
    _assert_same_bytes(again.dpos, rest.dpos, "dpos of a second resume")


def test_resuming_without_the_adaptive_state_would_not_be_the_same_run() -> None:
    # The control for the test above: the same stop resumed with a fresh work (the clock restarted at
    # the first trial step, the predictor's b and e zero) takes other steps, so its bits differ.
    case = _case(chaotic=True)
    whole = _ours(case, dt=0.37, steps=40)
    first = _ours(case, dt=0.37, steps=7)
    fresh = ChaosResult(**{**first.__dict__, "work": None, "tangent": None})
    rest = chaos_run(case.m, case.x, case.v, integrator="ias15", dt=0.37, steps=33, every=1, resume=fresh,
                     settings={"first_dt": case.sim.dt})
    assert rest.finite and rest.times[-1] == whole.times[-1]
    assert not np.array_equal(rest.megno, whole.megno[7:])


def test_fixed_step_mode_takes_one_step_per_grid_point() -> None:
    case = _case(chaotic=False)
    result = _ours(case, dt=0.01, steps=300, settings={"adaptive": False})
    assert result.finite and result.work.counts[COUNT_ACCEPTED] == 300 and result.sums.n == 300
    assert np.array_equal(result.times, np.arange(301) * 0.01)


def test_a_collision_stops_the_run_with_ias15s_own_message() -> None:
    # Two bodies falling straight at each other: IAS15's step shrinks until it no longer moves the clock.
    m = np.array([1.0, 1e-3])
    x = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    v = np.zeros((2, 3))
    result = chaos_run(m, x, v, integrator="ias15", dt=0.1, steps=20, every=1, seed=1)
    assert not result.finite
    # from rest at r = 1 they meet at t = (pi / 2) / sqrt(2 G M) = 1.1102: the last sample is the grid's 1.1
    assert result.times.shape[0] == 12 and abs(result.times[-1] - 1.1) < 1e-15
    assert result.steps_done == 11  # the grid point reached
    message = get_integrator("ias15").failure_message(result.work)
    assert message is not None and "\n" not in message and "IAS15's step fell" in message


def test_every_ias15_setting_has_variational_equations() -> None:
    for settings in (None, {"adaptive": False}, {"epsilon": 0.0}, {"epsilon": 1e-6, "min_dt": 1e-4, "first_dt": 0.1}):
        assert chaos_refusal("ias15", settings) is None
    with pytest.raises(ValueError, match="epsilon"):  # a bad setting is the settings' own one-line error
        chaos_refusal("ias15", {"epsilon": -1.0})


def _gr_context(n: int):
    """A force context with ``gr`` (velocity-dependent: its derivative is not built) for N bodies."""
    from orbitsim.forces.hooks import forced_context
    from orbitsim.physics.force_context import make_force

    params = np.zeros((1, N_PARAMS))
    params[0, P_C] = 1e4
    gr = ForceSet(np.array([GR]), np.array([0]), params, np.zeros((1, 3, n)))
    return forced_context(make_force(1.0, 0.0, n), gr, n)


def test_the_tangent_accelerations_refuse_a_force_without_a_derivative() -> None:
    # The front door (chaos_refusal with the forces' table) refuses forces in one line; behind it, the
    # tangent accelerations every IAS15 tangent step and MEGNO read (with the hook of
    # orbitsim/forces/tangent.py) do not compile for a force whose derivative is not built.
    from numba.core.errors import TypingError

    from orbitsim.integrators.ias15.tangent import refresh_tangent

    case = _case(chaotic=False)
    tangent = get_integrator("ias15").make_tangent(np.ones((3, 3)), np.ones((3, 3)))
    with pytest.raises(TypingError, match="variational equations of"):
        refresh_tangent(np.ascontiguousarray(case.x.T), case.m, _gr_context(3), tangent)


@pytest.mark.slow  # typing a gr context compiles the force kernels before the refusal: ~20 s, every time
def test_a_force_without_a_derivative_never_runs_with_newtonian_variations() -> None:
    # The whole variational run, not only its tangent accelerations: it does not compile, so it cannot run.
    from numba.core.errors import TypingError

    case = _case(chaotic=False)
    record = get_integrator("ias15")
    n = case.m.shape[0]
    pos, vel = np.ascontiguousarray(case.x.T), np.ascontiguousarray(case.v.T)
    tangent = record.make_tangent(np.ascontiguousarray(case.variation[:, :3].T),
                                  np.ascontiguousarray(case.variation[:, 3:].T))
    out = (np.zeros(2), np.zeros(2, dtype=np.int64), np.zeros((2, 8)), np.zeros((0, 2, 3, n)), np.zeros((1, n)))
    with pytest.raises(TypingError, match="variational equations of"):
        record.run_chaos((pos, vel, np.zeros((3, n)), case.m), tangent, _gr_context(n), 1.0,
                         record.make_work(case.m, 1.0), 0.0, np.int64(0), np.array([0, 1]), np.ones(2, dtype=np.bool_),
                         out, np.zeros((2, 2)), megno_start(0.0))
