"""The ``adaptive`` kind of the benchmark matrix: IAS15 beside REBOUND's IAS15 over one span.

As in tests/bench/test_bench.py, nothing here asserts a time: what is tested is the bookkeeping. The
group is parsed with per-N values and its errors name the key; a run records both engines'
accepted steps over the same span; the targets table has the two IAS15 rows; a fixed-step group's
``integrators: all`` leaves IAS15 out.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml
from click.testing import CliRunner

from orbitsim.bench.matrix import BenchMatrixError, matrix_from_dict
from orbitsim.bench.runner import quick_matrix

#: A small IAS15 group: a few planets and a Plummer sphere, each with its own span and softening.
ADAPTIVE = {"name": "ias", "kind": "adaptive", "system": {5: "planets", 1000: "plummer"}, "n": [5, 1000],
            "t_end": {5: 200.0, 1000: 0.02}, "softening": {5: 0.0, 1000: 0.01}, "threads": [1, 0]}


def _group(**changes: object) -> dict:
    return {"groups": [{**ADAPTIVE, **changes}]}


def test_adaptive_group_reads_per_n_values_and_expands_each_engine() -> None:
    m = matrix_from_dict(_group(first_dt=0.005, repeats=4))
    p = m.groups[0].params
    assert p["system"] == {5: "planets", 1000: "plummer"} and p["t_end"] == {5: 200.0, 1000: 0.02}
    assert p["first_dt"] == {5: 0.005, 1000: 0.005} and p["epsilon"] == 1e-9
    cases = m.adaptive_cases()
    assert [(c.n, c.engine, c.threads) for c in cases] == [
        (5, "orbitsim", 1), (5, "orbitsim", None), (5, "rebound", 1),
        (1000, "orbitsim", 1), (1000, "orbitsim", None), (1000, "rebound", 1)]
    big = cases[3]
    assert (big.system, big.t_end, big.softening, big.repeats) == ("plummer", 0.02, 0.01, 4)
    assert big.case_id == "ias/orbitsim/ias15/plummer/n1000/t1"
    assert m.steps_cases() == []  # an adaptive group has no fixed-step cases
    assert quick_matrix(m).groups[0].params["t_end"] == {5: 20.0, 1000: 0.002}  # --quick: a tenth of the span


@pytest.mark.parametrize(("changes", "key", "reason"), [
    ({"t_end": None}, "groups[0].t_end", "is required"),
    ({"t_end": {5: 1.0}}, "groups[0].t_end", "no value for N = 1000"),
    ({"t_end": {5: 1.0, 1000: 1.0, 7: 1.0}}, "groups[0].t_end.7", "not an N of this group"),
    ({"t_end": {5: -1.0, 1000: 1.0}}, "groups[0].t_end.5", "expected a finite number > 0"),
    ({"t_end": "soon"}, "groups[0].t_end", "expected a finite number"),
    ({"system": {5: "nowhere", 1000: "plummer"}}, "groups[0].system.5", "not plummer or planets"),
    ({"first_dt": 0}, "groups[0].first_dt", "> 0"),
    ({"softening": {5: -0.1, 1000: 0.0}}, "groups[0].softening.5", ">= 0"),
    ({"epsilon": 0}, "groups[0].epsilon", "> 0"),
    ({"engines": ["mercury"]}, "groups[0].engines[0]", "valid: orbitsim, rebound"),
    ({"n": [5, 5]}, "groups[0].n", "each N once"),
    ({"steps": [100]}, "groups[0].steps", "unknown key"),
])
def test_adaptive_errors_name_the_key(changes: dict, key: str, reason: str) -> None:
    doc = _group(**changes)
    if changes.get("t_end", 0) is None:
        del doc["groups"][0]["t_end"]
    with pytest.raises(BenchMatrixError) as err:
        matrix_from_dict(doc, source="m.yaml")
    assert str(err.value).startswith(f"m.yaml: {key}: ") and reason in str(err.value), str(err.value)


def test_a_bad_adaptive_group_exits_2_naming_file_and_key(tmp_path: Path) -> None:
    from orbitsim.cli.bench import command

    matrix = tmp_path / "bad.yaml"
    matrix.write_text(yaml.safe_dump(_group(t_end={5: 1.0})), encoding="utf-8")
    result = CliRunner().invoke(command, [str(matrix), "-o", str(tmp_path / "out")])
    assert result.exit_code == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and str(matrix) in lines[0] and "groups[0].t_end" in lines[0], result.stderr
    assert not (tmp_path / "out").exists()


def test_all_integrators_of_a_steps_group_leave_ias15_out() -> None:
    from orbitsim.integrators.registry import INTEGRATORS

    cases = matrix_from_dict({"groups": [{"name": "g", "n": [5], "integrators": "all", "steps": [10],
                                          "engines": ["orbitsim"]}]}).steps_cases()
    names = {c.integrator for c in cases}
    assert "ias15" not in names
    assert names == {spec.name for spec in INTEGRATORS if not spec.adaptive}  # every fixed-step scheme
    for name in ("ias15", "gauss_radau"):  # named explicitly: refused, pointing to the adaptive kind
        with pytest.raises(BenchMatrixError, match=r"groups\[0\]\.integrators\[1\]: .*kind: adaptive"):
            matrix_from_dict({"groups": [{"name": "g", "n": [5], "integrators": ["verlet", name]}]})


@pytest.fixture(scope="module")
def quick_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[dict, Path, str]:
    """``orbitsim bench --quick`` on the IAS15 group and a verlet/leapfrog pair at N = 1024."""
    from orbitsim.cli.bench import command

    tmp = tmp_path_factory.mktemp("bench_adaptive")
    verlet = {"name": "throughput", "system": "plummer", "n": [1024], "steps": [20], "dt": 1e-4,
              "softening": 0.01}
    doc = {"name": "ias", "repeats": 2, "warmup": 0, "groups": [verlet, ADAPTIVE]}
    matrix = tmp / "m.yaml"
    matrix.write_text(yaml.safe_dump(doc, sort_keys=False), encoding="utf-8")
    out = tmp / "out"
    result = CliRunner().invoke(command, [str(matrix), "--quick", "-o", str(out), "--threads", "1", "--no-plots"])
    assert result.exit_code == 0, result.output
    return json.loads((out / "results.json").read_text()), out, result.stdout


def test_quick_run_counts_accepted_steps_of_both_engines(quick_run: tuple[dict, Path, str]) -> None:
    doc, out, _ = quick_run
    records = doc["adaptive"]
    assert {(r["n"], r["engine"]) for r in records} == {(5, "orbitsim"), (5, "rebound"), (1000, "orbitsim"),
                                                        (1000, "rebound")}
    for r in records:
        assert r["t_end"] == {5: 20.0, 1000: 0.002}[r["n"]]  # --quick: a tenth of the span
        assert r["steps"] > 0 and r["steps_values"] == [r["steps"]] * r["repeats"] == [r["steps"]] * 2, r["id"]
        for block in ("time_s", "per_step_s", "cpu_per_step_s"):
            assert r[block]["min"] <= r[block]["median"] <= r[block]["max"], (r["id"], block)
        assert r["per_step_s"]["values"] == pytest.approx([t / r["steps"] for t in r["time_s"]["values"]])
        if r["engine"] == "orbitsim":
            assert r["force_evaluations"] > r["steps"] and r["steps_rejected"] >= 0
            assert r["rebound_over_orbitsim"]["twin"] == f"ias/rebound/ias15/{r['system']}/n{r['n']}"
            assert r["rebound_over_orbitsim"]["rounds"] == 2
    # --threads 1 makes threads [1, 0] one case; the second is reported, not run twice.
    assert sum("same thread count" in s["reason"] for s in doc["skipped"]) == 2
    assert not any(c["integrator"] == "ias15" for c in doc["cases"])  # kept out of the fixed-step cases
    text = (out / "results.md").read_text()
    assert "## orbitsim beside REBOUND: IAS15 over the same span" in text and "| ias | 1000 | plummer |" in text


def test_quick_run_targets_have_both_ias15_rows(quick_run: tuple[dict, Path, str]) -> None:
    doc, _, stdout = quick_run
    rows = {row["key"]: row for row in doc["targets"]}
    small, large = rows["ias15_n5"], rows["ias15_n1000"]
    for row in (small, large):
        assert row["measured"] > 0 and row["margin"] > 0 and row["met"] in (True, False)
        assert row["target"] in stdout  # the table the command prints
    assert small["margin"] == pytest.approx(small["measured"])  # required: REBOUND / orbitsim >= 1
    assert "throughput/orbitsim/verlet/plummer/n1024" in large["required"]  # the run's own verlet ratio
    assert large["source"] == "ias/orbitsim/ias15/plummer/n1000/t1 vs ias/rebound/ias15/plummer/n1000"


def _record(engine: str, n: int, ratio: float | None = None) -> dict:
    per_step = {"median": 1e-3, "min": 1e-3, "max": 1e-3, "values": [1e-3]}
    rec = {"id": f"g/{engine}/ias15/s/n{n}", "engine": engine, "n": n, "threads": 1, "t_end": 1.0, "steps": 10,
           "per_step_s": per_step}
    if ratio is not None:
        rec["rebound_over_orbitsim"] = {"twin": f"g/rebound/ias15/s/n{n}", "wall": ratio, "cpu": ratio, "rounds": 1}
    return rec


def test_ias15_targets_degrade_when_a_case_is_missing() -> None:
    from orbitsim.bench.targets import IAS15_LARGE_FALLBACK, evaluate_targets

    rows = {r["key"]: r for r in evaluate_targets({"cases": [], "probes": []})}
    assert rows["ias15_n5"]["met"] is None and rows["ias15_n5"]["measured_text"] == "not measured"
    assert rows["ias15_n1000"]["met"] is None and "fallback" in rows["ias15_n1000"]["required"]
    # No verlet/leapfrog pair at N = 1024: the N = 1000 row requires the fallback ratio, and says so.
    doc = {"adaptive": [_record("orbitsim", 1000, 6.0), _record("rebound", 1000),
                        _record("orbitsim", 5, 0.8), _record("rebound", 5)]}
    rows = {r["key"]: r for r in evaluate_targets(doc)}
    assert rows["ias15_n1000"]["margin"] == pytest.approx(6.0 / IAS15_LARGE_FALLBACK)
    assert rows["ias15_n1000"]["met"] is True and "fallback" in rows["ias15_n1000"]["required"]
    assert rows["ias15_n5"]["margin"] == pytest.approx(0.8) and rows["ias15_n5"]["met"] is False
