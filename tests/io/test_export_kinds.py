"""``orbitsim export`` of traces from the run kinds ``test_export.py`` leaves out: an adaptive
(``ias15``) run, a run whose ``events:`` merged two bodies, a run with ``forces:``, the REBOUND
mapping of ``wisdom_holman`` and ``trace``, and a run continued by ``run --from`` with another
scheme and step."""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Any

import h5py
import numpy as np
import pytest
from click.testing import CliRunner, Result

from orbitsim.cli.main import cli
from orbitsim.io.trace import read_trace
from orbitsim.runner import run_scenario
from orbitsim.scenario import load_scenario, scenario_from_dict

THREE_BODIES = [
    {"name": "star", "m": 1.0, "x": [0.0, 0.0, 0.0], "v": [0.0, 0.0, 0.0], "r": 0.005},
    {"name": "inner", "m": 1e-3, "x": [1.0, 0.0, 0.01], "v": [0.0, 1.0, 0.02]},
    {"name": "outer", "m": 3e-4, "x": [0.0, -2.1, 0.0], "v": [0.7, 0.0, -0.01]},
]


def export(*args: str) -> Result:
    result = CliRunner().invoke(cli, ["export", *args])
    assert "Traceback" not in result.output, result.output
    return result


def run_doc(tmp_path: Path, doc: dict[str, Any], name: str = "run") -> Path:
    out = tmp_path / f"{name}.h5"
    summary = run_scenario(scenario_from_dict({"name": name, **doc}), out, handle_signals=False)
    assert summary.status == "complete", summary.message
    return out


def rebound_state(path: Path, n: int) -> tuple[Any, np.ndarray, np.ndarray, np.ndarray]:
    """The simulation in a REBOUND file and its particles' x, v, m (as stored: C doubles)."""
    rebound = pytest.importorskip("rebound")
    sim = rebound.Simulation(str(path))
    assert sim.N == n
    x, v, m = np.zeros((n, 3)), np.zeros((n, 3)), np.zeros(n)
    sim.serialize_particle_data(xyz=x, vxvyvz=v, m=m)
    return sim, x, v, m


def no_temporary_files(folder: Path) -> bool:
    return not [p for p in os.listdir(folder) if p.startswith(".")]


# -- ias15: an adaptive run, sampled on output.interval --------------------------------------------

IAS15 = {"integrator": "ias15", "dt": 0.01, "t_end": 2.0, "output": {"interval": 0.25, "positions": True},
         "bodies": THREE_BODIES}


@pytest.fixture
def ias15_trace(tmp_path: Path) -> Path:
    return run_doc(tmp_path, IAS15, "ias")


def test_ias15_scenario_keeps_its_scheme_and_clock_and_starts_on_the_sample(tmp_path: Path,
                                                                            ias15_trace: Path) -> None:
    whole = read_trace(ias15_trace)
    assert list(whole.time) == [0.25 * k for k in range(9)]
    result = export(str(ias15_trace), "--format", "scenario", "--sample", "3", "-o", str(tmp_path / "next.yaml"))
    assert result.exit_code == 0 and result.output == "", result.output
    scenario = load_scenario(tmp_path / "next.yaml")
    assert scenario.integrator == "ias15" and scenario.adaptive
    assert scenario.integrator_settings == {"epsilon": 1e-9, "min_dt": 0.0, "adaptive": True}
    assert (scenario.dt, scenario.interval) == (0.01, 0.25)
    # export_scenario: an adaptive run's t_end is absolute; the sample (t = 0.75) lies before the
    # original's end, so the continuation keeps that end.
    assert scenario.t_start == whole.time[3] == 0.75 and scenario.t_end == 2.0
    run_scenario(scenario, tmp_path / "next.h5", handle_signals=False)
    rest = read_trace(tmp_path / "next.h5")
    assert np.array_equal(rest.positions[0], whole.positions[3])
    assert np.array_equal(rest.velocities[0], whole.velocities[3])
    assert rest.attrs["integrator"] == "ias15"
    # Samples at t_start + k * interval: 0.75 + k * 0.25 are dyadic, so every time is exact.
    assert list(rest.time) == list(whole.time[3:])
    # IAS15's own state (trial step, predictor) is not in a sample, so it may pick other steps than the
    # original from here: equal to its error control (epsilon = 1e-9), not bit for bit (measured 2.2e-16).
    assert np.allclose(rest.positions[-1], whole.positions[-1], rtol=0, atol=1e-12)
    assert not np.array_equal(rest.positions[-1], rest.positions[0])


