"""Runs with forces (every scheme's own loop through the hooks of orbitsim.forces.hooks):
step for step against REBOUND + REBOUNDx, conservation, convergence order, reproducibility
(threads, chunking, checkpoints), and runs without forces left alone."""

from __future__ import annotations

import numpy as np
import pytest
from forces_helpers import make_forces, rebound_state
from suite_split import fast_only

from orbitsim.forces.table import GR, GR_FULL, GR_POTENTIAL, HARMONICS, MIGRATION, P_C, P_J2, P_J4, P_R_EQ, P_SPIN
from orbitsim.simulation import Simulation, SimulationError

rebound = pytest.importorskip("rebound")
pytest.importorskip("reboundx")

#: A strong-field speed of light (G = M = a = 1 units): GR is then 1e-3 of gravity, large enough
#: that a wrongly applied force shows far above round-off.
C_STRONG = 30.0
HARMONIC_PARAMS = {P_J2: 1e-2, P_J4: -1e-3, P_R_EQ: 0.3, P_SPIN + 2: 1.0}


def _rebound_system() -> rebound.Simulation:
    """A star and two planets (REBOUNDx's test masses, a = 1, e = 0.1, and an outer companion)."""
    sim = rebound.Simulation()
    sim.add(m=1.0)
    sim.add(m=1e-3, a=1.0, e=0.1, inc=0.1)
    sim.add(m=3e-4, a=1.7, e=0.05, inc=0.05, Omega=1.0)
    sim.move_to_com()
    return sim


def _system() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    return rebound_state(_rebound_system())


def _gr_potential(n: int = 3):
    return make_forces(n, [(GR_POTENTIAL, 0, {P_C: C_STRONG}, None)])


def _run(integrator: str, forces, steps: int, dt: float = 1e-2, targets=None, threads=None, settings=None,
         system=None):
    m, x, v = system or _system()
    sim = Simulation(m, x, v, integrator, dt, threads=threads, settings=settings or {}, forces=forces)
    chunks = list(sim.chunks(np.array(targets if targets is not None else [steps])))
    return sim, chunks


def _rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))


@pytest.mark.parametrize(("integrator", "forces", "configure"), [
    ("wisdom_holman", _gr_potential(), "whfast"),
    ("leapfrog", make_forces(3, [(HARMONICS, 0, HARMONIC_PARAMS, None)]), "leapfrog"),
])
def test_step_for_step_with_rebound_and_reboundx(integrator, forces, configure) -> None:
    from orbitsim.reference.rebx import attach_forces
    from orbitsim.reference.wh_pairing import configure_rebound_whfast

    dt, steps = 1e-2, 1000
    sim = _rebound_system()
    sim.dt = dt
    m, x, v = rebound_state(sim)
    if configure == "whfast":
        configure_rebound_whfast(sim, {})
    else:
        sim.integrator = configure
    attach_forces(sim, forces)
    sim.steps(steps)
    sim.synchronize()
    _, x_rebound, v_rebound = rebound_state(sim)
    ours, _ = _run(integrator, forces, steps, dt, system=(m, x, v))
    x_ours, v_ours = ours.state()
    # The bound; measured 5e-14 (WHFast) and 1e-14 (leapfrog): the same operations in the same order.
    assert _rel(x_ours, x_rebound) < 1e-10
    assert _rel(v_ours, v_rebound) < 1e-10
    # The force mattered: without it the run ends elsewhere by far more than the bound.
    plain, _ = _run(integrator, None, steps, dt, system=(m, x, v))
    assert _rel(plain.state()[0], x_rebound) > 1e-6


def _energy_errors(chunks) -> np.ndarray:
    energy = np.concatenate([c.kinetic + c.potential for c in chunks])
    return np.abs(energy - energy[0]) / abs(energy[0])


SYMPLECTIC = ["semi_implicit_euler", "verlet", "leapfrog", "leapfrog4", "leapfrog6", "leapfrog8", "wisdom_holman"]


