"""``orbitsim export``: REBOUND files and scenarios that hold a sample's exact bits, and CSV."""

from __future__ import annotations

import errno
import os
from pathlib import Path

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

from orbitsim.cli.main import cli
from orbitsim.io.trace import read_trace
from orbitsim.runner import run_scenario
from orbitsim.scenario import load_scenario, scenario_from_dict

THREE_BODIES = [
    {"name": "star", "m": 1.0, "x": [0.0, 0.0, 0.0], "v": [0.0, 0.0, 0.0], "r": 0.005},
    {"name": "inner", "m": 1e-3, "x": [1.0, 0.0, 0.01], "v": [0.0, 1.0, 0.02]},
    {"name": "outer", "m": 3e-4, "x": [0.0, -2.1, 0.0], "v": [0.7, 0.0, -0.01]},
]
#: Fixed-dt schemes whose state is x and v alone: a run restarted from a sample takes the same steps.
#: wisdom_holman continues bit for bit through its own coordinates, which the export writes
#: (tests/io/test_export_wh_state.py).
FIXED_DT = ["leapfrog", "leapfrog4", "verlet", "rk4", "semi_implicit_euler"]


def run(tmp_path: Path, integrator: str = "leapfrog4", steps: int = 200, name: str = "run") -> Path:
    doc = {"name": name, "integrator": integrator, "dt": 0.01, "steps": steps,
           "output": {"every": 1, "positions": True}, "bodies": THREE_BODIES}
    out = tmp_path / f"{name}.h5"
    run_scenario(scenario_from_dict(doc), out)
    return out


def export(*args: str) -> object:
    return CliRunner().invoke(cli, ["export", *args])


def test_rebound_file_holds_the_sample_bit_for_bit(tmp_path: Path) -> None:
    rebound = pytest.importorskip("rebound")
    trace_path = run(tmp_path, steps=20)
    result = export(str(trace_path), "--format", "rebound", "--sample", "7", "-o", str(tmp_path / "s.bin"))
    assert result.exit_code == 0, result.output
    trace = read_trace(trace_path)
    sim = rebound.Simulation(str(tmp_path / "s.bin"))
    x, v, m = np.zeros((3, 3)), np.zeros((3, 3)), np.zeros(3)
    sim.serialize_particle_data(xyz=x, vxvyvz=v, m=m)
    assert np.array_equal(x, trace.positions[7]) and np.array_equal(v, trace.velocities[7])
    assert np.array_equal(m, trace.masses)
    assert (sim.t, sim.dt, sim.G) == (trace.time[7], 0.01, 1.0)
    assert (str(sim.integrator), sim.integrator.order) == ("leapfrog", 4)
    assert sim.particles[0].r == 0.005
    assert not [p for p in os.listdir(tmp_path) if p.startswith(".")]  # no temporary file left


@pytest.mark.parametrize("integrator", FIXED_DT)
def test_exported_scenario_continues_the_run_bit_for_bit(tmp_path: Path, integrator: str) -> None:
    first = run(tmp_path, integrator=integrator)
    result = export(str(first), "--format", "scenario", "--sample", "100", "-o", str(tmp_path / "next.yaml"))
    assert result.exit_code == 0, result.output
    scenario = load_scenario(tmp_path / "next.yaml")
    assert (scenario.integrator, scenario.steps, scenario.dt) == (integrator, 100, 0.01)
    run_scenario(scenario, tmp_path / "next.h5")
    whole, rest = read_trace(first), read_trace(tmp_path / "next.h5")
    assert np.array_equal(rest.positions[0], whole.positions[100])
    assert np.array_equal(rest.positions[-1], whole.positions[-1])
    assert np.array_equal(rest.velocities[-1], whole.velocities[-1])
    assert not np.array_equal(rest.positions[-1], rest.positions[0])  # it did move
    # The continuation's clock goes on from the sample's: t_start = t_100 and sample n at t_100 + n * dt,
    # against the original's 0 + (100 + n) * dt. Two roundings against one, so not bit for bit (here 18
    # of the 101 times differ, by 1 ulp); the bound is 2 ulp of each time. The first is the stored time.
    assert scenario.t_start == whole.time[100] and rest.time[0] == whole.time[100]
    assert rest.time.shape == whole.time[100:].shape
    assert np.all(np.abs(rest.time - whole.time[100:]) <= 2 * np.spacing(whole.time[100:]))