def test_ias15_scenario_from_the_last_sample_runs_as_long_again(tmp_path: Path, ias15_trace: Path) -> None:
    result = export(str(ias15_trace), "--format", "scenario", "-o", str(tmp_path / "again.yaml"))
    assert result.exit_code == 0, result.output
    scenario = load_scenario(tmp_path / "again.yaml")
    # No time is left after the last sample: t_end = t_sample + (t_end - t_start) of the original.
    assert (scenario.t_start, scenario.t_end) == (2.0, 4.0)
    run_scenario(scenario, tmp_path / "again.h5", handle_signals=False)
    again, whole = read_trace(tmp_path / "again.h5"), read_trace(ias15_trace)
    assert np.array_equal(again.positions[0], whole.positions[-1])
    assert again.time[0] == 2.0 and again.time[-1] == 4.0 and again.n_samples == 9


def test_ias15_rebound_file_holds_the_sample_bit_for_bit(tmp_path: Path, ias15_trace: Path) -> None:
    out = tmp_path / "s.bin"
    result = export(str(ias15_trace), "--format", "rebound", "--sample", "5", "-o", str(out))
    assert result.exit_code == 0 and result.output == "", result.output  # no note: ias15 has a counterpart
    trace = read_trace(ias15_trace)
    sim, x, v, m = rebound_state(out, 3)
    assert np.array_equal(x, trace.positions[5]) and np.array_equal(v, trace.velocities[5])
    assert np.array_equal(m, trace.masses)
    assert str(sim.integrator) == "ias15"
    assert (sim.integrator.epsilon, sim.integrator.min_dt) == (1e-9, 0.0)
    assert (sim.t, sim.dt, sim.G) == (trace.time[5], 0.01, 1.0)  # dt: the scenario's first trial step
    assert sim.particles[0].r == 0.005
    assert no_temporary_files(tmp_path)


def test_ias15_csv_has_one_row_per_sample(tmp_path: Path, ias15_trace: Path) -> None:
    out = tmp_path / "ias.csv"
    assert export(str(ias15_trace), "--format", "csv", "--positions", "-o", str(out)).exit_code == 0
    trace = read_trace(ias15_trace)
    rows = out.read_text().splitlines()
    assert len(rows) == 1 + trace.n_samples == 10
    assert [float(r.split(",")[2]) for r in rows[1:]] == list(trace.time)
    assert [int(r.split(",")[1]) for r in rows[1:]] == list(range(9))  # output intervals, not IAS15 steps
    body_rows = (tmp_path / "ias.positions.csv").read_text().splitlines()
    assert len(body_rows) == 1 + 3 * trace.n_samples


# -- events: a head-on merge -------------------------------------------------------------------

#: Two m = 1 at rest at x = -1, 1 (r = 0.05): they touch at t = 2.211 (step 2211) and merge into a,
#: as in test_events_cli.py. 3000 verlet steps, a sample every 100.
MERGE = {"integrator": "verlet", "dt": 0.001, "t_end": 3.0, "output": {"every": 100, "positions": True},
         "events": {"collisions": {"detect": "line", "resolve": "merge"}},
         "bodies": [{"name": "a", "m": 1.0, "x": [-1.0, 0.0, 0.0], "v": [0.0, 0.0, 0.0], "r": 0.05},
                    {"name": "b", "m": 1.0, "x": [1.0, 0.0, 0.0], "v": [0.0, 0.0, 0.0], "r": 0.05}]}
MERGE_STEP = 2211


