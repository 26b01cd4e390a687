"""``orbitsim compare`` with IAS15 in both codes: the pair, ``--reference``, the side-by-side table,
adaptive scenarios with fixed-dt schemes beside them, and the Pythagorean problem to t = 70."""

from __future__ import annotations

import json
from pathlib import Path

import h5py
import numpy as np
import pytest
import yaml
from click.testing import CliRunner

from orbitsim.cli.main import cli

pytest.importorskip("rebound")

IAS15_PAIR = "orbitsim ias15 <-> REBOUND ias15"


@pytest.fixture
def pythagorean(tmp_path: Path) -> str:
    """The bundled Pythagorean problem, integrated by ias15 (first trial step 1e-4, to t = 70,
    sampled every 0.01) whatever the bundled file's integrator."""
    from orbitsim.scenario import config_dir

    doc = yaml.safe_load((config_dir() / "pythagorean.yaml").read_text())
    doc.update(integrator="ias15", dt=1.0e-4, t_end=70, output={"interval": 0.01})
    doc.pop("steps", None)
    path = tmp_path / "pythagorean.yaml"
    path.write_text(yaml.safe_dump(doc))
    return str(path)


def invoke(*args: str) -> tuple[int, str, str]:
    result = CliRunner().invoke(cli, list(args), catch_exceptions=False)
    return result.exit_code, result.stdout, result.stderr


@pytest.fixture(scope="module")
def giants(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, int, str]:
    """The giant planets to t = 200 (20 output intervals), orbitsim's ias15 as the reference."""
    out = tmp_path_factory.mktemp("cmp") / "giants"
    code, stdout, _ = invoke("compare", "giants", "-o", str(out), "--t-end", "200", "--reference", "orbitsim")
    return out, code, stdout


def test_ias15_pair_agrees_on_giants_to_1e_10(giants: tuple[Path, int, str]) -> None:
    out, code, stdout = giants
    assert code == 0, stdout
    summary = json.loads((out / "summary.json").read_text())
    assert summary["verdict"] == "pass"
    (pair,) = summary["pairs"]  # an adaptive scenario compares only its own integrator by default
    assert pair["name"] == IAS15_PAIR and pair["verdict"] == "agree"
    assert pair["max_relative_position_difference"] < 1e-10  # measured 1.2e-15
    assert pair["tolerance_source"] == "nominal"
    sc = summary["scenario"]
    assert sc["adaptive"] is True and sc["t_end"] == 200.0 and sc["output_interval"] == 10.0
    assert sc["steps"] == 20 and sc["samples"] == 21


def test_reference_orbitsim_is_the_reference(giants: tuple[Path, int, str]) -> None:
    summary = json.loads((giants[0] / "summary.json").read_text())
    assert summary["reference"]["choice"] == "orbitsim"
    assert summary["reference"]["label"] == "reference/orbitsim_ias15" and summary["reference"]["reliable"]
    assert summary["runs"][-1]["label"] == "reference/orbitsim_ias15"
    assert summary["runs"][-1]["final_position_error"] == 0.0  # measured against itself
    with h5py.File(giants[0] / "compare.h5", "r") as f:
        times = {label: f[label]["time"][:] for label in ("reference/ias15", "reference/orbitsim_ias15")}
    grid = np.arange(21) * 10.0
    for label, t in times.items():  # both land exactly on the output times
        np.testing.assert_allclose(t, grid, rtol=1e-15, atol=0, err_msg=label)
        assert t[-1] == 200.0, label


def test_side_by_side_table_of_both_references(giants: tuple[Path, int, str]) -> None:
    summary = json.loads((giants[0] / "summary.json").read_text())
    first, second = summary["references"]
    assert (first["choice"], first["chosen"]) == ("orbitsim", True)
    assert (second["choice"], second["chosen"]) == ("rebound", False)
    for ref in (first, second):
        assert ref["status"] == "complete" and ref["end_time"] == 200.0 and ref["epsilon"] == 1e-9
        assert ref["first_dt"] == 0.01 and ref["steps"] > 20 and ref["max_abs_energy_error"] < 1e-13
        assert ref["max_relative_position_difference"] < 1e-10
        assert "jupiter: bound to sun" in ref["final_state"] and "sun: has jupiter" in ref["final_state"]
    for name in ("report.md", "report.html"):
        text = (giants[0] / name).read_text()
        assert "IAS15 references" in text and "--reference orbitsim" in text, name
        assert "orbitsim ias15 (epsilon 1e-09)" in text and "REBOUND IAS15 (epsilon 1e-09)" in text, name
        assert "max rel. position difference to the other" in text, name


