"""The ``trace`` kind of the benchmark matrix: orbitsim's trace beside REBOUND's TRACE.

As in tests/bench/test_bench.py, nothing here asserts a time: what is tested is the bookkeeping. The
group is parsed with per-N values and its errors name the key; ``--group`` selects it alone; a
tiny run records both engines over the same steps, orbitsim's encounter counters and whether the
final states agree; the targets table has the two TRACE rows, judged only where encounters happened.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import yaml
from click.testing import CliRunner

from orbitsim.bench.matrix import BenchMatrixError, load_matrix, matrix_from_dict
from orbitsim.bench.runner import quick_matrix
from orbitsim.data import MATRICES, bundled_dir

rebound = pytest.importorskip("rebound")

#: A tiny TRACE group: 100 steps of many_encounters (its own dt, 0.034) and of a 20-body disc.
TRACE = {"name": "tr", "kind": "trace", "system": {7: "many_encounters", 20: "planetesimals"}, "n": [7, 20],
         "t_end": {7: 3.39, 20: 1.99}, "dt": 0.02}


def test_trace_group_reads_per_n_values_and_expands_both_engines() -> None:
    m = matrix_from_dict({"groups": [{**TRACE, "repeats": 4}]})
    p = m.groups[0].params
    assert p["system"] == {7: "many_encounters", 20: "planetesimals"} and p["t_end"] == {7: 3.39, 20: 1.99}
    assert p["dt"] == {7: 0.02, 20: 0.02} and p["softening"] == {7: 0.0, 20: 0.0}
    cases = m.trace_cases()
    assert [(c.n, c.engine, c.repeats) for c in cases] == [(7, "orbitsim", 4), (7, "rebound", 4), (20, "orbitsim", 4),
                                                           (20, "rebound", 4)]
    assert cases[0].case_id == "tr/orbitsim/trace/many_encounters/n7"
    assert m.steps_cases() == [] and m.adaptive_cases() == []
    quick = quick_matrix(m).groups[0].params["t_end"]
    assert quick == pytest.approx({7: 0.339, 20: 0.199})  # --quick: a tenth of the span


@pytest.mark.parametrize(("changes", "key", "reason"), [
    ({"t_end": {7: 1.0}}, "groups[0].t_end", "no value for N = 20"),
    ({"system": {7: "many_encounters", 20: "nowhere"}}, "groups[0].system.20", "not plummer or planets"),
    ({"system": {7: "planets", 20: "many_encounters"}}, "groups[0].system.20", "has 7 bodies, not N = 20"),
    ({"dt": {7: 0.0, 20: 0.02}}, "groups[0].dt.7", "> 0"),
    ({"engines": ["mercury"]}, "groups[0].engines[0]", "valid: orbitsim, rebound"),
    ({"threads": [1]}, "groups[0].threads", "unknown key"),
])
def test_trace_errors_name_the_key(changes: dict, key: str, reason: str) -> None:
    with pytest.raises(BenchMatrixError) as err:
        matrix_from_dict({"groups": [{**TRACE, **changes}]}, source="m.yaml")
    assert str(err.value).startswith(f"m.yaml: {key}: ") and reason in str(err.value), str(err.value)


@pytest.mark.parametrize("name", ["full", "quick"])
def test_bundled_matrices_select_the_trace_cases(name: str) -> None:
    """The issue's two set-ups: REBOUND's many encounters to t = 2000 (the full matrix) and a disc of
    ~100 planetesimals, selectable alone with ``--group trace``; bundled matrices load by name."""
    m = load_matrix(name).select(("trace",))
    assert m.name == name and Path(m.source) == bundled_dir(MATRICES) / f"{name}.yaml"
    assert [g.name for g in m.groups] == ["trace"]
    cases = {(c.system, c.n, c.engine): c for c in m.trace_cases()}
    assert set(cases) == {(s, n, e) for s, n in (("many_encounters", 7), ("planetesimals", 103))
                          for e in ("orbitsim", "rebound")}
    if name == "full":
        assert cases["many_encounters", 7, "orbitsim"].t_end == 2000.0
    with pytest.raises(BenchMatrixError, match=r"groups: no group named 'nope'; groups: .*trace"):
        load_matrix(name).select(("nope",))


def test_an_unknown_group_exits_2_naming_the_groups(tmp_path: Path) -> None:
    from orbitsim.cli.bench import command

    matrix = tmp_path / "m.yaml"
    matrix.write_text(yaml.safe_dump({"groups": [TRACE]}), encoding="utf-8")
    result = CliRunner().invoke(command, [str(matrix), "--group", "trace", "-o", str(tmp_path / "out")])
    lines = result.stderr.strip().splitlines()
    assert result.exit_code == 2 and len(lines) == 1, result.output
    assert str(matrix) in lines[0] and "no group named 'trace'; groups: tr" in lines[0]
    assert not (tmp_path / "out").exists()


def test_whole_steps_count_as_rebound_integrate_does() -> None:
    from orbitsim.bench.trace import whole_steps

    assert whole_steps(2000.0, 0.034) == 58824  # the bundled scenario's steps: t = 2000.016
    assert whole_steps(1.0, 0.5) == 2 and whole_steps(1.0, 0.3) == 4


def test_planetesimal_disc_is_reproducible_and_massive() -> None:
    from orbitsim.bench.systems import DISC_MASS, DISC_PLANETS, build_system, planetesimals

    m, x, v = planetesimals(103, seed=3)
    m2, x2, v2 = planetesimals(103, seed=3)
    assert np.array_equal(x, x2) and np.array_equal(v, v2) and np.array_equal(m, m2)
    assert m[0] == 1.0 and tuple(m[1:3]) == tuple(p[0] for p in DISC_PLANETS)
    assert np.all((m[3:] >= DISC_MASS[0]) & (m[3:] <= DISC_MASS[1]))  # massive: TRACE's encounters count them
    assert np.allclose(m @ x, 0.0, atol=1e-15) and np.allclose(m @ v, 0.0, atol=1e-15)  # barycentric
    assert build_system("planetesimals", 5).n == 5


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[dict, Path, str]:
    """``orbitsim bench m.yaml --group tr``: the TRACE group alone (the steps group is not run)."""
    from orbitsim.cli.bench import command

    tmp = tmp_path_factory.mktemp("bench_trace")
    steps = {"name": "small", "system": "planets", "n": [5], "steps": [100]}
    matrix = tmp / "m.yaml"
    matrix.write_text(yaml.safe_dump({"repeats": 2, "warmup": 0, "groups": [steps, TRACE]}), encoding="utf-8")
    out = tmp / "out"
    result = CliRunner().invoke(command, [str(matrix), "--group", "tr", "-o", str(out), "--no-plots"])
    assert result.exit_code == 0, result.output
    return json.loads((out / "results.json").read_text()), out, result.stdout


def test_tiny_run_records_both_engines_over_the_same_steps(tiny_run: tuple[dict, Path, str]) -> None:
    doc, out, _ = tiny_run
    assert doc["cases"] == [] and doc["adaptive"] == []  # only the selected group ran
    records = {(r["n"], r["engine"]): r for r in doc["trace"]}
    assert set(records) == {(7, "orbitsim"), (7, "rebound"), (20, "orbitsim"), (20, "rebound")}
    for r in records.values():
        assert r["steps"] == 100 and r["repeats"] == 2 and len(r["time_s"]["values"]) == 2, r["id"]
        assert r["time_s"]["min"] <= r["time_s"]["median"] <= r["time_s"]["max"]
        assert r["dt"] == {7: 0.034, 20: 0.02}[r["n"]]  # the scenario brings its own dt
    for n in (7, 20):
        ours, theirs = records[n, "orbitsim"], records[n, "rebound"]
        assert ours["counters"]["steps"] == 100 and {"redone", "encounter_bs_substeps"} <= set(ours["counters"])
        ratio = ours["orbitsim_over_rebound"]
        assert ratio["twin"] == theirs["id"] and ratio["rounds"] == 2
        assert ratio["best"] == pytest.approx(ours["time_s"]["min"] / theirs["time_s"]["min"])
        same = ours["agreement"]
        if rebound.__version__ == "5.2.2":  # the port is REBOUND 5.2.2's operations in its order
            assert same["bitwise"] and same["position"] == 0.0 and same["velocity"] == 0.0
        assert same["position"] < 1e-6
    text = (out / "results.md").read_text()
    assert "## orbitsim beside REBOUND: TRACE over the same steps" in text and "| tr | 7 | many_encounters |" in text


def test_tiny_run_targets_have_both_trace_rows(tiny_run: tuple[dict, Path, str]) -> None:
    doc, _, stdout = tiny_run
    rows = {row["key"]: row for row in doc["targets"]}
    for key, system in (("trace_many_encounters", "many_encounters"), ("trace_disc", "planetesimals")):
        row = rows[key]
        assert row["measured"] > 0 and row["target"] in stdout, row
        assert row["source"] == f"tr/orbitsim/trace/{system}/n{7 if key == 'trace_many_encounters' else 20} vs " \
                                f"tr/rebound/trace/{system}/n{7 if key == 'trace_many_encounters' else 20}"
        encounters = next(r for r in doc["trace"] if r["system"] == system and r["engine"] == "orbitsim")[
            "counters"]["encounter_bs_substeps"]
        assert (row["met"] is None) == (encounters == 0), row  # judged only where encounters happened


def _record(engine: str, system: str, best: float, substeps: int = 10) -> dict:
    rec = {"id": f"g/{engine}/trace/{system}/n7", "engine": engine, "system": system, "steps": 100, "t_end": 1.0,
           "counters": {"redone": 1, "encounter_bs_substeps": substeps} if engine == "orbitsim" else {}}
    if engine == "orbitsim":
        rec["orbitsim_over_rebound"] = {"twin": f"g/rebound/trace/{system}/n7", "best": best, "wall": best,
                                        "cpu": best, "rounds": 3}
        rec["agreement"] = {"bitwise": True, "position": 0.0, "velocity": 0.0}
    return rec


def test_trace_targets_level_and_strict_and_without_encounters() -> None:
    from orbitsim.bench.targets import evaluate_targets

    rows = {r["key"]: r for r in evaluate_targets({"cases": [], "probes": []})}
    assert rows["trace_many_encounters"]["measured_text"] == "not measured" and rows["trace_disc"]["met"] is None
    # Level with REBOUND: enough for many encounters (<= 1), not for the disc (< 1).
    doc = {"trace": [_record("orbitsim", "many_encounters", 1.0), _record("orbitsim", "planetesimals", 1.0)]}
    rows = {r["key"]: r for r in evaluate_targets(doc)}
    assert rows["trace_many_encounters"]["met"] is True and rows["trace_disc"]["met"] is False
    assert "bit-identical" in rows["trace_disc"]["measured_text"]
    doc = {"trace": [_record("orbitsim", "planetesimals", 0.7, substeps=0)]}
    row = next(r for r in evaluate_targets(doc) if r["key"] == "trace_disc")
    assert row["met"] is None and "no close encounter" in row["measured_text"]
