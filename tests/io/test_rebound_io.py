"""REBOUND files in: ``bodies: {rebound: FILE}`` in a scenario and ``orbitsim run sim.bin``.

The acceptance case: REBOUND's outer Solar System (the DE421 state of ``test_rebound_agreement``)
saved with ``sim.save_to_file``, loaded by orbitsim and run with ``leapfrog`` for 1000 steps, agrees
with REBOUND's ``leapfrog`` run from the same file to 1e-12 relative in every position.
"""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from click.testing import CliRunner
from test_rebound_agreement import G_GAUSS, OUTER_SOLAR_SYSTEM

from orbitsim.cli.main import cli
from orbitsim.io.trace import read_trace
from orbitsim.runner import run_scenario
from orbitsim.scenario import ScenarioError, load_scenario

rebound = pytest.importorskip("rebound")

STEPS = 1000
#: Same scheme and coefficients from the same bits: the codes differ only in how the force sums
#: round (orbitsim reassociates its j-sum), ~1e-16 per step, grown to below 1e-13 after 1000 steps of
#: 10 days (measured); 1e-12 is the issue's bound and leaves a factor > 10 of margin.
AGREEMENT = 1e-12


def save_outer_solar_system(path: Path, integrator: str = "leapfrog", dt: float = 10.0) -> None:
    sim = rebound.Simulation()
    sim.G = G_GAUSS
    for _, m, x, v in OUTER_SOLAR_SYSTEM:
        sim.add(m=m, x=x[0], y=x[1], z=x[2], vx=v[0], vy=v[1], vz=v[2])
    sim.integrator = integrator
    sim.dt = dt
    sim.save_to_file(str(path))


