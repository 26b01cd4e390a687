"""Sweep files: expansion, run ids, and errors that name the sweep key path (no cluster needed)."""

from __future__ import annotations

import textwrap
from pathlib import Path

import pytest

from orbitsim.batch.sweep import RUN_ID_CHARS, SweepError, load_sweep
from orbitsim.data import SWEEPS, bundled_files


def write(tmp_path: Path, text: str, name: str = "sweep.yaml") -> Path:
    path = tmp_path / name
    path.write_text(textwrap.dedent(text))
    return path


def test_grid_is_a_cartesian_product_with_the_first_key_slowest(tmp_path):
    sweep = load_sweep(write(tmp_path, """
        base: two_body_circular
        overrides: {steps: 10}
        grid:
          integrator: [verlet, rk4]
          dt: [0.01, 0.02, 0.04]
    """))
    assert sweep.name == "sweep" and sweep.params == ("integrator", "dt")
    assert [(c.params["integrator"], c.params["dt"]) for c in sweep.cases] == [
        ("verlet", 0.01), ("verlet", 0.02), ("verlet", 0.04), ("rk4", 0.01), ("rk4", 0.02), ("rk4", 0.04)]
    assert [c.where["dt"] for c in sweep.cases[:3]] == ["grid.dt[0]", "grid.dt[1]", "grid.dt[2]"]
    assert all(c.scenario.steps == 10 for c in sweep.cases)
    assert sweep.cases[4].scenario.integrator == "rk4" and sweep.cases[4].scenario.dt == 0.02


def test_dotted_paths_reach_bodies_and_generators(tmp_path):
    sweep = load_sweep(write(tmp_path, """
        base: two_body_eccentric
        overrides: {steps: 10}
        cases:
          - {bodies.1.e: 0.5}
          - {bodies.1.e: 0.7, dt: 0.002}
    """))
    assert sweep.params == ("bodies.1.e", "dt")
    assert sweep.cases[0].params == {"bodies.1.e": 0.5}  # a case lists only what it sets
    r0 = sweep.cases[0].scenario.positions[1] - sweep.cases[0].scenario.positions[0]
    r1 = sweep.cases[1].scenario.positions[1] - sweep.cases[1].scenario.positions[0]
    # started at apocentre (f = 180): the separation is a (1 + e)
    assert abs(float((r0 @ r0) ** 0.5) - 1.5) < 1e-12 and abs(float((r1 @ r1) ** 0.5) - 1.7) < 1e-12

    seeds = load_sweep(write(tmp_path, """
        base: plummer_1k
        overrides: {steps: 5, generator.n: 16}
        grid: {generator.seed: [1, 2]}
    """, "seeds.yaml"))
    a, b = (c.scenario.positions for c in seeds.cases)
    assert a.shape == (16, 3) and not (a == b).all()


def test_run_id_hashes_the_resolved_scenario_only(tmp_path):
    one = load_sweep(write(tmp_path, """
        name: first
        base: two_body_circular
        overrides: {steps: 10}
        grid: {dt: [0.01, 0.02]}
    """, "a.yaml"))
    # Another sweep, other order, an alias and a value written differently: the same two runs.
    two = load_sweep(write(tmp_path, """
        name: second
        base: two_body_circular
        overrides: {steps: 10}
        cases:
          - {dt: 2.0e-2, integrator: kdk}
          - {dt: 0.01}
    """, "b.yaml"))
    assert [c.run_id for c in one.cases] == [c.run_id for c in reversed(two.cases)]
    case = one.cases[0]
    assert len(case.run_id) == RUN_ID_CHARS and case.scenario.sha256.startswith(case.run_id)


def test_null_removes_a_key_so_t_end_can_replace_steps(tmp_path):
    sweep = load_sweep(write(tmp_path, """
        base: two_body_eccentric
        overrides: {steps: null, t_end: 1.0}
        grid: {dt: [0.1, 0.05]}
    """))
    assert [c.scenario.steps for c in sweep.cases] == [10, 20]


def test_bundled_example_sweeps_load():
    found = bundled_files(SWEEPS)
    assert set(found) == {"eccentricity_cases", "integrators_dt", "plummer_seeds"}
    for path in found.values():
        sweep = load_sweep(path)
        assert sweep.cases and len({c.run_id for c in sweep.cases}) == len(sweep.cases)
    assert len(load_sweep("plummer_seeds").cases) == 64  # by name, as `orbitsim batch plummer_seeds`


def error_of(tmp_path: Path, text: str) -> str:
    with pytest.raises(SweepError) as info:
        load_sweep(write(tmp_path, text))
    message = str(info.value)
    assert "\n" not in message and message.startswith(str(tmp_path / "sweep.yaml"))
    return message[len(str(tmp_path / "sweep.yaml")):]


