"""``orbitsim batch`` over runs with ``output.chaos``: MEGNO and the mLCE at the last sample in
summary.csv, summary.h5 and the terminal table, and nothing of them for a sweep without it.

The sweep goes through the real CLI on a one-worker local cluster; its runs use leapfrog, so one
scheme's variational loop is compiled.
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

from orbitsim.batch.summary import column_names, format_table
from orbitsim.batch.task import failed_result
from orbitsim.cli.main import cli

SCENARIO = """\
name: pair
integrator: leapfrog
dt: 0.01
steps: 300
output: {every: 100, chaos: {seed: 3}}
bodies:
  - {name: star, m: 1.0, x: [0, 0, 0], v: [0, 0, 0]}
  - {name: inner, m: 1.0e-3, x: [1.0, 0, 0.01], v: [0, 1.0, 0.02]}
  - {name: outer, m: 3.0e-4, x: [0, -2.1, 0], v: [0.7, 0, -0.01]}
"""

#: Two runs with the indicators (two seeds of the tangent vector), one without (output.chaos: null).
SWEEP = """\
base: pair.yaml
cases:
  - {output.chaos.seed: 3}
  - {output.chaos.seed: 4}
  - {output.chaos: null}
"""


def _csv(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def test_the_columns_follow_the_energy_errors_and_a_failed_run_has_none() -> None:
    names = column_names(())
    assert names[names.index("final_energy_error") + 1:][:2] == ["megno", "mlce"]
    assert math.isnan(failed_result("boom")["megno"]) and math.isnan(failed_result("boom")["mlce"])


@pytest.mark.skipif(not hasattr(os, "sched_getaffinity"), reason="Linux only")
def test_batch_summary_holds_each_runs_last_megno_and_mlce(tmp_path: Path) -> None:
    (tmp_path / "pair.yaml").write_text(SCENARIO)
    (tmp_path / "sweep.yaml").write_text(textwrap.dedent(SWEEP))
    out = tmp_path / "out"
    result = CliRunner().invoke(cli, ["batch", str(tmp_path / "sweep.yaml"), "-o", str(out), "--workers", "1",
                                      "--no-progress"])
    assert result.exit_code == 0, result.output
    rows = _csv(out / "summary.csv")
    assert [r["status"] for r in rows] == ["complete"] * 3
    for row in rows[:2]:  # the summary holds the trace's own last values, to the bit (shortest round trip)
        with h5py.File(out / row["trace"]) as f:
            assert float(row["megno"]) == f["megno"][-1] and float(row["mlce"]) == f["mlce"][-1]
    assert rows[0]["megno"] != rows[1]["megno"]  # two tangent vectors, two runs' own numbers
    assert rows[2]["megno"] == rows[2]["mlce"] == ""  # no output.chaos: nothing, not a zero
    with h5py.File(out / "summary.h5") as f:
        assert np.isnan(f["megno"][2]) and f["megno"][0] == float(rows[0]["megno"])
    header = next(line for line in result.output.splitlines() if line.startswith("case"))
    assert "MEGNO" in header and "mLCE" in header
    plain = [{**r, "params": {}, "case": int(r["case"]), "megno": math.nan, "mlce": math.nan,
              "max_abs_energy_error": 1e-9, "final_energy_error": 1e-9, "wall_time_s": 1.0, "steps_per_second": 1.0}
             for r in rows]
    assert "MEGNO" not in format_table(plain, ()).splitlines()[0]  # a sweep without chaos keeps its table
