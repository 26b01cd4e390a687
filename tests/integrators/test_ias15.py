"""IAS15: agreement with REBOUND's IAS15, the Pythagorean problem, exact output times, the fixed-step
mode, the scenario contract, and its coefficient tables recomputed exactly."""

from __future__ import annotations

from decimal import Decimal, getcontext
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
import rebound

from orbitsim.integrators.ias15 import counters
from orbitsim.integrators.ias15 import tables as ias15_tables
from orbitsim.integrators.registry import get_spec
from orbitsim.runner import run_scenario
from orbitsim.sampling import EveryPlan
from orbitsim.scenario import load_scenario
from orbitsim.scenario.errors import ScenarioError
from orbitsim.scenario.loader import scenario_from_dict
from orbitsim.simulation import Simulation


def giants_run(t_end: float, interval: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict]:
    """orbitsim's IAS15 on the bundled giants: sample times, positions (S, N, 3), energies, counters."""
    sc = load_scenario("giants")
    sim = Simulation(sc.masses, sc.positions, sc.velocities, "ias15", interval, sc.G, 0.0, 0.0, None,
                     {"first_dt": sc.dt, "t_end": t_end})
    chunks = list(sim.chunks(EveryPlan(round(t_end / interval), 1)))
    times = np.concatenate([c.time for c in chunks])
    pos = np.concatenate([c.positions for c in chunks])
    energy = np.concatenate([c.kinetic + c.potential for c in chunks])
    return times, pos, energy, counters(sim.work)


