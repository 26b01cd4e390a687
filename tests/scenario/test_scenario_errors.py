"""Every kind of malformed scenario: one line naming file, key path and fix; exit 2; no output file.

Each case is checked twice: through :func:`load_scenario` (the error object) and through
``orbitsim run`` with click's runner (exit code, message, no traceback, nothing written).
"""

from __future__ import annotations

import textwrap
from pathlib import Path

import pytest
from click.testing import CliRunner

from orbitsim.cli.main import cli
from orbitsim.scenario import ScenarioError, load_scenario

HEAD = "integrator: verlet\ndt: 0.01\nsteps: 10\n"
STAR = "  - {name: star, m: 1.0, x: [0, 0, 0], v: [0, 0, 0]}\n"
PLANET = "  - {name: planet, m: 1.0e-3, x: [1, 0, 0], v: [0, 1, 0]}\n"
BODIES = "bodies:\n" + STAR + PLANET

# (id, YAML text, key path expected in the message (None: no key), fragment of the reason)
CASES = [
    ("yaml_syntax", HEAD + "bodies: [\n", None, "YAML syntax error"),
    ("yaml_tab", HEAD + "bodies:\n\t- {name: a}\n", None, "YAML syntax error"),
    ("unknown_key", HEAD + "colour: red\n" + BODIES, "colour", "unknown key 'colour'"),
    ("misspelt_key", "integrator: verlet\ndt: 0.01\nstpes: 10\n" + BODIES, "stpes", "did you mean 'steps'?"),
    ("misspelt_nested_key", HEAD + "output: {evry: 2}\n" + BODIES, "output.evry", "did you mean 'every'?"),
    ("duplicate_key", HEAD + "dt: 0.02\n" + BODIES, "dt", "duplicate key 'dt' (first given on line 2)"),
    ("wrong_type", "integrator: verlet\ndt: fast\nsteps: 10\n" + BODIES, "dt", "expected a number"),
    ("wrong_type_vector", HEAD + "bodies:\n  - {name: a, m: 1, x: [0, 0], v: [0, 0, 0]}\n", "bodies[0].x",
     "list of 3 numbers"),
    ("missing_key", "integrator: verlet\nsteps: 10\n" + BODIES, "dt", "required key 'dt' is missing"),
    ("missing_body_key", HEAD + "bodies:\n  - {name: a, x: [0, 0, 0], v: [0, 0, 0]}\n", "bodies[0].m",
     "required key 'm'"),
    ("nan", "integrator: verlet\ndt: .nan\nsteps: 10\n" + BODIES, "dt", "finite"),
    ("inf", HEAD + "bodies:\n  - {name: a, m: 1, x: [.inf, 0, 0], v: [0, 0, 0]}\n", "bodies[0].x[0]",
     "finite"),
    ("negative_mass", HEAD + "bodies:\n" + STAR + "  - {name: b, m: -1, x: [1, 0, 0], v: [0, 0, 0]}\n",
     "bodies[1].m", "mass must be >= 0, got -1"),
    ("dt_zero", "integrator: verlet\ndt: 0\nsteps: 10\n" + BODIES, "dt", "must be non-zero"),
    # dt < 0 runs backwards (tests/scenario/test_backward.py); its end time must then be negative too.
    ("dt_negative_t_end_positive", "integrator: verlet\ndt: -0.1\nt_end: 1\n" + BODIES, "t_end", "must be < 0"),
    ("dt_negative_adaptive", "integrator: ias15\ndt: -0.1\nt_end: 1\n" + BODIES, "dt", "cannot run backwards"),
    ("steps_and_t_end", HEAD + "t_end: 1.0\n" + BODIES, "t_end", "only one of steps or t_end"),
    ("neither_steps_nor_t_end", "integrator: verlet\ndt: 0.01\n" + BODIES, None, "give one of steps or t_end"),
    ("steps_not_whole", "integrator: verlet\ndt: 0.01\nsteps: 10.5\n" + BODIES, "steps", "whole number"),
    ("every_and_interval", HEAD + "output: {every: 2, interval: 0.1}\n" + BODIES, "output.interval",
     "only one of every or interval"),
    ("duplicate_body_name", HEAD + "bodies:\n" + STAR + STAR.replace("0, 0, 0]", "1, 0, 0]", 1),
     "bodies[1].name", "duplicate body name 'star'"),
    ("unknown_primary", HEAD + "bodies:\n" + STAR + "  - {name: p, m: 0, primary: sun, a: 1, M: 0}\n",
     "bodies[1].primary", "unknown primary 'sun'"),
    ("elements_bad_sign", HEAD + "bodies:\n" + STAR + "  - {name: p, m: 0, primary: star, a: 1, e: 1.5, f: 0}\n",
     "bodies[1].a", "negative for a hyperbolic orbit"),
    ("unknown_integrator", "integrator: rk45\ndt: 0.01\nsteps: 10\n" + BODIES, "integrator",
     "unknown integrator 'rk45'"),
    ("unknown_integrator_setting", "integrator: {name: verlet, order: 2}\ndt: 0.01\nsteps: 10\n" + BODIES,
     "integrator.order", "takes no settings"),
    ("coincident_bodies", HEAD + "bodies:\n" + STAR + STAR.replace("star", "twin"), "bodies[1].x",
     "are both at (0, 0, 0) and softening is 0"),
    ("huge_generator", HEAD + "softening: 0.1\ngenerator: {kind: plummer, n: 1000000000000, seed: 1}\n",
     "generator.n", "of memory"),
    ("unknown_generator_kind", HEAD + "generator: {kind: plumer, n: 10, seed: 1}\n", "generator.kind",
     "did you mean 'plummer'?"),
    ("unknown_units", "units: cgs\n" + HEAD + BODIES, "units", "unknown value 'cgs'"),
    ("ephemeris_unknown_body", "units: au-day-msun\n" + HEAD + "ephemeris: {jd: 2451545.0, bodies: [sun, vulcan]}\n",
     "ephemeris.bodies[1]", "unknown ephemeris body 'vulcan'"),
    ("ephemeris_needs_units", HEAD + "ephemeris: {jd: 2451545.0, bodies: [sun]}\n", "units",
     "ephemeris states are in au and days"),
    ("object_tag", HEAD + "name: !!python/object/apply:os.system ['echo hacked']\n" + BODIES, "name",
     "is not allowed"),
    ("scalar_object_tag", "integrator: verlet\ndt: !!python/name:os.system\nsteps: 10\n" + BODIES, "dt",
     "is not allowed"),
    ("binary_tag", HEAD + "description: !!binary aGVsbG8=\n" + BODIES, "description", "is not allowed"),
    ("no_bodies", HEAD, None, "no bodies"),
    ("not_a_mapping", "- 1\n- 2\n", None, "expected a scenario of keys and values"),
    ("empty_file", "", None, "the scenario is empty"),
    ("bad_name", "name: ../evil\n" + HEAD + BODIES, "name", "plain file name"),
    # Times with a unit (issue 27, item 13): every time key names itself.
    ("dt_length_unit", "units: si\nintegrator: verlet\ndt: 1 km\nsteps: 10\n" + BODIES, "dt",
     "'km' is a length, not a time"),
    ("dt_unit_in_nbody", "integrator: verlet\ndt: 1 day\nsteps: 10\n" + BODIES, "dt", "no physical scale"),
    ("dt_unit_own_g", "units: si\nG: 1\nintegrator: verlet\ndt: 1 day\nsteps: 10\n" + BODIES, "dt",
     "sets its own G"),
    ("t_end_unknown_unit", "units: si\nintegrator: verlet\ndt: 1 h\nt_end: 3 fortnights\n" + BODIES, "t_end",
     "unknown unit"),
    ("t_end_unit_too_short", "units: si\nintegrator: verlet\ndt: 1 day\nt_end: 1 h\n" + BODIES, "t_end",
     "shorter than one step"),
    ("t_start_not_a_time", "units: si\nintegrator: verlet\ndt: 1 h\nsteps: 10\nt_start: 1 Msun\n" + BODIES,
     "t_start", "'msun' is a mass, not a time"),
    ("interval_negative_unit", "units: si\n" + HEAD + "output: {interval: -1 day}\n" + BODIES, "output.interval",
     "must be > 0"),
    ("interval_bad_text", "units: si\n" + HEAD + "output: {interval: soon}\n" + BODIES, "output.interval",
     'such as "10 yr" or "1 day"'),
    ("checkpoint_every_shorter_than_a_step", "units: si\nintegrator: verlet\ndt: 1 day\nsteps: 10\n"
     "output: {checkpoint: {every: 1 h}}\n" + BODIES, "output.checkpoint.every", "shorter than one step"),
    ("checkpoint_every_mass", "units: si\n" + HEAD + "output: {checkpoint: {every: 2 kg}}\n" + BODIES,
     "output.checkpoint.every", "'kg' is a mass, not a time"),
    ("checkpoint_seconds_length", HEAD + "output: {checkpoint: {seconds: 10 km}}\n" + BODIES,
     "output.checkpoint.seconds", "'km' is a length, not a time"),
    ("checkpoint_seconds_negative", HEAD + "output: {checkpoint: {seconds: -2 min}}\n" + BODIES,
     "output.checkpoint.seconds", "must be > 0"),
    # Integrator names (item 14): the nearest name, REBOUND's names.
    ("misspelt_integrator", "integrator: leapfrg\ndt: 0.01\nsteps: 10\n" + BODIES, "integrator",
     "did you mean 'leapfrog'?"),
    ("rebound_mercurius", "integrator: mercurius\ndt: 0.01\nsteps: 10\n" + BODIES, "integrator",
     "REBOUND's mercurius is not in orbitsim; the closest is trace"),
    ("rebound_saba", "integrator: SABA4\ndt: 0.01\nsteps: 10\n" + BODIES, "integrator",
     "the closest is wisdom_holman"),
    ("rebound_leapfrog_order", "integrator: {name: leapfrog, order: 3}\ndt: 0.01\nsteps: 10\n" + BODIES,
     "integrator.order", "must be one of 2, 4, 6, 8"),
    # A disc of planetesimals (item 16).
    ("disc_m_min_alone", HEAD + "generator: {kind: disc, n: 5, seed: 1, r_min: 1, r_max: 2, m_min: 1e-6}\n",
     "generator.m_max", "give both m_min and m_max"),
    ("disc_m_min_above_m_max", HEAD + "generator: {kind: disc, n: 5, seed: 1, r_min: 1, r_max: 2, m_min: 2e-6, "
     "m_max: 1e-6, mass_index: -2}\n", "generator.m_max", "must be >= m_min"),
    ("disc_mass_zero", HEAD + "generator: {kind: disc, n: 5, seed: 1, r_min: 1, r_max: 2, m_min: 0, m_max: 1e-6, "
     "mass_index: -2}\n", "generator.m_min", "must be > 0"),
    ("disc_no_mass_index", HEAD + "generator: {kind: disc, n: 5, seed: 1, r_min: 1, r_max: 2, m_min: 1e-9, "
     "m_max: 1e-6}\n", "generator.mass_index", "needs the power-law index"),
    ("disc_mass_index_text", HEAD + "generator: {kind: disc, n: 5, seed: 1, r_min: 1, r_max: 2, m_min: 1e-9, "
     "m_max: 1e-6, mass_index: steep}\n", "generator.mass_index", "expected a number"),
    ("disc_density_without_masses", HEAD + "generator: {kind: disc, n: 5, seed: 1, r_min: 1, r_max: 2, "
     "density: 1}\n", "generator.density", "give m_min and m_max too"),
    ("disc_density_not_cubed", "units: au-yr-msun\n" + HEAD + "generator: {kind: disc, n: 5, seed: 1, r_min: 1, "
     "r_max: 2, m_min: 1e-9, m_max: 1e-9, density: 2 g/cm2}\n", "generator.density", "a mass over a length cubed"),
    ("disc_density_negative", HEAD + "generator: {kind: disc, n: 5, seed: 1, r_min: 1, r_max: 2, m_min: 1e-9, "
     "m_max: 1e-9, density: -3}\n", "generator.density", "must be > 0"),
    ("disc_star_r_negative", HEAD + "generator: {kind: disc, n: 5, seed: 1, r_min: 1, r_max: 2, star_r: -1}\n",
     "generator.star_r", "must be >= 0"),
]
IDS = [case[0] for case in CASES]


