"""The benchmark runner on tiny matrices: files written, fields present, REBOUND cases present.

No test here asserts a time: the machine is shared and timings are noise at this size. What is
tested is the bookkeeping: every case is there with median/min/max and its JIT time apart, the
ratios pair the right cases, bad matrices fail with one line naming the file and the key.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import yaml
from click.testing import CliRunner

from orbitsim.bench.matrix import BenchMatrixError, load_matrix, matrix_from_dict, steps_for
from orbitsim.bench.runner import SCHEMA, quick_matrix, run_matrix, write_results

#: A matrix that does a few milliseconds of work per case.
TINY = {
    "name": "tiny",
    "repeats": 2,
    "warmup": 0,
    "groups": [
        {"name": "big", "system": "plummer", "integrators": ["verlet"], "n": [24], "threads": [1],
         "work": 2.0e5, "rebound_work": 2.0e4, "dt": 1.0e-4},
        {"name": "small", "system": "planets", "integrators": ["verlet", "semi_implicit_euler"],
         "rebound_integrators": ["leapfrog", "leapfrog:4"], "n": [2, 5], "steps": [300]},
        {"name": "sampling", "kind": "sampling", "n": 5, "steps": 1000, "every": 100, "repeats": 2},
        {"name": "memory", "kind": "memory", "n": 32, "steps": 1, "trace_samples": 300},
        {"name": "kern", "kind": "kernels", "n": [8, 400], "work": 1e5, "repeats": 2},
    ],
}


def _write(path: Path, doc: dict) -> Path:
    path.write_text(yaml.safe_dump(doc, sort_keys=False), encoding="utf-8")
    return path


@pytest.fixture(scope="module")
def results(tmp_path_factory: pytest.TempPathFactory) -> tuple[dict, Path, list[Path]]:
    out = tmp_path_factory.mktemp("bench")
    doc = run_matrix(matrix_from_dict(TINY, source="tiny.yaml"), threads=1)
    files = write_results(doc, out)
    return doc, out, files


def test_results_files_are_written(results: tuple[dict, Path, list[Path]]) -> None:
    _, out, files = results
    for name in ("results.json", "results.md", "throughput.png", "small_n.png"):
        assert (out / name).is_file() and (out / name).stat().st_size > 0, name
    assert {f.name for f in files} >= {"results.json", "results.md", "throughput.png", "small_n.png"}
    text = (out / "results.md").read_text()
    assert "## Targets" in text and "orbitsim beside REBOUND" in text


def test_results_json_has_machine_versions_and_threads(results: tuple[dict, Path, list[Path]]) -> None:
    _, out, _ = results
    doc = json.loads((out / "results.json").read_text())
    assert doc["schema"] == SCHEMA
    assert doc["threads"] == 1 and doc["machine"]["threads"] == 1
    for key in ("cpu_model", "cpu_count", "numba_version", "numpy_version", "rebound_version", "orbitsim_version",
                "python_version", "numba_threading_layer"):
        assert key in doc["machine"], key
    assert {"orbitsim", "numba", "numpy", "rebound", "python"} <= set(doc["versions"])
    assert doc["ceiling"]["pairs_once_per_core"] == pytest.approx(2 * doc["ceiling"]["full_per_core"])


def test_every_case_has_statistics_and_separate_compile_time(results: tuple[dict, Path, list[Path]]) -> None:
    doc, _, _ = results
    cases = doc["cases"]
    # big: orbitsim verlet + REBOUND leapfrog at N = 24; small: (2 + 2) schemes x 2 sizes.
    assert len(cases) == 2 + 8
    for c in cases:
        for block in ("time_s", "per_step_s", "pairs_per_s"):
            assert c[block]["min"] <= c[block]["median"] <= c[block]["max"], (c["id"], block)
        assert len(c["time_s"]["values"]) == c["repeats"] == 2
        assert c["first_call_s"] > 0 and c["compile_s"] >= 0
        assert c["jit"] in (("compiled", "cache", "in-memory") if c["engine"] == "orbitsim" else ("n/a",))
        assert c["pairs_per_s"]["median"] == pytest.approx(
            c["force_evals"] * c["n"] * (c["n"] - 1) * c["steps"] / c["time_s"]["median"])
    leapfrog4 = next(c for c in cases if c["integrator"] == "leapfrog:4")
    assert leapfrog4["force_evals"] == 3


def test_rebound_cases_are_present_beside_orbitsim(results: tuple[dict, Path, list[Path]]) -> None:
    doc, _, _ = results
    engines = {(c["group"], c["n"], c["engine"]) for c in doc["cases"]}
    for group, n in (("big", 24), ("small", 2), ("small", 5)):
        assert {(group, n, "orbitsim"), (group, n, "rebound")} <= engines
    rows = {row["key"]: row for row in doc["targets"]}
    assert rows["small_n_verlet"]["measured"] is not None  # N = 5 pairs orbitsim with REBOUND
    assert rows["throughput_16k"]["met"] is None  # not measured by this matrix: reported, not failed


def test_probes_report_sampling_and_memory(results: tuple[dict, Path, list[Path]]) -> None:
    doc, _, _ = results
    probes = {p["kind"]: p for p in doc["probes"]}
    assert probes["sampling"]["samples"] == 11
    assert probes["sampling"]["with_samples"]["median"] > 0
    sampling = probes["sampling"]  # the overhead pairs the two runs of each round
    rounds = zip(sampling["with_samples"]["values"], sampling["without_samples"]["values"], strict=True)
    assert sampling["overhead"] == pytest.approx(float(np.median([a / b for a, b in rounds])) - 1.0)
    memory = probes["memory"]
    assert memory["large"]["peak_rss_mb"] > memory["large"]["baseline_rss_mb"] * 0.5
    assert memory["trace"]["samples"] == 300 and memory["trace"]["series"]


def test_kernel_probe_times_every_kernel_and_reports_crossovers(results: tuple[dict, Path, list[Path]]) -> None:
    doc, out, _ = results
    probe = next(p for p in doc["probes"] if p["kind"] == "kernels")
    small, large = probe["rows"]
    assert small["n"] == 8 and set(small["pairs_per_s"]) == {"all_pairs", "rows", "blocked"}
    assert large["n"] == 400 and set(large["pairs_per_s"]) == {"rows", "blocked"}  # all-pairs: small N only
    assert all(v > 0 for v in small["pairs_per_s"].values())
    assert "small_n_max" in probe and "parallel_min_n" in probe
    assert "blocked faster than rows from N" in (out / "results.md").read_text()


def test_cli_quick_on_a_custom_matrix(tmp_path: Path) -> None:
    from orbitsim.cli.bench import command

    doc = {"name": "cli", "repeats": 1, "warmup": 0, "groups": [TINY["groups"][1]]}
    matrix = _write(tmp_path / "m.yaml", doc)
    out = tmp_path / "out"
    result = CliRunner().invoke(command, [str(matrix), "--quick", "-o", str(out), "--threads", "1", "-q"])
    assert result.exit_code == 0, result.output
    saved = json.loads((out / "results.json").read_text())
    assert saved["matrix"]["quick"] is True and saved["threads"] == 1
    assert all(c["steps"] == 30 for c in saved["cases"])  # --quick: a tenth of the steps
    assert (out / "small_n.png").is_file()


@pytest.mark.parametrize(("group", "key"), [
    ({"name": "g", "n": ["many"]}, "groups[0].n[0]"),
    ({"name": "g", "n": [8], "colour": "red"}, "groups[0].colour"),
    ({"name": "g", "n": [8], "integrators": ["nope"]}, "groups[0].integrators[0]"),
    ({"name": "g", "kind": "speed"}, "groups[0].kind"),
    ({"name": "g", "n": [8], "steps": [10], "work": 1e6}, "groups[0].steps"),
    ({"name": "g", "n": [8], "rebound_integrators": ["ias15"]}, "groups[0].rebound_integrators[0]"),
])
def test_bad_matrix_exits_2_with_one_line_naming_file_and_key(tmp_path: Path, group: dict, key: str) -> None:
    from orbitsim.cli.bench import command

    matrix = _write(tmp_path / "bad.yaml", {"groups": [group]})
    result = CliRunner().invoke(command, [str(matrix), "-o", str(tmp_path / "out")])
    assert result.exit_code == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and str(matrix) in lines[0] and key in lines[0], result.stderr
    assert not (tmp_path / "out").exists()


def test_matrix_errors_are_one_line(tmp_path: Path) -> None:
    bad = tmp_path / "broken.yaml"
    bad.write_text("groups: [\n", encoding="utf-8")
    with pytest.raises(BenchMatrixError, match=r"broken\.yaml: not valid YAML \(line"):
        load_matrix(bad)
    with pytest.raises(BenchMatrixError, match="groups: expected a non-empty list"):
        matrix_from_dict({"groups": []})
    with pytest.raises(BenchMatrixError, match=r"groups\[1\]\.name: duplicate"):
        matrix_from_dict({"groups": [{"name": "a", "n": [4]}, {"name": "a", "n": [8]}]})


def test_yaml_numbers_without_a_dot_and_quick_cuts() -> None:
    m = matrix_from_dict({"groups": [{"name": "g", "n": [64], "work": "2e9", "rebound_work": "1e8"},
                                     {"name": "m", "kind": "memory", "trace_samples": "1e7"}]})
    assert m.groups[0].params["work"] == 2e9 and m.groups[1].params["trace_samples"] == 10**7
    q = quick_matrix(m)
    assert q.groups[0].params["work"] == 2e8 and q.groups[1].params["trace_samples"] == 0
    assert all(g.repeats <= 3 for g in q.groups)


def test_steps_follow_the_work_budget() -> None:
    assert steps_for(1e9, 1000, 1, 2, 10**6) == 1002  # ceil(1e9 / 999000) = ceil(1001.001)
    assert steps_for(1e9, 16384, 1, 3, 10**6) == 4
    assert steps_for(1e9, 2, 1, 2, 500) == 500
    cases = matrix_from_dict({"groups": [{"name": "g", "n": [100], "integrators": ["verlet", "leapfrog4"],
                                          "rebound_integrators": ["leapfrog:4"], "work": 9.9e6}]}).steps_cases()
    assert [(c.engine, c.integrator, c.steps) for c in cases] == [
        ("orbitsim", "verlet", 1000), ("orbitsim", "leapfrog4", 334), ("rebound", "leapfrog:4", 34)]
    fixed = matrix_from_dict({"groups": [{"name": "g", "n": [100, 200], "steps_by_n": {200: 7},
                                          "work": 9.9e6}]}).steps_cases()
    assert [(c.engine, c.n, c.steps) for c in fixed] == [
        ("orbitsim", 100, 1000), ("rebound", 100, 100), ("orbitsim", 200, 7), ("rebound", 200, 25)]


def test_cached_function_names_and_foreign_schemes(tmp_path: Path) -> None:
    from orbitsim.bench.probes import _foreign_integrators, cached_functions

    folder = tmp_path / "integrators_abc"
    folder.mkdir()
    for name in ("verlet.run-43.py311.nbi", "base.drift-60.py311.nbi", "rk4.step-50.py311.nbi"):
        (folder / name).write_bytes(b"")
    names = cached_functions(tmp_path)
    assert names == ["base.drift", "rk4.step", "verlet.run"]
    assert _foreign_integrators(names, "verlet") == ["rk4.step"]


def test_rss_growth_sees_a_trend_not_the_allocator_swing() -> None:
    from orbitsim.bench.probes import rss_growth

    samples = np.linspace(0, 1e7, 41)
    ramp_then_flat = [[w, 0.0, min(300.0, 180.0 + w * 1.2e-4) + (11.0 if k % 2 else -11.0)]
                      for k, w in enumerate(samples)]
    settled, growth = rss_growth(ramp_then_flat)
    assert 280.0 < settled < 320.0 and abs(growth) < 0.05 * settled
    growing = [[w, 0.0, 200.0 + w * 2e-5] for w in samples]  # +200 MB over the run
    settled, growth = rss_growth(growing)
    assert growth > 100.0


def _timed_case(group: str, engine: str, integrator: str, values: list[float], steps: int = 10) -> dict:
    summary = {"median": float(np.median(values)), "min": min(values), "max": max(values), "values": values}
    per_step = {k: summary[k] / steps for k in ("median", "min", "max")}
    return {"id": f"{group}/{engine}/{integrator}", "group": group, "engine": engine, "integrator": integrator,
            "n": 5, "steps": steps, "threads": 1, "repeats": len(values), "time_s": summary, "cpu_s": summary,
            "per_step_s": per_step, "cpu_per_step_s": per_step}


def test_ratios_pair_the_repeats_of_one_round() -> None:
    from orbitsim.bench.targets import evaluate_targets, paired_ratio

    # orbitsim takes 1 s a repeat and REBOUND 2 s; a burst of load (9x) slows orbitsim in rounds
    # 3-5 and REBOUND in rounds 4-5. Round by round the ratio is 0.5 in four rounds of five; the
    # ratio of the two medians says 4.5.
    orbitsim = _timed_case("pair", "orbitsim", "verlet", [1.0, 1.0, 9.0, 9.0, 9.0])
    rebound = _timed_case("pair", "rebound", "leapfrog", [2.0, 2.0, 2.0, 18.0, 18.0])
    assert paired_ratio(orbitsim, rebound) == pytest.approx(0.5)
    assert orbitsim["per_step_s"]["median"] / rebound["per_step_s"]["median"] == pytest.approx(4.5)
    # Times per step: the same repeats over twice the steps halve REBOUND's cost per step.
    longer = _timed_case("pair", "rebound", "leapfrog", [2.0, 2.0, 2.0, 18.0, 18.0], steps=20)
    assert paired_ratio(orbitsim, longer) == pytest.approx(1.0)
    # The targets take the group with the most rounds: the 5-round pair group (0.5, met), not the
    # 2-round one (2.0).
    few = [_timed_case("wide", "orbitsim", "verlet", [4.0, 4.0]),
           _timed_case("wide", "rebound", "leapfrog", [2.0, 2.0])]
    rows = {r["key"]: r for r in evaluate_targets({"cases": [*few, orbitsim, rebound]})}
    assert rows["small_n_verlet"]["measured"] == pytest.approx(0.5)
    assert rows["small_n_verlet"]["met"] is True and "pair" in rows["small_n_verlet"]["source"]


def test_the_ensemble_kind_reads_and_shrinks_for_quick():
    from orbitsim.bench.matrix import matrix_from_dict
    from orbitsim.bench.runner import quick_matrix

    matrix = matrix_from_dict({"groups": [{"name": "ens", "kind": "ensemble", "map_n": 20, "k": 4096,
                                           "large_map_n": 200}]})
    params = matrix.groups[0].params
    assert (params["map_n"], params["years"], params["k"], params["steps"]) == (20, 1e4, 4096, 2000)
    assert params["large_map_n"] == 200
    quick = quick_matrix(matrix).groups[0].params
    assert (quick["map_n"], quick["years"], quick["k"], quick["steps"]) == (8, 1e3, 512, 200)
    assert quick["large_map_n"] == 0  # minutes: never in --quick


@pytest.mark.slow
def test_the_ensemble_probe_times_both_codes():
    from types import SimpleNamespace

    from orbitsim.bench.ensemble import run_ensemble_probe

    group = SimpleNamespace(params={"map_n": 2, "years": 10.0, "indicator": "max_e", "k": 4, "steps": 10,
                                    "large_map_n": 3})
    result = run_ensemble_probe(group)
    for key in ("rebound_map_s", "orbitsim_map_s", "orbitsim_compute_s", "orbitsim_kernel_s", "ensemble_ns",
                "single_ns", "rebound_ns",
                "large_map_s", "large_rebound_estimate_s"):
        assert result[key] > 0.0, key
    side = result["step_ns_side_by_side"]
    assert len(side["ensemble_1_thread_ns"]) == len(side["whfast_ns"]) == 2  # two rounds, every contender
    assert isinstance(side["whfast512"], str) or min(side["whfast512"]["n_systems_2_ns"]) > 0.0
    rates = result["variational_pixel_steps_per_s"]
    assert set(rates) == {"wisdom_holman", "leapfrog", "leapfrog4", "verlet"}
    assert all(rate > 0.0 for rate in rates.values())
    lanes = result["variational_lanes_step_ns"]
    for key in ("lanes_threads_ns", "scalar_threads_ns", "lanes_1_thread_ns", "scalar_1_thread_ns"):
        assert len(lanes[key]) == 2 and min(lanes[key]) > 0.0, key  # two rounds, every contender


def test_the_ensemble_report_shows_the_variational_lanes_beside_the_scalar_kernel():
    from orbitsim.bench.report import markdown

    probe = {"group": "ensemble", "kind": "ensemble", "map_n": 2, "years": 1.0, "indicator": "megno",
             "rebound_map_s": 1.0, "orbitsim_map_s": 1.0, "orbitsim_compute_s": 0.5, "orbitsim_kernel_s": 0.4,
             "k": 4, "steps": 3, "ensemble_ns": 700.0, "single_ns": 700.0, "rebound_ns": 1200.0,
             "variational_lanes_step_ns": {"k": 4, "steps": 3, "threads": 2, "lanes_threads_ns": [180.0, 170.0],
                                           "scalar_threads_ns": [900.0, 950.0], "lanes_1_thread_ns": [340.0, 330.0],
                                           "scalar_1_thread_ns": [1700.0, 1600.0]}}
    text = markdown({"machine": {}, "matrix": {"name": "t", "quick": True}, "threads": 2, "probes": [probe]})
    line = next(row for row in text.splitlines() if "with the variational equations and MEGNO (wisdom_holman" in row)
    assert line.endswith("best of 2 rounds, K = 4: 16 lanes 330 on 1 thread, 170 on 2; scalar kernel 1600 on 1 "
                         "thread, 900 on 2")


def test_the_map_targets_read_the_ensemble_probe_and_say_when_it_is_missing():
    from orbitsim.bench.targets import evaluate_targets

    probe = {"group": "ensemble", "kind": "ensemble", "map_n": 20, "years": 1e4, "rebound_map_s": 5.5,
             "orbitsim_map_s": 1.6,
             "orbitsim_compute_s": 0.5, "orbitsim_setup_s": 0.2, "large_map_n": 200, "large_map_s": 48.0,
             "large_rebound_estimate_s": 550.0}
    rows = {row["key"]: row for row in evaluate_targets({"probes": [probe]})}
    assert rows["map_ratio"]["met"] and rows["map_ratio"]["measured"] == pytest.approx(11.0)  # 5.5 / 0.5
    assert "0.20 s readying the kernels" in rows["map_ratio"]["measured_text"]
    assert rows["map_large"]["met"] and rows["map_large"]["margin"] == pytest.approx(1.25)  # 60 / 48
    slow = dict(probe, orbitsim_compute_s=0.6, large_map_s=75.0)
    rows = {row["key"]: row for row in evaluate_targets({"probes": [slow]})}
    assert rows["map_ratio"]["met"] is False and rows["map_large"]["met"] is False
    rows = {row["key"]: row for row in evaluate_targets({"probes": [dict(probe, large_map_n=0)]})}
    assert rows["map_large"]["met"] is None and rows["map_large"]["measured_text"] == "not measured"
    rows = {row["key"]: row for row in evaluate_targets({"probes": [dict(probe, map_n=8, years=1e3)]})}
    assert rows["map_ratio"]["met"] is None and rows["map_ratio"]["measured_text"].endswith("not judged")  # --quick
    rows = {row["key"]: row for row in evaluate_targets({"probes": []})}
    assert rows["map_ratio"]["met"] is None and rows["map_large"]["met"] is None
