"""The order fit of ``orbitsim convergence`` (orbitsim.convergence.fit): it uses the
asymptotic part of a ladder, blames round-off only for a floor the ladder reached, and gives the
true reason and a ladder to try when there is no order; the default ladder reaches each scheme's
asymptotic range (orbitsim.convergence.run.extend_series).

The Kepler problem of the CLI tests is the bundled e = 0.9 orbit (two_body_eccentric) up to
T = 4.4, 0.7 of a period through pericentre (not a whole number of periods, see test_convergence).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from orbitsim.cli.main import cli
from orbitsim.convergence.fit import FITTED, FLOOR, ROUND_OFF, TOO_COARSE, fit_order

pytest.importorskip("rebound")

#: The CLI's default --order-tolerance: a fitted order within it of the declared one passes.
ORDER_TOLERANCE = 0.3
#: The issue's ladder: leapfrog6 on a Kepler problem, dt halving from the coarsest rung. Its first
#: two errors are pre-asymptotic (local slope 0.30), the last four fall at slope 5.9 .. 6.0.
ISSUE_ERRORS = np.array([0.525, 0.427, 9.7e-3, 1.6e-4, 2.6e-6, 4.0e-8])
ISSUE_DTS = 0.04 / 2.0 ** np.arange(6)


def invoke(*args: str) -> tuple[int, str, str]:
    result = CliRunner().invoke(cli, list(args), catch_exceptions=False)
    return result.exit_code, result.stdout, result.stderr


def test_pre_asymptotic_stall_is_not_round_off() -> None:
    """The issue: a stall at 0.5 error is the coarse end, not the round-off floor (before: "fitted
    n/a, round-off floor ~4.0e-08 reached")."""
    fit = fit_order(ISSUE_DTS, ISSUE_ERRORS, steps=np.round(4.4 / ISSUE_DTS))
    assert fit.kind == FITTED and fit.floor == 0.0
    assert abs(fit.order - 6.0) < 0.1  # the last four rungs' slopes are 5.92, 5.94, 6.02
    assert list(fit.used) == [False, False, True, True, True, True]
    assert "round-off" not in fit.note


def test_unfit_order_says_dt_is_above_the_asymptotic_range() -> None:
    """Every error above 10 %, or rungs below it whose slopes do not settle: dt is too coarse, and
    the note suggests a finer ladder (one that goes on past the finest rung run)."""
    dts = 0.01 / 2.0 ** np.arange(4)
    fit = fit_order(dts, np.array([4.0, 2.5, 1.5, 0.7]))
    assert fit.kind == TOO_COARSE and math.isnan(fit.order)
    assert fit.note.startswith("dt above the asymptotic range (every error above 0.1") and "try --dts" in fit.note
    assert max(fit.suggested) < dts[-1] and "round-off" not in fit.note
    # Errors that oscillate with the orbit's phase (measured: semi-implicit Euler, e = 0.5, 1.3 P).
    fit = fit_order(dts, np.array([5.3e-2, 4.9e-2, 3.1e-2, 1.7e-2]))
    assert fit.kind == TOO_COARSE and "local slopes 0.11, 0.66, 0.87 not settled" in fit.note
    assert min(fit.suggested) < dts[-1]


def test_floor_is_round_off_only_when_the_ladder_reaches_it() -> None:
    """A 4th-order error over a floor of ~1e-14: the floor rungs are left out, the slope is kept."""
    dts = 0.01 / 2.0 ** np.arange(8)
    errors = np.maximum(5.0 * dts**4, 1e-14 * (1 + 0.3 * np.arange(8)))
    fit = fit_order(dts, errors, steps=np.round(1.0 / dts))
    assert fit.kind == FITTED and abs(fit.order - 4.0) < 0.05 and "round-off floor" in fit.note
    assert not fit.used[-1]
    # An exact scheme: round-off scatter at every dt, no order, and not "dt above the range".
    noise = np.array([1.6e-15, 4.5e-15, 1.2e-15, 3.0e-15, 3.2e-15, 7.9e-15])
    fit = fit_order(dts[:6], noise, steps=np.round(1.0 / dts[:6]))
    assert fit.kind == ROUND_OFF and "error at round-off for every dt" in fit.note and not fit.used.any()
    # An 8th-order error meets a floor of ~5e-13 after two rungs: coarser dt is what is missing.
    fit = fit_order(dts[:5], np.array([3e-9, 1.2e-11, 6e-13, 8e-13, 4e-13]), steps=np.round(1.0 / dts[:5]))
    assert fit.kind == FLOOR and min(fit.suggested) >= dts[0] and "try --dts" in fit.note


@pytest.fixture(scope="module")
def eccentric_default_ladder(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, int, str]:
    out = tmp_path_factory.mktemp("conv") / "ecc"
    code, stdout, stderr = invoke("convergence", "two_body_eccentric", "-o", str(out), "--t-end", "4.4",
                                  "--integrators", "leapfrog6,leapfrog8,trace,wisdom_holman",
                                  "--rebound", "leapfrog:8")
    return out, code, stdout + stderr


def test_default_ladder_reaches_every_schemes_asymptotic_range(
        eccentric_default_ladder: tuple[Path, int, str]) -> None:
    """The default ladder (dt = 0.004 ... 0.000125) is already at round-off for leapfrog8 after one
    rung; it is extended coarser and denser until the order fits (before: "fitted n/a, round-off
    floor ~1.0e-14 reached" for both codes' order 8)."""
    out, code, output = eccentric_default_ladder
    assert code == 0, output
    series = {s["key"]: s for s in json.loads((out / "summary.json").read_text())["series"]}
    for key in ("leapfrog6", "leapfrog8", "trace", "leapfrog_order8"):
        s = series[key]
        assert s["fitted_order"] is not None and abs(s["fitted_order"] - s["declared_order"]) < ORDER_TOLERANCE, s
    for key in ("leapfrog8", "leapfrog_order8"):
        assert any(p["added"] and p["used_in_fit"] for p in series[key]["points"]), key
        assert series[key]["note"].startswith("ladder extended to dt = ")
    # Wisdom-Holman is exact on two bodies: its reason is round-off at every dt, after one coarser try.
    wh = series["wisdom_holman"]
    assert wh["fitted_order"] is None and wh["fit_kind"] == "round_off"
    assert "error at round-off for every dt" in wh["note"] and "dt above the asymptotic range" not in wh["note"]
    assert sum(p["added"] for p in wh["points"]) == 1


def test_lead_line_and_table_give_the_same_reason(eccentric_default_ladder: tuple[Path, int, str]) -> None:
    """The report's lead names each missing order with the table's own note (before: "fitted nan")."""
    out = eccentric_default_ladder[0]
    summary = json.loads((out / "summary.json").read_text())
    wh = next(s for s in summary["series"] if s["key"] == "wisdom_holman")
    text = (out / "report.md").read_text()
    lead = next(line for line in text.splitlines() if line.startswith("Fitted orders missing"))
    assert f"orbitsim wisdom_holman: no fitted order, declared 2 ({wh['note']})" in lead
    row = next(line for line in text.splitlines() if line.startswith("| orbitsim wisdom_holman |"))
    assert wh["note"] in row
    assert summary["off_order"] == [f"orbitsim wisdom_holman: no fitted order, declared 2 ({wh['note']})"]


def test_given_ladder_is_fitted_over_its_asymptotic_part(tmp_path: Path) -> None:
    """A ladder given with --dts is run as given. dt = 0.04 ... 0.00125 on the e = 0.9 orbit: trace's
    two coarse rungs are pre-asymptotic (9.5e-7, then 9.8e-5), leapfrog8's coarsest bends (local
    slope 10.1, then 7.2); before, trace was "n/a, round-off floor ~4.6e-10 reached" and leapfrog8
    fitted 6.42."""
    code, stdout, stderr = invoke("convergence", "two_body_eccentric", "-o", str(tmp_path), "--t-end", "4.4",
                                  "--integrators", "trace,leapfrog8", "--rebound", "none",
                                  "--dts", "0.04,0.02,0.01,0.005,0.0025,0.00125", "--check")
    assert code == 0, stdout + stderr
    series = {s["key"]: s for s in json.loads((tmp_path / "summary.json").read_text())["series"]}
    assert abs(series["trace"]["fitted_order"] - 2.0) < ORDER_TOLERANCE
    assert abs(series["leapfrog8"]["fitted_order"] - 8.0) < ORDER_TOLERANCE
    assert not any(p["added"] for s in series.values() for p in s["points"])
    assert "round-off floor ~4.6e-10" not in stdout
