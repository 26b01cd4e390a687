"""The whole-period trap of a convergence measurement: over whole orbits a scheme's leading error can
cancel, and the measured order is the next one (semi-implicit Euler, declared 1, fits 2.00 on the
bundled two_body_eccentric over its ten periods). The report must say so, never let the order stand
unexplained, and name an end time where it cannot happen."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from click.testing import CliRunner

from orbitsim.cli.main import cli
from orbitsim.convergence.run import WHOLE_PERIOD_TOLERANCE, whole_periods
from orbitsim.scenario import load_scenario


def test_whole_periods_are_found_and_a_fraction_is_not() -> None:
    sc = load_scenario("two_body_eccentric")
    trap = whole_periods(sc, sc.steps * sc.dt)
    assert trap is not None and (trap.body, trap.centre) == ("planet", "star")
    assert abs(trap.periods - 10.0) < WHOLE_PERIOD_TOLERANCE
    assert trap.better_t_end == pytest.approx(0.7 * trap.period, rel=1e-12)  # a product of two floats
    assert whole_periods(sc, trap.better_t_end - sc.t_start) is None
    assert whole_periods(sc, 4.4) is None


def test_an_order_above_the_declared_one_at_whole_periods_says_why(tmp_path: Path) -> None:
    out = tmp_path / "conv"
    result = CliRunner().invoke(cli, ["convergence", "two_body_eccentric", "-o", str(out), "--integrators",
                                      "semi_implicit_euler", "--rebound", "none", "--dts", "0.004,0.002,0.001,0.0005",
                                      "--check"])
    summary = json.loads((out / "summary.json").read_text())
    (series,) = summary["series"]
    assert series["fitted_order"] > 1.5  # the trap itself: second order measured for a first-order scheme
    assert "above the declared order: T is 10.0" in series["note"] and "--t-end 4.39" in series["note"]
    assert any("periods of planet about star" in note for note in summary["notes"])
    assert result.exit_code == 1 and "periods of planet about star" in result.output  # --check gives the reason


def test_measured_where_the_note_says_the_order_is_the_declared_one(tmp_path: Path) -> None:
    out = tmp_path / "conv"
    result = CliRunner().invoke(cli, ["convergence", "two_body_eccentric", "-o", str(out), "--integrators",
                                      "semi_implicit_euler", "--rebound", "none", "--t-end", "4.39603", "--check",
                                      "--dts", "0.0005,0.00025,0.000125,6.25e-05"])
    assert result.exit_code == 0, result.output
    summary = json.loads((out / "summary.json").read_text())
    assert not summary["notes"] and abs(summary["series"][0]["fitted_order"] - 1.0) < 0.3  # --check's own tolerance