def write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "broken.yaml"
    path.write_text(text, encoding="utf-8")
    return path


@pytest.mark.parametrize(("case", "text", "key", "fragment"), CASES, ids=IDS)
def test_malformed_scenario_error(tmp_path: Path, case: str, text: str, key: str | None, fragment: str) -> None:
    path = write(tmp_path, text)
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    err = info.value
    message = str(err)
    assert err.file == str(path)
    assert message.startswith(f"{path}: ")
    if key is not None:
        assert err.key == key, message
        assert f": {key}: " in message
    assert fragment in message
    assert "\n" not in message


@pytest.mark.parametrize(("case", "text", "key", "fragment"), CASES, ids=IDS)
def test_malformed_scenario_cli(tmp_path: Path, case: str, text: str, key: str | None, fragment: str) -> None:
    path = write(tmp_path, text)
    out = tmp_path / "out.h5"
    result = CliRunner().invoke(cli, ["run", str(path), "-o", str(out), "-q"])
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output
    assert result.exception is None or isinstance(result.exception, SystemExit)
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("orbitsim: error: ")
    assert str(path) in lines[0] and fragment in lines[0]
    if key is not None:
        assert key in lines[0]
    assert not out.exists() and not Path(str(out) + ".tmp").exists()
    assert list(tmp_path.iterdir()) == [path]


def test_duplicate_key_names_both_lines(tmp_path: Path) -> None:
    path = write(tmp_path, HEAD + textwrap.dedent("""\
        bodies:
          - name: a
            m: 1
            m: 2
            x: [0, 0, 0]
            v: [0, 0, 0]
        """))
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    assert info.value.key == "bodies[0].m" and info.value.line == 7
    assert "first given on line 6" in str(info.value)


def test_missing_file_and_unknown_bundled_name(tmp_path: Path) -> None:
    with pytest.raises(ScenarioError, match="no such file"):
        load_scenario(tmp_path / "nope.yaml")
    with pytest.raises(ScenarioError, match="did you mean 'figure_eight'"):
        load_scenario("figure_eigth")


def test_validate_reports_every_bad_file(tmp_path: Path) -> None:
    bad = write(tmp_path, HEAD + "stpes: 3\n" + BODIES)
    result = CliRunner().invoke(cli, ["validate", "two_body_circular", str(bad)])
    assert result.exit_code == 2
    assert "ok: two_body_circular" in result.output
    assert f"orbitsim: error: {bad}: stpes: unknown key 'stpes'; did you mean 'steps'?" in result.output
