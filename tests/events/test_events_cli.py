"""Events through the command line (issue 15): the three cases that opened the issue now report
what happened, and a run's events survive SIGKILL, Ctrl-C and ``run --from`` bit for bit.

The three cases run through click's runner on scenarios written into ``tmp_path``; the kills and
the Ctrl-C go to real processes (``python -m orbitsim``), with the helpers of
``test_checkpoint_kill.py``.
"""

from __future__ import annotations

import signal
import subprocess
import time
from pathlib import Path

import h5py
import numpy as np
import pytest
from click.testing import CliRunner
from test_checkpoint_kill import (
    START_TIMEOUT,
    _checkpoint_step,
    assert_same_datasets,
    datasets,
    orbitsim,
    run_and_kill,
)

from orbitsim.cli.main import cli
from orbitsim.runner import run_scenario
from orbitsim.scenario import load_scenario


def invoke(*args: str) -> tuple[int, str, str]:
    result = CliRunner().invoke(cli, list(args))
    assert "Traceback" not in result.output, result.output
    return result.exit_code, result.stdout, result.stderr


def events_table(path: Path) -> dict[str, np.ndarray]:
    with h5py.File(path, "r") as f:
        return {name: f["events"][name][()] for name in f["events"]}


def kinds(table: dict[str, np.ndarray]) -> list[str]:
    return [k.decode() if isinstance(k, bytes) else k for k in table["kind"]]


# -- 4. the three cases at the top of the issue ---------------------------------------------------

#: The issue's Kozai-Lidov case: the massless planet is ejected (orbitsim logged it at t = 3984 with
#: leapfrog4, after 67 unresolved pericentre passages from t = 3743 on; 0.6 s of stepping).
KOZAI = """\
name: kozai
integrator: leapfrog4
dt: 0.01
t_end: 5000
output: {every: 100, elements: true, primary: star}
events: {escape: {distance: 50}}
bodies:
  - {name: star, m: 1.0, x: [0, 0, 0], v: [0, 0, 0]}
  - {name: planet, m: 0.0, primary: star, a: 1.0, e: 0.0, M: 0}
  - {name: perturber, m: 1.0, primary: star, a: 10.0, e: 0.0, inc: 89.9, M: 0}
"""
#: The issue's comet: e = 0.99 at dt = 0.001 yr jumps over its perihelion (q = 0.01 au, t = 0.5
#: yr) and leaves on a hyperbola; measured: unresolved at t = 0.499, escape at t = 0.943.
COMET = """\
name: comet
units: au-yr-msun
integrator: verlet
dt: 0.001
t_end: 2
output: {every: 10, elements: true}
events: {escape: {distance: 50}}
bodies:
  - {name: sun, m: 1.0, x: [0, 0, 0], v: [0, 0, 0]}
  - {name: comet, m: 0.0, primary: sun, a: 1.0, e: 0.99, M: 180}
"""
#: The issue's head-on collision (two m = 1 at rest at x = -1, 1, dt = 0.001, t = 3), with radii;
#: they touch at t = 2.211.
HEAD_ON = """\
name: head_on
integrator: verlet
dt: 0.001
t_end: 3
output: {{every: 10}}
events: {{collisions: {{detect: line, resolve: {resolve}}}}}
bodies:
  - {{name: a, m: 1.0, x: [-1, 0, 0], v: [0, 0, 0], r: 0.05}}
  - {{name: b, m: 1.0, x: [1, 0, 0], v: [0, 0, 0], r: 0.05}}
"""


def test_kozai_lidov_ejection_is_an_escape_and_the_elements_show_it(tmp_path: Path) -> None:
    scenario = tmp_path / "kozai.yaml"
    scenario.write_text(KOZAI, encoding="utf-8")
    out = tmp_path / "kozai.h5"
    code, stdout, stderr = invoke("run", str(scenario), "-o", str(out))
    assert code == 0, stderr
    assert "1 escape (planet at t = " in stdout and "unresolved step" in stdout
    table = events_table(out)
    escapes = [k for k, kind in enumerate(kinds(table)) if kind == "escape"]
    assert len(escapes) == 1 and table["i"][escapes[0]] == 1 and table["extra"][escapes[0]] > 0
    with h5py.File(out, "r") as f:
        e, t = f["elements/e"][:, 1], f["time"][()]
    assert e[0] < 1e-12 and np.nanmax(e[t <= table["time"][escapes[0]]]) > 1  # hyperbolic about the star


