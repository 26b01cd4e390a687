"""The scenario's ``forces:`` list: resolution, arrays, round trips, and one-line refusals.

Every refusal is checked three ways: the error object of :func:`load_scenario` (file, key path, one
line), ``orbitsim validate`` and ``orbitsim run`` (exit 2, one line naming file and key, nothing
written).
"""

from __future__ import annotations

import math
import textwrap
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from orbitsim.batch.sweep import SweepError, load_sweep
from orbitsim.cli.main import cli
from orbitsim.forces.compat import FORCE_INTEGRATORS, check_integrator
from orbitsim.forces.table import GR_POTENTIAL, HARMONICS, MIGRATION, P_C, P_J2, P_J4, P_R_EQ, P_SPIN
from orbitsim.integrators.registry import NAMES
from orbitsim.scenario import ScenarioError, load_scenario, scenario_from_dict
from orbitsim.scenario.forces import SPEED_OF_LIGHT, default_c, force_set
from orbitsim.scenario.yamlio import parse_yaml

# The planet is listed first and the star second, so a default source that took body 0 (REBOUNDx's
# convention) instead of the heaviest would show.
HEAD = "integrator: {integrator}\ndt: 0.01\nsteps: 10\nunits: {units}\n"
BODIES = textwrap.dedent("""\
    bodies:
      - {name: planet, m: 1.0e-3, x: [1, 0, 0], v: [0, 1, 0]}
      - {name: star, m: 1.0, x: [0, 0, 0], v: [0, 0, 0]}
      - {name: moon, m: 0, x: [1.01, 0, 0], v: [0, 1.3, 0]}
    """)


def scenario_text(forces: str, integrator: str = "verlet", units: str = "au-yr-msun") -> str:
    return HEAD.format(integrator=integrator, units=units) + BODIES + "forces:\n" + textwrap.indent(
        textwrap.dedent(forces), "  ")


def write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "forced.yaml"
    path.write_text(text, encoding="utf-8")
    return path


def test_a_valid_list_resolves_defaults_and_builds_the_arrays(tmp_path: Path) -> None:
    path = write(tmp_path, scenario_text("""\
        - {force: gr_potential}
        - {force: harmonics, body: planet, J2: 1.0e-3, R_eq: 1.0e-4, spin_axis: [0, 3, 4]}
        - force: migration
          bodies:
            moon: {tau_a: -1.0e6, tau_e: -1.0e4}
            star: {tau_inc: 2.5e5}
        """).replace("- {name: star", "- {name: sun0, m: 0, x: [5, 0, 0], v: [0, 0.4, 0]}\n  - {name: star"))
    s = load_scenario(path)
    names = list(s.names)
    assert names == ["planet", "sun0", "star", "moon"]
    gr, harm, mig = s.forces
    assert gr == {"force": "gr_potential", "c": SPEED_OF_LIGHT["au-yr-msun"], "source": "star"}  # heaviest
    assert harm["J4"] == 0.0 and harm["spin_axis"] == [0.0, 0.6, 0.8]  # default J4; axis normalised
    assert mig["bodies"] == {"moon": {"tau_a": -1.0e6, "tau_e": -1.0e4}, "star": {"tau_inc": 2.5e5}}

    fs = force_set(s)
    ids, source, params, per_body = fs.arrays
    assert ids.tolist() == [GR_POTENTIAL, HARMONICS, MIGRATION] and ids.dtype == np.int64
    assert source.tolist() == [2, 0, -1] and source.dtype == np.int64
    assert params[0, P_C] == SPEED_OF_LIGHT["au-yr-msun"] and params[1, P_C] == 0.0
    assert (params[1, P_J2], params[1, P_J4], params[1, P_R_EQ]) == (1.0e-3, 0.0, 1.0e-4)
    assert params[1, P_SPIN:P_SPIN + 3].tolist() == [0.0, 0.6, 0.8]
    assert per_body.shape == (3, 3, 4) and not per_body[:2].any()
    expected = np.full((3, 4), np.inf)
    expected[0, 3], expected[1, 3], expected[2, 2] = -1.0e6, -1.0e4, 2.5e5  # tau_a, tau_e of moon; tau_inc of star
    assert np.array_equal(per_body[2], expected)
    assert fs.names == ("gr_potential", "harmonics", "migration") and fs.entries == s.forces


