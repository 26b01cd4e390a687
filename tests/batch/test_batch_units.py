"""Unit tests of the batch pieces that need no scenario and no cluster: key paths, summaries, sizing."""

from __future__ import annotations

import csv
import math
import os
import signal
import time

import h5py
import numpy as np
import pytest

from orbitsim.batch.cluster import plan_local
from orbitsim.batch.overrides import OverrideError, apply_override, path_components, paths_overlap
from orbitsim.batch.signals import interrupt_once
from orbitsim.batch.summary import column_names, format_table, write_csv, write_h5


def test_path_components_accepts_dots_and_brackets():
    assert path_components("bodies.1.e") == ("bodies", "1", "e")
    assert path_components("bodies[1].e") == ("bodies", "1", "e")
    assert path_components("dt") == ("dt",)


def test_paths_overlap_is_common_prefix_only_when_nested():
    assert paths_overlap(("bodies", "1", "e"), ("bodies", "1")) == 2
    assert paths_overlap(("dt",), ("dt",)) == 1
    assert paths_overlap(("bodies", "1", "a"), ("bodies", "1", "e")) == 2  # keys of one body
    assert paths_overlap(("bodies", "0", "m"), ("bodies", "1", "e")) == 0
    assert paths_overlap(("dt",), ("steps",)) == 0


def test_apply_override_sets_nested_values_and_creates_mapping_keys():
    doc = {"dt": 0.1, "bodies": [{"m": 1.0}, {"m": 1e-3, "e": 0.1}], "generator": {"seed": 1}}
    apply_override(doc, "dt", 0.05)
    apply_override(doc, "bodies.1.e", 0.5)
    apply_override(doc, "generator.seed", 7)
    apply_override(doc, "output.every", 10)  # optional section absent from the base
    assert doc == {"dt": 0.05, "bodies": [{"m": 1.0}, {"m": 1e-3, "e": 0.5}], "generator": {"seed": 7},
                   "output": {"every": 10}}


@pytest.mark.parametrize(
    ("path", "needle"),
    [("bodies.5.e", "has 2 entries; no index 5"), ("bodies.x", "not an index"), ("dt.x", "not a mapping"),
     ("", "empty key path")],
)
def test_apply_override_rejects_paths_that_do_not_fit(path, needle):
    doc = {"dt": 0.1, "bodies": [{}, {}]}
    with pytest.raises(OverrideError, match=needle) as info:
        apply_override(doc, path, 1)
    assert info.value.path == path


def _rows():
    base = {"steps_done": 100, "wall_time_s": 0.5, "steps_per_second": 200.0, "worker": "tcp://w:1",
            "resumed": False, "trace": "runs/a.h5", "error": ""}
    return [
        {"case": 0, "run_id": "a" * 16, "params": {"integrator": "verlet", "dt": 0.1}, "status": "complete",
         "max_abs_energy_error": 1.25e-7, "final_energy_error": -3.0e-8, **base},
        {"case": 1, "run_id": "b" * 16, "params": {"integrator": "rk4", "dt": 0.2}, "status": "failed",
         **base, "max_abs_energy_error": math.nan, "final_energy_error": math.nan, "steps_done": 0,
         "error": "ValueError: boom", "trace": ""},
    ]


def test_csv_summary_round_trips_floats_exactly(tmp_path):
    rows = _rows()
    path = write_csv(tmp_path / "summary.csv", rows, ("integrator", "dt"))
    with open(path, newline="") as fh:
        got = list(csv.DictReader(fh))
    assert list(got[0]) == column_names(("integrator", "dt"))
    assert float(got[0]["max_abs_energy_error"]) == rows[0]["max_abs_energy_error"]
    assert got[1]["max_abs_energy_error"] == ""  # a failed run has no energy error
    assert got[1]["error"] == "ValueError: boom"
    assert not (tmp_path / "summary.csv.tmp").exists()


def test_h5_summary_has_typed_columns_and_params(tmp_path):
    path = write_h5(tmp_path / "summary.h5", _rows(), ("integrator", "dt"), {"sweep_name": "s"})
    with h5py.File(path, "r") as f:
        assert f.attrs["sweep_name"] == "s"
        assert f["steps_done"].dtype == np.int64
        assert np.isnan(f["max_abs_energy_error"][1])
        assert list(f["status"].asstr()[()]) == ["complete", "failed"]
        assert f["params/dt"][()].tolist() == [0.1, 0.2]
        assert list(f["params/integrator"].asstr()[()]) == ["verlet", "rk4"]


def test_param_column_that_clashes_with_a_result_column_is_prefixed():
    assert "param:status" in column_names(("status",))


def test_format_table_lists_every_row_and_the_error():
    text = format_table(_rows(), ("integrator", "dt"))
    assert "verlet" in text and "rk4" in text and "ValueError: boom" in text
    assert len(text.splitlines()) == 3