def test_comet_on_a_hyperbola_is_unresolved_then_escapes(tmp_path: Path) -> None:
    scenario = tmp_path / "comet.yaml"
    scenario.write_text(COMET, encoding="utf-8")
    out = tmp_path / "comet.h5"
    code, stdout, stderr = invoke("run", str(scenario), "-o", str(out))
    assert code == 0, stderr
    assert "1 escape (comet at t = " in stdout and "1 unresolved step (comet at t = " in stdout
    table = events_table(out)
    assert kinds(table) == ["unresolved", "escape"]
    assert list(table["i"]) == [1, 1] and table["j"][0] == 0  # the comet, about the Sun
    assert 0 < table["extra"][0] < 0.001  # a suggested dt below the one used
    assert table["time"][0] < table["time"][1]
    with h5py.File(out, "r") as f:
        e = f["elements/e"][:, 1]
    assert e[0] == pytest.approx(0.99, rel=1e-12) and e[-1] > 1


def test_head_on_collision_halts_with_exit_6_or_merges(tmp_path: Path) -> None:
    for resolve, code_wanted, status in (("halt", 6, "halted"), ("merge", 0, "complete")):
        scenario = tmp_path / f"{resolve}.yaml"
        scenario.write_text(HEAD_ON.format(resolve=resolve), encoding="utf-8")
        out = tmp_path / f"{resolve}.h5"
        code, stdout, stderr = invoke("run", str(scenario), "-o", str(out))
        assert code == code_wanted, stderr
        table = events_table(out)
        assert kinds(table) == ["collision"] and (table["i"][0], table["j"][0]) == (0, 1)
        outcome = table["outcome"][0].decode()
        with h5py.File(out, "r") as f:
            assert f.attrs["status"] == status
            removed = f["bodies/removed_step"][()]
            last_positions = f["positions"][-1]
            last_step, steps = int(f["step"][-1]), int(f.attrs["steps_done"])
        if resolve == "halt":
            assert outcome == "halted" and "halted at t = 2.211" in stderr and list(removed) == [-1, -1]
            # docs/trace.md: "the last [sample] being the state it halted in" (2211 is off the every-10 plan)
            assert last_step == steps == 2211
        else:
            assert outcome == "merged" and "merged at t = 2.211" in stdout
            assert list(removed) == [-1, 2211] and np.isnan(last_positions[1]).all()


# -- 5. events survive checkpoints --------------------------------------------------------------

#: A star (r = 0.005), a prograde and a retrograde planet that pass within 0.02 of each other
#: every ~pi (~1570 close encounters in the run), and two massless bodies falling radially into
#: the star, merged at t = 200.1 and t = 2794.9 (caught by ``line``: they cross the star within one
#: step). 5e6 verlet steps: ~4 s; a checkpoint every 1e5 steps.
KILL = """\
name: events_kill
integrator: verlet
dt: 0.001
steps: {steps}
output: {{every: {every}, checkpoint: {{every: 100000}}}}
events:
  collisions: {{detect: line, resolve: merge}}
  encounters: {{distance: 0.05}}
bodies:
  - {{name: star, m: 1.0, x: [0, 0, 0], v: [0, 0, 0], r: 0.005}}
  - {{name: pro, m: 1.0e-6, primary: star, a: 1.0, f: 0, r: 1.0e-4}}
  - {{name: retro, m: 1.0e-6, primary: star, a: 1.02, inc: 180, f: -64.2, r: 1.0e-4}}
  - {{name: early, m: 0.0, x: [31.9, 0, 0], v: [0, 0, 0]}}
  - {{name: late, m: 0.0, x: [0, 185.0, 0], v: [0, 0, 0]}}
"""
KILL_STEPS = 5_000_000
#: Kill after the first checkpoint past these steps: between the merges, and after the second,
#: with 2e6 steps (~1.5 s) to spare, so a poller starved on a busy machine still kills mid-run.
KILL_AT = (1_500_000, 3_000_000)


