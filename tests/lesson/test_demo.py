"""``orbitsim demo`` (the lesson) and ``make demo`` from a clean clone."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
from pathlib import Path

import pytest
from click.testing import CliRunner

from orbitsim.cli.main import cli

pytest.importorskip("rebound")

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def demo(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    out = tmp_path_factory.mktemp("demo") / "report"
    result = CliRunner().invoke(cli, ["demo", "-o", str(out)], catch_exceptions=False)
    assert result.exit_code == 0, result.output
    return out, result.stdout


def test_demo_writes_report_and_says_where(demo: tuple[Path, str]) -> None:
    out, stdout = demo
    for name in ("report.html", "report.md", "lesson_orbits.png", "lesson_dt.png", "summary.json", "lesson.html"):
        assert (out / name).stat().st_size > 0, name
    assert stdout.strip().splitlines()[-1] == f"report: {(out / 'report.html').resolve()}"


def test_demo_report_tells_the_lesson(demo: tuple[Path, str]) -> None:
    html = (demo[0] / "report.html").read_text()
    # The first figure is the three orbits over their energy traces.
    assert html.index("lesson_orbits.png") < html.index("lesson_dt.png")
    for word in ("explicit Euler", "semi-implicit Euler", "velocity Verlet", "IAS15", "REBOUND", "numba",
                 "CPU", "lesson", "orbitsim demo"):
        assert word in html, word


def test_the_three_schemes_behave_as_the_lesson_says(demo: tuple[Path, str]) -> None:
    schemes = {s["integrator"]: s for s in json.loads((demo[0] / "summary.json").read_text())["schemes"]}
    euler, semi, verlet = schemes["euler"], schemes["semi_implicit_euler"], schemes["verlet"]
    # Explicit Euler's energy climbs and its orbit spirals out.
    assert euler["energy_drift_slope"] > 0 and euler["max_abs_energy_error"] > 0.1
    assert euler["max_separation"] > 1.5 * verlet["max_separation"]
    # Semi-implicit Euler is bounded but coarser than Verlet, which is the flattest.
    assert euler["max_abs_energy_error"] > semi["max_abs_energy_error"] > verlet["max_abs_energy_error"]
    assert abs(semi["energy_drift_slope"]) < 1e-2 * euler["energy_drift_slope"]
    # Raising dt: first order for semi-implicit Euler, second for Verlet.
    assert semi["energy_order"] == pytest.approx(1.0, abs=0.3)
    assert verlet["energy_order"] == pytest.approx(2.0, abs=0.3)


def test_lesson_scenario_is_bundled() -> None:
    from orbitsim.scenario import bundled_scenarios, load_scenario

    assert "lesson" in bundled_scenarios()
    sc = load_scenario("lesson")
    assert sc.n_bodies == 2 and sc.steps == 945


def _has_commit(repo: Path) -> bool:
    return subprocess.run(["git", "-C", str(repo), "rev-parse", "--verify", "HEAD"], capture_output=True,
                          check=False).returncode == 0


@pytest.mark.slow
@pytest.mark.timeout(1800)
def test_make_demo_from_a_clean_clone(tmp_path: Path) -> None:
    """`git clone` + `make demo`: builds a fresh venv (pip needs PyPI), runs the lesson."""
    if shutil.which("git") is None or shutil.which("make") is None:
        pytest.skip("needs git and make")
    if not _has_commit(REPO):
        pytest.skip("the repository has no commit to clone yet")
    clone = tmp_path / "clone"
    subprocess.run(["git", "clone", "--quiet", str(REPO), str(clone)], check=True)
    # Nor the make variables of a suite run by `make test-slow`: with MAKELEVEL set the clone's make
    # is a sub-make, which adds "make[1]: Leaving directory ..." after the demo's own last line.
    env = {k: v for k, v in os.environ.items()
           if not k.startswith(("VIRTUAL_ENV", "PYTHONPATH", "ORBITSIM_", "MAKE", "MFLAGS"))}
    done = subprocess.run(["make", "demo"], cwd=clone, env=env, capture_output=True, text=True, timeout=1800,
                          check=False)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    assert (clone / "demo-report" / "report.html").is_file()
    assert done.stdout.strip().splitlines()[-1].startswith("report: ")
