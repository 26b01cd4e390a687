"""run_scenario: traces, status, output protection, stop requests, divergence, sampling."""

from __future__ import annotations

import math
from pathlib import Path

import h5py
import numpy as np
import pytest

from orbitsim.io.trace import read_trace
from orbitsim.runner import OutputError, default_output, run_scenario
from orbitsim.scenario import ScenarioError, load_scenario, scenario_from_dict

PAIR = {
    "name": "pair",
    "integrator": "verlet",
    "dt": 0.01,
    "steps": 300,
    "output": {"every": 10},
    "bodies": [
        {"name": "star", "m": 1.0, "x": [0, 0, 0], "v": [0, 0, 0]},
        {"name": "planet", "m": 1e-3, "primary": "star", "a": 1.0, "e": 0.2, "M": 0},
    ],
}
HEAD_ON = {
    "name": "head_on",
    "integrator": "verlet",
    "dt": 0.5,
    "steps": 50,
    "output": {"every": 1},
    # Tiny masses keep the bodies on exact binary-fraction positions, so at t = 1 they meet at
    # exactly x = 0, where the unsoftened force is infinite.
    "bodies": [
        {"name": "left", "m": 1e-20, "x": [-1, 0, 0], "v": [1, 0, 0]},
        {"name": "right", "m": 1e-20, "x": [1, 0, 0], "v": [-1, 0, 0]},
    ],
}


def test_complete_run_writes_the_trace(tmp_path: Path) -> None:
    scenario = scenario_from_dict(PAIR)
    out = tmp_path / "pair.h5"
    summary = run_scenario(scenario, out)
    assert (summary.status, summary.exit_code, summary.steps_done, summary.samples) == ("complete", 0, 300, 31)
    assert summary.end_time == pytest.approx(3.0) and summary.output == out
    assert 0 < summary.max_abs_energy_error < 1e-3 and summary.steps_per_s > 0
    trace = read_trace(out)
    attrs = trace.attrs
    assert attrs["status"] == "complete" and attrs["format"] == "orbitsim.trace" and attrs["format_version"] == 1
    assert attrs["scenario"] == scenario.to_yaml() and attrs["scenario_sha256"] == scenario.sha256
    assert (attrs["integrator"], attrs["dt"], attrs["steps_requested"], attrs["steps_done"]) == ("verlet", 0.01,
                                                                                                 300, 300)
    assert (attrs["G"], attrs["softening"], attrs["units"]) == (1.0, 0.0, "nbody")
    for key in ("orbitsim_version", "wall_time_s", "provenance_numpy_version", "provenance_numba_version",
                "provenance_llvmlite_version", "provenance_cpu_model", "threads"):
        assert key in attrs, key
    assert np.array_equal(trace.step, np.arange(0, 301, 10))
    assert trace.positions.shape == (31, 2, 3) and trace.names == ("star", "planet")
    assert np.max(np.abs(trace.energy_error)) == pytest.approx(summary.max_abs_energy_error)
    assert not Path(str(out) + ".tmp").exists()


def test_trace_datasets_are_chunked_and_compressed(tmp_path: Path) -> None:
    out = tmp_path / "pair.h5"
    run_scenario(scenario_from_dict(PAIR), out)
    with h5py.File(out) as f:
        for name in ("time", "energy", "energy_error", "momentum", "angular_momentum", "positions"):
            assert f[name].chunks is not None and f[name].compression == "gzip", name
            assert f[name].maxshape[0] is None


def test_resolved_scenario_in_trace_reruns_to_same_bits(tmp_path: Path) -> None:
    first = run_scenario(load_scenario("figure_eight").with_overrides(steps=500), tmp_path / "a.h5")
    text = read_trace(first.output).attrs["scenario"]
    (tmp_path / "again.yaml").write_text(text, encoding="utf-8")
    second = run_scenario(load_scenario(tmp_path / "again.yaml"), tmp_path / "b.h5")
    a, b = read_trace(first.output), read_trace(second.output)
    assert np.array_equal(a.positions, b.positions) and np.array_equal(a.energy, b.energy)
    assert a.attrs["scenario_sha256"] == b.attrs["scenario_sha256"]


def test_existing_output_needs_force(tmp_path: Path) -> None:
    scenario = scenario_from_dict(PAIR)
    out = tmp_path / "pair.h5"
    out.write_bytes(b"precious")
    with pytest.raises(OutputError, match="already exists; use --force"):
        run_scenario(scenario, out)
    assert out.read_bytes() == b"precious"
    run_scenario(scenario, out, force=True)
    assert read_trace(out).attrs["status"] == "complete"


def test_output_directory_must_exist(tmp_path: Path) -> None:
    with pytest.raises(OutputError, match="does not exist"):
        run_scenario(scenario_from_dict(PAIR), tmp_path / "missing" / "x.h5")


