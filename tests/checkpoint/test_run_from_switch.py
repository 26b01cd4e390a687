"""``orbitsim run --from TRACE --integrator NAME --dt DT``: a finished run continued with a new scheme or step."""

from __future__ import annotations

import json
from pathlib import Path

import h5py
import numpy as np
import pytest
from click.testing import CliRunner
from test_checkpoint_kill import assert_same_datasets

from orbitsim.cli.main import cli
from orbitsim.scenario import load_scenario
from orbitsim.simulation import simulate

# Sun and two planets: Wisdom-Holman's Jacobi work is then more than a copy of the inertial state.
SYSTEM = """\
name: sys3
integrator: {integrator}
dt: 0.01
steps: 100
output: {{every: 10, positions: true}}
bodies:
  - {{name: star, m: 1.0, x: [0, 0, 0], v: [0, 0, 0]}}
  - {{name: b, m: 1.0e-3, x: [1, 0, 0], v: [0, 1, 0]}}
  - {{name: c, m: 3.0e-4, x: [0, 2.2, 0.1], v: [-0.68, 0, 0]}}
"""


def invoke(*args: str) -> tuple[int, str, str]:
    result = CliRunner().invoke(cli, list(args))
    assert "Traceback" not in result.output
    return result.exit_code, result.stdout, result.stderr


def write(tmp_path: Path, integrator: str) -> Path:
    path = tmp_path / f"{integrator}.yaml"
    path.write_text(SYSTEM.format(integrator=integrator), encoding="utf-8")
    return path


def read(path: Path) -> tuple[dict, dict]:
    with h5py.File(path) as f:
        return dict(f.attrs), {k: f[k][()] for k in ("step", "time", "positions", "velocities")}


def test_same_integrator_and_dt_is_one_longer_run(tmp_path: Path) -> None:
    scenario = write(tmp_path, "verlet")
    assert invoke("run", str(scenario), "-o", str(tmp_path / "long.h5"), "--steps", "150", "-q")[0] == 0
    assert invoke("run", str(scenario), "-o", str(tmp_path / "out.h5"), "-q")[0] == 0
    code, _, err = invoke("run", "--from", str(tmp_path / "out.h5"), "--steps", "50", "--integrator", "kdk",
                          "--dt", "0.01", "-q")
    assert code == 0, err
    assert_same_datasets(tmp_path / "long.h5", tmp_path / "out.h5")
    assert "integrator_history" not in read(tmp_path / "out.h5")[0]


@pytest.mark.parametrize(("old", "new"), [("verlet", "leapfrog4"), ("leapfrog", "wisdom_holman"),
                                          ("wisdom_holman", "leapfrog6")])
def test_switch_is_a_new_run_of_the_new_scheme_from_the_state_at_the_switch(tmp_path: Path, old: str,
                                                                             new: str) -> None:
    scenario = write(tmp_path, old)
    out = tmp_path / "out.h5"
    assert invoke("run", str(scenario), "-o", str(out), "-q")[0] == 0
    code, _, err = invoke("run", "--from", str(out), "--integrator", new, "--steps", "60", "-q")
    assert code == 0, err
    attrs, data = read(out)
    at = int(np.flatnonzero(data["step"] == 100)[0])
    sc = load_scenario(str(scenario))
    fresh = simulate(sc.masses, data["positions"][at], data["velocities"][at], integrator=new, dt=sc.dt, steps=60,
                     every=10, G=sc.G, softening=sc.softening)
    # Bit for bit: the new scheme starts from the inertial state exactly as a new run does.
    assert np.array_equal(data["positions"][at:], fresh.positions)
    assert np.array_equal(data["velocities"][at:], fresh.velocities)
    assert list(data["step"][at:]) == list(range(100, 161, 10))
    assert attrs["integrator"] == new and attrs["steps_requested"] == 160
    (record,) = json.loads(attrs["integrator_history"])
    assert record["step"] == 100 and record["from"]["integrator"] == old and record["to"]["integrator"] == new