@pytest.fixture
def merged_trace(tmp_path: Path) -> Path:
    out = run_doc(tmp_path, MERGE, "merge")
    with h5py.File(out, "r") as f:
        assert list(f["bodies/removed_step"][()]) == [-1, MERGE_STEP]
        assert list(f["bodies/merged_into"][()]) == [-1, 0]
    return out


@pytest.mark.parametrize("fmt", ["scenario", "rebound"])
def test_a_sample_after_a_merge_exports_the_merged_body(tmp_path: Path, merged_trace: Path, fmt: str) -> None:
    """The end state after a merge: the one body left, with the summed mass and the grown radius, and
    a line on stdout naming who merged into whom (test_export_merged.py has the rest)."""
    if fmt == "rebound":
        pytest.importorskip("rebound")
    out = tmp_path / "after.out"
    result = export(str(merged_trace), "--format", fmt, "--sample", "-1", "-o", str(out))
    assert result.exit_code == 0, result.output
    assert result.stdout == (f"{merged_trace}: 1 of 2 bodies left the run before sample 30 (t = 3): b merged into a "
                             f"at t = 2.211 (step {MERGE_STEP}); exported the 1 still in it\n")
    whole = read_trace(merged_trace)
    radius = float(np.cbrt(0.05**3 + 0.05**3))  # the events driver's volume-conserving radius
    if fmt == "scenario":
        scenario = load_scenario(out)
        assert scenario.names == ("a",) and list(scenario.masses) == [2.0] and list(scenario.radii) == [radius]
        assert np.array_equal(scenario.positions, whole.positions[-1, :1])
        assert f"before it b merged into a at t = 2.211 (step {MERGE_STEP})" in scenario.description
    else:
        sim, x, v, m = rebound_state(out, 1)
        assert list(m) == [2.0] and [p.r for p in sim.particles] == [radius]
        assert np.array_equal(x, whole.positions[-1, :1]) and np.array_equal(v, whole.velocities[-1, :1])
    assert no_temporary_files(tmp_path)


def test_a_sample_before_the_merge_continues_the_run_and_merges_again(tmp_path: Path, merged_trace: Path) -> None:
    result = export(str(merged_trace), "--format", "scenario", "--sample", "10", "-o", str(tmp_path / "before.yaml"))
    assert result.exit_code == 0, result.output
    scenario = load_scenario(tmp_path / "before.yaml")
    assert scenario.events is not None
    assert (scenario.events.collisions.detect, scenario.events.collisions.resolve) == ("line", "merge")
    assert (scenario.steps, scenario.t_start) == (2000, 1.0)
    run_scenario(scenario, tmp_path / "before.h5", handle_signals=False)
    whole, rest = read_trace(merged_trace), read_trace(tmp_path / "before.h5")
    # verlet's state is x and v: the same steps, the same merge, NaN for b after it (bytes, so NaN == NaN).
    assert rest.positions.tobytes() == whole.positions[10:].tobytes()
    assert rest.velocities.tobytes() == whole.velocities[10:].tobytes()
    with h5py.File(tmp_path / "before.h5", "r") as f:
        assert list(f["bodies/removed_step"][()]) == [-1, MERGE_STEP - 1000]  # steps count from the new start
        (merged_at,) = f["events/time"][()]
        assert f["bodies/final_masses"][()].tolist() == [2.0, 1.0]
    with h5py.File(merged_trace, "r") as f:
        (original_at,) = f["events/time"][()]
    # t_start + n dt rounds once more than the original's n dt (cli.md: "to an ulp or two").
    assert abs(merged_at - original_at) <= 2 * np.spacing(original_at)