# Each scheme compiles its loop with gr_potential (9-16 s cold): `make test` bounds leapfrog and Wisdom-Holman.
@pytest.mark.parametrize("integrator", fast_only(SYMPLECTIC, ["leapfrog", "wisdom_holman"]))
def test_symplectic_energy_with_gr_potential_is_bounded(integrator) -> None:
    steps = 6000  # about 50 orbits of the inner planet at dt = 0.05, where even leapfrog8's error is not round-off
    _, chunks = _run(integrator, _gr_potential(), steps, dt=0.05, targets=np.arange(0, steps + 1, 50))
    err = _energy_errors(chunks)
    half = len(err) // 2
    # Bounded, not drifting: the second half's largest error is no larger than 2x the first half's
    # (a secular drift would double it over a doubled time); 1e-13 is the round-off random walk of
    # 6000 steps (measured 4e-14), below which there is nothing to bound.
    assert err[half:].max() < 2.0 * err[:half].max() + 1e-13
    assert err.max() < 1e-2  # and small: the orbit is resolved
    # And the samples' energy includes the force's potential: without it the error is the size
    # of the GR potential's oscillation, far above the scheme's own error.
    kinetic_potential = np.concatenate([c.kinetic + c.potential for c in chunks])
    m, x, v = _system()
    sim = Simulation(m, x, v, integrator, 1e-2, forces=_gr_potential())
    assert kinetic_potential[0] == pytest.approx(sim.total_energy(), rel=1e-15, abs=0.0)
    from orbitsim.physics.diagnostics import kinetic_energy, potential_energy

    newtonian = kinetic_energy(sim.vel, sim.m) + potential_energy(sim.pos, sim.m, 1.0, 0.0, sim.rows)
    assert sim.total_energy() != newtonian


# As above, with gr as an operator: `make test` keeps leapfrog and leapfrog4.
@pytest.mark.parametrize("integrator", fast_only(["verlet", "leapfrog", "leapfrog4", "wisdom_holman"],
                                                  ["leapfrog", "leapfrog4"]))
def test_velocity_operator_keeps_the_gr_hamiltonian_bounded(integrator) -> None:
    """gr as REBOUNDx's operator V(dt/2) S(dt) V(dt/2) around a symmetric scheme (Tamayo et al.
    2020): the GR Hamiltonian (Newtonian energy + force_energy) oscillates without drifting."""
    steps = 12_000  # about 100 orbits at dt = 0.05
    _, chunks = _run(integrator, make_forces(3, [(GR, 0, {P_C: C_STRONG}, None)]), steps, dt=0.05,
                     targets=np.arange(0, steps + 1, 50))
    err = _energy_errors(chunks)
    half = len(err) // 2
    # Measured: the two halves' largest errors agree to 1% (2e-7 ... 2e-4 by scheme); a drift would
    # double the second's. 1.1 leaves room for where the sampling catches the oscillation's peak.
    assert err[half:].max() < 1.1 * err[:half].max()
    assert err.max() < 1e-3  # the orbit is resolved: the bound means something


def _final_error(integrator: str, forces, dt: float, t_end: float, reference: np.ndarray) -> float:
    sim, _ = _run(integrator, forces, round(t_end / dt), dt)
    return float(np.max(np.abs(sim.pos - reference)))


#: rk4 with gr_potential and with gr_full each compile rk4's loop (and, for gr_full, IAS15's
#: reference) for a force set no other default test uses: they run in `make test-slow`, as does euler
#: with gr (its own forced loop). rk4's order with a force stays in `make test` through gr
#: (velocity-dependent, so every stage's force is exercised); gr_full's runs are all in `make test-slow`.
@pytest.mark.parametrize(("integrator", "order", "force_id"), [
    ("semi_implicit_euler", 1, GR_POTENTIAL), ("verlet", 2, GR_POTENTIAL), ("leapfrog", 2, GR_POTENTIAL),
    ("leapfrog4", 4, GR_POTENTIAL), ("wisdom_holman", 2, GR_POTENTIAL),
    pytest.param("rk4", 4, GR_POTENTIAL, marks=pytest.mark.slow),
    pytest.param("euler", 1, GR, marks=pytest.mark.slow), ("verlet", 2, GR), ("leapfrog", 2, GR), ("rk4", 4, GR),
    pytest.param("rk4", 4, GR_FULL, marks=pytest.mark.slow),
])
def test_convergence_order_with_forces(integrator, order, force_id) -> None:
    forces = make_forces(3, [(force_id, 0 if force_id != GR_FULL else -1, {P_C: C_STRONG}, None)])
    t_end = 1.6
    reference, _ = _run("ias15", forces, 1, dt=t_end, settings={"epsilon": 1e-11})
    dts = np.array([0.02, 0.01, 0.005]) if order < 4 else np.array([0.08, 0.04, 0.02])
    errors = [_final_error(integrator, forces, dt, t_end, reference.pos) for dt in dts]
    slope = np.polyfit(np.log(dts), np.log(errors), 1)[0]
    # The declared order, within 0.35: three halvings of dt, each pre-asymptotic by a few percent.
    assert abs(slope - order) < 0.35, (slope, errors)