def test_fixed_dt_schemes_in_an_adaptive_compare(tmp_path: Path, pythagorean: str) -> None:
    """--t-end sets an adaptive scenario's end time; a fixed-dt pair steps by its dt (1e-4) and is
    sampled on the output grid (every 0.01), and the report says so."""
    code, stdout, _ = invoke("compare", pythagorean, "-o", str(tmp_path / "out"), "--t-end", "2",
                             "--integrators", "ias15,leapfrog4", "--rebound", "leapfrog:4")
    assert code == 0, stdout
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["scenario"]["t_end"] == 2.0 and summary["scenario"]["steps"] == 200
    assert summary["reference"]["choice"] == "rebound" and summary["reference"]["label"] == "reference/ias15"
    runs = {r["label"]: r for r in summary["runs"]}
    assert runs["orbitsim/leapfrog4"]["steps"] == 20000 and runs["orbitsim/leapfrog4"]["samples"] == 201
    assert {p["name"]: p["verdict"] for p in summary["pairs"]} == {
        IAS15_PAIR: "agree", "orbitsim leapfrog4 <-> REBOUND leapfrog (order 4)": "agree"}
    assert any("dt = 0.0001" in note and "20000 steps" in note for note in summary["notes"])
    assert "fixed-dt integrators step by the scenario's dt" in (tmp_path / "out" / "report.md").read_text()


def test_fixed_dt_that_misses_the_output_times_is_refused(tmp_path: Path) -> None:
    code, _, stderr = invoke("compare", "giants", "-o", str(tmp_path / "out"), "--t-end", "100",
                             "--integrators", "leapfrog4", "--dt", "0.03")
    assert code == 2 and "does not land on the output time" in stderr and "--dt" in stderr
    assert not (tmp_path / "out").exists()


def test_pythagorean_both_ias15_to_t70(tmp_path: Path, pythagorean: str) -> None:
    """Burrau's problem to t = 70: both IAS15s get through every encounter with |dE/E| < 1e-9,
    m3 escapes and m4, m5 stay a binary; the two codes' agreement through the later encounters is
    chaotic (a REBOUND twin from 4 ulp diverges as much), reported as not testable, exit 5."""
    code, stdout, stderr = invoke("compare", pythagorean, "-o", str(tmp_path / "out"))
    assert code == 5, stdout
    assert "agreement not testable" in stderr and IAS15_PAIR in stderr
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["verdict"] == "not_testable" and summary["failed_pairs"] == []
    (pair,) = summary["pairs"]
    assert pair["verdict"] == "chaotic" and pair["within_tolerance"] and pair["tolerance_source"] == "twin"
    assert pair["untestable_from"] > 16.0
    for ref in summary["references"]:
        assert ref["status"] == "complete" and ref["end_time"] == 70.0, ref
        assert ref["max_abs_energy_error"] < 1e-9, ref  # measured 5e-11 (REBOUND), 1.3e-10 (orbitsim)
        assert "m3: escaping" in ref["final_state"], ref
        assert "m4: bound to m5" in ref["final_state"] and "m5: has m4 bound to it" in ref["final_state"], ref
    text = (tmp_path / "out" / "report.md").read_text()
    assert "NOT TESTABLE" in text and "chaotic: agreement not testable" in text and "m3: escaping" in text


def test_a_star_is_not_described_as_bound_to_its_planet() -> None:
    """The final state used to read ``star: bound to b``: the star's most bound partner is its
    innermost planet (issue 27, item 8). The lighter body of a bound pair is bound to the heavier."""
    from types import SimpleNamespace

    from orbitsim.compare.ias15 import escape_summary

    m = np.array([1.0, 1e-3, 1e-3, 1e-3, 1e-3, 1e-6])
    a = np.array([0.0, 1.0, 2.0, 3.0, 4.0, 50.0])
    pos = np.zeros((6, 3))
    vel = np.zeros((6, 3))
    pos[:, 0] = a
    vel[1:5, 1] = np.sqrt(1.0 / a[1:5])  # circular about the star
    vel[5, 1] = 1.0  # far out and fast: escaping (v^2 / 2 = 0.5 > GM / r = 0.02)
    vel[5, 0] = 0.5  # and receding
    record = SimpleNamespace(n_samples=1, positions=pos[None], velocities=vel[None])
    text = escape_summary(record, m, 1.0, ["star", "b", "c", "d", "e", "comet"])
    parts = text.split("; ")
    assert parts[0] == "star: has b, c, d and 1 more bound to it", text
    assert parts[1:5] == ["b: bound to star", "c: bound to star", "d: bound to star", "e: bound to star"], text
    assert parts[5].startswith("comet: escaping (r = "), text
