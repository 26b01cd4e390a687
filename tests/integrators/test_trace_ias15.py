"""TRACE's FULL_IAS15 pericentre step (:mod:`orbitsim.integrators.trace.ias15`) against REBOUND 5.2.2.

REBOUND's FULL_IAS15 branch (``integrator_trace.c`` 1030-1052) is not reachable on its own from
Python, so most tests emulate it with REBOUND's plain IAS15 (:func:`rebound_full_ias15`): a new
IAS15 per outer step, the step count and the cut of each next step done by hand exactly as the
branch does them, through ``sim.steps(1)``, which runs one ``reb_integrator_ias15_step``. One
test drives REBOUND's TRACE itself with every step a FULL_IAS15 step. Comparisons are ``==`` on
every coordinate: the port keeps REBOUND's order of floating-point operations.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from orbitsim.integrators.ias15.core import (
    CLOCK_DT_LAST_DONE,
    CLOCK_T,
    COUNT_ACCEPTED,
    COUNT_REJECTED,
    COUNT_STATUS,
)
from orbitsim.integrators.trace.ias15 import (
    STATUS_NON_FINITE,
    STATUS_OK,
    STATUS_STEP_UNDERFLOW,
    full_ias15_step,
    make_full_ias15_work,
)
from orbitsim.integrators.trace.operators import dh_to_inertial, inertial_to_dh

rebound = pytest.importorskip("rebound")

bitwise = pytest.mark.skipif(rebound.__version__ != "5.2.2", reason="bitwise parity is with REBOUND 5.2.2")


def state_of(sim: rebound.Simulation) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Inertial (3, N) positions and velocities and the masses of a REBOUND simulation."""
    ps = sim.particles
    pos = np.array([[p.x for p in ps], [p.y for p in ps], [p.z for p in ps]])
    vel = np.array([[p.vx for p in ps], [p.vy for p in ps], [p.vz for p in ps]])
    return pos, vel, np.array([p.m for p in ps])


def pericenter(f: float = 0.0) -> rebound.Simulation:
    """REBOUND's test_pericenter: Jupiter, and a Saturn-mass body on a polar e = 0.99 orbit
    (pericentre 0.096) at true anomaly f (0: at pericentre), dt = 0.15 * 2 pi."""
    sim = rebound.Simulation()
    sun = rebound.Particle(m=1.0)
    sim.add(sun)
    sim.add(primary=sun, m=9.55e-4, a=5.2)
    sim.add(primary=sun, m=2.857e-4, a=9.58, e=0.99, inc=math.pi / 2.0, f=f)
    sim.move_to_com()
    sim.dt = 0.15 * 2.0 * math.pi
    return sim


def three_bodies() -> rebound.Simulation:
    """A plain hierarchical 3-body system: two planets of 1e-3 and 3e-4 on mildly eccentric,
    inclined orbits, dt = 0.7 (a ninth of the inner period)."""
    sim = rebound.Simulation()
    sim.add(m=1.0)
    sim.add(m=1e-3, a=1.0, e=0.1, inc=0.05, f=0.4)
    sim.add(m=3e-4, a=1.7, e=0.2, inc=0.2, Omega=1.0, f=2.5)
    sim.move_to_com()
    sim.dt = 0.7
    return sim


def rebound_full_ias15(sim: rebound.Simulation, t: float, dt: float, dt_last_done: float) -> None:
    """REBOUND's FULL_IAS15 branch on ``sim``'s particles: a new IAS15 (epsilon 1e-9, min_dt 0,
    PRS23), REBOUND's ``r->dt_last_done`` as it stands, then ``while t < t + dt and |dt_next / dt| >
    1e-14``: one IAS15 step, and the next step cut to end at t + dt (integrator_trace.c:1041-1048)."""
    sim.integrator = "ias15"  # frees the old state and creates a new one
    assert (sim.integrator.epsilon, sim.integrator.min_dt, str(sim.integrator.adaptive_mode)) == (1e-9, 0.0,
                                                                                                 "PRS23")
    sim.t, sim.dt, sim.dt_last_done = t, dt, dt_last_done
    t_needed = t + dt
    while sim.t < t_needed and abs(sim.dt / dt) > 1e-14:
        sim.steps(1)
        if sim.t + sim.dt > t_needed:
            sim.dt = t_needed - sim.t


