"""What the user sees when a command is given bad input: one line `orbitsim: error: ...` on stderr,
exit code 2, no traceback, and nothing written (issue 14, items 6 and 9).

Every case goes through the real CLI (click's CliRunner, in-process, so that numba and h5py are
imported once for the module).
"""

from __future__ import annotations

import dataclasses
import os
import shutil
import subprocess
import sys
from pathlib import Path

import h5py
import pytest
from click.testing import CliRunner
from test_cli import TINY

from orbitsim.cli.main import cli


def invoke(*args: str) -> tuple[int, str, str]:
    """Exit code, stdout and stderr of one command."""
    result = CliRunner().invoke(cli, list(args))
    assert "Traceback" not in result.output
    return result.exit_code, result.stdout, result.stderr


def one_error_line(args: list[str], *fragments: str) -> str:
    """Run a command that must fail with exit code 2 and one error line holding every fragment."""
    code, _, err = invoke(*args)
    assert code == 2, err
    assert err.count("\n") == 1 and err.startswith("orbitsim: error: "), err
    for fragment in fragments:
        assert fragment in err, (fragment, err)
    return err


@pytest.fixture(scope="module")
def made(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """The tiny scenario and the complete trace of its run (positions recorded)."""
    root = tmp_path_factory.mktemp("made")
    scenario = root / "tiny.yaml"
    scenario.write_text(TINY, encoding="utf-8")
    trace = root / "tiny.h5"
    assert invoke("run", str(scenario), "-o", str(trace), "-q")[0] == 0
    return scenario, trace


@pytest.fixture
def trace(made: tuple[Path, Path], tmp_path: Path) -> Path:
    """A private copy of the complete trace."""
    return Path(shutil.copy(made[1], tmp_path / "run.h5"))


def files_in(folder: Path) -> set[str]:
    return {p.name for p in folder.iterdir()}


# --threads above what the machine can run -------------------------------------------------------


@pytest.mark.parametrize("command", [
    ["run", "two_body_circular", "-o", "{tmp}/t.h5", "--steps", "10"],
    ["run", "--from", "{tmp}/missing.h5", "--steps", "10"],
    ["resume", "{tmp}/missing.h5"],
    ["compare", "two_body_circular", "-o", "{tmp}/cmp", "--steps", "10"],
    ["bench", "--quick", "-o", "{tmp}/bench"],
])
def test_threads_above_the_limit_is_one_line(command: list[str], tmp_path: Path) -> None:
    args = [a.replace("{tmp}", str(tmp_path)) for a in command]
    # A subprocess: numba reads NUMBA_NUM_THREADS once, and changing it under an imported numba
    # would break the runs of the tests that follow.
    proc = subprocess.run([sys.executable, "-m", "orbitsim", *args, "--threads", "2"], capture_output=True,
                          text=True, timeout=120, env={**os.environ, "NUMBA_NUM_THREADS": "1", "ORBITSIM_DEBUG": ""})
    assert proc.returncode == 2 and proc.stderr == ("orbitsim: error: --threads 2: at most 1 thread can run here "
                                                    "(NUMBA_NUM_THREADS=1); give --threads 1 to 1\n")
    # No machine has this many cores; the limit named is this process's own.
    one_error_line([*args, "--threads", "100000"], "--threads 100000", "CPU cores", "give --threads 1 to")
    one_error_line([*args, "--threads", "0"], "--threads 0", "give a count from 1 to")
    assert files_in(tmp_path) == set()  # refused while parsing: no trace, no compare or bench folder


# plot -o in a format matplotlib cannot write --------------------------------------------------


@pytest.mark.parametrize("name", ["x.mp4", "x"])
def test_plot_refuses_an_unwritable_format_before_reading(name: str, tmp_path: Path) -> None:
    # The trace does not exist: the format is checked first, before any work.
    err = one_error_line(["plot", str(tmp_path / "none.h5"), "-o", str(tmp_path / name)], ".png", ".pdf", ".svg")
    assert "no such trace" not in err
    assert files_in(tmp_path) == set()


# -o given an existing directory -------------------------------------------------------------


def test_output_directory_is_one_line_for_every_command(made: tuple[Path, Path], tmp_path: Path) -> None:
    scenario, trace = made
    out = tmp_path / "out"
    out.mkdir()
    one_error_line(["run", str(scenario), "-o", f"{out}/"],
                   f"{out}/: is a directory; give a file name such as {out}/tiny.h5")
    one_error_line(["run", str(scenario), "-o", str(out)], f"{out}: is a directory", f"{out}/tiny.h5")
    one_error_line(["run", "--from", str(trace), "--steps", "10", "-o", str(out)],
                   f"{out}: is a directory; give a file name such as {out}/tiny.h5")
    one_error_line(["plot", str(trace), "-o", str(out)], f"{out}: is a directory; give a file name such as "
                                                         f"{out}/tiny.png")
    assert files_in(out) == set()


# traces with a dataset missing, or shorter than the others ----------------------------------


def damage(path: Path, dataset: str, shorten: bool) -> None:
    with h5py.File(path, "a") as f:
        data = f[dataset][()]
        del f[dataset]
        if shorten:
            f[dataset] = data[:-3]


@pytest.mark.parametrize(("dataset", "shorten", "says"), [
    ("time", False, "dataset 'time' is missing"),
    ("energy_error", False, "dataset 'energy_error' is missing"),
    ("bodies/names", False, "dataset 'bodies/names' is missing"),
    ("bodies/masses", False, "dataset 'bodies/masses' is missing"),
    ("velocities", False, "dataset 'velocities' is missing"),
    ("energy_error", True, "dataset 'energy_error' has 18 samples, 'time' has 21"),
    ("positions", True, "dataset 'positions' has 18 samples, 'time' has 21"),
])
def test_damaged_trace_is_one_line_everywhere(trace: Path, tmp_path: Path, dataset: str, shorten: bool,
                                              says: str) -> None:
    damage(trace, dataset, shorten)
    before = trace.read_bytes()
    for args in (["info", str(trace)], ["info", str(trace), "--scenario"],
                 ["plot", str(trace), "-o", str(tmp_path / "fig.png")],
                 ["resume", str(trace)],
                 ["run", "--from", str(trace), "--steps", "10", "-o", str(tmp_path / "longer.h5")]):
        one_error_line(args, f"{trace}: damaged trace: {says}")
    assert trace.read_bytes() == before
    assert not (tmp_path / "fig.png").exists() and not (tmp_path / "longer.h5").exists()


# -o with a name that is not HDF5 ---------------------------------------------------------------


def test_trace_outputs_must_be_named_as_hdf5(made: tuple[Path, Path], tmp_path: Path) -> None:
    scenario, trace = made
    for name in ("out.csv", "out"):
        one_error_line(["run", str(scenario), "-o", str(tmp_path / name)], "writes HDF5 traces",
                       f"give a .h5 path such as {tmp_path / 'out.h5'}")
    one_error_line(["run", "--from", str(trace), "--steps", "10", "-o", str(tmp_path / "more.csv")],
                   "writes HDF5 traces", f"{tmp_path / 'more.h5'}")
    assert files_in(tmp_path) == set()
    # An old trace named out.csv (an orbitsim that allowed it) is not rewritten under that name.
    old = Path(shutil.copy(trace, tmp_path / "old.csv"))
    one_error_line(["run", "--from", str(old), "--steps", "10"], "writes HDF5 traces",
                   f"give -o {tmp_path / 'old.h5'}")
    one_error_line(["resume", str(old)], "writes HDF5 traces", "rename old.csv to old.h5",
                   f"orbitsim resume {tmp_path / 'old.h5'}")
    assert files_in(tmp_path) == {"old.csv"} and old.read_bytes() == trace.read_bytes()


def test_other_hdf5_suffixes_are_accepted(made: tuple[Path, Path], tmp_path: Path) -> None:
    code, _, err = invoke("run", str(made[0]), "-o", str(tmp_path / "t.HDF5"), "-q")
    assert code == 0 and err == "" and (tmp_path / "t.HDF5").is_file()


# resume of a complete run still checks SCENARIO and --integrator ------------------------------


def test_resume_of_a_complete_run_checks_what_it_is_given(made: tuple[Path, Path], trace: Path) -> None:
    scenario = made[0]
    before = trace.read_bytes()
    one_error_line(["resume", str(trace), "two_body_circular"], "SCENARIO is not the scenario of this run",
                   "name: tiny vs two_body_circular")
    one_error_line(["resume", str(trace), "--integrator", "rk4"], "made with integrator verlet")
    assert trace.read_bytes() == before
    code, out, err = invoke("resume", str(trace), str(scenario), "--integrator", "verlet")
    assert code == 0 and err == "" and "already complete" in out


def test_resume_checks_before_removing_a_stale_checkpoint(made: tuple[Path, Path], trace: Path) -> None:
    from orbitsim.checkpoint.plan import read_trace_state
    from orbitsim.io.checkpoint import checkpoint_path, write_checkpoint

    # A checkpoint of the complete run left beside it (a kill after the trace was renamed into place).
    stale = checkpoint_path(trace)
    write_checkpoint(stale, read_trace_state(trace).checkpoint)
    one_error_line(["resume", str(trace), "two_body_circular"], "SCENARIO is not the scenario of this run")
    assert stale.exists()  # refused before anything was touched
    code, out, _ = invoke("resume", str(trace), str(made[0]))
    assert code == 0 and "already complete" in out and not stale.exists()


# the steps/s of a slow run ---------------------------------------------------------------------


@pytest.mark.parametrize(("wall", "rate"), [(800.0, "(0.25 steps/s)"), (4000.0, "(20 s/step)"),
                                            (2.0, "(100 steps/s)"), (0.5, "(400 steps/s)")])
def test_summary_gives_a_meaningful_rate_at_any_speed(made: tuple[Path, Path], tmp_path: Path,
                                                      monkeypatch: pytest.MonkeyPatch, wall: float,
                                                      rate: str) -> None:
    import orbitsim.runner

    real = orbitsim.runner.run_scenario

    def slow(*args: object, **kwargs: object) -> orbitsim.runner.RunSummary:
        # The same run, reported as if it had taken `wall` seconds (never a measured speed).
        return dataclasses.replace(real(*args, **kwargs), wall_time_s=wall)

    monkeypatch.setattr(orbitsim.runner, "run_scenario", slow)
    code, out, _ = invoke("run", str(made[0]), "-o", str(tmp_path / "slow.h5"))
    assert code == 0 and f"200 of 200 steps in {wall:.3g} s {rate}," in out