#: verlet's loop with gr_potential + gr is compiled only by its cases of the two tests below: they run
#: in `make test-slow`. The one sample loop and the force hooks they test are the same for every
#: fixed-step scheme, and `make test` keeps them through Wisdom-Holman (fixed step) and, in the
#: checkpoint test, IAS15 (adaptive); IAS15's and rk4's (gr_full) cut runs each compile a loop of their
#: own (25-30 s cold) and run in `make test-slow`.
SHARED_LOOP_SLOW = pytest.param("verlet", marks=pytest.mark.slow)


@pytest.mark.parametrize("integrator", [SHARED_LOOP_SLOW, "wisdom_holman", *fast_only(["ias15", "rk4"], [])])
def test_forced_runs_same_bits_however_cut(integrator) -> None:
    forces = make_forces(3, [(GR_POTENTIAL, 0, {P_C: C_STRONG}, None),
                             (GR if integrator != "rk4" else GR_FULL, 0 if integrator != "rk4" else -1,
                              {P_C: C_STRONG}, None)])
    one, _ = _run(integrator, forces, 400)
    again, _ = _run(integrator, forces, 400)
    cut, _ = _run(integrator, forces, 400, targets=[*np.arange(0, 401, 7).tolist(), 400])
    for other in (again, cut):
        assert np.array_equal(one.pos, other.pos) and np.array_equal(one.vel, other.vel)


# Compiles leapfrog with forces for the parallel kernel (~17 s cold); tests/physics/ checks the kernel's threads.
@pytest.mark.slow
def test_forced_runs_do_not_depend_on_threads() -> None:
    import numba

    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("needs 2 Numba threads")
    from orbitsim.physics.gravity import PARALLEL_MIN_N

    n = PARALLEL_MIN_N + 16  # the gravity kernel runs in parallel from here
    rng = np.random.default_rng(3)
    m = np.concatenate([[1.0], np.full(n - 1, 1e-9)])
    x = rng.normal(size=(n, 3))
    x[0] = 0.0
    v = rng.normal(scale=0.3, size=(n, 3))
    taus = np.full((3, n), np.inf)
    taus[0, 1:] = -1e3
    forces = make_forces(n, [(GR_POTENTIAL, 0, {P_C: C_STRONG}, None), (MIGRATION, -1, {}, taus)])
    states = []
    for threads in (1, 2):
        sim, _ = _run("leapfrog", forces, 5, 1e-3, threads=threads, system=(m, x, v))
        states.append((sim.pos.copy(), sim.vel.copy()))
    assert np.array_equal(states[0][0], states[1][0]) and np.array_equal(states[0][1], states[1][1])


# IAS15 with forces compiles for ~28 s cold: its resume runs in make test-slow.
@pytest.mark.parametrize("integrator", [SHARED_LOOP_SLOW, "wisdom_holman", *fast_only(["ias15"], [])])
def test_checkpoint_resume_with_forces_is_bit_identical(integrator) -> None:
    from orbitsim.checkpoint.state import capture_state, restore_state

    forces = make_forces(3, [(GR_POTENTIAL, 0, {P_C: C_STRONG}, None), (GR, 0, {P_C: C_STRONG}, None)])
    straight, _ = _run(integrator, forces, 600)
    first, _ = _run(integrator, forces, 300)
    saved = capture_state(first)
    m, x, v = _system()
    resumed = Simulation(m, x, v, integrator, 1e-2, forces=forces)
    restore_state(resumed, saved)
    list(resumed.chunks(np.array([600])))
    assert np.array_equal(resumed.pos, straight.pos) and np.array_equal(resumed.vel, straight.vel)