def test_csv_series_and_positions(tmp_path: Path) -> None:
    trace_path = run(tmp_path, steps=10)
    out = tmp_path / "run.csv"
    result = export(str(trace_path), "--format", "csv", "--positions", "-o", str(out))
    assert result.exit_code == 0, result.output
    trace = read_trace(trace_path)
    rows = out.read_text().splitlines()
    assert rows[0].split(",")[:7] == ["sample", "step", "time", "kinetic", "potential", "energy", "energy_error"]
    assert len(rows) == 1 + trace.n_samples
    last = rows[-1].split(",")
    assert float(last[5]) == trace.energy[-1] and float(last[12]) == trace.angular_momentum[-1, 2]
    body_rows = (tmp_path / "run.positions.csv").read_text().splitlines()
    assert len(body_rows) == 1 + trace.n_samples * 3
    sample, step, time, body, *state = body_rows[-1].split(",")
    assert (int(sample), int(step), float(time), body) == (trace.n_samples - 1, trace.step[-1], trace.time[-1], "outer")
    assert [float(c) for c in state] == [*trace.positions[-1, 2], *trace.velocities[-1, 2]]


def test_csv_includes_recorded_elements(tmp_path: Path) -> None:
    doc = {"name": "el", "integrator": "leapfrog", "dt": 0.01, "steps": 5,
           "output": {"every": 1, "elements": True}, "bodies": THREE_BODIES}
    run_scenario(scenario_from_dict(doc), tmp_path / "el.h5")
    assert export(str(tmp_path / "el.h5"), "--format", "csv", "-o", str(tmp_path / "el.csv")).exit_code == 0
    header = (tmp_path / "el.csv").read_text().splitlines()[0].split(",")
    assert "a[inner]" in header and "inc[outer]" in header
    with h5py.File(tmp_path / "el.h5") as f:
        a = f["elements/a"][-1, 1]
    assert float((tmp_path / "el.csv").read_text().splitlines()[-1].split(",")[header.index("a[inner]")]) == a


def test_csv_includes_megno_and_mlce_of_a_chaos_run(tmp_path: Path) -> None:
    from orbitsim.chaos.state import CHAOS_SERIES
    from orbitsim.io.csv_export import CHAOS_COLUMNS

    assert CHAOS_COLUMNS == CHAOS_SERIES  # written out so that the CSV writer loads no numba
    doc = {"name": "ch", "integrator": "leapfrog4", "dt": 0.01, "steps": 50,
           "output": {"every": 5, "chaos": {"seed": 1}}, "bodies": THREE_BODIES}
    run_scenario(scenario_from_dict(doc), tmp_path / "ch.h5")
    assert export(str(tmp_path / "ch.h5"), "--format", "csv", "-o", str(tmp_path / "ch.csv")).exit_code == 0
    lines = (tmp_path / "ch.csv").read_text().splitlines()
    header = lines[0].split(",")
    assert header[header.index("Lz") + 1:header.index("Lz") + 3] == ["megno", "mlce"]
    with h5py.File(tmp_path / "ch.h5") as f:
        megno, mlce = f["megno"][()], f["mlce"][()]
    rows = [line.split(",") for line in lines[1:]]
    assert len(rows) == megno.shape[0] == 11
    # %.17g reads back to the same bits
    assert np.array_equal([float(r[header.index("megno")]) for r in rows], megno)
    assert np.array_equal([float(r[header.index("mlce")]) for r in rows], mlce)
    run_scenario(scenario_from_dict({**doc, "name": "plain", "output": {"every": 5}}), tmp_path / "plain.h5")
    assert export(str(tmp_path / "plain.h5"), "--format", "csv", "-o", str(tmp_path / "plain.csv")).exit_code == 0
    assert "megno" not in (tmp_path / "plain.csv").read_text().splitlines()[0]  # only where the run recorded it