def write_scenario(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "scenario.yaml"
    path.write_text(text, encoding="utf-8")
    return path


def test_outer_solar_system_matches_rebound_leapfrog(tmp_path: Path) -> None:
    save_outer_solar_system(tmp_path / "oss.bin")
    names = [body[0] for body in OUTER_SOLAR_SYSTEM]
    scenario = load_scenario(write_scenario(tmp_path, f"bodies: {{rebound: oss.bin, names: {names}}}\n"
                                                      f"steps: {STEPS}\noutput: {{every: {STEPS}}}\n"))
    assert scenario.integrator == "leapfrog" and scenario.dt == 10.0 and scenario.G == G_GAUSS
    assert scenario.names == tuple(names)
    run_scenario(scenario, tmp_path / "oss.h5")
    ours = read_trace(tmp_path / "oss.h5").positions[-1]
    sim = rebound.Simulation(str(tmp_path / "oss.bin"))
    assert str(sim.integrator) == "leapfrog"
    sim.steps(STEPS)
    theirs = np.array([[p.x, p.y, p.z] for p in sim.particles])
    rel = np.linalg.norm(ours - theirs, axis=1) / np.linalg.norm(theirs, axis=1)
    assert rel.max() < AGREEMENT, rel
    assert rel.max() > 0.0 or np.array_equal(ours, theirs)


def test_state_is_read_bit_for_bit(tmp_path: Path) -> None:
    save_outer_solar_system(tmp_path / "oss.bin", integrator="whfast", dt=5.0)
    scenario = load_scenario(write_scenario(tmp_path, "bodies: {rebound: oss.bin}\nsteps: 1\n"))
    assert np.array_equal(scenario.masses, [body[1] for body in OUTER_SOLAR_SYSTEM])
    assert np.array_equal(scenario.positions, [body[2] for body in OUTER_SOLAR_SYSTEM])
    assert np.array_equal(scenario.velocities, [body[3] for body in OUTER_SOLAR_SYSTEM])
    assert scenario.integrator == "wisdom_holman"
    assert scenario.integrator_settings["coordinates"] == "jacobi"
    assert scenario.names[0] == "p0"


def test_archive_snapshot_and_radii(tmp_path: Path) -> None:
    path = tmp_path / "archive.bin"
    sim = rebound.Simulation()
    sim.add(m=1.0, r=0.005)
    sim.add(m=1e-3, a=1.0, e=0.1, r=0.001)
    sim.integrator, sim.dt = "leapfrog", 0.01
    sim.save_to_file(str(path))
    first = sim.particles[1].x
    sim.integrate(1.0)
    sim.save_to_file(str(path))  # appends: a Simulationarchive of two snapshots
    scenario = load_scenario(write_scenario(tmp_path, "bodies: {rebound: archive.bin, snapshot: 0}\nsteps: 1\n"))
    assert scenario.positions[1, 0] == first
    assert list(scenario.radii) == [0.005, 0.001]
    last = load_scenario(write_scenario(tmp_path, "bodies: {rebound: archive.bin}\nsteps: 1\n"))
    assert last.positions[1, 0] == sim.particles[1].x != first
    assert "REBOUND t = 1.0" in last.description


@pytest.mark.parametrize(("text", "key", "words"), [
    ("bodies: {rebound: missing.bin}\nsteps: 1\n", "bodies.rebound", "missing.bin: no such file"),
    ("bodies: {rebound: junk.bin}\nsteps: 1\n", "bodies.rebound", "not a REBOUND simulation file"),
    ("bodies: {rebound: ok.bin, snapshot: 2}\nsteps: 1\n", "bodies.snapshot", "holds 1 snapshot"),
    ("bodies: {rebound: ok.bin, names: [a]}\nsteps: 1\n", "bodies.names", "list of 6 names"),
    ("bodies: {rebound: ok.bin, colour: red}\nsteps: 1\n", "bodies.colour", "unknown key"),
    ("bodies: {rebound: saba.bin}\nsteps: 1\n", "bodies.rebound", "'saba' has no orbitsim counterpart"),
])
def test_errors_name_the_file_and_key(tmp_path: Path, text: str, key: str, words: str) -> None:
    (tmp_path / "junk.bin").write_bytes(b"not a simulation")
    save_outer_solar_system(tmp_path / "ok.bin")
    save_outer_solar_system(tmp_path / "saba.bin", integrator="saba")
    with pytest.raises(ScenarioError) as info:
        load_scenario(write_scenario(tmp_path, text))
    assert info.value.key == key and words in str(info.value) and "scenario.yaml" in str(info.value)
    assert "\n" not in str(info.value)


def test_an_unmapped_integrator_is_fine_when_the_scenario_names_one(tmp_path: Path) -> None:
    save_outer_solar_system(tmp_path / "saba.bin", integrator="saba")
    scenario = load_scenario(write_scenario(tmp_path, "bodies: {rebound: saba.bin}\nintegrator: leapfrog4\n"
                                                      "dt: 2.5\nsteps: 1\n"))
    assert (scenario.integrator, scenario.dt) == ("leapfrog4", 2.5)


def test_cli_runs_a_rebound_file(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    save_outer_solar_system(tmp_path / "oss.bin", integrator="ias15")
    result = CliRunner().invoke(cli, ["run", "oss.bin", "--t-end", "100", "-o", "oss.h5", "-q"])
    assert result.exit_code == 0, result.output
    trace = read_trace("oss.h5")
    assert trace.attrs["integrator"] == "ias15" and trace.time[-1] == 100.0
    result = CliRunner().invoke(cli, ["run", "oss.bin", "-o", "again.h5"])
    assert result.exit_code == 2 and "give --steps N or --t-end T" in result.output
    assert not Path("again.h5").exists()
    save_outer_solar_system(tmp_path / "saba.bin", integrator="saba")
    result = CliRunner().invoke(cli, ["run", "saba.bin", "--steps", "3", "-o", "saba.h5"])
    assert result.exit_code == 2 and "'saba' has no orbitsim counterpart" in result.output
    assert len(result.output.strip().splitlines()) == 1


# -- unsynchronised snapshots (safe_mode = 0) ----------------------------------------------------

#: The issue's archive: a star, a 1 au planet and an outer one in au, yr, M_sun, WHFast with
#: safe_mode = 0 and corrector 11, a snapshot every 2 yr. dt = 0.04 yr: the owed half drift then
#: moves the 1 au planet by ~0.13 au.
G_YEAR = 4.0 * np.pi**2
WH_DT = 0.04
CONTINUATION_STEPS = 50
#: orbitsim continues from REBOUND's synchronised state (corrector, then dt/2 and dt drifts) where
#: REBOUND continues from its own coordinates (one merged dt drift): the two agree to round-off,
#: measured 3e-14 au after 50 steps of corrector 11 (both codes are the same map); 1e-12 is the
#: issue's bound.
CONTINUATION_AGREEMENT = 1e-12


def save_unsynchronised(path: Path, integrator: str = "whfast", **config: Any) -> None:
    """A Simulationarchive of REBOUND's ``integrator`` with ``safe_mode = 0`` (where it has one):
    snapshots every 2 yr to t = 7 yr, those at ~2, 4, 6 yr taken between steps, unsynchronised."""
    sim = rebound.Simulation()
    sim.G = G_YEAR
    sim.add(m=1.0)
    sim.add(m=1e-3, a=1.0, e=0.05)
    sim.add(m=3e-4, a=1.9, e=0.1, inc=0.05)
    sim.move_to_com()
    sim.integrator = integrator
    fields = {fd.name.decode() for fd in sim.integrator.callbacks.field_descriptor_list}
    if "safe_mode" in fields:
        sim.integrator.safe_mode = 0
    for key, value in config.items():
        setattr(sim.integrator, key, value)
    sim.dt = WH_DT
    sim.save_to_file(str(path), interval=2.0, delete_file=True)
    sim.integrate(7.0, exact_finish_time=0)


def archive_snapshot(path: Path, index: int) -> Any:
    with warnings.catch_warnings():  # "The simulation might not be synchronized": that is the point
        warnings.simplefilter("ignore", RuntimeWarning)
        return rebound.Simulationarchive(str(path))[index]


def particle_state(sim: Any) -> tuple[np.ndarray, np.ndarray]:
    x, v = np.zeros((sim.N, 3)), np.zeros((sim.N, 3))
    sim.serialize_particle_data(xyz=x, vxvyvz=v)
    return x, v


def test_an_unsynchronised_whfast_snapshot_is_read_as_rebound_synchronises_it(tmp_path: Path) -> None:
    save_unsynchronised(tmp_path / "wh.bin", corrector=11)
    raw = archive_snapshot(tmp_path / "wh.bin", 1)
    assert raw.is_synchronized == 0 and raw.integrator.safe_mode == 0  # the file is what the test is about
    raw_x, _ = particle_state(raw)
    synced = archive_snapshot(tmp_path / "wh.bin", 1)
    synced.synchronize()
    sync_x, sync_v = particle_state(synced)
    assert np.linalg.norm(raw_x[1] - sync_x[1]) > 0.1  # what was read before: 0.13 au off

    scenario = load_scenario(write_scenario(tmp_path, f"bodies: {{rebound: wh.bin, snapshot: 1}}\n"
                                                      f"steps: {CONTINUATION_STEPS}\n"
                                                      f"output: {{every: {CONTINUATION_STEPS}}}\n"))
    assert np.array_equal(scenario.positions, sync_x) and np.array_equal(scenario.velocities, sync_v)
    assert scenario.integrator_settings == {"coordinates": "jacobi", "corrector": 11}
    assert scenario.t_start == raw.t

    run_scenario(scenario, tmp_path / "wh.h5")
    ours = read_trace(tmp_path / "wh.h5").positions[-1]
    theirs_sim = archive_snapshot(tmp_path / "wh.bin", 1)  # REBOUND goes on from its own coordinates...
    theirs_sim.steps(CONTINUATION_STEPS)
    theirs_sim.synchronize()  # ...and reports the synchronised state
    theirs, _ = particle_state(theirs_sim)
    assert np.max(np.abs(ours - theirs)) < CONTINUATION_AGREEMENT


@pytest.mark.parametrize(("integrator", "config"), [
    ("whfast", {"coordinates": "democraticheliocentric"}),
    ("whfast", {"keep_unsynchronized": 1}),  # is_synchronized stays 0 after synchronize() unless cleared
    ("saba", {}),
    ("mercurius", {}),
    ("eos", {}),
    ("trace", {}),  # REBOUND 5.2.2's TRACE has no safe_mode: always synchronised, read as saved
    ("leapfrog", {}),
])
def test_every_snapshot_is_read_as_rebound_synchronises_it(tmp_path: Path, integrator: str,
                                                           config: dict[str, Any]) -> None:
    save_unsynchronised(tmp_path / "sim.bin", integrator, **config)
    synced = archive_snapshot(tmp_path / "sim.bin", 2)
    if "keep_unsynchronized" in config:
        synced.integrator.keep_unsynchronized = 0  # REBOUND's synchronize() then updates the particles for good
    synced.synchronize()
    x, v = particle_state(synced)
    text = "bodies: {rebound: sim.bin, snapshot: 2}\nsteps: 1\n"
    if integrator in ("saba", "mercurius", "eos"):  # no orbitsim counterpart: the scenario names one
        text += "integrator: leapfrog\n"
    scenario = load_scenario(write_scenario(tmp_path, text))
    assert np.array_equal(scenario.positions, x) and np.array_equal(scenario.velocities, v)


def test_a_snapshot_rebound_cannot_synchronise_is_refused_in_one_line(tmp_path: Path,
                                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    save_unsynchronised(tmp_path / "wh.bin", corrector=11)
    monkeypatch.setattr(rebound.Simulation, "synchronize", lambda self: None)  # a REBOUND that leaves it so
    with pytest.raises(ScenarioError) as info:
        load_scenario(write_scenario(tmp_path, "bodies: {rebound: wh.bin, snapshot: 1}\nsteps: 1\n"))
    assert info.value.key == "bodies.snapshot" and "\n" not in str(info.value)
    assert "wh.bin: snapshot 1 was saved unsynchronised (REBOUND whfast with safe_mode = 0)" in str(info.value)
    monkeypatch.chdir(tmp_path)
    result = CliRunner().invoke(cli, ["run", "wh.bin", "--steps", "3", "-o", "wh.h5"])
    assert result.exit_code == 2 and "saved unsynchronised (REBOUND whfast with safe_mode = 0)" in result.output
    assert len(result.output.strip().splitlines()) == 1 and not Path("wh.h5").exists()