@pytest.fixture(scope="module")
def kill_reference(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, dict[str, np.ndarray]]:
    """The scenario, its uninterrupted trace (which also warms Numba's cache), its events table."""
    folder = tmp_path_factory.mktemp("events_kill")
    scenario = folder / "events_kill.yaml"
    scenario.write_text(KILL.format(steps=KILL_STEPS, every=2000), encoding="utf-8")
    reference = folder / "reference.h5"
    assert run_scenario(load_scenario(scenario), reference, handle_signals=False).status == "complete"
    table = events_table(reference)
    merges = table["step"][np.array(kinds(table)) == "collision"]
    assert len(merges) == 2 and merges[0] < KILL_AT[0] < merges[1] < KILL_AT[1], merges
    return scenario, reference, table


def steps_done(out: Path) -> int:
    info = subprocess.run(orbitsim("info", str(out)), capture_output=True, text=True, timeout=120)
    assert info.returncode == 0 and "resumable            yes" in info.stdout, info.stdout + info.stderr
    return int(info.stdout.split("steps_done")[1].split()[0])


def assert_events_around(table: dict[str, np.ndarray], step: int) -> None:
    """Something is logged before ``step`` and after it (the kill point)."""
    assert (table["step"] < step).any() and (table["step"] > step).any()


@pytest.mark.slow  # kills TRACE with events repeatedly (~17 s); make test keeps the Ctrl-C case
def test_events_survive_sigkill_and_resume_bit_for_bit(kill_reference: tuple[Path, Path, dict[str, np.ndarray]],
                                                      tmp_path: Path) -> None:
    scenario, reference, table = kill_reference
    out = tmp_path / "killed.h5"
    command = orbitsim("run", str(scenario), "-o", str(out), "-q")
    for at in KILL_AT:
        assert run_and_kill(command, Path(f"{out}.ckpt"), at, 0.01) is None, "finished before the kill"
        assert not out.exists()
        killed_at = steps_done(out)
        assert killed_at >= at
        assert_events_around(table, killed_at)
        command = orbitsim("resume", str(out), "-q")
    final = subprocess.run(command, capture_output=True, text=True, timeout=300)
    assert final.returncode == 0, final.stderr
    assert "events/kind" in datasets(out) and "energy_offset" in datasets(out)
    assert_same_datasets(reference, out)


