"""Scenario loading and resolution: schema, units, bodies from every source, resolved YAML, overrides."""

from __future__ import annotations

import math
import textwrap
from pathlib import Path

import numpy as np
import pytest

from orbitsim.scenario import (
    Scenario,
    ScenarioError,
    bundled_scenarios,
    load_scenario,
    resolve_steps,
    scenario_from_dict,
)
from orbitsim.scenario.yamlio import parse_yaml
from orbitsim.units import GAUSSIAN_K, GAUSSIAN_YEAR_DAYS

TWO_BODY = {
    "name": "pair",
    "integrator": "kdk",
    "dt": 0.01,
    "steps": 100,
    "bodies": [
        {"name": "star", "m": 1.0, "x": [0, 0, 0], "v": [0, 0, 0]},
        {"name": "planet", "m": 1e-3, "primary": "star", "a": 1.0, "e": 0.1, "M": 30},
    ],
}


def write(tmp_path: Path, text: str, name: str = "s.yaml") -> Path:
    path = tmp_path / name
    path.write_text(textwrap.dedent(text), encoding="utf-8")
    return path


def test_minimal_scenario_defaults() -> None:
    s = scenario_from_dict(TWO_BODY)
    assert isinstance(s, Scenario)
    assert s.integrator == "verlet"  # alias resolved to the canonical name
    assert (s.units, s.G, s.softening, s.frame, s.source) == ("nbody", 1.0, 0.0, "as_given", "<inline>")
    assert s.names == ("star", "planet") and s.n_bodies == 2
    assert s.masses.shape == (2,) and s.positions.shape == (2, 3) and s.velocities.shape == (2, 3)
    assert s.record_positions is True  # default up to N = 1000
    assert s.steps == 100 and s.t_end is None and s.end_time == pytest.approx(1.0)
    assert s.sample_every == 1  # ceil(100 / 1000)
    steps = s.sample_steps()
    assert steps[0] == 0 and steps[-1] == 100 and steps.dtype == np.int64


def test_scenario_is_frozen() -> None:
    s = scenario_from_dict(TWO_BODY)
    with pytest.raises(AttributeError):
        s.dt = 1.0  # type: ignore[misc]


@pytest.mark.parametrize(("units", "G"), [("nbody", 1.0), ("au-yr-msun", 4 * math.pi**2),
                                          ("au-day-msun", GAUSSIAN_K**2), ("si", 6.67430e-11)])
def test_units_set_g(units: str, G: float) -> None:
    assert scenario_from_dict({**TWO_BODY, "units": units}).G == pytest.approx(G, rel=1e-15)


def test_explicit_g_overrides_units() -> None:
    assert scenario_from_dict({**TWO_BODY, "units": "si", "G": 2.5}).G == 2.5


def test_t_end_resolves_to_whole_steps_that_fit() -> None:
    doc = {k: v for k, v in TWO_BODY.items() if k != "steps"}
    s = scenario_from_dict({**doc, "dt": 0.3, "t_end": 1.0})
    assert s.steps == 3 and s.t_end == 1.0 and not s.t_end_is_whole
    assert s.end_time == pytest.approx(0.9)
    (note,) = s.notes()
    assert "not a whole number of steps" in note and "3 whole steps" in note and "t = 0.9" in note


def test_t_end_round_off_counts_as_whole() -> None:
    assert resolve_steps(1.0, 0.1) == (10, True)  # 1 / 0.1 = 9.999999999999998
    assert resolve_steps(100.0, 0.01) == (10000, True)
    with pytest.raises(ScenarioError, match="shorter than one step"):
        resolve_steps(0.05, 0.1)


def test_interval_sampling_lands_on_last_whole_step() -> None:
    doc = {**TWO_BODY, "dt": 0.3, "steps": 10, "output": {"interval": 1.0}}
    s = scenario_from_dict(doc)
    steps = s.sample_steps()
    times = steps * s.dt
    assert steps[0] == 0 and steps[-1] == 10
    for k, t in enumerate(times[:-1]):
        assert t <= k * 1.0 < t + s.dt  # the last whole step not past each sample time


def test_positions_default_off_above_1000_bodies() -> None:
    doc = {"integrator": "verlet", "dt": 0.01, "steps": 1, "softening": 0.01,
           "generator": {"kind": "plummer", "n": 1001, "seed": 0}}
    assert scenario_from_dict(doc).record_positions is False
    assert scenario_from_dict({**doc, "output": {"positions": True}}).record_positions is True