def test_a_sample_before_the_merge_exports_to_rebound(tmp_path: Path, merged_trace: Path) -> None:
    pytest.importorskip("rebound")
    out = tmp_path / "s10.bin"
    result = export(str(merged_trace), "--format", "rebound", "--sample", "10", "-o", str(out))
    assert result.exit_code == 0, result.output
    assert result.stderr == ("orbitsim: note: verlet has no REBOUND counterpart: the file keeps REBOUND's default "
                             "integrator (ias15)\n")  # cli.md: "a scheme REBOUND lacks keeps ... ias15, with a note"
    whole = read_trace(merged_trace)
    sim, x, v, m = rebound_state(out, 2)
    assert str(sim.integrator) == "ias15"
    assert np.array_equal(x, whole.positions[10]) and np.array_equal(v, whole.velocities[10])
    assert list(m) == [1.0, 1.0] and [p.r for p in sim.particles] == [0.05, 0.05]


def test_csv_positions_of_a_merged_body_are_nan_rows(tmp_path: Path, merged_trace: Path) -> None:
    """cli.md: one row per sample and body. A merged body keeps its rows after the merge, its six
    values written as ``nan`` (what ``%.17g`` prints for the trace's NaN, read back by ``float``),
    so the file says the body is gone rather than leaving it out or repeating its last state."""
    out = tmp_path / "m.csv"
    result = export(str(merged_trace), "--format", "csv", "--positions", "-o", str(out))
    assert result.exit_code == 0, result.output
    rows = [r.split(",") for r in (tmp_path / "m.positions.csv").read_text().splitlines()[1:]]
    assert len(rows) == 31 * 2
    b_rows = [r for r in rows if r[3] == "b"]
    assert len(b_rows) == 31
    before = [r for r in b_rows if int(r[1]) < MERGE_STEP]
    after = [r for r in b_rows if int(r[1]) > MERGE_STEP]
    assert len(before) == 23 and len(after) == 8
    assert all(r[4:] == ["nan"] * 6 for r in after)
    assert all(all(math.isfinite(float(c)) for c in r[4:]) for r in before)
    assert all(math.isnan(float(c)) for r in after for c in r[4:])
    whole = read_trace(merged_trace)
    a_last = [r for r in rows if r[3] == "a"][-1]
    assert [float(c) for c in a_last[4:]] == [*whole.positions[-1, 0], *whole.velocities[-1, 0]]
    series = out.read_text().splitlines()
    assert len(series) == 1 + 31 and "nan" not in "".join(series)  # the series stays finite across the merge


# -- forces ------------------------------------------------------------------------------------

#: A star and one eccentric planet in G = 1 units with c = 30 (not the real 10065) so that each force
#: moves the orbit visibly within 200 steps.
FORCES = {
    "gr_potential": {"force": "gr_potential", "c": 30.0, "source": "star"},
    "gr": {"force": "gr", "c": 30.0, "source": "star"},
    "harmonics": {"force": "harmonics", "body": "star", "J2": 0.01, "R_eq": 0.1, "spin_axis": [0.1, 0.0, 1.0]},
    "migration": {"force": "migration", "bodies": {"planet": {"tau_a": -50.0, "tau_e": -20.0}}},
}
STAR_PLANET = [{"name": "star", "m": 1.0, "x": [0.0, 0.0, 0.0], "v": [0.0, 0.0, 0.0]},
               {"name": "planet", "m": 1e-3, "x": [0.5, 0.0, 0.02], "v": [0.0, 1.7, 0.05]}]


def forces_doc(integrator: str, force: dict[str, Any] | None) -> dict[str, Any]:
    doc = {"integrator": integrator, "dt": 0.005, "steps": 200, "output": {"every": 1, "positions": True},
           "bodies": STAR_PLANET}
    return doc if force is None else {**doc, "forces": [force]}