def ours(pos: np.ndarray, vel: np.ndarray, m: np.ndarray, dt: float, t: float, dt_last_done: float,
         work: tuple | None = None, softening: float = 0.0, n_active: int | None = None) -> tuple:
    """:func:`full_ias15_step` in place (G = 1); returns (status, work)."""
    work = make_full_ias15_work(m.size) if work is None else work
    n_active = m.size if n_active is None else n_active
    status = full_ias15_step(pos, vel, np.zeros_like(pos), m, 1.0, softening * softening, n_active, dt, t,
                             dt_last_done, work)
    return status, work


def assert_bitwise(sim: rebound.Simulation, pos: np.ndarray, vel: np.ndarray) -> None:
    rb_pos, rb_vel, _ = state_of(sim)
    assert np.array_equal(rb_pos, pos), f"positions differ by up to {np.max(np.abs(rb_pos - pos)):.3e}"
    assert np.array_equal(rb_vel, vel), f"velocities differ by up to {np.max(np.abs(rb_vel - vel)):.3e}"


@bitwise
@pytest.mark.parametrize("make_sim", [pericenter, lambda: pericenter(-0.3), three_bodies],
                         ids=["at_pericentre", "before_pericentre", "three_bodies"])
@pytest.mark.parametrize("t", [0.0, 123.4])
@pytest.mark.parametrize("first_step_of_integrate", [True, False])
def test_one_step_is_rebounds_fresh_ias15_bit_for_bit(make_sim, t: float, first_step_of_integrate: bool) -> None:
    """From t (the absolute clock decides where the last step is cut), with REBOUND's
    dt_last_done 0 (first step of an ``integrate``) or the previous outer dt."""
    sim = make_sim()
    pos, vel, m = state_of(sim)
    dt = sim.dt
    dt_last_done = 0.0 if first_step_of_integrate else dt
    status, work = ours(pos, vel, m, dt, t, dt_last_done)
    rebound_full_ias15(sim, t, dt, dt_last_done)
    assert status == STATUS_OK
    assert work.clock[CLOCK_T] == sim.t
    assert_bitwise(sim, pos, vel)


def test_dt_last_done_decides_how_a_rejected_first_try_is_retried() -> None:
    """The outer dt is far too long at pericentre, so IAS15's first try is rejected; whether REBOUND
    then predicts the retry's polynomial (from zeros) depends on dt_last_done != 0 only."""
    results = []
    for dt_last_done in (0.0, 1e-3, 0.9):
        sim = pericenter()
        pos, vel, m = state_of(sim)
        _, work = ours(pos, vel, m, sim.dt, 0.0, dt_last_done)
        assert work.counts[COUNT_REJECTED] >= 1
        results.append(pos)
    assert not np.array_equal(results[0], results[1])
    assert np.array_equal(results[1], results[2])


@bitwise
@pytest.mark.parametrize("make_sim", [lambda: pericenter(-0.3), three_bodies], ids=["pericentre", "three_bodies"])
def test_consecutive_steps_each_with_a_fresh_ias15_are_bit_identical(make_sim) -> None:
    """Twelve outer steps through a pericentre passage, one work reused, each call a new IAS15."""
    sim = make_sim()
    pos, vel, m = state_of(sim)
    dt = sim.dt
    work = make_full_ias15_work(m.size)
    t, dt_last_done, steps = 0.0, 0.0, []
    for _ in range(12):
        status, _ = ours(pos, vel, m, dt, t, dt_last_done, work)
        rebound_full_ias15(sim, t, dt, dt_last_done)
        assert status == STATUS_OK
        assert_bitwise(sim, pos, vel)
        steps.append(int(work.counts[COUNT_ACCEPTED]))
        t, dt_last_done = t + dt, dt  # TRACE's r->t += r->dt; r->dt_last_done = r->dt
    assert max(steps) > 5 * min(steps)  # the pericentre passage took many more IAS15 steps


@bitwise
def test_test_particles_and_softening_are_bit_identical() -> None:
    """Basic gravity's second loop (massless bodies after N_active feel the active ones only) and
    the softening inside the square root."""
    sim = three_bodies()
    sim.add(m=0.0, a=1.3, e=0.3, f=1.0)
    sim.add(m=0.0, a=0.6, e=0.5, inc=1.0)
    sim.N_active = 3
    sim.softening = 0.05
    pos, vel, m = state_of(sim)
    status, _ = ours(pos, vel, m, sim.dt, 2.0, sim.dt, softening=0.05, n_active=3)
    rebound_full_ias15(sim, 2.0, sim.dt, sim.dt)
    assert status == STATUS_OK
    assert_bitwise(sim, pos, vel)


