"""Non-finite energies are never printed or stored as healthy numbers (issue 14, item 3).

A non-finite initial state (finite inputs whose products overflow float64) is refused by
``validate`` and ``run`` alike before anything is written; an energy that becomes non-finite
during a run ends it as ``diverged`` with a max |dE/E| that is not a finite number. No numpy
RuntimeWarning reaches stderr on either path: these tests run the real CLI in a fresh process,
where a warning would be shown (pytest's own process may have shown it once already).
"""

from __future__ import annotations

import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from orbitsim.cli.main import cli
from orbitsim.io.trace import read_trace
from orbitsim.runner import run_scenario
from orbitsim.scenario import load_scenario

HEAD = "integrator: verlet\ndt: 0.01\nsteps: 100\n"
# The reproduction: G m m / r = 1e600 overflows, so E0 would be -inf.
HUGE_PAIR = HEAD + ("bodies:\n  - {name: a, m: 1e300, x: [0, 0, 0], v: [0, 0, 0]}\n"
                    "  - {name: b, m: 1e300, x: [1, 0, 0], v: [0, 1, 0]}\n")
# A finite E0 = -1e300; after one step the light body moves at ~1e297, and its m v^2 / 2 (1e594)
# overflows while its position and velocity stay finite: E = +inf at step 1.
THROWN = ("name: thrown\nintegrator: verlet\ndt: 0.001\nsteps: 20\noutput: {every: 1}\nbodies:\n"
          "  - {name: heavy, m: 1e300, x: [0, 0, 0], v: [0, 0, 0]}\n"
          "  - {name: light, m: LIGHT, x: [1, 0, 0], v: [0, 0, 0]}\n")