@pytest.mark.parametrize("integrator", ["leapfrog", "verlet"])
@pytest.mark.parametrize("force", list(FORCES))
def test_exported_scenario_keeps_the_forces_and_continues_bit_for_bit(tmp_path: Path, integrator: str,
                                                                       force: str) -> None:
    first = run_doc(tmp_path, forces_doc(integrator, FORCES[force]), "forced")
    newtonian = run_doc(tmp_path, forces_doc(integrator, None), "newtonian")
    result = export(str(first), "--format", "scenario", "--sample", "100", "-o", str(tmp_path / "next.yaml"))
    assert result.exit_code == 0, result.output
    scenario = load_scenario(tmp_path / "next.yaml")
    assert scenario.forces == scenario_from_dict({"name": "x", **forces_doc(integrator, FORCES[force])}).forces
    assert (scenario.integrator, scenario.steps, scenario.dt) == (integrator, 100, 0.005)
    run_scenario(scenario, tmp_path / "next.h5", handle_signals=False)
    whole, rest, plain = read_trace(first), read_trace(tmp_path / "next.h5"), read_trace(newtonian)
    assert np.array_equal(rest.positions[0], whole.positions[100])
    assert np.array_equal(rest.positions, whole.positions[100:])
    assert np.array_equal(rest.velocities, whole.velocities[100:])
    assert not np.array_equal(whole.positions[-1], plain.positions[-1])  # the force did act on the run


# -- the REBOUND mapping of wisdom_holman and trace ---------------------------------------------

@pytest.mark.parametrize(("settings", "coordinates", "corrector"), [
    ({"coordinates": "jacobi", "corrector": 11}, "JACOBI", 11),
    ({"coordinates": "democratic_heliocentric"}, "DEMOCRATICHELIOCENTRIC", 0),
])
def test_wisdom_holman_exports_as_whfast_with_its_coordinates_and_corrector(
        tmp_path: Path, settings: dict[str, Any], coordinates: str, corrector: int) -> None:
    from orbitsim.io.rebound_file import read_rebound_file

    doc = {"integrator": {"name": "wisdom_holman", **settings}, "dt": 0.01, "steps": 50,
           "output": {"every": 5, "positions": True}, "bodies": THREE_BODIES}
    trace_path = run_doc(tmp_path, doc, "wh")
    out = tmp_path / "wh.bin"
    result = export(str(trace_path), "--format", "rebound", "--sample", "4", "-o", str(out))
    assert result.exit_code == 0 and result.output == "", result.output
    trace = read_trace(trace_path)
    sim, x, v, m = rebound_state(out, 3)
    assert np.array_equal(x, trace.positions[4]) and np.array_equal(v, trace.velocities[4])
    assert np.array_equal(m, trace.masses)
    assert (sim.t, sim.dt, sim.G) == (trace.time[4], 0.01, 1.0)
    config = sim.integrator
    assert (str(config), str(config.coordinates), int(config.corrector)) == ("whfast", coordinates, corrector)
    # What orbitsim.reference.wh_pairing sets so that WHFast steps as orbitsim's map does: no
    # synchronisation between steps, outputs from a copy, never a shortened last step.
    assert (int(config.corrector2), str(config.kernel), int(config.safe_mode), int(config.keep_unsynchronized),
            int(sim.exact_finish_time)) == (0, "DEFAULT", 0, 1, 0)
    snapshot = read_rebound_file(out)  # and back: `orbitsim run wh.bin` maps it to the same scheme
    full = {"coordinates": "jacobi", "corrector": 0, **settings}
    assert snapshot.integrator == ("wisdom_holman", full)


@pytest.mark.parametrize("settings", [
    {},
    {"r_crit_hill": 2.5, "peri_crit_eta": 0.5, "peri_mode": "partial_bs"},
])
def test_trace_exports_as_rebound_trace_with_its_settings(tmp_path: Path, settings: dict[str, Any]) -> None:
    from orbitsim.io.rebound_file import read_rebound_file

    doc = {"integrator": {"name": "trace", **settings}, "dt": 0.01, "steps": 50,
           "output": {"every": 5, "positions": True}, "bodies": THREE_BODIES}
    trace_path = run_doc(tmp_path, doc, "tr")
    out = tmp_path / "tr.bin"
    result = export(str(trace_path), "--format", "rebound", "--sample", "7", "-o", str(out))
    assert result.exit_code == 0 and result.output == "", result.output
    trace = read_trace(trace_path)
    sim, x, v, m = rebound_state(out, 3)
    assert np.array_equal(x, trace.positions[7]) and np.array_equal(v, trace.velocities[7])
    assert np.array_equal(m, trace.masses)
    assert (sim.t, sim.dt, sim.G) == (trace.time[7], 0.01, 1.0)
    full = {"r_crit_hill": 3.0, "peri_crit_eta": 1.0, "peri_mode": "full_bs", **settings}  # orbitsim's defaults
    config = sim.integrator
    assert str(config) == "trace"
    assert (config.r_crit_hill, config.peri_crit_eta, str(config.peri_mode)) == (
        full["r_crit_hill"], full["peri_crit_eta"], full["peri_mode"].upper())
    assert [p.r for p in sim.particles] == [0.005, 0.0, 0.0]
    assert read_rebound_file(out).integrator == ("trace", full)


