"""``orbitsim compare``: both codes on small scenarios, the files it writes, and its verdicts."""

from __future__ import annotations

import json
from pathlib import Path

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

from orbitsim.cli.main import cli

pytest.importorskip("rebound")

RUN_FILES = ("compare.h5", "summary.json", "report.md", "report.html", "energy_error.png",
             "position_error.png", "pair_difference.png", "orbits.png")


def invoke(*args: str) -> tuple[int, str, str]:
    result = CliRunner().invoke(cli, list(args), catch_exceptions=False)
    return result.exit_code, result.stdout, result.stderr


@pytest.fixture(scope="module")
def circular(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, int, str]:
    """One comparison reused by several tests: two-body circular orbit, 400 steps."""
    out = tmp_path_factory.mktemp("cmp") / "circ"
    code, stdout, _ = invoke("compare", "two_body_circular", "-o", str(out), "--steps", "400",
                             "--integrators", "verlet,leapfrog,leapfrog4",
                             "--rebound", "leapfrog,leapfrog:4,whfast")
    return out, code, stdout


def test_compare_passes_and_writes_every_file(circular: tuple[Path, int, str]) -> None:
    out, code, stdout = circular
    assert code == 0, stdout
    for name in RUN_FILES:
        assert (out / name).is_file() and (out / name).stat().st_size > 0, name
    assert f"report: {out / 'report.html'}" in stdout


def test_summary_json_has_runs_pairs_and_verdict(circular: tuple[Path, int, str]) -> None:
    summary = json.loads((circular[0] / "summary.json").read_text())
    assert summary["format"] == "orbitsim.compare.summary" and summary["passed"] is True
    assert summary["verdict"] == "pass" and summary["untestable_pairs"] == []
    assert summary["reference"]["reliable"] is True and summary["reference"]["max_abs_energy_error"] < 1e-12
    labels = [r["label"] for r in summary["runs"]]
    assert labels == ["orbitsim/verlet", "orbitsim/leapfrog", "orbitsim/leapfrog4", "rebound/leapfrog_order2",
                      "rebound/leapfrog_order4", "rebound/whfast", "reference/ias15"]
    for run in summary["runs"]:
        assert run["status"] == "complete" and run["samples"] == 41
        for key in ("max_abs_energy_error", "energy_drift_slope", "wall_time_s", "steps_per_second"):
            assert isinstance(run[key], float), key
        assert run["final_position_error"] is not None
    pairs = {p["name"]: p for p in summary["pairs"]}
    assert "orbitsim leapfrog4 <-> REBOUND leapfrog (order 4)" in pairs
    for pair in pairs.values():
        assert pair["agree"] and pair["max_relative_position_difference"] < 1e-11 < pair["tolerance"] < 1
        assert pair["verdict"] == "agree" and pair["untestable_from"] is None
    assert summary["provenance"]["rebound_version"] != "not installed"


def test_reports_name_every_run_versions_and_machine(circular: tuple[Path, int, str]) -> None:
    summary = json.loads((circular[0] / "summary.json").read_text())
    for name in ("report.md", "report.html"):
        text = (circular[0] / name).read_text()
        for run in summary["runs"]:
            assert run["display"] in text, (name, run["display"])
        for word in ("two_body_circular", "REBOUND", "numba", "numpy", "CPU", "orbitsim compare two_body_circular"):
            assert word in text
        for png in ("energy_error.png", "position_error.png", "pair_difference.png", "orbits.png"):
            assert png in text


def test_compare_h5_groups_are_traces(circular: tuple[Path, int, str]) -> None:
    from orbitsim.compare.tracegroup import COMPARE_FORMAT, list_trace_groups, read_trace_group

    with h5py.File(circular[0] / "compare.h5", "r") as f:
        assert f.attrs["format"] == COMPARE_FORMAT and "scenario" in f.attrs
        groups = list_trace_groups(f)
        assert {"orbitsim/leapfrog4", "rebound/leapfrog_order4", "reference/ias15"} <= set(groups)
        trace = read_trace_group(f["orbitsim/leapfrog4"])
    assert trace.attrs["format"] == "orbitsim.trace" and trace.names == ("star", "planet")
    assert trace.positions.shape == (41, 2, 3) and trace.energy_error[0] == 0.0
    np.testing.assert_array_equal(trace.step, np.arange(0, 401, 10))


def test_mismatched_pair_exits_1_and_names_it(tmp_path: Path) -> None:
    code, _, stderr = invoke("compare", "two_body_circular", "-o", str(tmp_path / "bad"), "--steps", "200",
                                  "--integrators", "leapfrog4", "--rebound", "leapfrog:4",
                                  "--pair", "verlet=leapfrog:4")
    assert code == 1
    assert "orbitsim verlet <-> REBOUND leapfrog (order 4)" in stderr
    assert stderr.startswith("orbitsim: error:") and len(stderr.strip().splitlines()) == 1
    summary = json.loads((tmp_path / "bad" / "summary.json").read_text())
    assert summary["failed_pairs"] == ["orbitsim verlet <-> REBOUND leapfrog (order 4)"]
    assert "FAIL" in (tmp_path / "bad" / "report.md").read_text()


def test_outer_solar_system_defaults(tmp_path: Path) -> None:
    """Default runs on a hierarchical system: WHFast joins because the Sun dominates."""
    code, stdout, _ = invoke("compare", "outer_solar_system", "-o", str(tmp_path), "--steps", "300", "-q")
    assert code == 0, stdout
    summary = json.loads((tmp_path / "summary.json").read_text())
    labels = {r["label"] for r in summary["runs"]}
    assert {"orbitsim/leapfrog4", "rebound/leapfrog_order4", "rebound/whfast"} <= labels
    assert all(p["agree"] for p in summary["pairs"]) and len(summary["pairs"]) >= 2
    assert summary["verdict"] == "pass"


@pytest.mark.parametrize("args, message", [
    (["--rebound", "leapfrog:5"], "REBOUND leapfrog order"),
    (["--integrators", "nope"], "unknown integrator"),
    (["--pair", "verlet"], "--pair expects"),
    (["--steps", "10", "--t-end", "1"], "only one of"),
])
def test_bad_input_is_one_line_and_exit_2(tmp_path: Path, args: list[str], message: str) -> None:
    code, _, stderr = invoke("compare", "two_body_circular", "-o", str(tmp_path / "x"), *args)
    assert code == 2 and message in stderr and len(stderr.strip().splitlines()) == 1
    assert not (tmp_path / "x" / "compare.h5").exists()


def test_existing_results_need_force(circular: tuple[Path, int, str]) -> None:
    code, _, stderr = invoke("compare", "two_body_circular", "-o", str(circular[0]), "--steps", "10")
    assert code == 2 and "--force" in stderr


def test_help_documents_defaults() -> None:
    code, stdout, _ = invoke("compare", "--help")
    assert code == 0
    for word in ("--integrators", "--rebound", "--pair", "leapfrog4", "whfast", "IAS15", "Exit status",
                 "chaotic", "not testable", "5  no pair disagrees"):
        assert word in stdout