def test_a_bad_grid_value_is_named_by_its_sweep_key_and_line(tmp_path):
    message = error_of(tmp_path, """
        base: two_body_circular
        grid:
          integrator: [verlet]
          dt: [0.01, 0.02, 0]
    """)
    assert message == ": grid.dt[2]: must be non-zero (> 0 runs forwards, < 0 backwards), got 0 (line 5)"


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("base: two_body_circular\ncases:\n  - {dt: 0.1}\n  - {integrator: nope}\n",
         ": cases[1].integrator: unknown integrator"),
        ("base: two_body_circular\ngrid: {bodies.5.e: [0.1]}\n", ": grid.bodies.5.e[0]: bodies has 2 entries"),
        ("base: two_body_circular\ngrid: {bodies.1.e: [1.5]}\n",
         ": grid.bodies.1.e[0]: bodies[1].a: a must be negative"),
        ("base: two_body_circular\noverrides: {stpes: 3}\ngrid: {dt: [0.1]}\n", ": overrides.stpes: unknown key"),
        ("base: two_body_circular\ngrid: {dt: 0.1}\n", ": grid.dt: must be a non-empty list"),
        ("base: two_body_circular\n", ": give exactly one of `grid`"),
        ("base: two_body_circular\ngrid: {dt: [0.1]}\ncases: []\n", ": give exactly one of `grid`"),
        ("base: no_such_scenario\ngrid: {dt: [0.1]}\n", ": base: no scenario file or bundled scenario"),
        ("bsae: two_body_circular\ngrid: {dt: [0.1]}\n", ": bsae: unknown key"),
        ("base: two_body_circular\ngrid: {integrator: [verlet, kdk]}\n",
         ": case 1 (grid.integrator[1]): resolves to the same scenario as case 0"),
        ("base: {integrator: verlet, dt: 0, steps: 3, bodies: [{m: 1, x: [0, 0, 0], v: [0, 0, 0]}]}\n"
         "grid: {steps: [1]}\n", ": base.dt: must be non-zero (> 0 runs forwards, < 0 backwards), got 0"),
        ("base: two_body_circular\ngrid: {dt: [0.1]\n", ": YAML syntax error"),
        ("name: a/b\nbase: two_body_circular\ngrid: {dt: [0.1]}\n", ": name: must be a plain file name"),
    ],
)
def test_invalid_sweeps_fail_with_one_line_naming_the_key(tmp_path, text, expected):
    assert expected in error_of(tmp_path, text)


def test_missing_sweep_file_is_a_sweep_error(tmp_path):
    with pytest.raises(SweepError, match="cannot read sweep file"):
        load_sweep(tmp_path / "nope.yaml")


def test_skip_invalid_keeps_each_invalid_case_aside_with_its_error_and_line(tmp_path):
    text = """
        base: two_body_circular
        overrides: {steps: 10}
        grid:
          integrator: [verlet, kdk, rk4]
          dt: [0.01, 0]
    """
    with pytest.raises(SweepError, match=r"grid\.dt\[1\]"):  # the default is unchanged: the sweep is refused
        load_sweep(write(tmp_path, text))
    sweep = load_sweep(write(tmp_path, text), skip_invalid=True)
    # Cases 1, 3 and 5 have dt = 0; case 2 (kdk, an alias of verlet) repeats case 0's scenario.
    assert [c.index for c in sweep.cases] == [0, 4]
    assert [c.index for c in sweep.invalid] == [1, 2, 3, 5]
    assert sweep.params == ("integrator", "dt")
    bad = sweep.invalid[0]
    assert bad.params == {"integrator": "verlet", "dt": 0} and bad.where["dt"] == "grid.dt[1]"
    assert bad.message == "grid.dt[1]: must be non-zero (> 0 runs forwards, < 0 backwards), got 0 (line 6)"
    assert sweep.invalid[1].message.startswith("case 2 (grid.integrator[1], grid.dt[0]): resolves to the same "
                                               "scenario as case 0")
    assert all("\n" not in c.message and str(tmp_path) not in c.message for c in sweep.invalid)


def test_skip_invalid_still_refuses_a_sweep_with_no_valid_case(tmp_path):
    path = write(tmp_path, """
        base: two_body_circular
        grid: {dt: [0, 0.0]}
    """)
    with pytest.raises(SweepError) as info:
        load_sweep(path, skip_invalid=True)
    assert str(info.value) == f"{path}: grid.dt[0]: must be non-zero (> 0 runs forwards, < 0 backwards), got 0 (line 3)"
