"""A first run compiles each orbitsim kernel once (issue 28, item 6).

Numba compiles a jitted function once per distinct tuple of argument types. Types that differ for no
reason (a module constant passed as a literal beside the same value at run time, None beside a
context without forces) make a cold run compile the same kernel twice: Wisdom-Holman's correctors
compiled the interaction kick and its pair loop a second time (0.8 s of a 20 s first run), TRACE's two
Bulirsch-Stoer loops compiled ``bs_step`` and its midpoint step twice (11 s). This runs a small
Wisdom-Holman scenario with a corrector from an empty cache, in its own process (the cache
directory is fixed at import), and fails on any orbitsim function compiled with more than one
signature. Slow (about 20 s of CPU, all compilation), so it runs in ``make test-slow``.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

WH_CORRECTED = """\
name: wh_corrected
integrator: {name: wisdom_holman, coordinates: jacobi, corrector: 11}
dt: 0.01
steps: 4
output: {every: 2}
bodies:
  - {name: star, m: 1.0, x: [0, 0, 0], v: [0, 0, 0]}
  - {name: inner, m: 1.0e-3, primary: star, a: 1.0, e: 0.1, M: 0}
  - {name: outer, m: 1.0e-3, primary: star, a: 2.0, e: 0.05, M: 1}
"""

#: Runs the CLI in this process with a listener on Numba's compile events; prints, as JSON, each
#: orbitsim function compiled and the argument types of each compilation.
PROBE = """\
import json, sys
from numba.core import event
seen = {}
class Listener(event.Listener):
    def on_start(self, ev):
        d = ev.data["dispatcher"]
        if d.py_func.__module__.startswith("orbitsim"):
            name = d.py_func.__module__ + "." + d.py_func.__qualname__
            seen.setdefault(name, []).append(str(ev.data["args"]))
    def on_end(self, ev):
        pass
event.register("numba:compile", Listener())
from click.testing import CliRunner
from orbitsim.cli.main import cli
result = CliRunner().invoke(cli, sys.argv[1:], catch_exceptions=False)
print(json.dumps({"exit": result.exit_code, "output": result.output, "compiled": seen}))
"""


def cold_compiles(cwd: Path, *args: str) -> dict[str, list[str]]:
    """Run ``orbitsim ARGS`` in ``cwd`` from an empty cache, in its own process (the cache directory
    is fixed at import); the orbitsim functions it compiled, each with its compilations' argument types."""
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", "NUMBA_DISABLE_JIT")}
    env["ORBITSIM_CACHE_DIR"] = str(cwd / "cache")  # empty: every kernel is compiled here
    ran = subprocess.run([sys.executable, "-c", PROBE, *args], cwd=cwd, capture_output=True, text=True, timeout=600,
                         env=env)
    assert ran.returncode == 0, ran.stderr
    report = json.loads(ran.stdout.splitlines()[-1])
    assert report["exit"] == 0, report["output"]
    return report["compiled"]


@pytest.mark.slow
def test_a_cold_wisdom_holman_run_with_a_corrector_compiles_each_kernel_once(tmp_path: Path) -> None:
    (tmp_path / "wh.yaml").write_text(WH_CORRECTED, encoding="utf-8")
    compiled = cold_compiles(tmp_path, "run", "wh.yaml", "-q", "-o", "out.h5")
    # The run did compile (an empty cache), the corrector among it.
    assert "orbitsim.integrators.wisdom_holman.correctors.apply_corrector" in compiled, sorted(compiled)
    twice = {name: sigs for name, sigs in compiled.items() if len(sigs) > 1}
    assert not twice, json.dumps(twice, indent=1)


@pytest.mark.slow
def test_a_cold_wisdom_holman_run_without_a_corrector_compiles_none(tmp_path: Path) -> None:
    """Without a corrector the stage tables are None, and the run compiles no corrector stage (5-8 s
    of a first run when they were empty arrays behind a run-time branch)."""
    (tmp_path / "wh.yaml").write_text(WH_CORRECTED.replace("corrector: 11", "corrector: 0"), encoding="utf-8")
    compiled = cold_compiles(tmp_path, "run", "wh.yaml", "-q", "-o", "out.h5")
    assert "orbitsim.integrators.wisdom_holman._run_plain" in compiled, sorted(compiled)
    # apply_corrector alone, for None stage tables: Numba removed its stage loop before typing (None has no
    # shape, so the compilation would have failed had it typed the loop)
    apply = "orbitsim.integrators.wisdom_holman.correctors.apply_corrector"
    correctors = {name: sigs for name, sigs in compiled.items() if ".correctors." in name}
    assert list(correctors) == [apply], correctors
    assert all(sig.endswith("none, none)") for sig in correctors[apply]), correctors
    # and no loop with the velocity operator: the run has no velocity-dependent force
    assert not {name for name in compiled if name.endswith("_split")}, sorted(compiled)
    # nor any democratic heliocentric transform: a Jacobi run's work has heliocentric None, which prunes them
    assert not {name for name in compiled if "democratic_heliocentric" in name}, sorted(compiled)


#: Bundled scenarios, the force kernel a 10-step run of each must compile, and the kernels it must not:
#: the disc (201 bodies: one block of rows, serial) and the Plummer sphere (1,000 bodies: blocks in
#: parallel). Neither compiles the step check, which numpy and the interpreter do below 1,025 bodies.
_GRAVITY, _DIAGNOSTICS = "orbitsim.physics.gravity.", "orbitsim.physics.diagnostics."
FORCE_PATHS = {
    "kepler_disc": (_GRAVITY + "accelerations_rows",
                    {_GRAVITY + "all_pairs_accelerations", _GRAVITY + "accelerations_serial",
                     _GRAVITY + "accelerations_blocks", _GRAVITY + "_combine_blocks",
                     _DIAGNOSTICS + "_potential_parallel", _DIAGNOSTICS + "_potential_small"}),
    "plummer_1k": (_GRAVITY + "accelerations_blocks",
                   {_GRAVITY + "all_pairs_accelerations", _GRAVITY + "accelerations_serial",
                    _GRAVITY + "accelerations_rows", _DIAGNOSTICS + "_potential_serial",
                    _DIAGNOSTICS + "_potential_small"}),
}


@pytest.mark.slow
@pytest.mark.parametrize("scenario", sorted(FORCE_PATHS))
def test_a_cold_run_of_many_bodies_compiles_its_own_force_path_and_no_step_check(scenario: str,
                                                                                 tmp_path: Path) -> None:
    """A 10-step run from an empty cache looks at its states without compiling the step check (a
    second of a 6 s first run), and compiles the force kernel and potential of its N's context alone,
    not the other contexts' beside them (one to two seconds more); and still each kernel once."""
    compiled = cold_compiles(tmp_path, "run", scenario, "--steps", "10", "-q", "-o", "out.h5")
    used, unused = FORCE_PATHS[scenario]
    assert used in compiled, sorted(compiled)
    unused = unused | {"orbitsim.events.timescales.orbit_timescales"}
    assert not unused & set(compiled), sorted(unused & set(compiled))
    # distinct signatures: an inline="always" overload is typed again, with the same types, at each call site
    twice = {name: sigs for name, sigs in compiled.items() if len(set(sigs)) > 1}
    assert not twice, json.dumps(twice, indent=1)