def test_ias15_velocity_dependent_force_predicts_node_velocities() -> None:
    """With gr in the derivative IAS15 keeps its 1e-12-level accuracy only if the node velocities
    are predicted (REBOUND's force_is_velocity_dependent branch): it matches REBOUND + REBOUNDx."""
    from orbitsim.reference.rebx import attach_forces

    forces = make_forces(3, [(GR, 0, {P_C: C_STRONG}, None)])
    sim = _rebound_system()
    m, x, v = rebound_state(sim)
    sim.integrator = "ias15"
    attach_forces(sim, forces)
    sim.integrate(5.0, exact_finish_time=1)
    ours, _ = _run("ias15", forces, 1, dt=5.0, settings={"first_dt": sim.dt}, system=(m, x, v))
    # Same predictor, same step control: the codes agree to round-off (measured ~1e-15).
    assert _rel(ours.pos, rebound_state(sim)[1].T) < 1e-12


def test_runs_without_forces_keep_their_plain_loop() -> None:
    """Without forces a step gets the plain context (``forces`` None: every hook compiles to nothing);
    with them the same scheme's ``run`` gets the context with the force records."""
    sim, _ = _run("verlet", None, 10)
    assert sim.step_force is sim.force and sim.force.forces is None
    forced, _ = _run("verlet", _gr_potential(3), 10)
    assert forced.step_force.forces is not None and type(forced.step_force) is type(forced.force)


#: Force rows and whether they need the velocity operator V(h): gr and migration act on velocities.
_VELOCITY_CASES = [
    (None, False),
    ([(GR_POTENTIAL, 0, {P_C: C_STRONG}, None)], False),
    ([(HARMONICS, 0, HARMONIC_PARAMS, None)], False),
    ([(GR, 0, {P_C: C_STRONG}, None)], True),
    ([(MIGRATION, 0, {}, np.full((3, 3), np.inf))], True),
    ([(GR_POTENTIAL, 0, {P_C: C_STRONG}, None), (GR, 0, {P_C: C_STRONG}, None)], True),
]


@pytest.mark.parametrize("integrator", ["verlet", "wisdom_holman"])
@pytest.mark.parametrize(("rows", "velocity"), _VELOCITY_CASES)
def test_a_scheme_with_a_velocity_operator_runs_the_loop_of_its_forces(integrator, rows, velocity) -> None:
    """verlet's and Wisdom-Holman's ``run`` and ``run_watched`` are two kernels each (ByVelocityForces), so
    a run types and compiles only the loop it takes: the split loop V(dt/2) S V(dt/2) exactly when a force
    depends on velocities, read from the context's type as the hooks read it."""
    from orbitsim.forces.hooks import velocity_forces_in

    m, x, v = _system()
    sim = Simulation(m, x, v, integrator, 1e-2, forces=None if rows is None else make_forces(3, rows))
    assert velocity_forces_in(sim.step_force) is velocity
    for entry in (sim.scheme.run, sim.scheme.run_watched):
        picked = entry.split if velocity else entry.plain
        assert picked.py_func.__name__.endswith("_split" if velocity else "_plain")


def test_the_loop_without_the_velocity_operator_refuses_velocity_forces() -> None:
    """Called directly with gr, the plain loop fails while Numba types it, never runs without V(h)."""
    from numba.core.errors import TypingError

    from orbitsim.integrators import verlet

    m, x, v = _system()
    sim = Simulation(m, x, v, "verlet", 1e-2, forces=make_forces(3, [(GR, 0, {P_C: C_STRONG}, None)]))
    state = (sim.pos, sim.vel, sim.acc, sim.m)
    with pytest.raises(TypingError, match="velocity-dependent forces"):
        verlet._run_plain(state, sim.step_force, sim.dt, sim.work, 0.0, 0, np.array([1]), np.array([True]),
                          np.zeros((1, 1)))


