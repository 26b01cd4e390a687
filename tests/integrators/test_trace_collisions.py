"""TRACE's collisions inside close encounters, through ``orbitsim run``: REBOUND's own collision
tests (rebound/tests/test_trace.py) on their exact initial states, and what a user sees."""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

from orbitsim.cli.main import cli

#: REBOUND's test_simple_collision: p2 (m = 1e-8) on an e = 0.4 orbit hits p1 (m = 1e-5) at
#: t = 0.56, inside an encounter. The states are REBOUND 5.2.2's from its orbital elements.
SIMPLE = """\
name: simple_collision
integrator: trace
dt: 0.01
steps: 100
output: {{every: 1}}
events:
  collisions: {{detect: {detect}, resolve: {resolve}}}
  unresolved: false
bodies:
  - {{name: star, m: 1.0, x: [0.0, 0.0, 0.0], v: [0.0, 0.0, 0.0]}}
  - {{name: p1, m: 1.0e-05, r: 0.00016, x: [0.44999999999999996, 0.0, 0.0], v: [0.0, 1.5634797372812, 0.0]}}
  - {{name: p2, m: 1.0e-08, r: 4.0e-05, x: [0.22047437147767954, -0.30187495012979704, 0.0],
      v: [1.1881053832166133, 1.4562235287762688, 0.0]}}
"""
SIMPLE_STATE = ((1.0, 0.0, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)),
                (1e-05, 0.00016, (0.44999999999999996, 0.0, 0.0), (0.0, 1.5634797372812, 0.0)),
                (1e-08, 4e-05, (0.22047437147767954, -0.30187495012979704, 0.0),
                 (1.1881053832166133, 1.4562235287762688, 0.0)))
#: REBOUND's test_collision_with_star: body 2 falls into the star (r = 0.00465) from x = 1.
WITH_STAR = """\
name: collision_with_star
integrator: trace
dt: 0.01
steps: 100
output: {every: 1}
events:
  collisions: {detect: direct, resolve: merge}
  unresolved: false
bodies:
  - {name: star, m: 1.0, r: 0.00465, x: [0.0, 0.0, 0.0], v: [0.0, 0.0, 0.0]}
  - {name: p1, m: 1.0e-05, r: 0.00016, x: [-0.3533494576070969, 0.3954735332532194, 0.0],
     v: [-1.0599045356575272, -0.804873713617475, 0.0]}
  - {name: faller, m: 0.0001, r: 0.0014, x: [1.0, 0.0, 0.0], v: [-0.4, 0.0, 0.0]}
  - {name: p3, m: 1.0e-05, r: 0.00016, x: [1.3500964558952753, 3.95430035949265e-06, 0.0],
     v: [-5.059348007376716e-05, 0.9027170446278884, 0.0]}
"""
WITH_STAR_STATE = ((1.0, 0.00465, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)),
                   (1e-05, 0.00016, (-0.3533494576070969, 0.3954735332532194, 0.0),
                    (-1.0599045356575272, -0.804873713617475, 0.0)),
                   (0.0001, 0.0014, (1.0, 0.0, 0.0), (-0.4, 0.0, 0.0)),
                   (1e-05, 0.00016, (1.3500964558952753, 3.95430035949265e-06, 0.0),
                    (-5.059348007376716e-05, 0.9027170446278884, 0.0)))


def run(tmp_path: Path, text: str, name: str) -> tuple[int, str, Path]:
    scenario = tmp_path / f"{name}.yaml"
    scenario.write_text(text, encoding="utf-8")
    out = tmp_path / f"{name}.h5"
    result = CliRunner().invoke(cli, ["run", str(scenario), "-o", str(out)])
    assert "Traceback" not in result.output, result.output
    return result.exit_code, result.output, out


def read(out: Path) -> dict[str, np.ndarray]:
    with h5py.File(out, "r") as f:
        data = {name: f[name][()] for name in ("positions", "velocities", "energy_error", "energy_offset", "time")}
        data.update({f"bodies/{k}": f["bodies"][k][()] for k in f["bodies"]})
        data.update({f"events/{k}": f["events"][k][()] for k in f["events"]})
    return data


def com_velocity(masses: np.ndarray, vel: np.ndarray) -> np.ndarray:
    alive = ~np.isnan(vel[:, 0])
    return (masses[alive, None] * vel[alive]).sum(axis=0) / masses[alive].sum()


def test_planet_planet_merge_meets_rebounds_bounds(tmp_path: Path) -> None:
    """REBOUND's bounds: N - 1 bodies, the mass bit-exact, the centre-of-mass velocity within
    1e-16, |dE/E| of E + offset < 3e-9 (measured 1.3e-9; REBOUND 1.2e-9)."""
    code, output, out = run(tmp_path, SIMPLE.format(detect="direct", resolve="merge"), "merge")
    assert code == 0, output
    assert "1 collision (p1 and p2, merged at t = 0.56" in output
    d = read(out)
    assert np.all(np.isnan(d["positions"][-1, 2])) and not np.any(np.isnan(d["positions"][-1, :2]))
    final = d["bodies/final_masses"]
    assert final[1] == 1e-05 + 1e-08  # one addition: bit-exact
    assert d["bodies/merged_into"].tolist() == [-1, -1, 1]
    v0 = com_velocity(d["bodies/masses"], d["velocities"][0])
    v1 = com_velocity(final, d["velocities"][-1])  # the merged body's NaN row drops out
    assert np.max(np.abs(v1 - v0)) < 1e-16  # REBOUND's own bound: momentum is conserved by the merge
    assert np.max(np.abs(d["energy_error"])) < 3e-9
    assert d["energy_offset"][-1] > 0.0  # the merge is inelastic: energy leaves the orbits
    # The merge happened inside a step, at an accepted BS sub-step's end, not on the step grid.
    t_hit = d["events/time"][0]
    assert 0.56 < t_hit < 0.57 and abs(t_hit / 0.01 - round(t_hit / 0.01)) > 1e-6


