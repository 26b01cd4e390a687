"""Numbers beyond range are refused by ``validate`` and ``run`` alike (issue 14, item 4).

Every step count (``steps``, ``t_end / dt``, ``output.every``, ``output.interval / dt``,
``output.checkpoint.every``) is at most ``MAX_STEPS`` = 2**53, from the file or from an option:
exit 2, one line naming the key (or the option) and the limit, nothing written.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from click.testing import CliRunner

from orbitsim.cli.main import cli
from orbitsim.scenario import ScenarioError, load_scenario
from orbitsim.scenario.timing import MAX_STEPS

BODIES = ("bodies:\n  - {name: star, m: 1.0, x: [0, 0, 0], v: [0, 0, 0]}\n"
          "  - {name: planet, m: 1.0e-3, x: [1, 0, 0], v: [0, 1, 0]}\n")
SMALL = "integrator: verlet\ndt: 0.01\nsteps: 100\n" + BODIES
LIMIT = str(MAX_STEPS)

# (id, YAML text, key the error names)
FILE_CASES = [
    ("steps_1e20", "integrator: verlet\ndt: 0.01\nsteps: 1e20\n" + BODIES, "steps"),
    ("steps_just_over", f"integrator: verlet\ndt: 0.01\nsteps: {MAX_STEPS + 1}\n" + BODIES, "steps"),
    ("t_end_over_dt", "integrator: verlet\ndt: 0.01\nt_end: 1e17\n" + BODIES, "t_end"),
    ("t_end_overflows", "integrator: verlet\ndt: 1e-10\nt_end: 1e308\n" + BODIES, "t_end"),
    ("every", SMALL + "output: {every: 1e20}\n", "output.every"),
    ("interval_over_dt", SMALL + "output: {interval: 1e300}\n", "output.interval"),
    ("checkpoint_every", SMALL + "output: {checkpoint: {every: 1e20}}\n", "output.checkpoint.every"),
]


def one_error_line(result: object) -> str:
    lines = result.stderr.splitlines()
    assert result.exit_code == 2, result.output
    assert len(lines) == 1 and lines[0].startswith("orbitsim: error: "), result.output
    assert "Traceback" not in result.output and "Warning" not in result.output
    return lines[0]


@pytest.mark.parametrize(("case", "text", "key"), FILE_CASES, ids=[c[0] for c in FILE_CASES])
def test_step_counts_beyond_the_limit_in_a_file(tmp_path: Path, case: str, text: str, key: str) -> None:
    path = tmp_path / "s.yaml"
    path.write_text(text, encoding="utf-8")
    runner = CliRunner()
    for args in (["validate", str(path)], ["run", str(path), "-o", str(tmp_path / "out.h5")]):
        line = one_error_line(runner.invoke(cli, args))
        assert line.startswith(f"orbitsim: error: {path}: {key}: ") and LIMIT in line and "(line " in line
    assert list(tmp_path.iterdir()) == [path]


# (option and value, what the message names): the reproductions and every step-count option
OPTION_CASES = [
    (["--t-end", "1e308"], "--t-end"),  # OverflowError before
    (["--t-end", "1e17"], "--t-end"),  # more steps than int64 holds before
    (["--steps", str(10**20)], "--steps"),
    (["--steps", str(MAX_STEPS + 1)], "--steps"),
    (["--dt", "1e-300"], "--dt"),  # a file's t_end with a tiny dt
    (["--every", str(10**20)], "--every"),
    (["--interval", "1e300"], "--interval"),
    (["--checkpoint-every", str(10**20)], "--checkpoint-every"),
]


@pytest.mark.parametrize(("option", "named"), OPTION_CASES, ids=[" ".join(c[0]) for c in OPTION_CASES])
def test_step_counts_beyond_the_limit_from_options(tmp_path: Path, option: list[str], named: str) -> None:
    path = tmp_path / "s.yaml"
    path.write_text("integrator: verlet\ndt: 0.01\nt_end: 1\n" + BODIES, encoding="utf-8")
    out = tmp_path / "out.h5"
    line = one_error_line(CliRunner().invoke(cli, ["run", str(path), "-o", str(out), *option]))
    assert line.startswith(f"orbitsim: error: {named} ") and LIMIT in line  # the option, its value, the limit
    assert f" {float(option[1]):g}: " in line or f" {option[1]}: " in line
    assert list(tmp_path.iterdir()) == [path]


def test_the_limit_itself_is_accepted(tmp_path: Path) -> None:
    path = tmp_path / "s.yaml"
    path.write_text(SMALL.replace("steps: 100", f"steps: {MAX_STEPS}"), encoding="utf-8")
    scenario = load_scenario(path)
    assert scenario.steps == MAX_STEPS
    assert scenario.with_overrides(every=MAX_STEPS).sample_plan().count() == 2  # step 0 and the last
    with pytest.raises(ScenarioError, match=LIMIT) as info:
        scenario.with_overrides(steps=MAX_STEPS + 1)
    assert info.value.key == "steps"
    # 2**53 steps of dt = 1 end at t = 2**53 exactly: the float64 times are still whole numbers
    assert float(MAX_STEPS) * 1.0 == MAX_STEPS


def test_steps_times_dt_must_be_finite(tmp_path: Path) -> None:
    path = tmp_path / "s.yaml"
    path.write_text(SMALL.replace("dt: 0.01", "dt: 1e300").replace("steps: 100", "steps: 1e10"), encoding="utf-8")
    with pytest.raises(ScenarioError, match="overflows float64") as info:
        load_scenario(path)
    assert info.value.key == "dt"
