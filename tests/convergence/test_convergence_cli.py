"""``orbitsim convergence`` and the order fit behind it.

The CLI test uses the bundled eccentric (e = 0.9) Kepler orbit, started at apocentre, up to
T = 4.4: 0.7 of a period, through the pericentre passage and not a whole number of periods (at
whole periods from an apsis semi-implicit Euler's first-order error cancels). Measured errors
(relative position, against IAS15) at dt = 0.002 ... 0.00025: verlet/leapfrog 1.1e-3 ... 1.7e-5
(slope 2.00), rk4 1.2e-6 ... 2.3e-10 (4.13), leapfrog4 3.7e-6 ... 9.1e-10 (4.00).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from orbitsim.cli.main import cli
from orbitsim.convergence.run import fit_order, ladder
from orbitsim.data import SCENARIOS, bundled_dir

pytest.importorskip("rebound")

LADDER = "0.002,0.001,0.0005,0.00025"
ORDER_TOLERANCE = 0.3


def invoke(*args: str) -> tuple[int, str, str]:
    result = CliRunner().invoke(cli, list(args), catch_exceptions=False)
    return result.exit_code, result.stdout, result.stderr


@pytest.fixture(scope="module")
def eccentric(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, int, str]:
    out = tmp_path_factory.mktemp("conv") / "ecc"
    code, stdout, _ = invoke("convergence", "two_body_eccentric", "-o", str(out),
                             "--integrators", "verlet,leapfrog,rk4,leapfrog4", "--rebound", "leapfrog:4",
                             "--dts", LADDER, "--t-end", "4.4", "--check")
    return out, code, stdout


def test_fitted_orders_match_declared_on_eccentric_kepler(eccentric: tuple[Path, int, str]) -> None:
    out, code, stdout = eccentric
    assert code == 0, stdout
    summary = json.loads((out / "summary.json").read_text())
    fitted = {s["key"]: (s["fitted_order"], s["declared_order"]) for s in summary["series"]}
    assert set(fitted) == {"verlet", "leapfrog", "rk4", "leapfrog4", "leapfrog_order4"}
    for key, (got, declared) in fitted.items():
        assert abs(got - declared) <= ORDER_TOLERANCE, (key, got, declared)
    assert summary["off_order"] == []


def test_convergence_writes_table_and_figures(eccentric: tuple[Path, int, str]) -> None:
    out = eccentric[0]
    for name in ("summary.json", "report.md", "report.html", "convergence.png", "work_precision.png"):
        assert (out / name).stat().st_size > 0, name
    text = (out / "report.md").read_text()
    assert "| integrator | declared order | fitted order |" in text
    for display in ("orbitsim verlet", "orbitsim rk4", "orbitsim leapfrog4", "REBOUND leapfrog (order 4)"):
        assert display in text
    summary = json.loads((out / "summary.json").read_text())
    points = summary["series"][0]["points"]
    assert [p["dt"] for p in points] == [0.002, 0.001, 0.0005, 0.00025]
    assert [p["steps"] for p in points] == [2200, 4400, 8800, 17600]
    assert all(p["wall_time_s"] > 0 for p in points)


def test_check_fails_when_an_order_cannot_be_measured(tmp_path: Path) -> None:
    """Explicit Euler with coarse steps stays above 10 % error: no order, so --check exits 1."""
    code, _, stderr = invoke("convergence", "two_body_eccentric", "-o", str(tmp_path), "--integrators", "euler",
                             "--rebound", "none", "--dts", "0.004,0.002,0.001", "--t-end", "4.4", "--check", "-q")
    assert code == 1 and "orbitsim euler" in stderr


def test_bad_ladder_is_exit_2(tmp_path: Path) -> None:
    code, _, stderr = invoke("convergence", "two_body_eccentric", "-o", str(tmp_path), "--dts", "0.01,abc")
    assert code == 2 and "--dts" in stderr


def test_fit_order_on_synthetic_ladders() -> None:
    dts = 0.01 / 2.0 ** np.arange(8)
    fit = fit_order(dts, 3.0 * dts**4)
    assert fit.order == pytest.approx(4.0) and fit.used.sum() == 4 and fit.note == ""
    # With a round-off floor the stagnant points are dropped and the slope survives.
    errors = np.maximum(5.0 * dts**4, 1e-14 * (1 + 0.3 * np.arange(8)))
    fit = fit_order(dts, errors, steps=np.round(1.0 / dts))
    assert fit.order == pytest.approx(4.0, abs=0.05) and "floor" in fit.note and not fit.used[-1]
    # Above the 10 % ceiling nothing is asymptotic: dt is too coarse (not a round-off floor).
    fit = fit_order(dts[:3], np.array([0.9, 0.5, 0.3]))
    assert math.isnan(fit.order) and fit.note.startswith("dt above the asymptotic range")


def test_ladder_defaults_and_validation() -> None:
    assert ladder(0.01, None) == pytest.approx([0.04, 0.02, 0.01, 0.005, 0.0025, 0.00125])
    assert ladder(0.01, [0.001, 0.002]) == [0.002, 0.001]
    with pytest.raises(ValueError):
        ladder(0.01, [0.0])


def test_t_end_is_on_the_scenario_clock(tmp_path: Path) -> None:
    """--t-end is absolute like a scenario's t_end: with t_start = 10, --t-end 14.4 measures the same 4.4
    time units as --t-end 4.4 from 0, so the rungs take the same steps and land on the same errors."""
    text = (bundled_dir(SCENARIOS) / "two_body_eccentric.yaml").read_text()
    later = tmp_path / "later.yaml"
    later.write_text(text + "t_start: 10\n", encoding="utf-8")
    args = ("--integrators", "verlet", "--rebound", "none", "--dts", "0.002,0.001", "-q")
    assert invoke("convergence", "two_body_eccentric", "-o", str(tmp_path / "a"), "--t-end", "4.4", *args)[0] == 0
    code, _, stderr = invoke("convergence", str(later), "-o", str(tmp_path / "b"), "--t-end", "14.4", *args)
    assert code == 0, stderr
    first, second = (json.loads((tmp_path / d / "summary.json").read_text())["series"][0]["points"] for d in "ab")
    assert [p["steps"] for p in second] == [p["steps"] for p in first] == [2200, 4400]
    # Same steps from the same state, the clock only shifted: the errors agree to the bit.
    assert [p["error"] for p in second] == [p["error"] for p in first]
    assert "End time t = 14.4" in (tmp_path / "b" / "report.md").read_text()
    code, _, stderr = invoke("convergence", str(later), "-o", str(tmp_path / "c"), "--t-end", "4.4", *args)
    assert code == 2 and "--t-end 4.4 is not after the scenario's t_start = 10" in stderr