@pytest.mark.parametrize(("integrator", "kwargs", "words"), [
    ("trace", {}, "trace cannot apply"),
    ("verlet", {"settings": {}, "force_id": GR_FULL}, "verlet cannot apply gr_full"),
    ("wisdom_holman", {"settings": {"corrector": 5}}, "correctors"),
])
def test_forces_refused_in_one_line(integrator, kwargs, words) -> None:
    m, x, v = _system()
    fid = kwargs.get("force_id", GR_POTENTIAL)
    forces = make_forces(3, [(fid, 0 if fid != GR_FULL else -1, {P_C: C_STRONG}, None)])
    with pytest.raises(SimulationError, match=words) as info:
        Simulation(m, x, v, integrator, 1e-2, settings=kwargs.get("settings", {}), forces=forces)
    assert "\n" not in str(info.value)


def test_forces_with_events_refused() -> None:
    from orbitsim.events import EventsConfig

    m, x, v = _system()
    with pytest.raises(SimulationError, match="events"):
        Simulation(m, x, v, "verlet", 1e-2, events=EventsConfig(), forces=_gr_potential())


TRIO_WITH_FORCES = {
    "name": "trio_forces",
    "units": "nbody",
    "dt": 0.01,
    "steps": 100_000,  # more than the first call's budget of steps, so the run can be stopped
    "output": {"every": 2500, "checkpoint": {"every": 10_000}},
    "bodies": [
        {"name": "star", "m": 1.0, "x": [0, 0, 0], "v": [0, 0, 0]},
        {"name": "inner", "m": 1e-3, "primary": "star", "a": 1.0, "e": 0.2, "M": 0},
        {"name": "outer", "m": 2e-3, "primary": "star", "a": 2.0, "e": 0.1, "M": 40, "inc": 3},
    ],
    "forces": [{"force": "harmonics", "body": "star", "J2": 1e-3, "R_eq": 0.05},
               {"force": "gr", "c": C_STRONG, "source": "star"}],
}


#: Each scheme's loop with this force set is compiled by no other test: the three run in `make test-slow`.
#: A resume with forces stays in `make test` at the Simulation level
#: (test_checkpoint_resume_with_forces_is_bit_identical[wisdom_holman]), and IAS15 with forces through
#: test_ias15_velocity_dependent_force_predicts_node_velocities.
@pytest.mark.slow  # a scenario run with forces, killed and resumed: its loop compiles for ~18 s cold
@pytest.mark.parametrize("name", ["leapfrog", "wisdom_holman", "ias15"])
def test_scenario_run_with_forces_resumes_to_the_same_bits(tmp_path, name) -> None:
    """orbitsim run with a forces: list, stopped and resumed from its checkpoint: the same trace as
    one uninterrupted run, with the forces in the trace's attributes."""
    import json

    import h5py
    from test_checkpoint_kill import assert_same_datasets

    from orbitsim.checkpoint import prepare_resume
    from orbitsim.runner import run_scenario
    from orbitsim.scenario import scenario_from_dict

    doc = {**TRIO_WITH_FORCES, "integrator": name}
    if name == "ias15":  # it chooses its own steps: an end time and a sampling interval instead
        doc = {k: v for k, v in doc.items() if k != "steps"} | {
            "t_end": 100.0, "output": {"interval": 0.02, "checkpoint": {"every": 1000}}}
    sc = scenario_from_dict(doc)
    run_scenario(sc, tmp_path / "ref.h5")
    calls = [0]

    def stop() -> bool:
        calls[0] += 1
        return calls[0] > 1

    first = run_scenario(sc, tmp_path / "out.h5", stop=stop)
    assert first.status == "interrupted" and first.resumable
    plan = prepare_resume(tmp_path / "out.h5")
    second = run_scenario(plan.scenario, plan.output, start=plan.start)
    assert second.status == "complete"
    assert_same_datasets(tmp_path / "ref.h5", tmp_path / "out.h5")
    with h5py.File(tmp_path / "ref.h5") as trace:
        assert [f["force"] for f in json.loads(trace.attrs["forces"])] == ["harmonics", "gr"]