def test_new_dt_gives_the_step_count_and_time_grid(tmp_path: Path) -> None:
    scenario = write(tmp_path, "verlet")
    out = tmp_path / "out.h5"
    assert invoke("run", str(scenario), "-o", str(out), "-q")[0] == 0  # t = 1 after 100 steps of 0.01
    code, _, err = invoke("run", "--from", str(out), "--dt", "0.02", "--t-end", "3", "-q")
    assert code == 0, err
    attrs, data = read(out)
    assert data["step"][-1] == 200 and attrs["steps_done"] == 200 and attrs["dt"] == 0.02  # (3 - 1) / 0.02 more
    later = data["step"] >= 100
    expected = 1.0 + (data["step"][later] - 100) * 0.02
    # t0 + n * dt_new rounds once more than T_K + (n - K) * dt_new: a couple of ulp of t <= 3.
    assert np.all(np.abs(data["time"][later] - expected) <= 4 * np.spacing(3.0))
    assert np.all(np.diff(data["time"]) > 0)
    (record,) = json.loads(attrs["integrator_history"])
    assert (record["step"], record["time"], record["from"]["dt"], record["to"]["dt"]) == (100, 1.0, 0.01, 0.02)


def test_a_switched_run_extends_and_records_every_change(tmp_path: Path) -> None:
    scenario = write(tmp_path, "verlet")
    once, twice = tmp_path / "once.h5", tmp_path / "twice.h5"
    for out in (once, twice):
        assert invoke("run", str(scenario), "-o", str(out), "-q")[0] == 0
    assert invoke("run", "--from", str(once), "--dt", "0.005", "--steps", "80", "-q")[0] == 0
    assert invoke("run", "--from", str(twice), "--dt", "0.005", "--steps", "40", "-q")[0] == 0
    assert invoke("run", "--from", str(twice), "--steps", "40", "-q")[0] == 0  # its clock (t0) carried over
    assert_same_datasets(once, twice)
    assert invoke("run", "--from", str(twice), "--integrator", "leapfrog", "--steps", "20", "-q")[0] == 0
    history = json.loads(read(twice)[0]["integrator_history"])
    assert [(r["step"], r["to"]["integrator"], r["to"]["dt"]) for r in history] == [
        (100, "verlet", 0.005), (180, "leapfrog", 0.005)]
    code, shown, _ = invoke("info", str(twice))  # info lists each change, not the raw JSON
    assert code == 0 and "history:  2 changes of scheme or dt (run --from)" in shown
    assert "  step 100 (t = 1): verlet (dt = 0.01) -> verlet (dt = 0.005)" in shown
    assert "  step 180 (t = 1.4): verlet (dt = 0.005) -> leapfrog (dt = 0.005)" in shown
    assert '"step"' not in shown


def test_refusals_are_one_line_and_write_nothing(tmp_path: Path) -> None:
    scenario = write(tmp_path, "verlet")
    out, new = tmp_path / "out.h5", tmp_path / "new.h5"
    assert invoke("run", str(scenario), "-o", str(out), "-q")[0] == 0
    before = out.read_bytes()
    for args, says in ((("--integrator", "ias15", "--t-end", "2"), "cannot switch to or from it"),
                       (("--integrator", "trace", "--backward", "--steps", "5"), "trace cannot run backwards"),
                       (("--integrator", "nope", "--steps", "5"), "unknown integrator 'nope'"),
                       (("--dt", "0.02", "--t-end", "0.5"), "is not beyond the run's end")):
        code, _, err = invoke("run", "--from", str(out), "-o", str(new), *args)
        assert code == 2 and err.startswith("orbitsim: error: ") and err.count("\n") == 1 and says in err, err
        assert not new.exists()
    assert out.read_bytes() == before
    interval = tmp_path / "interval.yaml"
    interval.write_text(SYSTEM.format(integrator="verlet").replace("every: 10", "interval: 0.1"), encoding="utf-8")
    assert invoke("run", str(interval), "-o", str(tmp_path / "i.h5"), "-q")[0] == 0
    code, _, err = invoke("run", "--from", str(tmp_path / "i.h5"), "--dt", "0.02", "--steps", "5")
    assert code == 2 and "its dt cannot change" in err