def rebound_trace_full_ias15(r_crit_hill: float) -> rebound.Simulation:
    """REBOUND's own TRACE in FULL_IAS15 mode on the pericentre set-up, peri_crit_eta 1e-6: every
    step is a pericentre step."""
    sim = pericenter(-0.3)
    sim.integrator = "trace"
    sim.integrator.peri_mode = "FULL_IAS15"
    sim.integrator.peri_crit_eta = 1e-6
    sim.integrator.r_crit_hill = r_crit_hill
    return sim


def full_try(pos, vel, m, com, dt, t, dt_last_done, work) -> None:
    """TRACE's step_try in a FULL mode: DH -> inertial about the stored centre of mass, the FULL
    step, inertial -> DH with the centre of mass recomputed (integrator_trace.c:1037, 1107)."""
    dh_to_inertial(pos, vel, m, m.size, com)
    status, _ = ours(pos, vel, m, dt, t, dt_last_done, work)
    assert status == STATUS_OK
    inertial_to_dh(pos, vel, m, m.size, com)


@bitwise
def test_rebounds_trace_with_every_step_a_full_ias15_step_is_reproduced() -> None:
    """r_crit_hill 1e-3: no pair is ever flagged, so no step is redone. A step is inertial -> DH,
    the FULL try, DH -> inertial (integrator_trace.c:1230, 1242, 1256)."""
    sim = rebound_trace_full_ias15(1e-3)
    pos, vel, m = state_of(sim)
    com = np.zeros(6)
    work = make_full_ias15_work(m.size)
    for _ in range(8):
        inertial_to_dh(pos, vel, m, m.size, com)
        full_try(pos, vel, m, com, sim.dt, sim.t, sim.dt_last_done, work)
        dh_to_inertial(pos, vel, m, m.size, com)
        sim.steps(1)
        assert_bitwise(sim, pos, vel)


@bitwise
def test_rebounds_trace_redoing_every_full_ias15_step_is_reproduced() -> None:
    """r_crit_hill 1e3: every pair is flagged at the end of the step, and in a FULL mode that
    always counts as new (the pre-step check skipped the pairs), so every step is redone: from
    the DH state at the start, about the centre of mass the first try left, and with REBOUND's
    dt_last_done now the first try's last IAS15 step (integrator_trace.c:1245-1254)."""
    sim = rebound_trace_full_ias15(1e3)
    pos, vel, m = state_of(sim)
    com = np.zeros(6)
    work = make_full_ias15_work(m.size)
    rejected_first_tries = 0
    for _ in range(6):
        inertial_to_dh(pos, vel, m, m.size, com)
        start = pos.copy(), vel.copy()
        full_try(pos, vel, m, com, sim.dt, sim.t, sim.dt_last_done, work)
        pos[:], vel[:] = start
        rejected_first_tries += work.counts[COUNT_REJECTED] > 0
        full_try(pos, vel, m, com, sim.dt, sim.t, work.clock[CLOCK_DT_LAST_DONE], work)
        dh_to_inertial(pos, vel, m, m.size, com)
        sim.steps(1)
        assert_bitwise(sim, pos, vel)
    assert rejected_first_tries >= 2  # so the redo's dt_last_done was put to the test


def energy_terms(pos: np.ndarray, vel: np.ndarray, m: np.ndarray) -> tuple[float, float]:
    """Kinetic and potential energy (G = 1), each pair once."""
    kinetic = 0.5 * float(np.sum(m * np.sum(vel * vel, axis=0)))
    potential = 0.0
    for i in range(m.size):
        for j in range(i + 1, m.size):
            potential -= m[i] * m[j] / float(np.linalg.norm(pos[:, i] - pos[:, j]))
    return kinetic, potential


@pytest.mark.parametrize("make_sim", [pericenter, lambda: pericenter(-0.3), three_bodies],
                         ids=["at_pericentre", "before_pericentre", "three_bodies"])