def rebound_giants(times: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """REBOUND's IAS15 (epsilon 1e-9, exact finish) on the same system, integrated to each time."""
    sc = load_scenario("giants")
    sim = rebound.Simulation()
    sim.G = sc.G
    for m, x, v in zip(sc.masses, sc.positions, sc.velocities, strict=True):
        sim.add(m=m, x=x[0], y=x[1], z=x[2], vx=v[0], vy=v[1], vz=v[2])
    sim.integrator = "ias15"
    sim.dt = sc.dt
    at, pos, energy = [], [], []
    for t in times:
        sim.integrate(t)
        at.append(sim.t)
        pos.append([[p.x, p.y, p.z] for p in sim.particles])
        energy.append(sim.energy())
    return np.array(at), np.array(pos), np.array(energy), sim.steps_done


def test_giants_agree_with_rebound_sample_by_sample() -> None:
    """The acceptance case: t = 1000, samples every 10, epsilon 1e-9."""
    times, pos, _, own = giants_run(1000.0, 10.0)
    r_times, r_pos, _, r_steps = rebound_giants(np.arange(101) * 10.0)
    assert np.array_equal(times, r_times)  # exact finish: each sample lands where REBOUND's does
    size = np.max(np.abs(pos[0]))
    # 1e-10 of the system's size is the bound; the two differ only in the force sum's order.
    assert np.max(np.abs(pos - r_pos)) < 1e-10 * size
    assert abs(own["steps_accepted"] - r_steps) <= 0.01 * r_steps  # within 1% (equal in practice)


def test_giants_energy_over_1e5_is_no_worse_than_twice_rebounds() -> None:
    times, _, energy, own = giants_run(1e5, 1000.0)
    _, _, r_energy, r_steps = rebound_giants(times)
    ours = np.max(np.abs(energy / energy[0] - 1.0))
    theirs = np.max(np.abs(r_energy / r_energy[0] - 1.0))
    assert ours <= 2.0 * max(theirs, 1e-16)  # 1e-16: one ulp of E, in case REBOUND's is exactly 0
    assert abs(own["steps_accepted"] - r_steps) <= 0.01 * r_steps
    assert own["steps_unconverged"] == 0


PYTHAGOREAN = """\
name: pythagorean_ias15
integrator: ias15
dt: 1.0e-4
t_end: 70
output: {interval: 0.01}
bodies:
  - {name: m3, m: 3.0, x: [1.0, 3.0, 0.0], v: [0, 0, 0]}
  - {name: m4, m: 4.0, x: [-2.0, -1.0, 0.0], v: [0, 0, 0]}
  - {name: m5, m: 5.0, x: [1.0, -1.0, 0.0], v: [0, 0, 0]}
"""


def test_pythagorean_problem_ejects_m3_and_leaves_a_binary(tmp_path: Path) -> None:
    scenario = tmp_path / "pythagorean.yaml"
    scenario.write_text(PYTHAGOREAN, encoding="utf-8")
    summary = run_scenario(load_scenario(scenario), tmp_path / "p.h5", handle_signals=False)
    assert summary.status == "complete" and summary.end_time == 70.0
    assert summary.max_abs_energy_error < 1e-9  # the bound; REBOUND's IAS15 gives 3e-11
    import h5py

    with h5py.File(tmp_path / "p.h5", "r") as f:
        x, v, m = f["positions"][-1], f["velocities"][-1], f["bodies/masses"][()]
    m3, m4, m5 = [(x[k], v[k], m[k]) for k in range(3)]
    pair_m = m4[2] + m5[2]
    pair_x = (m4[2] * m4[0] + m5[2] * m5[0]) / pair_m
    pair_v = (m4[2] * m4[1] + m5[2] * m5[1]) / pair_m
    # m = 3 against the 4-5 pair: positive two-body energy, and already far from it.
    dx, dv = m3[0] - pair_x, m3[1] - pair_v
    escape = 0.5 * np.dot(dv, dv) - (m3[2] + pair_m) / np.linalg.norm(dx)
    assert escape > 0 and np.linalg.norm(dx) > 10
    # m = 4 and m = 5 bound to each other.
    dx, dv = m4[0] - m5[0], m4[1] - m5[1]
    assert 0.5 * np.dot(dv, dv) - pair_m / np.linalg.norm(dx) < 0


def test_fixed_step_mode_takes_whole_steps_on_the_grid() -> None:
    sc = load_scenario("giants")
    settings = {"adaptive": False}
    sim = Simulation(sc.masses, sc.positions, sc.velocities, "ias15", 5.0, sc.G, 0.0, 0.0, None, settings)
    chunks = list(sim.chunks(EveryPlan(40, 4)))
    times = np.concatenate([c.time for c in chunks])
    assert np.array_equal(times, np.arange(0, 41, 4) * 5.0)
    own = counters(sim.work)
    assert own["steps_accepted"] == 40 and own["steps_rejected"] == 0


def test_fixed_step_mode_agrees_with_rebound_at_epsilon_zero() -> None:
    """Same scheme, same constant step: REBOUND with epsilon = 0 stepped one step at a time."""
    sc = load_scenario("giants")
    sim = Simulation(sc.masses, sc.positions, sc.velocities, "ias15", 5.0, sc.G, 0.0, 0.0, None,
                     {"adaptive": False})
    ours = np.concatenate([c.positions for c in sim.chunks(EveryPlan(200, 1))])
    reb = rebound.Simulation()
    reb.G = sc.G
    for m, x, v in zip(sc.masses, sc.positions, sc.velocities, strict=True):
        reb.add(m=m, x=x[0], y=x[1], z=x[2], vx=v[0], vy=v[1], vz=v[2])
    reb.integrator = "ias15"
    reb.integrator.epsilon = 0.0
    reb.dt = 5.0
    theirs = [[[p.x, p.y, p.z] for p in reb.particles]]
    for _ in range(200):
        reb.steps(1)
        theirs.append([[p.x, p.y, p.z] for p in reb.particles])
    # Round-off of the force sums' order only: 1e-13 of the system size over 200 steps.
    assert np.max(np.abs(ours - np.array(theirs))) < 1e-13 * np.max(np.abs(ours[0]))


def test_registry_entry() -> None:
    spec = get_spec("ias15")
    assert spec.adaptive and not spec.symplectic and not spec.reversible and spec.order == 15
    assert "Rein & Spiegel (2015)" in spec.reference
    assert get_spec("gauss_radau") is spec


GIANT = {"name": "g", "integrator": "ias15", "dt": 0.01,
         "bodies": [{"name": "a", "m": 1.0, "x": [0, 0, 0], "v": [0, 0, 0]},
                    {"name": "b", "m": 1e-3, "x": [1, 0, 0], "v": [0, 1, 0]}]}


@pytest.mark.parametrize(("extra", "key", "words"), [
    ({"steps": 100}, "steps", "give t_end"),
    ({"t_end": 10, "output": {"every": 5}}, "output.every", "output.interval"),
    ({"t_end": 10, "integrator": {"name": "ias15", "epsilon": -1}}, "integrator.epsilon", ">= 0"),
    ({"t_end": 10, "integrator": {"name": "ias15", "tolerance": 1}}, "integrator.tolerance", "unknown"),
])
def test_scenario_errors_name_the_key(extra: dict, key: str, words: str) -> None:
    with pytest.raises(ScenarioError) as err:
        scenario_from_dict({**GIANT, **extra})
    assert err.value.key == key and words in str(err.value)


def test_output_grid_ends_exactly_at_t_end() -> None:
    sc = scenario_from_dict({**GIANT, "t_end": 10.5, "output": {"interval": 2.0}})
    assert sc.adaptive and sc.steps == 6 and sc.end_time == 10.5 and sc.grid_dt == 2.0
    sim = Simulation(sc.masses, sc.positions, sc.velocities, "ias15", sc.grid_dt, sc.G, 0.0, 0.0, None,
                     sc.run_settings)
    times = np.concatenate([c.time for c in sim.chunks(sc.sample_plan(), record_positions=False)])
    assert np.array_equal(times, [0.0, 2.0, 4.0, 6.0, 8.0, 10.0, 10.5])


def test_stored_scenario_reloads_with_the_same_hash() -> None:
    """Traces and checkpoints store the resolved scenario; an adaptive one keeps t_end (its grid
    ends there exactly) rather than steps, which the loader refuses for ias15."""
    from orbitsim.scenario.yamlio import parse_yaml

    sc = scenario_from_dict({**GIANT, "t_end": 10.5, "output": {"interval": 2.0}})
    again = scenario_from_dict(parse_yaml(sc.to_yaml(), "stored")[0])
    assert again.sha256 == sc.sha256 and again.steps == 6 and again.end_time == 10.5


def test_run_from_continues_a_finished_run_bit_for_bit(tmp_path: Path) -> None:
    """``run --from`` restores the checkpoint of a run that ended at t = 40 and goes on to 80: the
    same datasets as one run to 80 (the clock, predictor and last full step carry over)."""
    import h5py
    from click.testing import CliRunner

    from orbitsim.cli.main import cli

    def run(*args: str) -> None:
        result = CliRunner().invoke(cli, ["run", *args, "-q"], catch_exceptions=False)
        assert result.exit_code == 0, result.output

    first, extended, direct = tmp_path / "first.h5", tmp_path / "extended.h5", tmp_path / "direct.h5"
    run("giants", "--t-end", "40", "--interval", "10", "-o", str(first))
    run("--from", str(first), "--t-end", "80", "-o", str(extended))
    run("giants", "--t-end", "80", "--interval", "10", "-o", str(direct))
    with h5py.File(extended, "r") as a, h5py.File(direct, "r") as b:
        assert a["time"][-1] == 80.0
        for name in ("time", "positions", "velocities", "energy"):
            assert a[name][()].tobytes() == b[name][()].tobytes(), name


def test_coefficient_tables_match_the_gauss_radau_nodes() -> None:
    """h: the roots of P_7(x) + P_6(x)... on [0, 1] recomputed by Newton in 40-digit decimals;
    rr, c, d from them in exact rational arithmetic. Each table entry is within a few ulps."""
    getcontext().prec = 40
    # Radau nodes with the left end fixed: roots of (P_7(x) + P_8(x)) / (1 + x) on [-1, 1].
    def legendre(n: int, x: Decimal) -> tuple[Decimal, Decimal]:
        p0, p1 = Decimal(1), x
        for k in range(1, n):
            p0, p1 = p1, ((2 * k + 1) * x * p1 - k * p0) / (k + 1)
        dp = n * (x * p1 - p0) / (x * x - 1)
        return p1, dp

    nodes = []
    for h in ias15_tables.H[1:]:
        x = Decimal(2 * float(h) - 1)
        for _ in range(60):
            p7, d7 = legendre(7, x)
            p8, d8 = legendre(8, x)
            x -= (p7 + p8) / (d7 + d8)
        nodes.append((x + 1) / 2)
    assert np.allclose(ias15_tables.H[1:], [float(h) for h in nodes], rtol=4e-16, atol=0)
    h = [Fraction(0)] + [Fraction(str(n)) for n in nodes]
    rr = [h[n] - h[j] for n in range(1, 8) for j in range(n)]
    assert np.allclose(ias15_tables.RR, [float(r) for r in rr], rtol=4e-16, atol=0)
    # c: coefficients of the basis polynomials t (t - h_1) ... (t - h_j) in powers of t.
    c = []
    for j in range(1, 7):
        poly = [Fraction(1)]  # coefficients of (t - h_1) ... (t - h_j), lowest power first
        for q in range(1, j + 1):
            poly = [(poly[k - 1] if k else 0) - h[q] * (poly[k] if k < len(poly) else 0) for k in range(len(poly) + 1)]
        c.extend(poly[:-1])
    assert np.allclose(ias15_tables.C, [float(x) for x in c], rtol=1e-15, atol=1e-25)
    # d inverts c: b = C g and g = D b as lower-triangular matrices with unit diagonal.
    cm, dm = np.eye(7), np.eye(7)
    k = 0
    for row in range(1, 7):
        for col in range(row):
            cm[col, row] = ias15_tables.C[k]
            dm[col, row] = ias15_tables.D[k]
            k += 1
    assert np.allclose(cm @ dm, np.eye(7), atol=1e-14)