def test_no_forces_means_an_empty_tuple_and_no_force_set(tmp_path: Path) -> None:
    s = load_scenario(write(tmp_path, HEAD.format(integrator="verlet", units="nbody") + BODIES))
    assert s.forces == () and force_set(s) is None
    assert "forces" not in s.to_dict()  # the resolved text (and SHA-256) of a scenario without forces is unchanged
    nulled = load_scenario(write(tmp_path, HEAD.format(integrator="verlet", units="nbody") + BODIES + "forces: null\n"))
    assert nulled.forces == () and nulled.sha256 == s.sha256


def test_the_resolved_scenario_round_trips_bit_for_bit(tmp_path: Path) -> None:
    path = write(tmp_path, scenario_text("""\
        - {force: gr, c: 10065.32012038219, source: star}
        - {force: harmonics, body: star, J2: 2.0e-7, J4: -1.0e-9, R_eq: 4.65e-3, spin_axis: [0.1, 0.2, 0.9]}
        - {force: migration, bodies: {moon: {tau_a: -3.0e5}}}
        """, units="nbody"))
    s = load_scenario(path)
    text = s.to_yaml()
    assert "forces:\n  - {force: \"gr\", c: 10065.32012038219, source: \"star\"}" in text
    again = scenario_from_dict(parse_yaml(text, "again")[0])
    assert again.forces == s.forces and again.sha256 == s.sha256 and again.to_yaml() == text
    axis = np.array(s.forces[1]["spin_axis"])
    assert abs(float(axis @ axis) - 1.0) < 1e-15  # normalised, to rounding


def test_overrides_revalidate_the_forces(tmp_path: Path) -> None:
    s = load_scenario(write(tmp_path, scenario_text("- {force: gr_full, c: 100.0}\n", integrator="rk4")))
    assert s.with_overrides(integrator="ias15", t_end=0.1).forces == s.forces
    with pytest.raises(ScenarioError) as info:
        s.with_overrides(integrator="leapfrog")
    assert info.value.key == "forces[0]" and "integrators that can: rk4, ias15" in str(info.value)
    assert s.with_overrides(names=("a", "b", "c")).forces == s.forces  # gr_full names no body
    gr = load_scenario(write(tmp_path, scenario_text("- {force: gr, source: star}\n")))
    with pytest.raises(ScenarioError) as info:
        gr.with_overrides(names=("planet", "sun", "moon"))
    assert info.value.key == "forces[0].source" and "no body named 'star'" in str(info.value)


def test_speed_of_light_defaults_follow_the_iau_definitions() -> None:
    assert default_c("si", 6.67430e-11) == 299_792_458.0
    assert default_c("au-day-msun", 0.01720209895**2) == pytest.approx(173.1446326742403, rel=1e-15)  # rounding only
    # orbitsim's year is the Gaussian year 2 pi / k days, so c per year is REBOUND's c per (yr / 2 pi) times 2 pi.
    assert default_c("au-yr-msun", 4 * math.pi**2) / (2 * math.pi) == pytest.approx(10065.32012038219, rel=1e-15)
    assert default_c("nbody", 1.0) is None
    assert default_c("au-yr-msun", 1.0) is None  # G overridden: the time unit is not the Gaussian year