def test_barycentric_frame_shift() -> None:
    doc = {**TWO_BODY, "frame": "barycentric"}
    s = scenario_from_dict(doc)
    raw = scenario_from_dict(TWO_BODY)
    assert np.allclose(s.masses @ s.positions, 0.0, atol=1e-17)
    assert np.allclose(s.masses @ s.velocities, 0.0, atol=1e-17)
    # A pure translation: relative positions are unchanged.
    assert np.allclose(s.positions[1] - s.positions[0], raw.positions[1] - raw.positions[0], rtol=1e-15)
    assert s.frame == "barycentric"


def test_elements_match_rebound_elliptic_and_hyperbolic() -> None:
    rebound = pytest.importorskip("rebound")
    doc = {
        "integrator": "verlet", "dt": 0.01, "steps": 1, "G": 1.3,
        "bodies": [
            {"name": "sun", "m": 1.2, "x": [0.1, -0.2, 0.3], "v": [0.01, 0.02, -0.03]},
            {"name": "ell", "m": 1e-3, "primary": "sun", "a": 1.5, "e": 0.3, "inc": 10, "Omega": 20,
             "omega": 30, "M": 40},
            {"name": "hyp", "m": 0.0, "primary": "sun", "a": -2.0, "e": 1.7, "inc": 95, "Omega": 200,
             "omega": -30, "f": -50},
        ],
    }
    s = scenario_from_dict(doc)
    sim = rebound.Simulation()
    sim.G = 1.3
    sim.add(m=1.2, x=0.1, y=-0.2, z=0.3, vx=0.01, vy=0.02, vz=-0.03)
    rad = math.radians
    sim.add(primary=sim.particles[0], m=1e-3, a=1.5, e=0.3, inc=rad(10), Omega=rad(20), omega=rad(30), M=rad(40))
    sim.add(primary=sim.particles[0], m=0.0, a=-2.0, e=1.7, inc=rad(95), Omega=rad(200), omega=rad(-30),
            f=rad(-50))
    for i in (1, 2):
        p = sim.particles[i]
        assert np.allclose(s.positions[i], [p.x, p.y, p.z], rtol=1e-12, atol=1e-13)
        assert np.allclose(s.velocities[i], [p.vx, p.vy, p.vz], rtol=1e-12, atol=1e-13)


def test_ephemeris_scenario_loads_de421_j2000() -> None:
    from orbitsim.initial_conditions.ephemeris import de421_states

    s = load_scenario("solar_system")
    assert s.units == "au-day-msun" and s.n_bodies == 10
    states = de421_states(list(s.names), 2451545.0)
    assert np.array_equal(s.positions, states.positions)
    assert np.allclose(s.masses * s.G, states.gm, rtol=1e-15)
    assert s.masses[s.names.index("sun")] == pytest.approx(1.0, rel=1e-9)
    earth = s.positions[s.names.index("earthmoon")] - s.positions[0]
    assert np.linalg.norm(earth) == pytest.approx(0.983, abs=0.01)  # perihelion season in January


def test_ephemeris_unit_conversion_keeps_gm() -> None:
    doc = {"integrator": "verlet", "dt": 1.0, "steps": 1, "units": "au-yr-msun",
           "ephemeris": {"jd": 2451545.0, "bodies": ["sun", "jupiter"]}}
    yr = scenario_from_dict(doc)
    day = scenario_from_dict({**doc, "units": "au-day-msun"})
    assert np.allclose(yr.velocities, day.velocities * GAUSSIAN_YEAR_DAYS, rtol=1e-15)
    assert np.allclose(yr.masses * yr.G, day.masses * day.G * GAUSSIAN_YEAR_DAYS**2, rtol=1e-14)


def test_generators_are_reproducible_and_named() -> None:
    doc = {"integrator": "verlet", "dt": 0.01, "steps": 1, "softening": 0.01,
           "generator": [{"kind": "plummer", "n": 50, "seed": 7, "prefix": "p"},
                         {"kind": "disc", "n": 20, "seed": 1, "r_min": 10, "r_max": 20, "star": "sun"}]}
    a, b = scenario_from_dict(doc), scenario_from_dict(doc)
    assert np.array_equal(a.positions, b.positions) and np.array_equal(a.velocities, b.velocities)
    assert a.n_bodies == 50 + 21
    assert a.names[0] == "p00" and a.names[50] == "sun" and a.names[51] == "disc00"


def test_elements_may_orbit_ephemeris_bodies() -> None:
    doc = {"integrator": "verlet", "dt": 1.0, "steps": 1, "units": "au-day-msun",
           "ephemeris": {"epoch": "2000-01-01T12:00:00", "bodies": ["sun"]},
           "bodies": [{"name": "rock", "m": 0.0, "primary": "sun", "a": 2.5, "e": 0.1, "M": 0}]}
    s = scenario_from_dict(doc)
    assert np.linalg.norm(s.positions[1] - s.positions[0]) == pytest.approx(2.25, rel=1e-12)


