"""``integrator: trace`` in the engine: through ``orbitsim run``, against REBOUND's TRACE and
against orbitsim's Wisdom-Holman on the bundled many-encounters scenario."""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

from orbitsim.cli.main import cli
from orbitsim.runner import run_scenario
from orbitsim.scenario import load_scenario
from orbitsim.scenario.errors import ScenarioError
from orbitsim.scenario.loader import scenario_from_dict

rebound = pytest.importorskip("rebound")


def rebound_trace(steps: int) -> tuple[np.ndarray, np.ndarray]:
    """REBOUND's TRACE on the bundled many_encounters state, ``steps`` whole steps."""
    sc = load_scenario("many_encounters")
    sim = rebound.Simulation()
    sim.G = sc.G
    for m, x, v in zip(sc.masses, sc.positions, sc.velocities, strict=True):
        sim.add(m=float(m), x=float(x[0]), y=float(x[1]), z=float(x[2]), vx=float(v[0]), vy=float(v[1]),
                vz=float(v[2]))
    sim.integrator = "trace"
    sim.dt = sc.dt
    sim.steps(steps)
    return (np.array([[p.x, p.y, p.z] for p in sim.particles]),
            np.array([[p.vx, p.vy, p.vz] for p in sim.particles]))


@pytest.mark.skipif(rebound.__version__ != "5.2.2", reason="bitwise parity is with REBOUND 5.2.2")
def test_orbitsim_run_is_rebounds_trace_bit_for_bit(tmp_path: Path) -> None:
    """3000 steps (t = 102: encounters, redone steps and FULL_BS pericentre steps among them)."""
    out = tmp_path / "me.h5"
    result = CliRunner().invoke(cli, ["run", "many_encounters", "--steps", "3000", "--every", "1000", "-o", str(out),
                                      "-q"], catch_exceptions=False)
    assert result.exit_code == 0, result.output
    with h5py.File(out, "r") as f:
        x, v = f["positions"][-1], f["velocities"][-1]
        redone = int(f.attrs["trace_redone"])
    xr, vr = rebound_trace(3000)
    assert np.array_equal(x, xr) and np.array_equal(v, vr)
    assert redone > 0  # the span does exercise the reject-and-redo path


def test_many_encounters_energy_where_wisdom_holman_fails(tmp_path: Path) -> None:
    """REBOUND's bounds on its own test, through the run loop: |dE/E| < 5e-5, and below 1e-4 of
    the fixed-step map's error on the same steps (measured: max 1.1e-5 against wisdom_holman's 0.14;
    REBOUND: 5.7e-6 at the end against WHFast's 21)."""
    sc = load_scenario("many_encounters")
    trace = run_scenario(sc, tmp_path / "trace.h5", handle_signals=False)
    wh = run_scenario(sc.with_overrides(integrator="wisdom_holman"), tmp_path / "wh.h5", handle_signals=False)
    assert trace.status == "complete" and trace.max_abs_energy_error < 5e-5
    assert trace.max_abs_energy_error < 1e-4 * wh.max_abs_energy_error


BASE = {"name": "t", "integrator": "trace", "dt": 0.01, "steps": 10,
        "bodies": [{"name": "star", "m": 1.0, "x": [0, 0, 0], "v": [0, 0, 0]},
                   {"name": "p", "m": 1e-3, "x": [1, 0, 0], "v": [0, 1, 0]}]}


@pytest.mark.parametrize(("settings", "words"), [
    ({"peri_mode": "sometimes"}, "peri_mode"),
    ({"r_crit_hill": 0}, "r_crit_hill"),
    ({"peri_crit_eta": -1}, "peri_crit_eta"),
    ({"epsilon": 1e-9}, "epsilon"),
])
def test_bad_settings_name_the_key(settings: dict, words: str) -> None:
    with pytest.raises(ScenarioError, match=words) as err:
        scenario_from_dict({**BASE, "integrator": {"name": "trace", **settings}})
    assert "integrator" in str(err.value)


def test_a_test_particle_before_a_massive_body_is_refused_by_the_loader() -> None:
    """``validate`` must refuse what ``run`` cannot do: TRACE's test particles come last."""
    bodies = [BASE["bodies"][0], {"name": "tp", "m": 0.0, "x": [2, 0, 0], "v": [0, 0.7, 0]}, BASE["bodies"][1]]
    with pytest.raises(ScenarioError, match="test particles") as err:
        scenario_from_dict({**BASE, "bodies": bodies})
    assert err.value.key == "bodies"


def jacobi_constant(x: np.ndarray, v: np.ndarray, m: np.ndarray) -> float:
    """C_J of body 2 (massless) in the field of bodies 0 and 1 (G = 1), as REBOUND's test writes
    it: 2 n l_z - 2 (|v|^2 / 2 - m0 / r0 - m1 / r1), n the mean motion of body 1 about body 0."""
    rel_x, rel_v = x[1] - x[0], v[1] - v[0]
    mu = m[0] + m[1]
    a = 1.0 / (2.0 / np.linalg.norm(rel_x) - rel_v @ rel_v / mu)
    n = np.sqrt(mu / a**3)
    energy = 0.5 * v[2] @ v[2] - m[0] / np.linalg.norm(x[2] - x[0]) - m[1] / np.linalg.norm(x[2] - x[1])
    return 2.0 * n * np.cross(x[2], v[2])[2] - 2.0 * energy