def test_energy_is_conserved_to_round_off_over_one_outer_step(make_sim) -> None:
    """IAS15 at epsilon 1e-9 keeps its truncation error below double round-off (Rein & Spiegel
    2015), so the energy error is round-off: ~1e-16 per IAS15 step of the terms' size T + |U|,
    growing like the square root of the ~50 steps of a pericentre passage. Measured
    |dE| / (T + |U|): 1.3e-15, 9.5e-16 and 5.6e-17; the bound leaves a factor 7. Relative to |E|
    that is |dE/E| = 7.8e-14, 5.4e-14 and 1.8e-16: at pericentre T + |U| is 58 |E|, which is the
    cancellation that |dE/E| alone would hide."""
    sim = make_sim()
    pos, vel, m = state_of(sim)
    t0, u0 = energy_terms(pos, vel, m)
    status, _ = ours(pos, vel, m, sim.dt, 0.0, 0.0)
    t1, u1 = energy_terms(pos, vel, m)
    assert status == STATUS_OK
    assert abs((t1 + u1) - (t0 + u0)) < 1e-14 * max(t0 - u0, t1 - u1)


def test_a_used_work_gives_the_bits_of_a_new_one() -> None:
    """Every call starts a new integrator: nothing of the previous call's polynomial, compensation
    terms or counters leaks into the next."""
    sim = pericenter(-0.3)
    pos, vel, m = state_of(sim)
    used = make_full_ias15_work(m.size)
    ours(pos.copy(), vel.copy(), m, sim.dt, 0.0, 0.0, used)
    fresh_pos, fresh_vel = pos.copy(), vel.copy()
    _, fresh = ours(fresh_pos, fresh_vel, m, sim.dt, 5.0, 0.7)
    _, used = ours(pos, vel, m, sim.dt, 5.0, 0.7, used)
    assert np.array_equal(fresh_pos, pos) and np.array_equal(fresh_vel, vel)
    assert np.array_equal(fresh.counts, used.counts)
    assert used.clock[CLOCK_DT_LAST_DONE] != 0.7  # what a redo of this step must pass on


def test_coincident_bodies_and_non_finite_input_end_with_a_status() -> None:
    pos = np.array([[0.0, 1.0, 1.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    vel = np.array([[0.0, 0.0, 0.0], [0.0, 1.0, -1.0], [0.0, 0.0, 0.0]])
    m = np.array([1.0, 1e-3, 1e-3])
    status, work = ours(pos.copy(), vel.copy(), m, 0.5, 0.0, 0.0)
    assert status == STATUS_NON_FINITE == work.counts[COUNT_STATUS]
    pos[1, 2] = np.nan
    pos[0, 1] = 0.5
    status, _ = ours(pos, vel, m, 0.5, 0.0, 0.0)
    assert status == STATUS_NON_FINITE


def test_a_head_on_collision_ends_with_step_underflow_short_of_the_target() -> None:
    """Two bodies falling straight onto each other (they meet at t = pi/4): IAS15's step shrinks
    below 1e-14 of dt, where REBOUND's loop gives up silently, and the step stops with a status."""
    pos = np.array([[-0.5, 0.5], [0.0, 0.0], [0.0, 0.0]])
    vel = np.zeros((3, 2))
    status, work = ours(pos, vel, np.array([1.0, 1.0]), 1.0, 0.0, 0.0)
    assert status == STATUS_STEP_UNDERFLOW
    assert work.clock[CLOCK_T] == pytest.approx(math.pi / 4.0, rel=1e-6)
    assert np.all(np.isfinite(pos)) and abs(pos[0, 0]) < 1e-6


def test_make_work_needs_two_bodies() -> None:
    with pytest.raises(ValueError, match="two bodies"):
        make_full_ias15_work(1)


def test_the_work_made_inside_a_step_is_ias15s_own_layout_and_settings() -> None:
    """new_full_ias15_work (jitted, made by each pericentre step) mirrors ias15.make_work: the same
    fields, shapes, dtypes and zeros, and FULL_IAS15_SETTINGS."""
    from orbitsim.integrators.ias15 import make_work
    from orbitsim.integrators.ias15.core import WORK_FIELDS
    from orbitsim.integrators.trace.ias15 import FULL_IAS15_SETTINGS

    theirs = make_work(np.zeros(5), 1.0, FULL_IAS15_SETTINGS)
    mine = make_full_ias15_work(5)
    assert len(mine) == len(theirs) == len(WORK_FIELDS)
    for name, a, b in zip(WORK_FIELDS, mine, theirs, strict=True):
        if isinstance(b, np.ndarray):
            assert (a.shape, a.dtype) == (b.shape, b.dtype), name
            assert np.array_equal(a, b), name
        else:
            assert type(a) is type(b) and a == b, name