def test_compatibility_table_names_real_integrators_and_refuses_trace() -> None:
    for name, integrators in FORCE_INTEGRATORS.items():
        assert set(integrators) <= set(NAMES) and "trace" not in integrators, name
        for integrator in NAMES:
            refusal = check_integrator([name], integrator)
            assert (refusal is None) == (integrator in integrators)
            if refusal is not None:
                assert "\n" not in refusal and refusal.endswith(f"integrators that can: {', '.join(integrators)}")
    refusal = check_integrator(["gr_potential", "gr_full"], "wisdom_holman")
    assert refusal.startswith("wisdom_holman cannot apply gr_full")
    assert check_integrator([], "trace") is None


def test_a_sweep_can_vary_a_force_parameter_and_is_blamed_for_a_bad_one(tmp_path: Path) -> None:
    base = write(tmp_path, scenario_text("- {force: harmonics, body: star, J2: 1.0e-3, R_eq: 0.01}\n"))
    sweep = tmp_path / "sweep.yaml"
    sweep.write_text(f"base: {base}\ngrid: {{forces.0.J2: [1.0e-3, 2.0e-3]}}\n")
    cases = load_sweep(sweep).cases
    assert [c.scenario.forces[0]["J2"] for c in cases] == [1.0e-3, 2.0e-3]
    sweep.write_text(f"base: {base}\ngrid: {{forces.0.J2: [1.0e-3, -2.0e-3]}}\n")
    with pytest.raises(SweepError, match=r"grid\.forces\.0\.J2\[1\]: .*must be >= 0"):
        load_sweep(sweep)


def test_validate_lists_the_forces_and_notes_migration(tmp_path: Path) -> None:
    path = write(tmp_path, scenario_text("""\
        - {force: gr, source: star}
        - {force: migration, bodies: {moon: {tau_e: -1.0e3}}}
        """))
    result = CliRunner().invoke(cli, ["validate", str(path)])
    assert result.exit_code == 0, result.output
    assert "  forces: gr about star (c = 63242.27149), migration of moon" in result.output
    assert "migration adds or removes energy on purpose" in result.output