def test_chaotic_exchange_keeps_the_jacobi_constant(tmp_path: Path) -> None:
    """REBOUND's test_chaotic_exchange: a test particle swapping orbits with a Jupiter of mass 0.01
    in repeated close encounters (r_crit_hill 3.63), to t = 2000; REBOUND's bound on C_J is 1e-6
    (measured 4.7e-7; REBOUND 5.0e-7)."""
    mj = 0.01 / 0.99
    f_star, f_jup = mj / (1 + mj), 1 / (1 + mj)
    speed = float(np.sqrt((1 + mj) / 5.2))
    star = {"name": "star", "m": 1.0, "x": [-f_star * 5.2, 0, 0], "v": [0, -f_star * speed, 0]}
    bodies = [star, {"name": "jupiter", "m": mj, "x": [f_jup * 5.2, 0, 0], "v": [0, f_jup * speed, 0]},
              {"name": "tp", "m": 0.0, "x": [4.42 + star["x"][0], 0, 0],
               "v": [0, 0.0072 * 365.25 / (2 * np.pi) + star["v"][1], 0]}]
    dt = (8.0 / 365.0) * 2.0 * np.pi
    sc = scenario_from_dict({"name": "exchange", "integrator": {"name": "trace", "r_crit_hill": 3.63}, "dt": dt,
                             "steps": 14523, "output": {"every": 14523, "positions": True}, "bodies": bodies})
    summary = run_scenario(sc, tmp_path / "x.h5", handle_signals=False)
    assert summary.status == "complete"
    with h5py.File(tmp_path / "x.h5", "r") as f:
        x, v, m = f["positions"][()], f["velocities"][()], f["bodies/masses"][()]
        redone = int(f.attrs["trace_redone"])
    c0, c1 = jacobi_constant(x[0], v[0], m), jacobi_constant(x[-1], v[-1], m)
    assert abs((c1 - c0) / c0) < 1e-6
    assert redone > 0  # the particle did meet Jupiter


def test_the_run_line_says_how_often_trace_switched(tmp_path: Path) -> None:
    result = CliRunner().invoke(cli, ["run", "many_encounters", "--steps", "3000", "-o", str(tmp_path / "m.h5")],
                                catch_exceptions=False)
    assert result.exit_code == 0, result.output
    line = result.stdout.splitlines()[0]
    assert "(trace: " in line and " steps redone, " in line and "Bulirsch-Stoer sub-steps)" in line
    with h5py.File(tmp_path / "m.h5", "r") as f:
        assert f"{int(f.attrs['trace_redone']):,} steps redone" in line


#: REBOUND's test_pericenter state (5.2.2, exact): Jupiter, and a Saturn-mass body on a polar
#: e = 0.99 orbit whose pericentre passages are TRACE's pericentre steps; dt = 0.15 * 2 pi.
PERICENTRE = {
    "name": "pericentre", "integrator": "trace", "dt": 0.9424777960769379, "steps": 1960, "output": {"every": 40},
    "bodies": [
        {"name": "sun", "m": 1.0, "x": [-0.004987182462718505, 0.0, 0.0],
         "v": [0.0, -0.00041847592812391986, -0.0013007012540937597]},
        {"name": "jupiter", "m": 0.000955, "x": [5.195012817537282, 0.0, 0.0],
         "v": [0.0, 0.43831988135768046, -0.0013007012540937597]},
        {"name": "comet", "m": 0.0002857, "x": [0.09081281753728164, 0.0, 0.0],
         "v": [0.0, -0.00041847592812364073, 4.557029834761706]}]}


@pytest.mark.slow  # TRACE with events through orbitsim run, each pericentre mode its own kernel (~20 s cold)
@pytest.mark.parametrize("peri_mode", ["full_bs", "full_ias15"])
def test_pericentre_passages_through_orbitsim_run(tmp_path: Path, peri_mode: str) -> None:
    """REBOUND's bound on its pericentre test, |dE/E| < 1e-4, through the run loop, in both FULL
    modes (measured, largest over the run: 1.1e-5 in both; REBOUND's end value 5.7e-6), and the
    same bits as REBOUND's TRACE stepped as often."""
    sc = scenario_from_dict({**PERICENTRE, "integrator": {"name": "trace", "peri_mode": peri_mode}})
    result = run_scenario(sc, tmp_path / "p.h5", handle_signals=False)
    assert result.status == "complete" and result.max_abs_energy_error < 1e-4
    with h5py.File(tmp_path / "p.h5", "r") as f:
        x, v = f["positions"][-1], f["velocities"][-1]
        full_steps = int(f.attrs["trace_full_bs_steps"])
        ias15_steps = int(f.attrs["trace_full_ias15_steps"])
    assert full_steps > 0 and (ias15_steps > 0) == (peri_mode == "full_ias15")
    if rebound.__version__ == "5.2.2":
        sim = rebound.Simulation()
        for body in PERICENTRE["bodies"]:
            sim.add(m=body["m"], x=body["x"][0], y=body["x"][1], z=body["x"][2], vx=body["v"][0],
                    vy=body["v"][1], vz=body["v"][2])
        sim.integrator, sim.dt = "trace", PERICENTRE["dt"]
        sim.integrator.peri_mode = {"full_bs": 1, "full_ias15": 2}[peri_mode]
        sim.steps(PERICENTRE["steps"])
        assert np.array_equal(x, [[p.x, p.y, p.z] for p in sim.particles])
        assert np.array_equal(v, [[p.vx, p.vy, p.vz] for p in sim.particles])