def test_resolved_yaml_reloads_to_the_same_bits(tmp_path: Path) -> None:
    for name in ("figure_eight", "solar_system", "kepler_disc", "two_body_eccentric"):
        s = load_scenario(name)
        text = s.to_yaml()
        again = load_scenario(write(tmp_path, text, f"{name}.yaml"))
        for attr in ("masses", "positions", "velocities"):
            assert np.array_equal(getattr(s, attr), getattr(again, attr)), (name, attr)
        assert (again.steps, again.dt, again.G, again.names) == (s.steps, s.dt, s.G, s.names)
        assert np.array_equal(again.sample_steps(), s.sample_steps())
        assert again.sha256 == s.sha256 and again.to_yaml() == text


def test_yaml_reader_extensions() -> None:
    doc, lines = parse_yaml("a: 1e-3\nb: 2000-01-01\nc:\n  - 1\n", "x.yaml")
    assert doc == {"a": 0.001, "b": "2000-01-01", "c": [1]}
    assert lines["c[0]"] == 4 and lines["b"] == 2


def test_with_overrides_revalidates() -> None:
    doc = {k: v for k, v in TWO_BODY.items() if k != "steps"}
    s = scenario_from_dict({**doc, "t_end": 1.0, "output": {"interval": 0.1}})
    assert s.with_overrides(dt=0.001).steps == 1000  # t_end kept, steps re-derived
    by_steps = s.with_overrides(steps=7)
    assert (by_steps.steps, by_steps.t_end) == (7, None)
    assert by_steps.with_overrides(dt=0.5).steps == 7  # steps kept when the scenario gave steps
    every = s.with_overrides(every=3)
    assert (every.every, every.interval) == (3, None)
    assert s.with_overrides(integrator="leapfrog4").integrator == "leapfrog4"
    with pytest.raises(ScenarioError, match="dt"):
        s.with_overrides(dt=-1.0)
    with pytest.raises(ScenarioError, match="unknown integrator"):
        s.with_overrides(integrator="nope")
    with pytest.raises(ScenarioError, match="unknown key 'stpes'; did you mean 'steps'"):
        s.with_overrides(stpes=3)
    assert s.with_overrides(dt=None) is not s  # None values are ignored, still a copy


def test_integrator_settings_are_checked() -> None:
    wh = {**TWO_BODY, "integrator": {"name": "wh", "corrector": 17}}
    s = scenario_from_dict(wh)
    assert s.integrator == "wisdom_holman" and s.integrator_settings["corrector"] == 17
    assert "corrector: 17" in s.to_yaml()
    with pytest.raises(ScenarioError, match=r"integrator\.corector: unknown key 'corector'; did you mean"):
        scenario_from_dict({**TWO_BODY, "integrator": {"name": "wh", "corector": 17}})
    with pytest.raises(ScenarioError, match=r"integrator\.corrector"):
        scenario_from_dict({**TWO_BODY, "integrator": {"name": "wh", "corrector": 4}})
    with pytest.raises(ScenarioError, match="takes no settings"):
        scenario_from_dict({**TWO_BODY, "integrator": {"name": "verlet", "order": 2}})


def test_error_str_is_one_line_with_file_key_and_line(tmp_path: Path) -> None:
    path = write(tmp_path, """\
        integrator: verlet
        dt: 0.1
        steps: 10
        bodies:
          - {name: a, m: 1, x: [0, 0, 0], v: [0, 0, 0]}
          - {name: b, m: -1, x: [1, 0, 0], v: [0, 0, 0]}
        """)
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    err = info.value
    assert (err.file, err.key, err.line) == (str(path), "bodies[1].m", 6)
    assert str(err) == f"{path}: bodies[1].m: mass must be >= 0, got -1 (line 6)"
    assert "\n" not in str(err) and isinstance(err, ValueError)


def test_bundled_scenarios_found() -> None:
    found = bundled_scenarios()
    expected = {"two_body_circular", "two_body_eccentric", "figure_eight", "pythagorean", "solar_system",
                "outer_solar_system", "plummer_1k", "plummer_16k"}
    assert expected <= set(found)
    assert all(p.suffix == ".yaml" and p.is_file() for p in found.values())


def test_name_defaults_to_file_stem(tmp_path: Path) -> None:
    path = write(tmp_path, "integrator: verlet\ndt: 0.1\nsteps: 1\nbodies: [{name: a, m: 1, x: [0,0,0], "
                 "v: [0,0,0]}]\n", "my run.yaml")
    assert load_scenario(path).name == "my_run"
