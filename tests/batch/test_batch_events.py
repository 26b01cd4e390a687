"""``orbitsim batch`` and events: the count columns in summary.csv, summary.h5 and the terminal
table, and ``halted`` as a result (exit 0), not a failure.

The sweeps go through the real CLI on a one-worker local cluster; their runs use verlet, so only one
scheme's events kernels are compiled.
"""

from __future__ import annotations

import csv
import math
import os
import textwrap
from pathlib import Path

import h5py
import numpy as np
import pytest
from click.testing import CliRunner
from test_info_events import HEAD_ON as INFO_HEAD_ON

from orbitsim.batch.summary import column_names, events_cell, format_table, write_csv, write_h5
from orbitsim.batch.task import failed_result, trace_result
from orbitsim.cli.main import cli

COUNTS = ("encounters", "collisions", "escapes", "unresolved")

#: Two bodies thrown at each other (they touch near t = 1.88) and a distant star.
HEAD_ON = INFO_HEAD_ON.replace("RESOLVE", "merge")

#: merge (complete, 1 collision); halt (halted at the collision); no events section (all 0);
#: merge with encounters below 0.3 (1 collision, 1 encounter cut short by the merge).
SWEEP = """\
base: head_on.yaml
cases:
  - {events.collisions.resolve: merge}
  - {events.collisions.resolve: halt}
  - {events: null}
  - {events.encounters: {distance: 0.3}}
"""


def _row(status: str, **counts: int | None) -> dict:
    base = {"steps_done": 10, "max_abs_energy_error": 1e-6, "final_energy_error": 1e-7, "wall_time_s": 0.1,
            "steps_per_second": 100.0, "worker": "w", "resumed": False, "trace": "runs/x.h5", "error": ""}
    return {"case": 0, "run_id": "a" * 16, "params": {}, "status": status, **base,
            **{c: counts.get(c, 0) for c in COUNTS}}


def test_summary_files_have_count_columns_whole_in_csv_and_nan_for_a_failed_run_in_h5(tmp_path: Path) -> None:
    rows = [_row("complete", encounters=3, escapes=1), _row("complete"),
            {**_row("failed"), **{c: None for c in COUNTS}, "case": 2}]
    path = write_csv(tmp_path / "summary.csv", rows, ())
    with open(path, newline="") as fh:
        got = list(csv.DictReader(fh))
    assert [n for n in column_names(()) if n in COUNTS] == list(COUNTS)
    assert [[r[c] for c in COUNTS] for r in got] == [["3", "0", "1", "0"], ["0"] * 4, [""] * 4]
    with h5py.File(write_h5(tmp_path / "summary.h5", rows, ()), "r") as f:
        for c in COUNTS:
            assert f[c].dtype == np.float64  # float64, so that a run with no trace can be NaN
        assert f["encounters"][:2].tolist() == [3.0, 0.0] and f["escapes"][:2].tolist() == [1.0, 0.0]
        assert all(math.isnan(f[c][2]) for c in COUNTS)


def test_failed_result_has_no_counts() -> None:
    result = failed_result("boom")
    assert all(result[c] is None for c in COUNTS)


def test_terminal_table_has_an_events_column_only_when_a_run_logged_one() -> None:
    plain = format_table([_row("complete"), {**_row("failed"), **{c: None for c in COUNTS}}], ())
    assert "events logged" not in plain.splitlines()[0]
    assert events_cell(_row("complete", encounters=3, escapes=1)) == "3 enc, 1 esc"
    assert events_cell({**_row("failed"), **{c: None for c in COUNTS}}) == ""
    text = format_table([_row("complete", encounters=12, collisions=3, escapes=1, unresolved=40)], ())
    header, line = text.splitlines()
    assert header.split()[-3:] == ["events", "logged", "error"] and "12 enc, 3 col, 1 esc, 40 unres" in line


def test_trace_result_counts_a_plain_trace_as_zero_events(tmp_path: Path) -> None:
    scenario = tmp_path / "plain.yaml"
    scenario.write_text(HEAD_ON.replace("events:\n  collisions: {detect: line, resolve: merge}\n", ""))
    out = tmp_path / "plain.h5"
    assert CliRunner().invoke(cli, ["run", str(scenario), "-o", str(out), "-q"]).exit_code == 0
    assert {c: trace_result(out)[c] for c in COUNTS} == dict.fromkeys(COUNTS, 0)


def _sweep(tmp_path: Path) -> Path:
    (tmp_path / "head_on.yaml").write_text(HEAD_ON)
    path = tmp_path / "sweep.yaml"
    path.write_text(textwrap.dedent(SWEEP))
    return path


def _csv(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


@pytest.mark.skipif(not hasattr(os, "sched_getaffinity"), reason="Linux only")
def test_batch_counts_events_and_a_halted_run_is_a_result(tmp_path: Path) -> None:
    out = tmp_path / "out"
    result = CliRunner().invoke(cli, ["batch", str(_sweep(tmp_path)), "-o", str(out), "--workers", "1",
                                      "--no-progress"])
    assert result.exit_code == 0, result.output  # halted is a result, like diverged: not a failure
    assert "4 runs: 3 complete, 1 halted;" in result.output
    rows = _csv(out / "summary.csv")
    assert [r["status"] for r in rows] == ["complete", "halted", "complete", "complete"]
    assert [[r[c] for c in COUNTS] for r in rows] == [["0", "1", "0", "0"], ["0", "1", "0", "0"],
                                                       ["0", "0", "0", "0"], ["1", "1", "0", "0"]]
    assert rows[1]["error"].startswith("halted at t = 1.8") and rows[0]["error"] == ""
    with h5py.File(out / "summary.h5") as f:
        assert f["collisions"][()].tolist() == [1.0, 1.0, 0.0, 1.0]
        assert list(f["status"].asstr()[()]) == ["complete", "halted", "complete", "complete"]
    table = result.output.splitlines()
    header = next(line for line in table if line.startswith("case"))
    assert "events logged" in header
    assert any(" halted " in line and "1 col" in line for line in table)
    assert any(" complete " in line and "1 enc, 1 col" in line for line in table)
