"""``validate`` makes every check ``run`` makes before stepping (issue 14, item 5): the trace size,
also without positions, against the free disk space; the initial state; and a time estimate that
``validate`` prints and ``run`` warns with. Nothing here asserts on how fast anything runs."""

from __future__ import annotations

import os
import re
import shutil
from pathlib import Path

import numba
import pytest
from click.testing import CliRunner

import orbitsim.estimate as estimate
import orbitsim.preflight as preflight
from orbitsim.cli.main import cli
from orbitsim.runner import run_scenario
from orbitsim.scenario import load_scenario, scenario_from_dict

BODIES = [{"name": "star", "m": 1.0, "x": [0, 0, 0], "v": [0, 0, 0]},
          {"name": "planet", "m": 1e-3, "primary": "star", "a": 1.0, "e": 0.1, "M": 0}]
# The case: 10^9 samples of a run without positions, 96 GB of energies and momenta.
BILLION = ("name: billion\nintegrator: verlet\ndt: 0.01\nsteps: 1e9\noutput: {every: 1, positions: false}\n"
           "bodies:\n  - {name: star, m: 1.0, x: [0, 0, 0], v: [0, 0, 0]}\n"
           "  - {name: planet, m: 1.0e-3, primary: star, a: 1.0, M: 0}\n")
TIME_LINE = re.compile(r"^  time: about [\d.]+ (us|ms|s|min|h|days|years) per step at N = \d+ on this machine, "
                       r"about [\d.]+ (us|ms|s|min|h|days|years) in all$", re.M)


def scenario(**changes: object) -> object:
    doc = {"name": "pair", "integrator": "verlet", "dt": 0.01, "steps": 300, "output": {"every": 10},
           "bodies": BODIES, **changes}
    return scenario_from_dict(doc)


def write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "s.yaml"
    path.write_text(text, encoding="utf-8")
    return path


def test_trace_size_counts_energies_and_momenta_without_positions() -> None:
    sc = scenario(steps=10**9, output={"every": 1, "positions": False})
    per_sample = 8 * (6 + 2 * 3)  # time, step, T, U, E, dE/E and two 3-vectors
    fixed = preflight.TRACE_BYTES_PER_BODY * 2 + preflight.TRACE_BYTES_FIXED
    assert preflight.trace_bytes(sc) == per_sample * (10**9 + 1) + fixed
    with_states = scenario(steps=10**9, output={"every": 1, "positions": True})
    assert preflight.trace_bytes(with_states) == (per_sample + 48 * 2) * (10**9 + 1) + fixed
    checkpointed = scenario(steps=10**9, output={"every": 1, "positions": False, "checkpoint": {"every": 10**6}})
    assert preflight.trace_bytes(checkpointed) == 2 * preflight.trace_bytes(sc)  # journal and trace coexist


@pytest.mark.parametrize("positions", [True, False])
def test_trace_size_bounds_a_real_trace(tmp_path: Path, positions: bool) -> None:
    sc = scenario(output={"every": 1, "positions": positions})
    run_scenario(sc, tmp_path / "t.h5", handle_signals=False)
    assert (tmp_path / "t.h5").stat().st_size <= preflight.trace_bytes(sc)


@pytest.mark.parametrize(("text", "key"), [(BILLION, "output.every"),
                                            (BILLION.replace("positions: false", "positions: true"),
                                             "output.positions")], ids=["no_positions", "positions"])
def test_validate_and_run_refuse_alike_a_trace_that_would_not_fit(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                                  text: str, key: str) -> None:
    write(tmp_path, text)
    usage = shutil.disk_usage(tmp_path)
    monkeypatch.setattr(shutil, "disk_usage", lambda where: usage._replace(free=50 * 2**30))  # 50 GiB
    monkeypatch.chdir(tmp_path)
    runner = CliRunner()
    for args in (["validate", "s.yaml"], ["run", "s.yaml", "-o", "out.h5"]):
        result = runner.invoke(cli, args)
        assert result.exit_code == 2, result.output
        lines = result.stderr.splitlines()
        assert len(lines) == 1 and lines[0].startswith(f"orbitsim: error: s.yaml: {key}: the trace needs about ")
        assert "GiB free" in lines[0] and result.stdout == ""
        assert sorted(os.listdir(tmp_path)) == ["s.yaml"]


def test_validate_ok_line_gives_the_trace_size(tmp_path: Path) -> None:
    result = CliRunner().invoke(cli, ["validate", str(write(tmp_path, BILLION.replace("1e9", "1000")))])
    assert result.exit_code == 0
    assert re.search(r"^ok: .*, positions off, trace about [\d.]+ KiB$", result.output, re.M), result.output


def test_validate_times_a_long_run(tmp_path: Path) -> None:
    path = write(tmp_path, BILLION.replace("steps: 1e9", "steps: 1e12").replace("every: 1,", "every: 1e9,"))
    result = CliRunner().invoke(cli, ["validate", str(path)])
    assert result.exit_code == 0, result.output
    assert TIME_LINE.search(result.output) and "at N = 2 on" in result.output, result.output