def orbitsim(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    """The real command in a fresh interpreter (so a RuntimeWarning would not be hidden as a repeat)."""
    env = {**os.environ, "PYTHONWARNINGS": "default"}
    return subprocess.run([sys.executable, "-m", "orbitsim", *args], cwd=cwd, capture_output=True, text=True,
                          timeout=300, env=env)


def write(tmp_path: Path, text: str, name: str = "s.yaml") -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def test_huge_masses_are_refused_by_validate_and_run_before_anything_is_written(tmp_path: Path) -> None:
    write(tmp_path, HUGE_PAIR)
    for args in (["validate", "s.yaml"], ["run", "s.yaml", "-o", "out.h5"]):
        proc = orbitsim(*args, cwd=tmp_path)
        assert proc.returncode == 2, proc.stderr
        lines = proc.stderr.splitlines()
        assert len(lines) == 1, proc.stderr
        assert lines[0].startswith("orbitsim: error: s.yaml: bodies[1].m: ")
        assert "not be finite" in lines[0] and "'a' and 'b'" in lines[0]
        assert "Warning" not in proc.stderr + proc.stdout
        assert proc.stdout == ""
        assert sorted(p.name for p in tmp_path.iterdir()) == ["s.yaml"]


@pytest.mark.parametrize(("light", "printed"), [("1", "inf"), ("0", "nan")], ids=["inf", "nan"])
def test_energy_that_overflows_mid_run_ends_it_as_diverged(tmp_path: Path, light: str, printed: str) -> None:
    # light = 0: a test particle's 0 * |v|^2 = 0 * inf is nan, the case max(0.0, nan) = 0.0 hid.
    write(tmp_path, THROWN.replace("LIGHT", light))
    proc = orbitsim("run", "s.yaml", "-o", "out.h5", cwd=tmp_path)
    assert proc.returncode == 3, proc.stderr
    assert "Warning" not in proc.stderr + proc.stdout
    assert f"max |dE/E| = {printed}," in proc.stdout and "max |dE/E| = 0," not in proc.stdout
    lines = proc.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("orbitsim: error: run diverged: the energy became non-finite")
    assert "at t = 0.001 (step 1)" in lines[0]
    trace = read_trace(tmp_path / "out.h5")
    assert trace.attrs["status"] == "diverged" and trace.attrs["steps_done"] == 1
    assert trace.n_samples == 1  # step 0 only: the non-finite sample is not stored
    assert np.all(np.isfinite(trace.energy)) and np.all(np.isfinite(trace.energy_error))


def test_run_summary_never_reports_a_finite_error_after_a_non_finite_energy(tmp_path: Path) -> None:
    summary = run_scenario(load_scenario(write(tmp_path, THROWN.replace("LIGHT", "0"))), tmp_path / "o.h5",
                           handle_signals=False)
    assert summary.status == "diverged" and summary.exit_code == 3
    assert not math.isfinite(summary.max_abs_energy_error)
    assert "energy became non-finite" in summary.message


# (id, bodies or generator text, key the error names, fragment of the reason)
OVERFLOWS = [
    ("kinetic", "bodies:\n  - {name: a, m: 1e300, x: [0, 0, 0], v: [1e10, 0, 0]}\n", "bodies[0].m",
     "kinetic energy"),
    ("test_particle_speed", "bodies:\n  - {name: a, m: 1, x: [0, 0, 0], v: [0, 0, 0]}\n"
     "  - {name: b, m: 0, x: [1, 0, 0], v: [1e200, 0, 0]}\n", "bodies[1].v", "kinetic energy"),
    # m |v| overflows (1.87e308) while m |v|^2 / 2 (1.03e308) does not
    ("momentum", "bodies:\n  - {name: a, m: 1.7e308, x: [0, 0, 0], v: [1.1, 0, 0]}\n", "bodies[0].m",
     "momentum"),
    ("angular_momentum", "bodies:\n  - {name: a, m: 1, x: [1e200, 0, 0], v: [0, 1e150, 0]}\n", "bodies[0].x",
     "angular momentum"),
    ("close_pair", "bodies:\n  - {name: a, m: 1e200, x: [0, 0, 0], v: [0, 0, 0]}\n"
     "  - {name: b, m: 1e200, x: [1e-200, 0, 0], v: [0, 0, 0]}\n", "bodies[1].m", "'a' and 'b'"),
    ("generator", "generator: {kind: plummer, n: 50, seed: 1, total_mass: 1e300}\n", "generator",
     "of body 'plummer"),
    # States built from finite inputs that overflow on the way: elements, generators, the barycentre
    ("elements_gm", "bodies:\n  - {name: s, m: 1e308, x: [0, 0, 0], v: [0, 0, 0]}\n"
     "  - {name: p, m: 1e308, primary: s, a: 1, M: 1}\n", "bodies[1].m", "G (m_primary + m)"),
    ("elements_state", "bodies:\n  - {name: s, m: 1e300, x: [0, 0, 0], v: [0, 0, 0]}\n"
     "  - {name: p, m: 1, primary: s, a: 1e-300, e: 0.5, M: 1}\n", "bodies[1].a", "position or velocity"),
    ("disc", "generator: {kind: disc, n: 10, seed: 1, central_mass: 1e308, r_min: 1e-300, r_max: 1}\n",
     "generator", "generated"),
    ("barycentre", "frame: barycentric\nbodies:\n  - {name: a, m: 1e300, x: [0, 0, 0], v: [0, 0, 0]}\n"
     "  - {name: b, m: 1e300, x: [1e10, 0, 0], v: [0, 1, 0]}\n", "frame", "centre of mass"),
    # Above 256 bodies the potential comes from the run's own jitted diagnostic.
    ("jitted_potential", "generator: {kind: plummer, n: 300, seed: 1}\n"
     "bodies:\n  - {name: a, m: 1e200, x: [9, 0, 0], v: [0, 0, 0]}\n"
     "  - {name: b, m: 1e200, x: [10, 0, 0], v: [0, 0, 0]}\n", "bodies[1].m", "'a' and 'b'"),
]


@pytest.mark.parametrize(("case", "bodies", "key", "fragment"), OVERFLOWS, ids=[c[0] for c in OVERFLOWS])
def test_overflowing_initial_states_name_the_key(tmp_path: Path, case: str, bodies: str, key: str,
                                                 fragment: str) -> None:
    path = write(tmp_path, HEAD + bodies)
    runner = CliRunner()
    for args in (["validate", str(path)], ["run", str(path), "-o", str(tmp_path / "out.h5"), "-q"]):
        result = runner.invoke(cli, args)
        assert result.exit_code == 2, result.output
        lines = result.stderr.splitlines()
        assert len(lines) == 1 and lines[0].startswith(f"orbitsim: error: {path}: {key}"), result.output
        assert fragment in lines[0] and "overflow" in lines[0] and "float64" in lines[0]
        assert list(tmp_path.iterdir()) == [path]


def test_check_initial_state_accepts_the_bundled_scenarios() -> None:
    from orbitsim.preflight import check_initial_state
    from orbitsim.scenario import bundled_scenarios

    for name in bundled_scenarios():
        check_initial_state(load_scenario(name))  # raises ScenarioError if not


def test_softening_bounds_the_potential_without_computing_it(monkeypatch: pytest.MonkeyPatch) -> None:
    import orbitsim.physics.diagnostics as diagnostics
    from orbitsim.preflight import check_initial_state

    def forbidden(*args: object) -> float:
        raise AssertionError("a softened system needs no O(N^2) potential")

    monkeypatch.setattr(diagnostics, "potential_energy", forbidden)
    check_initial_state(load_scenario("plummer_16k"))
