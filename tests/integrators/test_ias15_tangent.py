"""IAS15's variational equations and MEGNO (orbitsim.integrators.ias15.tangent): REBOUND 5.2.2's numbers
sample by sample, REBOUND's own MEGNO test cases, the tangent map against two nearby runs, the step
control left to the bodies, and a rescaling that moves no bit."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import pytest
import rebound

from orbitsim.integrators.ias15 import integrate_to, make_work
from orbitsim.integrators.ias15.core import CLOCK_DT, CLOCK_STARTED, CLOCK_T, COUNT_ACCEPTED, IAS15Work
from orbitsim.integrators.ias15.tables import H, W
from orbitsim.integrators.ias15.tangent import (
    REACHED,
    IAS15Tangent,
    advance_grid_tangent,
    integrate_to_tangent,
    make_tangent,
    megno_state,
    refresh_tangent,
)
from orbitsim.physics.force_context import accelerations_at, make_force


class System(NamedTuple):
    sim: rebound.Simulation  # REBOUND's, with init_megno(seed=0) done
    m: np.ndarray
    pos: np.ndarray  # (3, N)
    vel: np.ndarray
    dpos: np.ndarray  # REBOUND's variational particle, (3, N)
    dvel: np.ndarray


def _system(chaotic: bool, t0: float = 0.0) -> System:
    """REBOUND's test_megno.py systems (regular: test_ias15 / test_initial_t_ias15; chaotic: test_chaotic)."""
    sim = rebound.Simulation()
    sim.integrator = "ias15"
    sim.t = t0
    if chaotic:
        sim.add(m=1.0)
        sim.add(m=1e-4, P=1.0)
        sim.add(m=1e-4, P=1.17)
    else:
        sim.add(m=1.0)
        sim.add(m=1e-3, a=1.5, e=0.1, inc=0.1)
        sim.add(m=1e-3, a=15.0, e=0.1, inc=0.1)
    sim.init_megno(seed=0)
    if chaotic:
        sim.move_to_com()
    ps, vs = sim.particles, sim.particles_var

    def cols(parts, keys):
        return np.ascontiguousarray(np.array([[getattr(p, k) for k in keys] for p in parts]).T)

    return System(sim, np.array([p.m for p in ps]), cols(ps, "xyz"), cols(ps, ("vx", "vy", "vz")),
                  cols(vs, "xyz"), cols(vs, ("vx", "vy", "vz")))


def _ours(s: System, t0: float, first_dt: float, settings: dict | None = None):
    """orbitsim's state for ``s``: (pos, vel, acc, force, work, tangent), the clock started at t0."""
    pos, vel = s.pos.copy(), s.vel.copy()
    force = make_force(1.0, 0.0, pos.shape[1])
    acc = np.zeros_like(pos)
    accelerations_at(force, pos, s.m, acc)
    work = make_work(s.m, 1.0, settings)
    work.clock[CLOCK_T], work.clock[CLOCK_DT], work.clock[CLOCK_STARTED] = t0, first_dt, 1.0
    return pos, vel, acc, force, work, make_tangent(s.dpos, s.dvel, t0)