def test_exporting_a_chaos_run_as_a_scenario_says_the_indicators_start_again(tmp_path: Path) -> None:
    doc = {"name": "ch", "integrator": "leapfrog", "dt": 0.01, "steps": 40,
           "output": {"every": 10, "positions": True, "chaos": {"seed": 1}}, "bodies": THREE_BODIES}
    run_scenario(scenario_from_dict(doc), tmp_path / "ch.h5")
    result = export(str(tmp_path / "ch.h5"), "--format", "scenario", "--sample", "2", "-o", str(tmp_path / "next.yaml"))
    assert result.exit_code == 0, result.output
    lines = [line for line in result.output.splitlines() if "chaos indicators" in line]
    assert len(lines) == 1 and "start again" in lines[0] and "t = 0.2" in lines[0]
    assert f"orbitsim run --from {tmp_path / 'ch.h5'}" in lines[0]
    # the exported scenario does start them again: its first sample is MEGNO's start, not the trace's value there
    run_scenario(load_scenario(tmp_path / "next.yaml"), tmp_path / "next.h5")
    with h5py.File(tmp_path / "ch.h5") as f, h5py.File(tmp_path / "next.h5") as g:
        assert g["megno"][0] == 0.0 != f["megno"][2]
        assert np.array_equal(g["positions"][0], f["positions"][2])  # the bodies do continue from the sample
    plain = {**doc, "name": "plain", "output": {"every": 10, "positions": True}}
    run_scenario(scenario_from_dict(plain), tmp_path / "plain.h5")
    result = export(str(tmp_path / "plain.h5"), "--format", "scenario", "-o", str(tmp_path / "p.yaml"))
    assert result.exit_code == 0 and "chaos" not in result.output  # only a chaos run's export says it


def test_state_exports_need_positions(tmp_path: Path) -> None:
    doc = {"name": "blind", "integrator": "leapfrog", "dt": 0.01, "steps": 5,
           "output": {"every": 1, "positions": False}, "bodies": THREE_BODIES}
    run_scenario(scenario_from_dict(doc), tmp_path / "blind.h5")
    for fmt in ("rebound", "scenario"):
        result = export(str(tmp_path / "blind.h5"), "--format", fmt, "-o", str(tmp_path / "x.out"))
        assert result.exit_code == 2 and "did not record positions" in result.output
        assert len(result.output.strip().splitlines()) == 1
    assert sorted(os.listdir(tmp_path)) == ["blind.h5"]


@pytest.mark.parametrize(("args", "words"), [
    (["--format", "scenario", "--sample", "99"], "sample 99 is out of range"),
    (["--format", "csv", "--sample", "3"], "--sample is for"),
    (["--format", "rebound", "--positions"], "--positions is for --format csv"),
])
def test_bad_requests_are_one_line(tmp_path: Path, args: list[str], words: str) -> None:
    trace_path = run(tmp_path, steps=5)
    result = export(str(trace_path), *args, "-o", str(tmp_path / "out.x"))
    assert result.exit_code == 2 and words in result.output
    assert len(result.output.strip().splitlines()) == 1 and not (tmp_path / "out.x").exists()


def test_existing_output_needs_force(tmp_path: Path) -> None:
    trace_path = run(tmp_path, steps=5)
    (tmp_path / "keep.csv").write_text("old")
    result = export(str(trace_path), "--format", "csv", "-o", str(tmp_path / "keep.csv"))
    assert result.exit_code == 2 and "--force" in result.output
    assert (tmp_path / "keep.csv").read_text() == "old"
    assert export(str(trace_path), "--format", "csv", "-o", str(tmp_path / "keep.csv"), "--force").exit_code == 0
    assert (tmp_path / "keep.csv").read_text().startswith("sample,")


@pytest.mark.parametrize("fmt", ["csv", "scenario", "rebound"])
def test_a_failed_write_leaves_the_old_file(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, fmt: str) -> None:
    pytest.importorskip("rebound")
    import orbitsim.io.durable as durable

    trace_path = run(tmp_path, steps=5)
    target = tmp_path / "out.any"
    target.write_text("old")

    def disk_full(tmp: Path, path: Path) -> None:
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(path))

    monkeypatch.setattr(durable, "replace_durably", disk_full)
    result = export(str(trace_path), "--format", fmt, "-o", str(target), "--force")
    assert result.exit_code == 4 and "No space left on device" in result.output
    assert len(result.output.strip().splitlines()) == 1
    assert target.read_text() == "old"
    assert sorted(os.listdir(tmp_path)) == ["out.any", "run.h5"]