@pytest.mark.skipif(pytest.importorskip("rebound").__version__ != "5.2.2", reason="bitwise parity is with 5.2.2")
@pytest.mark.parametrize("case", ["planets", "star"])
def test_merge_is_rebounds_bit_for_bit_step_by_step(tmp_path: Path, case: str) -> None:
    """Every step, before and after the merge, equals REBOUND's TRACE with direct detection and
    merging; the energy offsets agree to 1e-6 relative (orbitsim also counts the change of the
    third bodies' potential energy with the pair, ~8e-16 for the planets, which REBOUND leaves out)."""
    import rebound

    text, state = ((SIMPLE.format(detect="direct", resolve="merge"), SIMPLE_STATE) if case == "planets"
                   else (WITH_STAR, WITH_STAR_STATE))
    code, output, out = run(tmp_path, text, case)
    assert code == 0, output
    d = read(out)
    sim = rebound.Simulation()
    for m, r, x, v in state:
        sim.add(m=m, r=r, x=x[0], y=x[1], z=x[2], vx=v[0], vy=v[1], vz=v[2])
    sim.integrator, sim.dt = "trace", 0.01
    sim.track_energy_offset, sim.collision, sim.collision_resolve = 1, "direct", "merge"
    for k in range(1, 101):
        sim.steps(1)
        alive = ~np.isnan(d["positions"][k, :, 0])
        assert sim.N == alive.sum()
        assert np.array_equal(d["positions"][k, alive], [[p.x, p.y, p.z] for p in sim.particles]), k
        assert np.array_equal(d["velocities"][k, alive], [[p.vx, p.vy, p.vz] for p in sim.particles]), k
    assert sim.N == len(state) - 1
    assert d["energy_offset"][-1] == pytest.approx(sim.energy_offset, rel=1e-6)


def test_line_detection_merges_the_same_pair(tmp_path: Path) -> None:
    code, output, _ = run(tmp_path, SIMPLE.format(detect="line", resolve="merge"), "line")
    assert code == 0, output
    assert "1 collision (p1 and p2, merged at t = 0.56" in output


def test_halt_inside_an_encounter_stops_after_that_step_with_exit_6(tmp_path: Path) -> None:
    """The contact is found inside the step; the run ends on the step grid just after it, with
    the bodies unmerged, and says so in one line."""
    code, output, out = run(tmp_path, SIMPLE.format(detect="direct", resolve="halt"), "halt")
    assert code == 6, output
    assert "halted" in output and "p1 and p2" in output
    d = read(out)
    assert d["time"][-1] == pytest.approx(0.57, abs=1e-12) and not np.any(np.isnan(d["positions"][-1]))
    assert [o.decode() if isinstance(o, bytes) else o for o in d["events/outcome"]] == ["halted"]


def test_log_records_the_contact_once(tmp_path: Path) -> None:
    """With ``resolve: log`` the bodies pass through each other (BS follows them: point masses
    1e-4 apart); the contact is one event, not one per sub-step or per step."""
    code, output, out = run(tmp_path, SIMPLE.format(detect="direct", resolve="log"), "log")
    assert code == 0, output
    d = read(out)
    kinds = [k.decode() if isinstance(k, bytes) else k for k in d["events/kind"]]
    assert kinds.count("collision") == 1


def test_a_body_falling_into_the_star_merges_with_it(tmp_path: Path) -> None:
    """REBOUND's bounds: N - 1, the mass exact, the centre-of-mass velocity, |dE/E| < 5e-2
    (REBOUND measures 1.4e-5; the star's radius makes the falling body an encounter with the star,
    so the contact is found inside the BS sub-steps)."""
    code, output, out = run(tmp_path, WITH_STAR, "star")
    assert code == 0, output
    assert "faller" in output and "merged" in output
    d = read(out)
    final = d["bodies/final_masses"]
    assert final[0] == 1.0 + 0.0001
    assert d["bodies/merged_into"].tolist() == [-1, -1, 0, -1]
    v0 = com_velocity(d["bodies/masses"], d["velocities"][0])
    v1 = com_velocity(final, d["velocities"][-1])
    assert np.max(np.abs(v1 - v0)) < 1e-16
    assert np.max(np.abs(d["energy_error"])) < 5e-2


def test_extending_a_run_across_or_after_the_merge_is_bit_identical(tmp_path: Path) -> None:
    """40 + 60 steps (the merge falls in the extension) and 60 + 40 (the merged system is what
    the checkpoint holds) end on the same bits and the same energy offset as 100 straight."""
    text = SIMPLE.format(detect="direct", resolve="merge")
    code, output, straight = run(tmp_path, text, "straight")
    assert code == 0, output
    with h5py.File(straight, "r") as f:
        want = f["positions"][-1], f["velocities"][-1], f["energy_offset"][-1]
    for first in (40, 60):
        code, output, part = run(tmp_path, text.replace("steps: 100", f"steps: {first}"), f"part{first}")
        assert code == 0, output
        out = tmp_path / f"extended{first}.h5"
        result = CliRunner().invoke(cli, ["run", "--from", str(part), "--steps", str(100 - first), "-o", str(out)])
        assert result.exit_code == 0, result.output
        with h5py.File(out, "r") as f:
            got = f["positions"][-1], f["velocities"][-1], f["energy_offset"][-1]
            assert f["events"]["time"].shape == (1,)
        assert np.array_equal(got[0], want[0], equal_nan=True) and np.array_equal(got[1], want[1], equal_nan=True)
        assert got[2] == want[2]
