"""The bundled scenarios in orbitsim/data/scenarios/: they validate, run, and do what their descriptions say."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from orbitsim.cli.main import cli
from orbitsim.io.trace import read_trace
from orbitsim.runner import run_scenario
from orbitsim.scenario import bundled_scenarios, load_scenario

REQUIRED = ("two_body_circular", "two_body_eccentric", "figure_eight", "pythagorean", "solar_system",
            "outer_solar_system", "plummer_1k", "plummer_16k")
BUNDLED = sorted(bundled_scenarios())

#: Full runs and the max |dE/E| each must stay under (pythagorean: ias15 through encounters at
#: 1e-4 separations, 1.3e-10 measured; many_encounters: trace, REBOUND's bound, 1.1e-5 measured).
ENERGY_BOUNDS = {"two_body_circular": 1e-7, "two_body_eccentric": 1e-5, "figure_eight": 1e-9, "pythagorean": 1e-9,
                 "many_encounters": 5e-5, "solar_system": 1e-6, "outer_solar_system": 1e-6, "plummer_1k": 1e-2,
                 "plummer_16k": 1e-5}


def test_required_scenarios_are_bundled() -> None:
    missing = set(REQUIRED) - set(BUNDLED)
    assert not missing


def test_every_bundled_scenario_validates() -> None:
    result = CliRunner().invoke(cli, ["validate", *BUNDLED])
    assert result.exit_code == 0, result.output
    assert result.output.count("ok: ") == len(BUNDLED)


@pytest.mark.parametrize("name", BUNDLED)
def test_bundled_scenario_is_self_consistent(name: str) -> None:
    s = load_scenario(name)
    assert s.name == name and s.description
    assert Path(s.source).name == f"{name}.yaml"
    assert s.n_bodies >= 2 and len(set(s.names)) == s.n_bodies
    # A bundled run must stay small on disk: positions only where N is modest.
    per_sample = 48 * s.n_bodies if s.record_positions else 0
    assert len(s.sample_steps()) * (per_sample + 100) < 64 * 2**20


def test_figure_eight_initial_conditions() -> None:
    s = load_scenario("figure_eight")
    x1 = np.array([0.97000436, -0.24308753, 0.0])
    v3 = np.array([-0.93240737, -0.86473146, 0.0])
    assert np.array_equal(s.positions, [x1, -x1, np.zeros(3)])
    assert np.array_equal(s.velocities, [-v3 / 2, -v3 / 2, v3])
    assert s.G == 1.0 and np.all(s.masses == 1.0)


def test_pythagorean_initial_conditions() -> None:
    s = load_scenario("pythagorean")
    assert np.array_equal(s.masses, [3, 4, 5]) and s.softening == 0.0 and s.G == 1.0
    assert np.array_equal(s.positions[:, :2], [[1, 3], [-2, -1], [1, -1]]) and not np.any(s.velocities)


def test_plummer_16k_keeps_the_trace_small() -> None:
    s = load_scenario("plummer_16k")
    assert s.n_bodies == 16384 and not s.record_positions and s.steps <= 10


#: Bundled scenarios whose loop is a kernel family of its own, 10-45 s to compile on a cold cache (TRACE
#: with events, IAS15 or Wisdom-Holman with GR or harmonics, Wisdom-Holman's corrector, a 16k-body
#: Plummer sphere): they run a few steps in `make test-slow`, beside their full runs. `make test` runs
#: every other bundled scenario, which covers every scheme; forces stay in it through tests/forces/.
SLOW_TO_COMPILE = {"j2_satellite", "many_encounters", "mercury_gr", "mercury_gr_planets", "resonance_capture",
                   "solar_system_wh", "comet", "plummer_16k"}


@pytest.mark.parametrize("name", [pytest.param(n, marks=pytest.mark.slow) if n in SLOW_TO_COMPILE else n
                                  for n in BUNDLED])
def test_bundled_scenario_runs_a_few_steps(name: str, tmp_path: Path) -> None:
    s = load_scenario(name)
    if s.adaptive:  # its grid is the output intervals: the first few of them
        s = dataclasses.replace(s, steps=min(s.steps, 5), t_end=min(s.steps, 5) * s.grid_dt)
    else:
        s = s.with_overrides(steps=min(s.steps, 1 if s.n_bodies > 5000 else 50), every=1)
    summary = run_scenario(s, tmp_path / f"{name}.h5")
    assert summary.status == "complete", summary.message
    assert read_trace(summary.output).n_samples == s.steps + 1


@pytest.mark.slow
@pytest.mark.parametrize("name", BUNDLED)
def test_bundled_scenario_full_run(name: str, tmp_path: Path) -> None:
    summary = run_scenario(load_scenario(name), tmp_path / f"{name}.h5")
    assert summary.status == "complete", summary.message
    if name in ENERGY_BOUNDS:
        assert summary.max_abs_energy_error < ENERGY_BOUNDS[name]