def test_default_output_is_name_in_cwd(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    scenario = scenario_from_dict(PAIR)
    assert default_output(scenario) == Path("pair.h5")
    run_scenario(scenario)
    assert (tmp_path / "pair.h5").is_file()


def test_stop_callback_interrupts_and_keeps_samples(tmp_path: Path) -> None:
    # Long enough that the simulation hands samples over in several chunks (its first call
    # takes at most 50,000 steps of a 2-body system).
    scenario = scenario_from_dict({**PAIR, "steps": 1_000_000, "output": {"every": 1000}})
    seen: list[int] = []
    summary = run_scenario(scenario, tmp_path / "x.h5", stop=lambda: bool(seen),
                           on_chunk=lambda sim, chunk: seen.append(len(chunk)))
    assert summary.status == "interrupted" and summary.exit_code == 1
    assert summary.samples == sum(seen) >= 1 and summary.steps_done < 1_000_000
    trace = read_trace(tmp_path / "x.h5")
    assert trace.attrs["status"] == "interrupted" and trace.n_samples == summary.samples
    assert "interrupted by a stop request" in trace.attrs["message"]


def test_divergence_keeps_finite_samples(tmp_path: Path) -> None:
    summary = run_scenario(scenario_from_dict(HEAD_ON), tmp_path / "d.h5")
    assert summary.status == "diverged" and summary.exit_code == 3
    assert "left, right" in summary.message and "t = 0.5" in summary.message
    trace = read_trace(tmp_path / "d.h5")
    assert trace.attrs["status"] == "diverged" and trace.attrs["message"] == summary.message
    assert trace.n_samples == 2 and np.all(np.isfinite(trace.positions))
    assert trace.attrs["steps_done"] == 2


def test_interval_sampling_records_true_step_times(tmp_path: Path) -> None:
    scenario = scenario_from_dict({**PAIR, "dt": 0.03, "steps": 100, "output": {"interval": 0.1}})
    run_scenario(scenario, tmp_path / "i.h5")
    trace = read_trace(tmp_path / "i.h5")
    assert np.array_equal(trace.time, trace.step * 0.03)  # the step's own time, not the requested one
    for k, t in enumerate(trace.time[:-1]):
        assert t <= k * 0.1 + 1e-15 and k * 0.1 - t < 0.03
    assert trace.step[-1] == 100


def test_progress_reports_every_chunk(tmp_path: Path) -> None:
    calls: list[tuple[int, int]] = []
    run_scenario(scenario_from_dict(PAIR), tmp_path / "p.h5", progress=lambda d, t: calls.append((d, t)))
    assert calls[0] == (0, 300) and calls[-1] == (300, 300)
    assert [d for d, _ in calls] == sorted(d for d, _ in calls)


def test_positions_not_recorded_when_off(tmp_path: Path) -> None:
    scenario = scenario_from_dict({**PAIR, "output": {"every": 100, "positions": False}})
    run_scenario(scenario, tmp_path / "n.h5")
    trace = read_trace(tmp_path / "n.h5")
    assert trace.positions is None and trace.velocities is None and trace.n_samples == 4


def test_positions_that_would_not_fit_on_disk_are_refused(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import shutil

    usage = shutil.disk_usage(tmp_path)
    monkeypatch.setattr(shutil, "disk_usage", lambda path: usage._replace(free=100))
    with pytest.raises(ScenarioError, match=r"output\.positions"):
        run_scenario(scenario_from_dict(PAIR), tmp_path / "big.h5")
    assert not list(tmp_path.iterdir())


def test_stop_before_the_first_sample_leaves_an_empty_interrupted_trace(tmp_path: Path) -> None:
    summary = run_scenario(scenario_from_dict(PAIR), tmp_path / "e.h5", stop=lambda: True)
    assert summary.status == "interrupted" and summary.samples == 0
    assert math.isnan(summary.max_abs_energy_error)
    trace = read_trace(tmp_path / "e.h5")
    assert trace.attrs["status"] == "interrupted" and trace.n_samples == 0


def test_signal_during_a_run_stops_it_and_restores_handlers(tmp_path: Path) -> None:
    import os
    import signal

    before = signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM), signal.getsignal(signal.SIGALRM)
    scenario = scenario_from_dict({**PAIR, "steps": 1_000_000, "output": {"every": 1000}})
    sent: list[int] = []

    def send_once(sim: object, chunk: object) -> None:
        if not sent:  # arrives inside the critical section: handled once the chunk is written
            sent.append(1)
            os.kill(os.getpid(), signal.SIGTERM)

    summary = run_scenario(scenario, tmp_path / "s.h5", on_chunk=send_once)
    assert (summary.status, summary.exit_code) == ("interrupted", 143)
    assert "SIGTERM" in summary.message and summary.samples >= 1
    assert read_trace(tmp_path / "s.h5").n_samples == summary.samples
    after = signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM), signal.getsignal(signal.SIGALRM)
    assert after == before
