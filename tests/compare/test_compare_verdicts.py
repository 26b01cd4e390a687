"""``orbitsim compare`` verdicts that must not read as a pass: chaos and an unreliable reference.

Through the real CLI, as a user sees them: the terminal line, the one error line and exit status
5, summary.json and both reports. Scenarios are short: the Pythagorean problem up to its first
close encounter (t = 15.83) is the cheapest strongly chaotic run at hand, and two bodies falling
straight onto each other (no softening) break IAS15 within 2.5 time units.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from orbitsim.cli.main import cli

pytest.importorskip("rebound")

#: Exit status of a comparison in which nothing disagrees but nothing can pass either.
EXIT_NOT_TESTABLE = 5

#: Two equal masses at rest, 2 apart: they collide at t = pi/2 sqrt(r^3 / (2 G M)) = 2.22.
HEAD_ON = """\
name: head_on
units: nbody
integrator: leapfrog
dt: 0.001
t_end: 2.5
output:
  every: 10
bodies:
  - {name: a, m: 1.0, x: [-1, 0, 0], v: [0, 0, 0]}
  - {name: b, m: 1.0, x: [1, 0, 0], v: [0, 0, 0]}
"""


def invoke(*args: str) -> tuple[int, str, str]:
    result = CliRunner().invoke(cli, list(args), catch_exceptions=False)
    return result.exit_code, result.stdout, result.stderr


def pythagorean(out: Path, t_end: str) -> tuple[int, str, str]:
    return invoke("compare", "pythagorean", "-o", str(out), "--t-end", t_end,
                  "--integrators", "leapfrog4", "--rebound", "leapfrog:4")


def one_error_line(stderr: str) -> str:
    lines = stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("orbitsim: error: "), stderr
    return lines[0]


def test_chaotic_pair_is_not_a_pass(tmp_path: Path) -> None:
    """Through the first close encounter the twin diverges by 1.5e-4: the allowed difference
    (1.5e-2 of the system's size) is far above 1e-3, so agreement tests nothing."""
    code, stdout, stderr = pythagorean(tmp_path, "16")
    assert code == EXIT_NOT_TESTABLE, stdout
    line = next(s for s in stdout.splitlines() if "<-> REBOUND leapfrog (order 4)" in s)
    assert line.lstrip().startswith("CHAOTIC") and "set by round-off amplification" in line
    assert "chaotic: agreement not testable" in line and "agree " not in line
    error = one_error_line(stderr)
    assert "agreement not testable" in error and "leapfrog4" in error and "chaotic" in error
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["verdict"] == "not_testable" and summary["passed"] is False
    assert summary["failed_pairs"] == [] and len(summary["untestable_pairs"]) == 1
    (pair,) = summary["pairs"]
    assert pair["verdict"] == "chaotic" and pair["agree"] is False and pair["within_tolerance"] is True
    assert pair["tolerance_source"] == "twin" and pair["max_allowed"] > pair["testable_limit"] == 1e-3
    assert 15.0 < pair["untestable_from"] < 16.0  # the encounter at t = 15.83
    for name in ("report.md", "report.html"):
        text = (tmp_path / name).read_text()
        assert "NOT TESTABLE" in text and "chaotic: agreement not testable" in text and "PASS" not in text, name
    assert 'class="warn"' in (tmp_path / "report.html").read_text()


def test_twin_raised_tolerance_is_named_on_the_terminal(tmp_path: Path) -> None:
    """Before the encounter the pair agrees, and the tolerance is set by the twin (3.9e-7, below
    1e-3): still a pass, but the terminal says where the allowed difference came from."""
    code, stdout, _ = pythagorean(tmp_path, "15.5")
    assert code == 0, stdout
    line = next(s for s in stdout.splitlines() if "<-> REBOUND leapfrog (order 4)" in s)
    assert line.lstrip().startswith("agree") and "set by round-off amplification" in line
    summary = json.loads((tmp_path / "summary.json").read_text())
    (pair,) = summary["pairs"]
    assert summary["verdict"] == "pass" and pair["verdict"] == "agree" and pair["tolerance_source"] == "twin"


def test_unreliable_reference_is_flagged_and_not_a_pass(tmp_path: Path) -> None:
    """IAS15 steps across the collision and its |dE/E| explodes (1e40); both fixed-step codes
    produce the same garbage bit for bit, which must not read as agreement."""
    scenario = tmp_path / "head_on.yaml"
    scenario.write_text(HEAD_ON)
    out = tmp_path / "out"
    code, stdout, stderr = invoke("compare", str(scenario), "-o", str(out), "--integrators", "leapfrog",
                                  "--rebound", "leapfrog")
    assert code == EXIT_NOT_TESTABLE, stdout
    assert "WARNING  reference unreliable" in stdout and "|dE/E|" in stdout
    line = next(s for s in stdout.splitlines() if "<-> REBOUND leapfrog (order 2)" in s)
    assert line.lstrip().startswith("UNTESTED") and "reference unreliable" in line
    error = one_error_line(stderr)
    assert "agreement not testable: reference unreliable" in error and "|dE/E|" in error
    summary = json.loads((out / "summary.json").read_text())
    reference = summary["reference"]
    assert reference["reliable"] is False and reference["max_abs_energy_error"] > 1e30  # measured 1e40
    assert summary["verdict"] == "not_testable" and summary["passed"] is False
    assert [p["verdict"] for p in summary["pairs"]] == ["reference_unreliable"]
    for name in ("report.md", "report.html"):
        text = (out / name).read_text()
        assert "NOT TESTABLE" in text and "UNRELIABLE as a reference" in text and "PASS" not in text, name


def test_unreliable_reference_without_pairs_is_not_a_pass(tmp_path: Path) -> None:
    """No matched pair to judge (rk4 has no REBOUND partner) still does not make a broken
    reference a pass; the empty REBOUND panel adds no matplotlib warning to the one error line."""
    scenario = tmp_path / "head_on.yaml"
    scenario.write_text(HEAD_ON)
    code, _, stderr = invoke("compare", str(scenario), "-o", str(tmp_path / "out"), "--integrators", "rk4", "-q")
    assert code == EXIT_NOT_TESTABLE
    assert "agreement not testable: reference unreliable" in one_error_line(stderr)
    assert json.loads((tmp_path / "out" / "summary.json").read_text())["verdict"] == "not_testable"


def test_mismatch_still_exits_1_even_when_the_reference_is_unreliable(tmp_path: Path) -> None:
    """A disagreement is the stronger finding: exit 1 names the pair, and the error line also
    says the rest cannot be tested."""
    scenario = tmp_path / "head_on.yaml"
    scenario.write_text(HEAD_ON)
    code, stdout, stderr = invoke("compare", str(scenario), "-o", str(tmp_path / "out"), "--integrators",
                                  "leapfrog4", "--rebound", "leapfrog:4", "--pair", "verlet=leapfrog:4")
    assert code == 1
    line = next(s for s in stdout.splitlines() if "orbitsim leapfrog4 <-> REBOUND leapfrog (order 4)" in s)
    assert line.lstrip().startswith("UNTESTED") and "reference unreliable" in line
    error = one_error_line(stderr)
    assert "disagree: orbitsim verlet <-> REBOUND leapfrog (order 4)" in error
    assert "also not testable: reference unreliable" in error
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["verdict"] == "fail"
    assert summary["failed_pairs"] == ["orbitsim verlet <-> REBOUND leapfrog (order 4)"]


def test_verdict_kinds_without_the_cli() -> None:
    """The classification itself: a twin that stops where REBOUND goes on is unbounded
    amplification (chaotic), and a reference that did not complete is unreliable."""
    from orbitsim.compare.metrics import CHAOTIC, REFERENCE_ENERGY_LIMIT, pair_verdict, reference_problem
    from orbitsim.record import RunRecord
    from orbitsim.reference.pairs import parse_pair

    def record(n: int, status: str = "complete", energy_jump: float = 0.0) -> RunRecord:
        steps = np.arange(n, dtype=np.int64) * 10
        positions = np.zeros((n, 2, 3))
        positions[:, 1, 0] = 1.0
        potential = -np.ones(n)
        potential[-1] -= energy_jump
        return RunRecord(engine="rebound", integrator="leapfrog", key="k", display="d", order=2, options={},
                         dt=0.1, time=steps * 0.1, step=steps, kinetic=np.zeros(n), potential=potential,
                         momentum=np.zeros((n, 3)), angular_momentum=np.zeros((n, 3)), positions=positions,
                         velocities=positions.copy(), wall_time_s=0.0, steps_done=int(steps[-1]), status=status)

    verdict = pair_verdict(parse_pair("leapfrog=leapfrog"), record(5), record(5), record(3, "diverged"))
    assert verdict.verdict == CHAOTIC and verdict.within_tolerance and not verdict.agree
    assert math.isclose(verdict.untestable_from, 3.0)  # the first sample the twin did not reach
    assert reference_problem(record(5)) == ""
    assert "did not complete" in reference_problem(record(5, "failed"))
    assert "|dE/E|" in reference_problem(record(5, energy_jump=10 * REFERENCE_ENERGY_LIMIT))
