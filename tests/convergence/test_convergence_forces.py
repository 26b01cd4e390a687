"""``orbitsim convergence`` with a scenario's ``forces:``: the REBOUND schemes and the IAS15
reference carry them through REBOUNDx (orbitsim.reference.force_pairing), so errors measure the
schemes, not a missing force; forces the reference cannot carry end the command with exit 5.

The scenario is forces_helpers.GR_PLANETS_YAML (a star and two planets, ``gr`` at c = 100).
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from click.testing import CliRunner
from forces_helpers import GR_PLANETS_YAML

from orbitsim.cli.main import cli

pytest.importorskip("rebound")

EXIT_NOT_TESTABLE = 5
#: The errors of orbitsim's and REBOUND's leapfrog4 differ by the pair's round-off only (measured
#: 4e-14 at the end time; a missing force would show as the GR displacement, ~1e-2).
ROUND_OFF = 1e-12


def invoke(*args: str) -> tuple[int, str, str]:
    result = CliRunner().invoke(cli, list(args), catch_exceptions=False)
    return result.exit_code, result.stdout, result.stderr


def scenario(tmp_path: Path, source: str = "star") -> str:
    path = tmp_path / f"gr_{source}.yaml"
    path.write_text(GR_PLANETS_YAML.replace("SOURCE", source), encoding="utf-8")
    return str(path)


def test_convergence_reference_and_rebound_carry_the_forces(tmp_path: Path) -> None:
    """With the forces on both sides and in the IAS15 reference, orbitsim's and REBOUND's
    leapfrog4 converge at order 4 on the same errors (before: neither REBOUND run had GR, so
    orbitsim's errors sat at the GR displacement, 1.5e-2 at every dt, reported as "round-off floor
    ~1.5e-02 reached", while REBOUND's leapfrog converged to the problem without GR)."""
    out = tmp_path / "conv"
    code, stdout, stderr = invoke("convergence", scenario(tmp_path), "-o", str(out), "--integrators", "leapfrog4",
                                  "--rebound", "leapfrog:4", "--dts", "0.02,0.01,0.005,0.0025", "--t-end", "7")
    assert code == 0, stdout + stderr
    series = {s["key"]: s for s in json.loads((out / "summary.json").read_text())["series"]}
    ours, theirs = series["leapfrog4"], series["leapfrog_order4"]
    for s in (ours, theirs):
        assert abs(s["fitted_order"] - 4.0) < 0.3, s  # the CLI's default --order-tolerance
    for a, b in zip(ours["points"], theirs["points"], strict=True):
        # The same scheme with the same forces: the errors differ by the pair's round-off only.
        assert abs(a["error"] - b["error"]) < ROUND_OFF
    assert "integrate_force" in theirs["forces"][0]
    assert "## Forces" in (out / "report.md").read_text()


def test_convergence_refuses_forces_its_reference_cannot_carry(tmp_path: Path) -> None:
    code, _, stderr = invoke("convergence", scenario(tmp_path, "b"), "-o", str(tmp_path / "conv"),
                             "--integrators", "leapfrog4", "--rebound", "none", "--dts", "0.02,0.01,0.005")
    assert code == EXIT_NOT_TESTABLE
    assert "not comparable: the IAS15 reference (REBOUND) cannot carry the forces" in stderr
    assert not (tmp_path / "conv" / "summary.json").exists()


def test_named_integrator_that_cannot_apply_the_forces_is_bad_input(tmp_path: Path) -> None:
    """trace applies no forces: named with --integrators it is refused before anything runs (by
    default it is left out with a note)."""
    code, _, stderr = invoke("convergence", scenario(tmp_path), "-o", str(tmp_path / "conv"),
                             "--integrators", "trace", "--rebound", "none", "--dts", "0.02,0.01,0.005")
    assert code == 2 and "forces: trace cannot apply them as the other code does: trace cannot apply gr" in stderr
    assert not (tmp_path / "conv" / "summary.json").exists()