def test_events_survive_ctrl_c_and_resume_bit_for_bit(kill_reference: tuple[Path, Path, dict[str, np.ndarray]],
                                                      tmp_path: Path) -> None:
    scenario, reference, table = kill_reference
    out = tmp_path / "interrupted.h5"
    checkpoint = Path(f"{out}.ckpt")
    proc = subprocess.Popen(orbitsim("run", str(scenario), "-o", str(out), "-q"), stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + START_TIMEOUT
    while _checkpoint_step(checkpoint) < KILL_AT[0]:
        assert proc.poll() is None, proc.communicate()
        if time.monotonic() > deadline:
            proc.kill()
            pytest.fail("no checkpoint in time")
        time.sleep(0.005)
    proc.send_signal(signal.SIGINT)
    _, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 130, stderr
    assert f"continue with `orbitsim resume {out}`" in stderr
    assert_events_around(table, steps_done(out))
    resumed = subprocess.run(orbitsim("resume", str(out), "-q"), capture_output=True, text=True, timeout=300)
    assert resumed.returncode == 0, resumed.stderr
    assert_same_datasets(reference, out)


def test_run_from_gives_the_events_of_one_longer_run(tmp_path: Path) -> None:
    """A run cut in the middle of a close encounter, after the first merge, then extended with
    ``run --from``: every dataset (the events table included) is that of one run. The encounter
    open at the cut is marked ``open`` in the first trace and logged once, whole, in the second."""
    total, every = 300_000, 20
    scenario = tmp_path / "short.yaml"
    scenario.write_text(KILL.format(steps=total, every=every), encoding="utf-8")
    assert invoke("run", str(scenario), "-o", str(tmp_path / "long.h5"), "-q")[0] == 0
    table = events_table(tmp_path / "long.h5")
    merge = int(table["step"][kinds(table).index("collision")])
    episodes = [(int(s0), int(s1)) for kind, s0, s1 in zip(kinds(table), table["step_start"], table["step"],
                                                           strict=True) if kind == "encounter" and s0 > merge]
    start, stop = episodes[0]
    cut = (start + stop) // 2 // every * every
    assert start <= cut < stop, (start, stop)
    out = tmp_path / "out.h5"
    assert invoke("run", str(scenario), "-o", str(out), "--steps", str(cut), "-q")[0] == 0
    first = events_table(out)
    assert "open" in [o.decode() for o in first["outcome"]]
    code, stdout, stderr = invoke("run", "--from", str(out), "--steps", str(total - cut))
    assert code == 0 and f"{total} of {total} steps" in stdout, stderr
    assert_same_datasets(tmp_path / "long.h5", out)


#: Two bodies on a parabolic orbit: E0 = 1.1e-16 (round-off), so energy_error is relative to
#: T0 + |U0| = 1, not to |E0| (the issue's "energy error when E0 is near zero").
PARABOLIC = """\
name: parabolic
integrator: verlet
dt: 0.0001
steps: 200000
output: {every: 1000}
bodies:
  - {name: a, m: 1.0, x: [-1, 0, 0], v: [0, -0.7071067811865476, 0]}
  - {name: b, m: 1.0, x: [1, 0, 0], v: [0, 0.7071067811865476, 0]}
"""


def test_energy_error_scale_survives_run_from(tmp_path: Path) -> None:
    """An extended run reports the max |dE/E| of one longer run: the checkpoint it continues from
    must carry the energy scale, or the continuation divides by |E0| ~ 1e-16. Measured: 1.68e-10
    for the long run."""
    scenario = tmp_path / "parabolic.yaml"
    scenario.write_text(PARABOLIC, encoding="utf-8")
    code, long_out, err = invoke("run", str(scenario), "-o", str(tmp_path / "long.h5"), "--steps", "400000")
    assert code == 0, err
    with h5py.File(tmp_path / "long.h5", "r") as f:
        assert abs(f.attrs["E0"]) < 1e-15 and f.attrs["energy_scale"] == 1.0
    assert invoke("run", str(scenario), "-o", str(tmp_path / "out.h5"), "-q")[0] == 0
    code, out, err = invoke("run", "--from", str(tmp_path / "out.h5"), "--steps", "200000")
    assert code == 0, err

    def max_error(summary: str) -> str:
        return summary.split("max |dE/E| = ")[1].split(",")[0]

    assert max_error(out) == max_error(long_out)
    assert_same_datasets(tmp_path / "long.h5", tmp_path / "out.h5")
    with h5py.File(tmp_path / "out.h5", "r") as f:
        assert f["checkpoint"].attrs["energy_scale"] == f.attrs["energy_scale"]


def test_a_departing_binary_is_not_an_escape_per_orbit(tmp_path: Path) -> None:
    """Pythagorean (ias15): m3 leaves and the 4-5 binary recoils the other way. Judged alone, a
    binary member's orbital speed swings its energy relative to the rest above and below zero
    once an orbit; judged with its partner (the pair's centre of mass), each body escapes at most
    once (measured: m3 at t = 61.2, m5 and m4 at 66.3 and 66.4; judged alone, m4 and m5 escaped
    again every binary orbit, 0.85 time units, five times each by t = 70)."""
    import yaml

    from orbitsim.scenario import config_dir

    doc = yaml.safe_load((config_dir() / "pythagorean.yaml").read_text(encoding="utf-8"))
    doc["events"] = {"escape": {"distance": 5.0}}
    scenario = tmp_path / "pyth.yaml"
    scenario.write_text(yaml.safe_dump(doc), encoding="utf-8")
    out = tmp_path / "pyth.h5"
    code, _, stderr = invoke("run", str(scenario), "-o", str(out))
    assert code == 0, stderr
    table = events_table(out)
    escaped = [int(i) for i, kind in zip(table["i"], kinds(table), strict=True) if kind == "escape"]
    assert escaped.count(0) == 1 and max(escaped.count(1), escaped.count(2)) <= 1, escaped