def _rebound_samples(sim: rebound.Simulation, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """REBOUND integrated to each time: (megno, lyapunov) per sample, and its variational particle (S, 6, N)."""
    indicators, var = [], []
    for t in times:
        sim.integrate(t)
        indicators.append((sim.megno(), sim.lyapunov()))
        var.append([[getattr(p, k) for p in sim.particles_var] for k in ("x", "y", "z", "vx", "vy", "vz")])
    return np.array(indicators), np.array(var)


def _copy(record: tuple) -> tuple:
    return type(record)(*(np.copy(f) if isinstance(f, np.ndarray) else f for f in record))


def _sampled(s: System, times: np.ndarray, t0: float = 0.0):
    """orbitsim integrated to each time: (megno, lyapunov) per sample, the tangent state (S, 6, N), work."""
    pos, vel, acc, force, work, tan = _ours(s, t0, s.sim.dt)
    refresh_tangent(pos, s.m, force, tan)
    out, var = [], []
    for t in times:  # one sample per call, so the tangent state can be read at each
        reached, ind = advance_grid_tangent(pos, vel, acc, s.m, force, work, tan, np.array([t]))
        assert reached == 1
        out.append(ind[0])
        var.append(np.vstack([tan.dpos, tan.dvel]))
    return np.array(out), np.array(var), work


def test_radau_weights_integrate_degree_14_exactly() -> None:
    # 8 Radau nodes with the left end fixed: exact for every polynomial of degree <= 2 * 8 - 2 on [0, 1].
    for k in range(15):
        assert abs(np.sum(W * H**k) - 2.0 / (k + 1)) < 4e-16 * 2  # weights for an interval of length 2


@pytest.mark.parametrize(("t0", "span"), [
    (0.0, 1e4), (1e6, 1e3), pytest.param(1e6, 1e4, marks=pytest.mark.slow)], ids=["t0=0", "t0=1e6", "t0=1e6-long"])
def test_regular_case_agrees_with_rebound_at_every_sample(t0: float, span: float) -> None:
    """REBOUND's test_megno regular systems (test_ias15, and test_initial_t_ias15 from t = 1e6):
    star m = 1; m = 1e-3 at a = 1.5 and 15, e = 0.1, i = 0.1."""
    s = _system(chaotic=False, t0=t0)
    times = t0 + np.linspace(0.0, span, 51)[1:]
    ours, our_var, work = _sampled(s, times, t0)
    theirs, their_var = _rebound_samples(s.sim, times)
    # The bound, 1e-10: the two differ only in the Newtonian force sum's order (round-off),
    # which a regular orbit carries linearly (measured at t0 = 0: MEGNO 3e-13, mLCE 5e-12, the
    # variational particle 3e-11). From t0 = 1e6 the clock's resolution (ulp 1.2e-10) is the floor: each
    # interval's last step, t_target - t, differs between the codes by that much, and so do the bodies
    # (measured over 1e4: mLCE 9e-11, the variational particle 3e-9).
    tol_indicators, tol_var = (1e-10, 1e-10) if t0 == 0.0 else (1e-9, 1e-8)
    assert np.all(np.abs(ours - theirs) <= tol_indicators * np.abs(theirs))
    scale = np.max(np.abs(their_var), axis=(1, 2))
    assert np.all(np.max(np.abs(our_var - their_var), axis=(1, 2)) <= tol_var * scale)
    assert work.counts[COUNT_ACCEPTED] == s.sim.steps_done  # the same steps
    if span == 1e4:  # REBOUND's own assertions
        assert abs(ours[-1, 0] - 2.0) < 0.2 and abs(ours[-1, 1]) < 1e-3


def test_chaotic_case_megno_grows_past_50_by_t_1000() -> None:
    """REBOUND's test_chaotic: m = 1e-4 at P = 1 and P = 1.17. Both codes agree while round-off is
    small, and both see MEGNO > 50 by t = 1000 (where chaos has long decorrelated their round-off)."""
    s = _system(chaotic=True)
    early = np.linspace(0.0, 20.0, 11)[1:]
    ours, our_var, _ = _sampled(s, early)
    theirs, their_var = _rebound_samples(s.sim, early)
    # over 20 periods the force sums' round-off has grown by e^(lambda t) ~ 10: still far below 1e-10
    assert np.all(np.abs(ours - theirs) <= 1e-10 * np.abs(theirs))
    scale = np.max(np.abs(their_var), axis=(1, 2))
    assert np.all(np.max(np.abs(our_var - their_var), axis=(1, 2)) <= 1e-10 * scale)
    s2 = _system(chaotic=True)
    pos, vel, acc, force, work, tan = _ours(s2, 0.0, s2.sim.dt)
    reached, ind = advance_grid_tangent(pos, vel, acc, s2.m, force, work, tan, np.array([1000.0]))
    s2.sim.integrate(1000.0)
    assert reached == 1 and ind[0, 0] > 50.0 and s2.sim.megno() > 50.0
    assert ind[0, 1] > 0.0  # a positive Lyapunov exponent
    assert megno_state(tan).n == work.counts[COUNT_ACCEPTED]  # one MEGNO update per accepted step


def _plain_steps(s: System, t_end: float, settings: dict | None, first_dt: float = 1e-3):
    """The plain IAS15 (no tangent state) from t = 0 to t_end exactly: positions, velocities, work."""
    pos, vel, acc, force, work, _ = _ours(s, 0.0, first_dt, settings)
    assert integrate_to(pos, vel, acc, s.m, force, work, t_end, None) == REACHED
    return pos, vel, work


def test_a_zero_tangent_leaves_the_plain_step_bit_for_bit() -> None:
    """With delta = 0 the tangent components add nothing to the convergence test: the bodies take
    exactly the plain step's steps and bits (the tangent step is the plain step plus components)."""
    s = _system(chaotic=False)
    s = s._replace(dpos=np.zeros_like(s.dpos), dvel=np.zeros_like(s.dvel))
    p_pos, p_vel, p_work = _plain_steps(s, 300.0, None)
    pos, vel, acc, force, work, tan = _ours(s, 0.0, s.sim.dt)
    with np.errstate(invalid="ignore"):  # MEGNO of a zero vector is 0/0: not what this test reads
        assert integrate_to_tangent(pos, vel, acc, s.m, force, work, tan, 300.0) == REACHED
    assert np.array_equal(pos, p_pos) and np.array_equal(vel, p_vel)
    assert np.array_equal(work.clock, p_work.clock) and np.array_equal(work.counts, p_work.counts)
    assert not np.any(tan.dpos) and not np.any(tan.dvel)


def test_the_step_control_reads_the_bodies_only() -> None:
    """REBOUND's PRS23 step control loops over the real particles: scaling the tangent state by an
    exact power of two (2^40 against 2^80, both dominating the convergence test so that it too reads
    the same ratio) leaves every step, the bodies and MEGNO bit for bit, and the tangent scaled."""
    s = _system(chaotic=False)
    runs = []
    for k in (40, 80):
        pos, vel, acc, force, work, tan = _ours(s, 0.0, s.sim.dt)
        tan.dpos[:] *= 2.0**k
        tan.dvel[:] *= 2.0**k
        refresh_tangent(pos, s.m, force, tan)
        assert integrate_to_tangent(pos, vel, acc, s.m, force, work, tan, 200.0) == REACHED
        runs.append((pos, work, tan))
    (pos_a, work_a, tan_a), (pos_b, work_b, tan_b) = runs
    assert np.array_equal(pos_a, pos_b) and np.array_equal(work_a.clock, work_b.clock)
    assert np.array_equal(work_a.counts, work_b.counts)
    assert np.array_equal(tan_a.dpos * 2.0**40, tan_b.dpos)
    assert np.array_equal(tan_a.megno, tan_b.megno)


def test_rescaling_by_a_power_of_two_moves_no_bit_of_megno() -> None:
    """A tangent state past |delta| = 2^200 is scaled by 2^-200 with its whole polynomial after the
    step: started at 2^40 and at 2^340 (rescaled once, to 2^140), the two runs keep every bit of the
    bodies and of MEGNO, and their tangent states differ by exactly 2^100."""
    s = _system(chaotic=False)
    runs = []
    for k in (40, 340):
        pos, vel, acc, force, work, tan = _ours(s, 0.0, s.sim.dt)
        tan.dpos[:] *= 2.0**k
        tan.dvel[:] *= 2.0**k
        refresh_tangent(pos, s.m, force, tan)
        assert integrate_to_tangent(pos, vel, acc, s.m, force, work, tan, 200.0) == REACHED
        runs.append((pos, work, tan))
    (pos_a, work_a, tan_a), (pos_b, work_b, tan_b) = runs
    assert tan_a.halvings[0] == 0 and tan_b.halvings[0] == 1
    assert np.array_equal(pos_a, pos_b) and np.array_equal(work_a.counts, work_b.counts)
    assert np.array_equal(tan_a.dpos * 2.0**100, tan_b.dpos) and np.array_equal(tan_a.dvel * 2.0**100, tan_b.dvel)
    assert np.array_equal(tan_a.megno, tan_b.megno)


@pytest.mark.parametrize("settings", [{"adaptive": False}, None], ids=["fixed-step", "adaptive"])
def test_tangent_map_is_the_derivative_of_two_nearby_runs(settings: dict | None) -> None:
    """delta(t) against (x(t; x0 + h delta0) - x(t; x0 - h delta0)) / 2h of two plain IAS15 runs."""
    s = _system(chaotic=False)
    t_end = 40.0  # several inner orbits
    first_dt = 0.01 if settings else 1e-3  # the fixed-step mode's constant step (the last one shortened)
    h = 1e-6
    ends = []
    for sign in (1.0, -1.0):
        moved = s._replace(pos=s.pos + sign * h * s.dpos, vel=s.vel + sign * h * s.dvel)
        p, v, _ = _plain_steps(moved, t_end, settings, first_dt)
        ends.append(np.vstack([p, v]))
    central = (ends[0] - ends[1]) / (2 * h)
    pos, vel, acc, force, work, tan = _ours(s, 0.0, first_dt, settings)
    refresh_tangent(pos, s.m, force, tan)
    assert integrate_to_tangent(pos, vel, acc, s.m, force, work, tan, t_end) == REACHED
    ours = np.vstack([tan.dpos, tan.dvel])
    # central differences: O(h^2) truncation and round-off / h (1e-16 / 1e-6 of the state over
    # |delta| ~ 30); measured 3e-10 (fixed step) and 4e-10 (adaptive, whose steps differ by round-off).
    assert np.max(np.abs(ours - central)) < 1e-8 * np.max(np.abs(central))


def test_restarting_from_copies_of_both_records_is_bit_for_bit() -> None:
    """Everything the tangent step carries is in the two records: a run split at t = 100 and resumed
    from copies of (work, tangent) ends with the bits of the unbroken run."""
    s = _system(chaotic=False)
    whole = _ours(s, 0.0, s.sim.dt)
    pos, vel, acc, force, work, tan = whole
    refresh_tangent(pos, s.m, force, tan)
    for t in (100.0, 250.0):
        assert integrate_to_tangent(pos, vel, acc, s.m, force, work, tan, t) == REACHED
    pos2, vel2, acc2, _, work2, tan2 = _ours(s, 0.0, s.sim.dt)
    refresh_tangent(pos2, s.m, force, tan2)
    assert integrate_to_tangent(pos2, vel2, acc2, s.m, force, work2, tan2, 100.0) == REACHED
    saved = (pos2.copy(), vel2.copy(), acc2.copy(), _copy(work2), _copy(tan2))
    pos3, vel3, acc3, work3, tan3 = saved
    assert isinstance(work3, IAS15Work) and isinstance(tan3, IAS15Tangent)
    assert integrate_to_tangent(pos3, vel3, acc3, s.m, force, work3, tan3, 250.0) == REACHED
    assert np.array_equal(pos3, pos) and np.array_equal(vel3, vel)
    for name, a, b in zip(IAS15Tangent._fields, tan3, tan, strict=True):
        assert np.array_equal(a, b), name
