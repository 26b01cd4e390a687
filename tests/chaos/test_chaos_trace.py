"""Chaos indicators through a scenario (``output.chaos``) and ``orbitsim run``: the trace's ``megno`` and
``mlce`` at every sample are chaos_run's bits and REBOUND's numbers; checkpoints, ``resume`` (after a
stop or a SIGKILL) and ``run --from`` continue the tangent vector and MEGNO's sums bit for bit; the
summary line and ``orbitsim info`` report MEGNO and the Lyapunov time."""

from __future__ import annotations

import subprocess
from pathlib import Path

import h5py
import numpy as np
import pytest
import rebound
from click.testing import CliRunner
from test_checkpoint import stop_after
from test_checkpoint_kill import assert_same_datasets, orbitsim, run_and_kill

from orbitsim.chaos.run import chaos_run
from orbitsim.checkpoint import prepare_extension, prepare_resume
from orbitsim.cli.main import cli
from orbitsim.runner import run_scenario
from orbitsim.scenario import load_scenario, scenario_from_dict


def _regular_rebound() -> rebound.Simulation:
    """REBOUND's own regular MEGNO case (rebound/tests/test_megno.py), WHFast in safe mode."""
    sim = rebound.Simulation()
    sim.integrator = "whfast"
    sim.add(m=1.0)
    sim.add(m=1e-3, a=1.5, e=0.1, inc=0.1)
    sim.add(m=1e-3, a=15.0, e=0.1, inc=0.1)
    sim.init_megno(seed=0)
    sim.dt = sim.particles[1].P * 0.07
    sim.integrator.safe_mode = 1
    sim.exact_finish_time = 0
    return sim


def _rows(particles, n: int) -> np.ndarray:
    return np.array([[p.x, p.y, p.z, p.vx, p.vy, p.vz] for p in (particles[i] for i in range(n))])


NAMES = ("star", "inner", "outer")


def _rebound_scenario(sim: rebound.Simulation, steps: int, every: int) -> dict:
    """The REBOUND system as a scenario: the same bodies, dt and variational particle."""
    state, var = _rows(sim.particles, 3), _rows(sim.var_config[0].particles, 3)
    bodies = [{"name": name, "m": float(sim.particles[k].m), "x": [float(c) for c in state[k, :3]],
               "v": [float(c) for c in state[k, 3:]]} for k, name in enumerate(NAMES)]
    variation = {name: {"dr": [float(c) for c in var[k, :3]], "dv": [float(c) for c in var[k, 3:]]}
                 for k, name in enumerate(NAMES)}
    return {"name": "regular", "integrator": "wisdom_holman", "dt": float(sim.dt), "steps": steps,
            "output": {"every": every, "chaos": {"indicator": "megno", "variation": variation}}, "bodies": bodies}


def test_scenario_run_is_chaos_run_and_agrees_with_rebound_whfast(tmp_path: Path) -> None:
    sim = _regular_rebound()
    every = 100
    steps = int(1e4 / sim.dt) // every * every
    sc = scenario_from_dict(_rebound_scenario(sim, steps, every))
    summary = run_scenario(sc, tmp_path / "run.h5", handle_signals=False)
    assert summary.status == "complete"
    with h5py.File(tmp_path / "run.h5", "r") as f:
        time, megno, mlce = f["time"][()], f["megno"][()], f["mlce"][()]
        attrs = dict(f.attrs)
    # chaos_run from the same bodies and variation: the same kernel, so the same bits.
    direct = chaos_run(sc.masses, sc.positions, sc.velocities, integrator="wisdom_holman", dt=sc.dt, steps=steps,
                       every=every, variation=sc.chaos.variation)
    assert time.tobytes() == direct.times.tobytes()
    assert megno.tobytes() == direct.megno.tobytes() and mlce.tobytes() == direct.mlce.tobytes()
    assert summary.chaos == (float(megno[-1]), float(mlce[-1]))
    theirs = np.zeros((time.shape[0] - 1, 2))
    for k in range(theirs.shape[0]):
        sim.steps(every)
        theirs[k] = sim.megno(), sim.lyapunov()
    assert abs(sim.t - time[-1]) < 1e-12 * time[-1]  # REBOUND sums dt, orbitsim's clock is n dt: ulps apart
    # Two codes' round-off (Kepler solvers, transforms) moves the orbits apart linearly; over 1e4 time
    # units that reached 1e-12 in MEGNO and 2e-11 in the slope (tests/chaos/test_wh_tangent.py).
    ours = np.stack([megno[1:], mlce[1:]], axis=1)
    assert np.all(np.abs(ours - theirs) <= 1e-10 * np.abs(theirs))
    assert abs(megno[-1] - 2.0) < 0.2 and abs(mlce[-1]) < 1e-3  # REBOUND's regular-case bounds
    assert attrs["chaos_indicator"] == "megno" and "chaos_seed" not in attrs
    assert '"inner": {"dr": [' in attrs["chaos_variation"] and "inertial" in attrs["chaos_tangent_convention"]