def test_plan_local_keeps_workers_times_threads_within_cores():
    assert plan_local(cores=2) == plan_local(workers=2, cores=2)
    plan = plan_local(cores=8, workers=3)
    assert plan.workers == 3 and plan.workers * plan.threads <= 8
    assert plan_local(cores=8, n_runs=2).workers == 2  # no idle workers for a tiny sweep
    assert plan_local(cores=2, workers=1).threads == 2
    with pytest.raises(ValueError):
        plan_local(workers=0)


def test_the_batch_command_imports_neither_numba_nor_dask():
    import subprocess
    import sys

    code = ("import sys, orbitsim.cli.batch, orbitsim.batch; "
            "print(sorted(m for m in ('numba', 'distributed', 'h5py') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


def test_batch_help_documents_the_options():
    from click.testing import CliRunner

    from orbitsim.cli.main import cli

    result = CliRunner().invoke(cli, ["batch", "--help"])
    assert result.exit_code == 0
    for option in ("--outdir", "--scheduler", "--workers", "--threads", "--resume", "--skip-invalid"):
        assert option in result.output


@pytest.mark.skipif(signal.getsignal(signal.SIGINT) is not signal.default_int_handler,
                    reason="needs Python's own SIGINT handler")
def test_interrupt_once_raises_on_the_first_ctrl_c_and_ignores_the_next_until_the_end():
    interrupts = 0
    with interrupt_once():
        try:
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(30)  # cut short by the KeyboardInterrupt
        except KeyboardInterrupt:
            interrupts += 1
        os.kill(os.getpid(), signal.SIGINT)  # a second Ctrl-C while the sweep shuts down: ignored
        time.sleep(0.05)
    assert interrupts == 1
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


@pytest.mark.skipif(signal.getsignal(signal.SIGINT) is not signal.default_int_handler
                    or signal.getsignal(signal.SIGTERM) is not signal.SIG_DFL, reason="needs the default handlers")
def test_interrupt_once_takes_sigterm_like_ctrl_c_and_says_which_it_was():
    # SIGTERM (timeout, Slurm) used to kill the driver outright: no summary, stale locks (issue 27, item 11).
    from orbitsim.batch.signals import SweepSignal

    caught = []
    with interrupt_once():
        try:
            os.kill(os.getpid(), signal.SIGTERM)
            time.sleep(30)  # cut short by the SweepSignal
        except SweepSignal as exc:
            caught.append(exc.signum)
        for later in (signal.SIGTERM, signal.SIGINT):  # while the sweep shuts down: ignored
            os.kill(os.getpid(), later)
        time.sleep(0.05)
    assert caught == [signal.SIGTERM]
    assert signal.getsignal(signal.SIGTERM) is signal.SIG_DFL
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


class _WriteFailureError(OSError):
    """Shaped like orbitsim.io.schema's: ``str()`` is the whole message, ``strerror`` too."""

    def __init__(self, code: int, message: str, filename: str) -> None:
        super().__init__(code, message, filename)

    def __str__(self) -> str:
        return str(self.strerror)


def test_a_failed_runs_error_is_one_line_with_the_os_reason_first():
    import errno

    from orbitsim.batch.task import run_error

    trace = "/out/runs/abc.h5"
    full = _WriteFailureError(errno.ENOSPC, f"{trace}: No space left on device while writing {trace}.tmp;\n"
                         "the run stopped at step 10 of 20", f"{trace}.tmp")
    assert run_error(full, trace) == (f"No space left on device while writing {trace}.tmp; "
                                      "the run stopped at step 10 of 20")
    assert run_error(OSError(errno.ENOSPC, "No space left on device", f"{trace}.tmp"), trace) == \
        f"No space left on device ({trace}.tmp)"
    assert run_error(_WriteFailureError(errno.EFBIG, "cannot write the trace", ""), trace) == \
        "File too large: cannot write the trace"
    assert run_error(ValueError("bad\nvalue"), trace) == "ValueError: bad value"
    assert run_error(OSError("Unable to write (error message = 'x')"), trace) == \
        "OSError: Unable to write (error message = 'x')"  # no errno: the text as it is


def test_run_case_turns_a_full_disk_into_a_failed_row(monkeypatch, tmp_path):
    import errno

    import orbitsim.runner
    from orbitsim.batch.task import run_case

    def full_disk(scenario, output, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device", f"{output}.tmp")

    monkeypatch.setattr(orbitsim.runner, "run_scenario", full_disk)
    row = run_case(None, str(tmp_path / "a.h5"))
    assert row["status"] == "failed" and row["error"] == f"No space left on device ({tmp_path / 'a.h5'}.tmp)"
    assert row["worker"] and math.isnan(row["max_abs_energy_error"])
