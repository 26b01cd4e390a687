"""The bundled files (orbitsim/data): found as package data, named by stem, a file path winning over
a name, and every one of them shipped by pyproject.toml's package-data."""

from __future__ import annotations

import fnmatch
import tomllib
from pathlib import Path

import pytest
from click.testing import CliRunner

from orbitsim.bench.matrix import load_matrix
from orbitsim.cli.main import cli
from orbitsim.data import KINDS, MATRICES, SCENARIOS, SWEEPS, bundled_dir, bundled_files, data_dir, locate
from orbitsim.scenario import bundled_scenarios, load_scenario

PACKAGE_DATA = Path(__file__).resolve().parents[2] / "orbitsim" / "data"


def test_the_bundled_files_are_the_package_s_own() -> None:
    assert data_dir() == PACKAGE_DATA
    assert set(bundled_files(MATRICES)) == {"full", "quick"}
    assert set(bundled_files(SWEEPS)) == {"eccentricity_cases", "integrators_dt", "plummer_seeds"}
    assert {"two_body_eccentric", "lesson", "plummer_16k"} <= set(bundled_scenarios())
    assert bundled_scenarios() == bundled_files(SCENARIOS)
    # one folder per kind: no sweep or matrix among the scenarios, nothing left beside the folders
    assert not set(bundled_scenarios()) & (set(bundled_files(SWEEPS)) | set(bundled_files(MATRICES)))
    assert not list(PACKAGE_DATA.glob("*.yaml"))


def test_every_bundled_file_is_package_data() -> None:
    """pyproject.toml's patterns cover every file under orbitsim/data (the slow wheel test in
    test_packaging.py checks the built wheel itself)."""
    config = tomllib.loads((PACKAGE_DATA.parents[1] / "pyproject.toml").read_text(encoding="utf-8"))
    patterns = config["tool"]["setuptools"]["package-data"]["orbitsim.data"]
    files = [p.relative_to(PACKAGE_DATA).as_posix() for p in PACKAGE_DATA.rglob("*")
             if p.is_file() and p.suffix not in (".py", ".pyc")]
    assert files and all(kind in {f.split("/")[0] for f in files} for kind in KINDS)
    assert [f for f in files if not any(fnmatch.fnmatch(f, pattern) for pattern in patterns)] == []


def test_names_load_the_bundled_files() -> None:
    assert load_matrix("quick").name == "quick" and load_matrix("full").name == "full"
    assert load_scenario("two_body_eccentric").name == "two_body_eccentric"
    assert locate(SWEEPS, "integrators_dt") == bundled_dir(SWEEPS) / "integrators_dt.yaml"


def test_a_file_wins_over_a_bundled_name(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    Path("integrators_dt").write_text("name: mine\n", encoding="utf-8")
    assert locate(SWEEPS, "integrators_dt") == Path("integrators_dt")
    # a path that does not exist comes back as given, for the reader to report in its own words
    assert locate(SWEEPS, "sweeps/integrators_dt.yaml") == Path("sweeps/integrators_dt.yaml")


def test_an_unknown_name_names_the_close_one() -> None:
    with pytest.raises(LookupError, match=r"^no such file or bundled sweep; did you mean 'integrators_dt'\?$"):
        locate(SWEEPS, "integrator_dt")
    with pytest.raises(LookupError, match=r"^no such file or bundled benchmark matrix; bundled: full, quick$"):
        locate(MATRICES, "zzz")
    with pytest.raises(ValueError, match="unknown kind"):
        bundled_dir("configs")


def test_orbitsim_config_dir_replaces_the_folder(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    (tmp_path / "scenarios").mkdir()
    (tmp_path / "scenarios" / "mine.yaml").write_text("bodies: []\n", encoding="utf-8")
    monkeypatch.setenv("ORBITSIM_CONFIG_DIR", str(tmp_path))
    assert list(bundled_scenarios()) == ["mine"]
    assert bundled_files(SWEEPS) == {}  # no sweeps/ there


@pytest.mark.parametrize(("args", "expected"), [
    (["batch", "integrator_dt", "-o", "unused"], "no such file or bundled sweep; did you mean 'integrators_dt'?"),
    (["bench", "quik", "-o", "unused"], "no such file or bundled benchmark matrix; did you mean 'quick'?"),
])
def test_the_commands_take_bundled_names(args: list[str], expected: str, tmp_path: Path,
                                         monkeypatch: pytest.MonkeyPatch) -> None:
    """A misspelt bundled name is one line, exit 2, naming the close name; nothing is written."""
    monkeypatch.chdir(tmp_path)
    result = CliRunner().invoke(cli, args)
    assert result.exit_code == 2 and result.output.strip().splitlines() == [f"orbitsim: error: {args[1]}: {expected}"]
    assert list(tmp_path.iterdir()) == []


def test_list_names_every_bundled_file_and_where_it_is() -> None:
    for what, kind in (("sweeps", SWEEPS), ("matrices", MATRICES)):
        result = CliRunner().invoke(cli, ["list", what])
        assert result.exit_code == 0, result.output
        for name, path in bundled_files(kind).items():
            assert any(line.split()[0] == name and line.endswith(str(path)) for line in result.output.splitlines())
    result = CliRunner().invoke(cli, ["list"])
    assert all(word in result.output for word in ("leapfrog4", "figure_eight", "plummer_seeds", "quick"))