GR_ENTRY = "- {force: gr, source: star}\n"
BAD = [
    # (id, forces list, integrator, units, key, fragment of the reason)
    ("not_a_list", "{force: gr}", "verlet", "au-yr-msun", "forces", "expected a list of forces"),
    ("entry_not_mapping", "- gr\n", "verlet", "au-yr-msun", "forces[0]", "expected a force"),
    ("missing_force", "- {c: 1.0}\n", "verlet", "nbody", "forces[0].force", "required key 'force'"),
    ("unknown_force", "- {force: gr_ful}\n", "verlet", "nbody", "forces[0].force", "did you mean 'gr_full'?"),
    ("unknown_key", "- {force: gr, colour: red}\n", "verlet", "au-yr-msun", "forces[0].colour", "unknown key"),
    ("key_of_another_force", "- {force: gr_full, c: 1.0, source: star}\n", "rk4", "nbody",
     "forces[0].source", "gr_full takes no 'source'"),
    ("missing_body", "- {force: gr, source: sun}\n", "verlet", "au-yr-msun", "forces[0].source",
     "no body named 'sun'"),
    ("harmonics_no_body", "- {force: harmonics, J2: 1.0e-3, R_eq: 0.1}\n", "verlet", "nbody",
     "forces[0].body", "required key 'body'"),
    ("massless_source", "- {force: gr_potential, source: moon}\n", "verlet", "au-yr-msun", "forces[0].source",
     "has no mass"),
    ("j2_text", "- {force: harmonics, body: star, J2: big, R_eq: 0.1}\n", "verlet", "nbody", "forces[0].J2",
     "expected a number"),
    ("j2_negative", "- {force: harmonics, body: star, J2: -1.0e-3, R_eq: 0.1}\n", "verlet", "nbody",
     "forces[0].J2", "must be >= 0"),
    ("j2_nan", "- {force: harmonics, body: star, J2: .nan, R_eq: 0.1}\n", "verlet", "nbody", "forces[0].J2",
     "finite"),
    ("j2_inf", "- {force: harmonics, body: star, J2: .inf, R_eq: 0.1}\n", "verlet", "nbody", "forces[0].J2",
     "finite"),
    ("r_eq_zero", "- {force: harmonics, body: star, J2: 1.0e-3, R_eq: 0}\n", "verlet", "nbody",
     "forces[0].R_eq", "must be > 0"),
    ("r_eq_negative", "- {force: harmonics, body: star, J2: 1.0e-3, R_eq: -2}\n", "verlet", "nbody",
     "forces[0].R_eq", "must be > 0"),
    ("zero_spin_axis", "- {force: harmonics, body: star, J2: 1.0e-3, R_eq: 0.1, spin_axis: [0, 0, 0]}\n",
     "verlet", "nbody", "forces[0].spin_axis", "non-zero"),
    ("short_spin_axis", "- {force: harmonics, body: star, J2: 1.0e-3, R_eq: 0.1, spin_axis: [0, 1]}\n",
     "verlet", "nbody", "forces[0].spin_axis", "list of 3 numbers"),
    ("c_missing_nbody", GR_ENTRY, "verlet", "nbody", "forces[0].c", "units nbody have no physical scale"),
    ("c_zero", "- {force: gr, c: 0}\n", "verlet", "au-yr-msun", "forces[0].c", "must be > 0"),
    ("tau_zero", "- {force: migration, bodies: {moon: {tau_a: 0}}}\n", "verlet", "nbody",
     "forces[0].bodies.moon.tau_a", "non-zero"),
    ("tau_unknown", "- {force: migration, bodies: {moon: {tau_b: 1.0}}}\n", "verlet", "nbody",
     "forces[0].bodies.moon.tau_b", "unknown key 'tau_b'"),
    ("tau_none", "- {force: migration, bodies: {moon: {}}}\n", "verlet", "nbody", "forces[0].bodies.moon",
     "give at least one of tau_a"),
    ("migrate_missing_body", "- {force: migration, bodies: {neptune: {tau_a: -1.0e6}}}\n", "verlet", "nbody",
     "forces[0].bodies.neptune", "no body named 'neptune'"),
    ("two_gr", GR_ENTRY + "- {force: gr_potential}\n", "verlet", "au-yr-msun", "forces[1]", "give one of"),
    ("gr_full_leapfrog", "- {force: gr_full, c: 100.0}\n", "leapfrog", "nbody", "forces[0]",
     "leapfrog cannot apply gr_full"),
    ("gr_full_wisdom_holman", "- {force: gr_full, c: 100.0}\n", "wisdom_holman", "nbody", "forces[0]",
     "integrators that can: rk4, ias15"),
    ("forces_with_trace", GR_ENTRY, "trace", "au-yr-msun", "forces[0]", "trace cannot apply gr"),
]
IDS = [case[0] for case in BAD]


def _text(forces: str, integrator: str, units: str) -> str:
    if forces.startswith("{"):
        return HEAD.format(integrator=integrator, units=units) + BODIES + f"forces: {forces}\n"
    return scenario_text(forces, integrator, units)


@pytest.mark.parametrize(("case", "forces", "integrator", "units", "key", "fragment"), BAD, ids=IDS)
def test_bad_forces_raise_one_line_naming_file_and_key(tmp_path: Path, case: str, forces: str, integrator: str,
                                                      units: str, key: str, fragment: str) -> None:
    path = write(tmp_path, _text(forces, integrator, units))
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    message = str(info.value)
    assert info.value.key == key, message
    assert message.startswith(f"{path}: {key}: ") and fragment in message and "\n" not in message
    assert info.value.line is not None and info.value.line > 4  # the forces are after HEAD and the bodies