def test_short_runs_are_not_timed_at_all(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import orbitsim.simulation

    def no_simulation(*args: object, **kwargs: object) -> None:
        raise AssertionError("a short run must not be timed")

    monkeypatch.setattr(orbitsim.simulation, "Simulation", no_simulation)
    assert estimate.estimate_time(load_scenario("plummer_16k")) is None  # 5 steps: it cannot matter
    result = CliRunner().invoke(cli, ["validate", "two_body_circular", "plummer_1k"])
    assert result.exit_code == 0 and "time:" not in result.output


def test_estimate_scales_the_subsample_by_the_pair_count(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(estimate, "_time_steps", lambda sim, sample_s: 1e-3)
    monkeypatch.setattr(estimate, "_time_sample", lambda sim: 1e-4)
    monkeypatch.setattr(estimate, "usable_threads", lambda threads: 2.0)
    gen = {"kind": "plummer", "n": 2000, "seed": 1}
    big = scenario_from_dict({"integrator": "verlet", "dt": 1e-3, "steps": 10, "softening": 0.01,
                              "output": {"every": 5}, "generator": gen})
    measured = estimate.estimate_time(big, always=True)
    scale = 2000 * 1999 / (1000 * 999) / 2.0  # pairs, over the two usable threads (N >= 384)
    assert measured.n_timed == 1000 and measured.step_s == pytest.approx(1e-3 * scale, rel=1e-12)  # round-off
    assert measured.total_s == pytest.approx(10 * 1e-3 * scale + 3 * 1e-4 * scale, rel=1e-12)  # round-off
    small = estimate.estimate_time(scenario(), always=True)  # N = 2: timed whole, serial kernels
    assert small.n_timed == 2 and small.step_s == 1e-3


def test_estimate_leaves_the_thread_count_as_the_run_will_find_it() -> None:
    before = numba.get_num_threads()
    assert estimate.estimate_time(scenario(), always=True) is not None
    assert numba.get_num_threads() == before
    assert 1.0 <= estimate.usable_threads(before) <= before


def test_run_warns_before_a_long_run_and_only_then(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(estimate, "LONG_RUN_S", 0.0)  # every run counts as long here
    monkeypatch.setattr(estimate, "ESTIMATE_MIN_WORK", 0.0)
    path = write(tmp_path, BILLION.replace("1e9", "100"))
    runner = CliRunner()
    result = runner.invoke(cli, ["run", str(path), "-o", str(tmp_path / "out.h5")])
    assert result.exit_code == 0, result.output
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("orbitsim: note: this run is expected to take a long time: about ")
    assert runner.invoke(cli, ["run", str(path), "-o", str(tmp_path / "q.h5"), "-q"]).stderr == ""
    refused = runner.invoke(cli, ["run", str(path), "-o", str(tmp_path / "out.h5")])  # exists, no --force
    assert refused.exit_code == 2
    assert len(refused.stderr.splitlines()) == 1 and "already exists" in refused.stderr


def test_a_run_of_few_but_slow_steps_is_timed(monkeypatch: pytest.MonkeyPatch) -> None:
    """Issue 27, item 9: one step of 50,000 bodies is 1.25e9 pair units, over 10 s on a slow, busy
    machine; a run of one such step is below ESTIMATE_MIN_WORK, and still timed."""
    monkeypatch.setattr(estimate, "_time_steps", lambda sim, sample_s: 1e-3)
    monkeypatch.setattr(estimate, "_time_sample", lambda sim: 1e-4)
    one_step = scenario_from_dict({"integrator": "verlet", "dt": 1e-3, "steps": 1, "softening": 0.01,
                                   "generator": {"kind": "plummer", "n": 50_000, "seed": 1}})
    assert estimate.rough_work(one_step) < estimate.ESTIMATE_MIN_WORK
    assert estimate.estimate_time(one_step) is not None


@pytest.mark.parametrize(("steps", "long"), [(100, False), (1000, True)])
def test_run_says_in_one_line_when_each_step_takes_over_10_s(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                              steps: int, long: bool) -> None:
    def slow(sc: object, **kwargs: object) -> estimate.TimeEstimate:
        return estimate.TimeEstimate(n_bodies=2, n_timed=2, step_s=25.0, sample_s=0.0, steps=steps, samples=2)

    monkeypatch.setattr(estimate, "estimate_time", slow)
    path = write(tmp_path, BILLION.replace("1e9", "100"))
    result = CliRunner().invoke(cli, ["run", str(path), "-o", str(tmp_path / "out.h5")])
    assert result.exit_code == 0, result.output
    lines = result.stderr.splitlines()
    start = ("orbitsim: note: this run is expected to take a long time: about 25 s per step" if long else
             "orbitsim: note: this run's steps are expected to be slow: about 25 s per step")
    assert len(lines) == 1 and lines[0].startswith(start), lines
    assert lines[0].endswith("; each step takes over 10 s: Ctrl-C stops within 2 s and discards the step in progress")


def test_formats() -> None:
    assert [estimate.format_seconds(s) for s in (2.0, 11160.0, 869e-6, 59.0)] == ["2 s", "3.1 h", "870 us", "59 s"]
    assert [preflight.format_bytes(b) for b in (100, 1536, 3 * 2**40)] == ["100 B", "1.5 KiB", "3 TiB"]