# -- a run continued by `run --from` with another scheme and step --------------------------------

SWITCH = {"integrator": "leapfrog", "dt": 0.01, "steps": 100, "output": {"every": 10, "positions": True},
          "bodies": THREE_BODIES}


@pytest.fixture
def switched_trace(tmp_path: Path) -> Path:
    """100 leapfrog steps of 0.01, then 60 verlet steps of 0.005: samples 0-10 by leapfrog, 11-16 by verlet."""
    out = run_doc(tmp_path, SWITCH, "sw")
    result = CliRunner().invoke(cli, ["run", "--from", str(out), "--integrator", "verlet", "--dt", "0.005",
                                      "--steps", "60", "-q"])
    assert result.exit_code == 0, result.output
    with h5py.File(out, "r") as f:
        (record,) = json.loads(f.attrs["integrator_history"])
        assert f["step"][()].tolist() == [*range(0, 101, 10), *range(110, 161, 10)]
    assert (record["step"], record["from"], record["to"]) == (100, {"integrator": "leapfrog", "dt": 0.01},
                                                               {"integrator": "verlet", "dt": 0.005})
    return out


def test_a_sample_after_a_switch_continues_the_new_scheme_bit_for_bit(tmp_path: Path, switched_trace: Path) -> None:
    result = export(str(switched_trace), "--format", "scenario", "--sample", "12", "-o", str(tmp_path / "n.yaml"))
    assert result.exit_code == 0, result.output
    scenario = load_scenario(tmp_path / "n.yaml")
    whole = read_trace(switched_trace)
    assert (scenario.integrator, scenario.dt, scenario.steps) == ("verlet", 0.005, 40)
    assert scenario.t_start == whole.time[12]
    run_scenario(scenario, tmp_path / "n.h5", handle_signals=False)
    rest = read_trace(tmp_path / "n.h5")
    assert np.array_equal(rest.positions, whole.positions[12:])
    assert np.array_equal(rest.velocities, whole.velocities[12:])


@pytest.mark.parametrize("fmt", ["scenario", "rebound"])
def test_a_sample_before_a_switch_is_not_given_the_new_scheme(tmp_path: Path, switched_trace: Path, fmt: str) -> None:
    """Sample 3 (step 30) was taken by leapfrog at dt = 0.01. Exporting it as if verlet at dt = 0.005
    had made it gives a scenario that neither continues the trace (another scheme and step up to
    step 100) nor reaches its end (130 steps of 0.005 from t = 0.3 end at t = 0.95, not 1.3).
    The stored scenario holds only the scheme after the switch, so the export is refused."""
    if fmt == "rebound":
        pytest.importorskip("rebound")
    out = tmp_path / ("s3.yaml" if fmt == "scenario" else "s3.bin")
    result = export(str(switched_trace), "--format", fmt, "--sample", "3", "-o", str(out))
    # One scenario holds one scheme: refused in one line naming the scheme that took the sample.
    assert result.exit_code == 2 and result.stderr.count("\n") == 1 and not out.exists(), result.output
    assert ("sample 3 (step 30) was taken by leapfrog at dt = 0.01, before the run switched to verlet at "
            "dt = 0.005 at step 100 (run --from); export a sample from step 100 on") in result.stderr
