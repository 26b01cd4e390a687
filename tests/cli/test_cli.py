"""The orbitsim CLI: help texts, run/validate/list/info/plot, exit codes, lazy imports."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner

from orbitsim.cli.main import cli
from orbitsim.io.trace import read_trace

MY_COMMANDS = ("run", "validate", "list", "info", "plot")
TINY = """\
name: tiny
integrator: verlet
dt: 0.01
steps: 200
output: {every: 10}
bodies:
  - {name: star, m: 1.0, x: [0, 0, 0], v: [0, 0, 0]}
  - {name: planet, m: 1.0e-3, primary: star, a: 1.0, e: 0.1, M: 0}
"""
HEAD_ON = """\
name: head_on
integrator: verlet
dt: 0.5
steps: 50
output: {every: 1}
bodies:
  - {name: left, m: 1.0e-20, x: [-1, 0, 0], v: [1, 0, 0]}
  - {name: right, m: 1.0e-20, x: [1, 0, 0], v: [-1, 0, 0]}
"""


def invoke(*args: str) -> tuple[int, str]:
    result = CliRunner().invoke(cli, list(args))
    assert "Traceback" not in result.output
    return result.exit_code, result.output


@pytest.fixture
def tiny(tmp_path: Path) -> Path:
    path = tmp_path / "tiny.yaml"
    path.write_text(TINY, encoding="utf-8")
    return path


@pytest.mark.parametrize("command", MY_COMMANDS)
def test_every_command_and_option_has_help_with_an_example(command: str) -> None:
    import click

    code, out = invoke(command, "--help")
    assert code == 0 and "Usage: " in out and "Example" in out
    ctx = click.Context(cli)
    cmd = cli.get_command(ctx, command)
    assert "Example" in (cmd.help or "")
    for param in cmd.params:
        if isinstance(param, click.Option):
            assert param.help and "Example" in param.help, (command, param.name)


def test_python_dash_m_orbitsim_help() -> None:
    proc = subprocess.run([sys.executable, "-m", "orbitsim", "--help"], capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 0 and "Usage: orbitsim" in proc.stdout
    for command in MY_COMMANDS:
        assert command in proc.stdout


#: Every third-party library orbitsim imports but click: pyproject.toml bans each at the CLI's module level (TID253).
HEAVY_LIBRARIES = ("astropy", "dask", "de421", "distributed", "h5py", "imageio_ffmpeg", "jplephem", "llvmlite",
                   "matplotlib", "numba", "numpy", "PIL", "rebound", "reboundx", "scipy", "yaml")


def test_cli_start_up_imports_only_click() -> None:
    modules = sorted(p.stem for p in (Path(__file__).resolve().parents[2] / "orbitsim" / "cli").glob("*.py"))
    assert {"main", "run", "validate", "plot"} <= set(modules)  # every subcommand module, not just these
    code = ("import sys; import orbitsim.cli.main as m\n"
            f"for name in {modules!r}:\n"
            "    __import__('orbitsim.cli.' + name)\n"
            f"heavy = [x for x in {HEAVY_LIBRARIES!r} if x in sys.modules]\n"
            "assert not heavy, heavy\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr


def test_run_prints_summary_and_writes_trace(tiny: Path, tmp_path: Path) -> None:
    out = tmp_path / "t.h5"
    code, text = invoke("run", str(tiny), "-o", str(out))
    assert code == 0
    assert "tiny: complete, 200 of 200 steps" in text and "steps/s" in text and "max |dE/E| = " in text
    assert str(out) in text
    assert read_trace(out).attrs["status"] == "complete"


def test_run_quiet_prints_nothing(tiny: Path, tmp_path: Path) -> None:
    code, text = invoke("run", str(tiny), "-o", str(tmp_path / "q.h5"), "-q")
    assert code == 0 and text == ""


def test_run_default_output_in_cwd(tiny: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    code, _ = invoke("run", str(tiny), "-q")
    assert code == 0 and (tmp_path / "tiny.h5").is_file()


def test_run_refuses_to_overwrite_without_force(tiny: Path, tmp_path: Path) -> None:
    out = tmp_path / "t.h5"
    assert invoke("run", str(tiny), "-o", str(out), "-q")[0] == 0
    before = out.read_bytes()
    code, text = invoke("run", str(tiny), "-o", str(out), "--steps", "100")
    assert code == 2 and "already exists; use --force" in text and text.count("\n") == 1
    assert out.read_bytes() == before
    code, _ = invoke("run", str(tiny), "-o", str(out), "--steps", "100", "--force", "-q")
    assert code == 0 and read_trace(out).attrs["steps_done"] == 100


def test_run_overrides(tiny: Path, tmp_path: Path) -> None:
    out = tmp_path / "o.h5"
    code, _ = invoke("run", str(tiny), "-o", str(out), "--integrator", "leapfrog4", "--dt", "0.02",
                     "--t-end", "1", "--every", "5", "--no-positions", "-q")
    assert code == 0
    trace = read_trace(out)
    assert (trace.attrs["integrator"], trace.attrs["dt"], trace.attrs["steps_done"]) == ("leapfrog4", 0.02, 50)
    assert trace.n_samples == 11 and trace.positions is None


def test_t_end_not_whole_number_of_steps_is_reported(tiny: Path, tmp_path: Path) -> None:
    code, text = invoke("run", str(tiny), "-o", str(tmp_path / "w.h5"), "--dt", "0.3", "--t-end", "1")
    assert code == 0
    assert ("t_end = 1 is not a whole number of steps of dt = 0.3: the run takes 3 whole steps and ends at "
            "t = 0.9") in text
    assert "3 of 3 steps" in text and "to t = 0.9" in text


@pytest.mark.parametrize(("args", "option"), [
    (["--dt", "-1"], "--dt"), (["--dt", "0"], "--dt"), (["--dt", "nan"], "--dt"), (["--steps", "0"], "--steps"),
    (["--every", "0"], "--every"), (["--t-end", "inf"], "--t-end"), (["--integrator", "nope"], "--integrator"),
    (["--steps", "5", "--t-end", "1"], "--steps"), (["--every", "5", "--interval", "1"], "--every"),
])
def test_bad_options_exit_2_naming_the_option(tiny: Path, tmp_path: Path, args: list[str], option: str) -> None:
    out = tmp_path / "bad.h5"
    code, text = invoke("run", str(tiny), "-o", str(out), *args)
    assert code == 2 and option in text
    assert not out.exists()


def test_divergence_exits_3_naming_bodies(tmp_path: Path) -> None:
    path = tmp_path / "head_on.yaml"
    path.write_text(HEAD_ON, encoding="utf-8")
    out = tmp_path / "d.h5"
    code, text = invoke("run", str(path), "-o", str(out))
    assert code == 3
    assert "orbitsim: error: run diverged" in text and "left, right" in text and "t = 0.5" in text
    assert read_trace(out).attrs["status"] == "diverged"


def test_validate_ok_and_resolved(tiny: Path) -> None:
    code, text = invoke("validate", str(tiny), "figure_eight")
    assert code == 0 and "ok: " in text and "note: t_end = 31.6295699 is not a whole number" in text
    code, text = invoke("validate", str(tiny), "--resolved")
    assert code == 0 and text.startswith("# orbitsim scenario, fully resolved") and "primary" not in text


def test_list(tmp_path: Path) -> None:
    code, text = invoke("list", "integrators")
    assert code == 0 and "symplectic" in text and "leapfrog4" in text and "order" in text
    from orbitsim.integrators.registry import chaos_schemes

    header, *rows = text.splitlines()
    at = header.index("variational")  # the table's columns are aligned: each row's cell starts there
    variational = {row.split()[0]: row[at:].split()[0] for row in rows}
    assert variational["ias15"] == "yes" and variational["rk4"] == "no"
    assert {name for name, says in variational.items() if says == "yes"} == set(chaos_schemes())
    code, text = invoke("list", "scenarios")
    assert code == 0 and "figure_eight" in text and "16384" in text and "INVALID" not in text
    code, text = invoke("list")
    assert code == 0 and "verlet" in text and "plummer_1k" in text
    assert invoke("list", "planets")[0] == 2


def test_list_integrators_settings_prints_each_settings_doc_and_default() -> None:
    from orbitsim.integrators.registry import RECORDS

    code, text = invoke("list", "integrators", "--settings")
    assert code == 0 and "forces/step" not in text  # the settings, in place of the integrator table
    rows = {tuple(line.split()[:3]) for line in text.splitlines()}
    for record in RECORDS:
        for key, setting in record.settings.items():
            default = str(setting.default).lower() if isinstance(setting.default, bool) else str(setting.default)
            assert (record.spec.name, key, default) in rows, (record.spec.name, key)
            assert setting.doc in text, key
    assert ("ias15", "epsilon", "1e-09") in rows and "values: 0, 3, 5, 7, 11, 17" in text
    assert "no settings: euler, semi_implicit_euler, verlet, leapfrog, rk4" in text
    code, text = invoke("list", "scenarios", "--settings")
    assert code == 2 and "orbitsim list integrators --settings" in text


def test_info_and_plot(tiny: Path, tmp_path: Path) -> None:
    out = tmp_path / "t.h5"
    invoke("run", str(tiny), "-o", str(out), "-q")
    code, text = invoke("info", str(out))
    assert code == 0
    for fragment in ("status               complete", "samples:  21", "positions            (21, 2, 3)",
                     "bodies/names", "provenance_numba_version", "max |dE/E|"):
        assert fragment in text, fragment
    code, text = invoke("info", str(out), "--scenario")
    assert code == 0 and text == read_trace(out).attrs["scenario"]
    code, text = invoke("plot", str(out))
    figure = tmp_path / "t.png"
    assert code == 0 and figure.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    code, text = invoke("plot", str(out))
    assert code == 2 and "use --force" in text
    assert invoke("plot", str(out), "-o", str(tmp_path / "t.pdf"))[0] == 0


@pytest.mark.parametrize("content", [None, b"not hdf5 at all"])
def test_info_and_plot_reject_non_traces(tmp_path: Path, content: bytes | None) -> None:
    path = tmp_path / "x.h5"
    if content is not None:
        path.write_bytes(content)
    for command in ("info", "plot"):
        code, text = invoke(command, str(path))
        assert code == 2 and text.startswith(f"orbitsim: error: {path}: ") and text.count("\n") == 1
    assert not (tmp_path / "x.png").exists()


def test_subprocess_bad_scenario_has_no_traceback(tmp_path: Path) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text(TINY.replace("m: 1.0e-3", "m: -1"), encoding="utf-8")
    proc = subprocess.run([sys.executable, "-m", "orbitsim", "run", str(path), "-o", str(tmp_path / "o.h5")],
                          capture_output=True, text=True, timeout=120, env={**os.environ, "ORBITSIM_DEBUG": ""})
    assert proc.returncode == 2
    assert proc.stderr == f"orbitsim: error: {path}: bodies[1].m: mass must be >= 0, got -1 (line 8)\n"
    assert not (tmp_path / "o.h5").exists()


def test_progress_bar_waits_a_second_then_draws(monkeypatch: pytest.MonkeyPatch,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    from orbitsim.cli import run as run_module

    now = [100.0]
    monkeypatch.setattr(run_module.time, "monotonic", lambda: now[0])
    bar = run_module._ProgressBar("demo")
    bar(10, 100)
    assert capsys.readouterr().err == ""  # short runs print nothing
    now[0] += 2.0
    bar(50, 100)
    err = capsys.readouterr().err
    assert "demo [" in err and " 50%" in err and "50/100 steps" in err
    bar.close()
    assert capsys.readouterr().err == "\r\033[K"


def test_no_progress_bar_when_stderr_is_not_a_terminal(tiny: Path, tmp_path: Path) -> None:
    proc = subprocess.run([sys.executable, "-m", "orbitsim", "run", str(tiny), "-o", str(tmp_path / "p.h5"),
                           "--steps", "20000"], capture_output=True, text=True, timeout=300)
    # From an empty cache (a fresh clone, or the worker that reaches this first) the run also says, once,
    # that it compiles: that line is not a progress bar, and nothing else may be on stderr.
    compiling = "orbitsim: compiling kernels for verlet (first run only)\n"
    assert proc.returncode == 0 and proc.stderr in ("", compiling) and "tiny: complete" in proc.stdout