PAIR = {  # REBOUND's chaotic case (periods 1 and 1.17), over 100 time units: its chaos shows from t ~ 250
    "name": "pair",
    "integrator": "wisdom_holman",
    "dt": 0.005,
    "steps": 20_000,
    "output": {"every": 500, "chaos": {"seed": 4}},
    "bodies": [
        {"name": "star", "m": 1.0, "x": [0, 0, 0], "v": [0, 0, 0]},
        {"name": "b", "m": 1e-4, "primary": "star", "a": 1.0, "e": 0.0},
        {"name": "c", "m": 1e-4, "primary": "star", "a": 1.1102, "e": 0.0},
    ],
}
CHECKPOINTED = {**PAIR, "output": {**PAIR["output"], "checkpoint": {"every": 3000}}}


def test_a_run_without_chaos_has_no_chaos_datasets(tmp_path: Path) -> None:
    plain = scenario_from_dict({**PAIR, "output": {"every": 500}})
    run_scenario(plain, tmp_path / "plain.h5", handle_signals=False)
    with h5py.File(tmp_path / "plain.h5", "r") as f:
        assert "megno" not in f and "mlce" not in f and not [k for k in f.attrs if k.startswith("chaos")]
        assert "chaos" not in f["checkpoint"]


@pytest.mark.parametrize("integrator", ["wisdom_holman", "leapfrog4"])
@pytest.mark.parametrize("doc", [PAIR, CHECKPOINTED], ids=["streamed", "checkpointed"])
def test_stopped_run_resumes_to_the_same_bits(tmp_path: Path, integrator: str, doc: dict) -> None:
    sc = scenario_from_dict({**doc, "integrator": integrator, "steps": 60_000})  # longer than the first call
    reference = run_scenario(sc, tmp_path / "ref.h5", handle_signals=False)
    first = run_scenario(sc, tmp_path / "out.h5", stop=stop_after(1), handle_signals=False)
    assert first.status == "interrupted" and first.resumable and 0 < first.steps_done < sc.steps
    plan = prepare_resume(tmp_path / "out.h5")
    assert plan.start.checkpoint.state.chaos["megno_updates"][0] == first.steps_done
    second = run_scenario(plan.scenario, plan.output, start=plan.start, handle_signals=False)
    assert second.status == "complete" and second.chaos == reference.chaos
    assert_same_datasets(tmp_path / "ref.h5", tmp_path / "out.h5")
    with h5py.File(tmp_path / "out.h5", "r") as f:
        assert f["megno"].shape == f["mlce"].shape == f["time"].shape == (sc.steps // 500 + 1,)
        assert f["megno"][0] == 0.0 and np.all(np.isfinite(f["megno"][()])) and f["megno"][-1] > 1.0


def test_extension_equals_one_longer_run(tmp_path: Path) -> None:
    run_scenario(scenario_from_dict({**PAIR, "steps": 30_000}), tmp_path / "long.h5", handle_signals=False)
    run_scenario(scenario_from_dict({**PAIR, "steps": 20_000}), tmp_path / "out.h5", handle_signals=False)
    plan = prepare_extension(tmp_path / "out.h5", steps=10_000)
    assert run_scenario(plan.scenario, plan.output, start=plan.start, handle_signals=False).status == "complete"
    assert_same_datasets(tmp_path / "long.h5", tmp_path / "out.h5")


def test_extension_to_a_scheme_without_variational_equations_is_refused(tmp_path: Path) -> None:
    run_scenario(scenario_from_dict(PAIR), tmp_path / "out.h5", handle_signals=False)
    with pytest.raises(ValueError, match="no variational equations"):
        prepare_extension(tmp_path / "out.h5", steps=100, integrator="rk4")


KILLED = """\
name: kill_chaos
integrator: wisdom_holman
dt: 0.01
steps: 300000
output: {every: 4000, checkpoint: {every: 10000}, chaos: {seed: 2}}
bodies:
  - {name: star, m: 1.0, x: [0, 0, 0], v: [0, 0, 0]}
  - {name: b, m: 1.0e-4, primary: star, a: 1.0, e: 0.05}
  - {name: c, m: 1.0e-4, primary: star, a: 1.11, e: 0.02, inc: 1}
  - {name: d, m: 1.0e-5, primary: star, a: 1.6, e: 0.1, inc: 2}
"""


def test_sigkilled_run_resumes_to_the_same_bits(tmp_path: Path) -> None:
    """A real process (~1.3 s of stepping) killed with SIGKILL past a checkpoint, then `orbitsim resume`."""
    scenario = tmp_path / "kill.yaml"
    scenario.write_text(KILLED, encoding="utf-8")
    reference = tmp_path / "ref.h5"
    assert run_scenario(load_scenario(scenario), reference, handle_signals=False).status == "complete"
    out = tmp_path / "out.h5"
    code = run_and_kill(orbitsim("run", str(scenario), "-o", str(out), "-q"), Path(f"{out}.ckpt"), 50_000, 0.01)
    assert code is None and not out.exists(), "the run finished before it was killed"
    final = subprocess.run(orbitsim("resume", str(out)), capture_output=True, text=True, timeout=300)
    assert final.returncode == 0, final.stderr
    assert "MEGNO = " in final.stdout and "Lyapunov time = " in final.stdout
    with h5py.File(out, "r") as f:
        assert f["megno"][-1] > 20.0  # chaotic (two 1e-4 planets 3.5 mutual Hill radii apart): the tangent grows
    assert_same_datasets(reference, out)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["kill.yaml", "out.h5", "ref.h5"]


def test_summary_line_and_info_report_megno_and_the_lyapunov_time(tmp_path: Path) -> None:
    doc = {**PAIR, "units": "au-yr-msun", "dt": 0.001, "steps": 4000, "output": {"every": 400, "chaos": {}}}
    path = tmp_path / "pair.yaml"
    import yaml

    path.write_text(yaml.safe_dump(doc), encoding="utf-8")
    out = tmp_path / "pair.h5"
    run = CliRunner().invoke(cli, ["run", str(path), "-o", str(out)])
    assert run.exit_code == 0, run.output
    with h5py.File(out, "r") as f:
        megno, mlce, last = float(f["megno"][-1]), float(f["mlce"][-1]), float(f["time"][-1])
        assert f.attrs["chaos_seed"] == 0
    assert mlce > 0.0
    expected = f"MEGNO = {megno:.6g}, mLCE = {mlce:.3g} /yr, Lyapunov time = {1 / mlce:.3g} yr"
    assert run.stdout.count("\n") == 1 and expected in run.stdout, run.stdout
    info = CliRunner().invoke(cli, ["info", str(out)])
    assert info.exit_code == 0
    line = next(line for line in info.stdout.splitlines() if line.startswith("chaos:"))
    assert expected in line and f"at t = {last:.10g}" in line and "seed 0" in line


def test_run_from_with_another_scheme_continues_the_tangent_vector(tmp_path: Path) -> None:
    run_scenario(scenario_from_dict(PAIR), tmp_path / "out.h5", handle_signals=False)
    with h5py.File(tmp_path / "out.h5", "r") as f:
        before = {name: f["checkpoint/chaos"][name][()] for name in ("dpos", "megno_sums")}
    plan = prepare_extension(tmp_path / "out.h5", steps=2000, integrator="leapfrog4")
    assert plan.start.rebuild and np.array_equal(plan.start.checkpoint.state.chaos["dpos"], before["dpos"])
    assert run_scenario(plan.scenario, plan.output, start=plan.start, handle_signals=False).status == "complete"
    with h5py.File(tmp_path / "out.h5", "r") as f:
        # Not restarted: MEGNO's sums count every step from t = 0 (initial_t, the 7th sum, stays 0).
        assert f["checkpoint/chaos/megno_updates"][0] == PAIR["steps"] + 2000
        assert f["checkpoint/chaos/megno_sums"][6] == 0.0 and f["megno"].shape == (PAIR["steps"] // 500 + 5,)


@pytest.mark.slow  # compiles a chaos run with GR's derivative (~25 s cold)
def test_a_force_whose_derivative_is_built_enters_the_scenario_run(tmp_path: Path) -> None:
    from orbitsim.chaos.state import forces_with_derivatives

    if "gr_potential" not in forces_with_derivatives():
        pytest.skip("gr_potential's derivative is not built here: the scenario is refused (test_chaos_scenario.py)")
    doc = {**PAIR, "steps": 4000, "bodies": [*PAIR["bodies"][:2], {**PAIR["bodies"][2], "a": 1.3}]}
    forced = {**doc, "forces": [{"force": "gr_potential", "source": "star", "c": 100.0}]}
    megno = []
    for name, document in (("plain", doc), ("forced", forced)):
        assert run_scenario(scenario_from_dict(document), tmp_path / f"{name}.h5", handle_signals=False).chaos
        with h5py.File(tmp_path / f"{name}.h5", "r") as f:
            megno.append(f["megno"][()])
    assert np.all(np.isfinite(megno[1])) and not np.array_equal(megno[0], megno[1])  # a run of the forced system


IAS15_PAIR = {**{k: v for k, v in PAIR.items() if k != "steps"}, "integrator": "ias15", "dt": 0.01, "t_end": 200.0,
              "output": {"interval": 5.0, "chaos": {"seed": 4}, "checkpoint": {"every": 4}}}


def test_an_ias15_scenario_run_is_chaos_run_and_extends_to_the_same_bits(tmp_path: Path) -> None:
    # IAS15's tangent record is its own (its tangent polynomial): the trace and the checkpoints carry it
    sc = scenario_from_dict(IAS15_PAIR)
    reference = run_scenario(sc, tmp_path / "ref.h5", handle_signals=False)
    assert reference.status == "complete"
    # chaos_run's dt for IAS15 is the output grid (the scenario's interval); the scenario's dt its first trial step
    direct = chaos_run(sc.masses, sc.positions, sc.velocities, integrator="ias15", dt=sc.grid_dt, steps=40,
                       every=1, settings=sc.run_settings, seed=sc.chaos.seed)
    with h5py.File(tmp_path / "ref.h5", "r") as f:
        assert f["megno"][()].tobytes() == direct.megno.tobytes()  # the same kernel, the same bits
        assert f["mlce"][()].tobytes() == direct.mlce.tobytes()
    # run half, then extend from its checkpoint: the tangent record (IAS15's own) and MEGNO's sums carry on
    half = scenario_from_dict({**IAS15_PAIR, "t_end": 100.0})
    assert run_scenario(half, tmp_path / "out.h5", handle_signals=False).status == "complete"
    plan = prepare_extension(tmp_path / "out.h5", t_end=200.0)
    second = run_scenario(plan.scenario, plan.output, start=plan.start, handle_signals=False)
    assert second.status == "complete" and second.chaos == reference.chaos
    assert_same_datasets(tmp_path / "ref.h5", tmp_path / "out.h5")