@pytest.mark.parametrize("command", ["validate", "run"])
@pytest.mark.parametrize(("case", "forces", "integrator", "units", "key", "fragment"), BAD, ids=IDS)
def test_bad_forces_are_refused_by_the_cli(tmp_path: Path, command: str, case: str, forces: str, integrator: str,
                                           units: str, key: str, fragment: str) -> None:
    path = write(tmp_path, _text(forces, integrator, units))
    out = tmp_path / "out.h5"
    args = [command, str(path)] + (["-o", str(out), "-q"] if command == "run" else [])
    result = CliRunner().invoke(cli, args)
    assert result.exit_code == 2, result.output
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"orbitsim: error: {path}: {key}: "), result.output
    assert fragment in lines[0]
    assert sorted(tmp_path.iterdir()) == [path]  # nothing written: no trace, no temporary file


def test_migration_cannot_name_the_first_body(tmp_path: Path) -> None:
    path = write(tmp_path, scenario_text("- {force: migration, bodies: {planet: {tau_a: -1.0e6}}}\n", units="nbody"))
    with pytest.raises(ScenarioError, match=r"forced\.yaml: forces\[0\]\.bodies\.planet: 'planet' is the first body"):
        load_scenario(path)


def test_an_integrator_override_that_cannot_apply_a_force_is_refused_by_run(tmp_path: Path) -> None:
    path = write(tmp_path, scenario_text(GR_ENTRY))
    out = tmp_path / "out.h5"
    result = CliRunner().invoke(cli, ["run", str(path), "-o", str(out), "-q", "--integrator", "trace"])
    assert result.exit_code == 2, result.output
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and "forces[0]: trace cannot apply gr" in lines[0] and str(path) in lines[0]
    assert sorted(tmp_path.iterdir()) == [path]


@pytest.mark.parametrize(("extra", "integrator", "fragment"), [
    ("events: {escape: {distance: 50}}\n", "verlet", "events (collisions, encounters, escapes) are not watched"),
    ("", "{name: wisdom_holman, corrector: 11}", "symplectic correctors do not include the forces"),
])
def test_what_forced_loops_do_not_combine_yet_is_refused_before_the_run(tmp_path: Path, extra: str, integrator: str,
                                                                         fragment: str) -> None:
    # The Simulation refuses these too, but only once a run starts; validate and run refuse them
    # from the scenario, one line naming the force's key, nothing written.
    path = write(tmp_path, scenario_text(GR_ENTRY, integrator=integrator) + extra)
    for args in (["validate", str(path)], ["run", str(path), "-o", str(tmp_path / "out.h5"), "-q"]):
        result = CliRunner().invoke(cli, args)
        assert result.exit_code == 2, result.output
        lines = result.output.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith(f"orbitsim: error: {path}: forces[0]: ") and fragment in lines[0]
    assert sorted(tmp_path.iterdir()) == [path]


@pytest.mark.slow  # compiles a loop with migration (~13 s cold)
def test_a_dissipative_run_is_not_called_untrustworthy_for_the_energy_it_removes(tmp_path: Path) -> None:
    # migration removes energy on purpose; the run's note says so, and the |dE/E| > 1% warning,
    # which would blame the step, must not follow it.
    text = ("integrator: leapfrog\ndt: 0.01\nsteps: 300\nunits: nbody\nbodies:\n"
            "  - {name: star, m: 1.0, x: [0, 0, 0], v: [0, 0, 0]}\n"
            "  - {name: planet, m: 1.0e-3, x: [1, 0, 0], v: [0, 1, 0]}\n"
            "forces:\n  - {force: migration, bodies: {planet: {tau_a: -1.0}}}\n")
    path = write(tmp_path, text)
    result = CliRunner().invoke(cli, ["run", str(path), "-o", str(tmp_path / "out.h5")])
    assert result.exit_code == 0, result.output
    assert "migration adds or removes energy on purpose" in result.output
    err = float(result.output.split("max |dE/E| = ")[1].split(",")[0])
    assert err > 0.01  # the warning's threshold is crossed, so its absence is the check
    assert "cannot be trusted" not in result.output
