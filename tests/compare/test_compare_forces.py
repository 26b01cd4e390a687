"""``orbitsim compare`` with a scenario's ``forces:``: REBOUND carries them through REBOUNDx,
arranged as orbitsim applies each (orbitsim.reference.force_pairing), so the matched pairs agree
to round-off as they do without forces; a force one code cannot apply as the other does makes its
pair "not comparable" (exit 5), never DISAGREE.

The scenario (forces_helpers.GR_PLANETS_YAML): a star and two inclined, eccentric planets with
``gr`` at c = 100, strong enough to move the planets by 2.6e-2 of the system's size in 1000 steps:
before REBOUND carried the forces, every pair disagreed by that much.
"""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np
import pytest
import rebound
from click.testing import CliRunner
from forces_helpers import GR_PLANETS_YAML, make_forces, rebound_state

from orbitsim.cli.main import cli
from orbitsim.forces.table import GR, GR_POTENTIAL, HARMONICS, MIGRATION, P_C, P_J2, P_R_EQ, P_SPIN, ForceSet
from orbitsim.reference.bridge import ReboundScheme, parse_rebound_scheme, read_state, rebound_simulation
from orbitsim.reference.force_pairing import attach_rebound_forces, rebound_force_lines, rebound_refusal
from orbitsim.sampling import EveryPlan
from orbitsim.simulation import Simulation

EXIT_DISAGREE, EXIT_NOT_TESTABLE = 1, 5

#: Round-off agreement of a matched pair after 1000 steps: measured 2e-14 .. 7e-14 here (the
#: pairs' nominal tolerance at 1e4 steps is 1e-9; a missing force shows as 2.6e-2).
ROUND_OFF = 1e-12



def invoke(*args: str) -> tuple[int, str, str]:
    result = CliRunner().invoke(cli, list(args), catch_exceptions=False)
    return result.exit_code, result.stdout, result.stderr


def scenario(tmp_path: Path, source: str = "star") -> str:
    path = tmp_path / f"gr_{source}.yaml"
    path.write_text(GR_PLANETS_YAML.replace("SOURCE", source), encoding="utf-8")
    return str(path)


@pytest.fixture(scope="module")
def gr_compare(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, int, str, str]:
    tmp = tmp_path_factory.mktemp("grcmp")
    out = tmp / "out"
    code, stdout, stderr = invoke("compare", scenario(tmp), "-o", str(out),
                                  "--integrators", "leapfrog4,leapfrog,wisdom_holman,ias15")
    return out, code, stdout, stderr


def test_gr_pairs_agree_to_round_off(gr_compare: tuple[Path, int, str, str]) -> None:
    """gr is velocity-dependent: REBOUND applies it as integrate_force operators
    around each leapfrog and WHFast step (WHFast in safe mode) and as a force in IAS15, as orbitsim
    does; every pair then agrees to round-off (before: DISAGREE by 2.6e-2, exit 1)."""
    out, code, stdout, stderr = gr_compare
    assert code == 0, stdout + stderr
    summary = json.loads((out / "summary.json").read_text())
    pairs = {p["name"]: p for p in summary["pairs"]}
    assert len(pairs) == 4  # ias15, leapfrog, leapfrog4, wisdom_holman with their REBOUND partners
    for name, pair in pairs.items():
        assert pair["verdict"] == "agree", name
        assert pair["max_relative_position_difference"] < ROUND_OFF, name


def test_report_lists_the_forces_on_each_side(gr_compare: tuple[Path, int, str, str]) -> None:
    out = gr_compare[0]
    summary = json.loads((out / "summary.json").read_text())
    forces = {run["label"]: run["forces"] for run in summary["runs"]}
    assert forces["orbitsim/leapfrog4"] == ["gr about star (c = 100): its own operator (implicit midpoint) over dt/2 "
                                            "before and after each step"]
    assert "integrate_force operators" in forces["rebound/leapfrog_order4"][0]
    assert forces["rebound/whfast"][0].endswith("WHFast in safe mode")
    assert "IAS15's equations of motion" in forces["reference/ias15"][0]
    text = (out / "report.md").read_text()
    assert "## Forces" in text and "REBOUNDx gr" in text and "gr about star (c = 100)" in text


def test_a_force_rebound_cannot_express_is_not_comparable(tmp_path: Path) -> None:
    """REBOUNDx 5.1's gr is always about particle 0; about body 1 the REBOUND side cannot carry it,
    so every pair is "not comparable" with that reason and compare exits 5 (before: DISAGREE,
    exit 1, with no word about forces)."""
    out = tmp_path / "out"
    code, stdout, stderr = invoke("compare", scenario(tmp_path, "b"), "-o", str(out),
                                  "--integrators", "leapfrog4,leapfrog")
    assert code == EXIT_NOT_TESTABLE, stdout + stderr
    assert "DISAGREE" not in stdout
    line = stderr.strip().splitlines()
    assert len(line) == 1 and "not comparable: REBOUNDx 5.1 gr takes particle 0" in line[0]
    summary = json.loads((out / "summary.json").read_text())
    assert [p["verdict"] for p in summary["pairs"]] == ["not_comparable", "not_comparable"]
    assert summary["reference"]["choice"] == "orbitsim"  # REBOUND's IAS15 cannot carry it either
    assert any("REBOUND's IAS15 was not run" in n for n in summary["notes"])


def test_trace_with_forces_is_not_comparable(tmp_path: Path) -> None:
    """orbitsim's trace applies no forces: its pair with REBOUND TRACE is not comparable (exit 5)."""
    code, stdout, stderr = invoke("compare", scenario(tmp_path), "-o", str(tmp_path / "out"),
                                  "--integrators", "trace", "-q")
    assert code == EXIT_NOT_TESTABLE, stdout + stderr
    assert "orbitsim trace <-> REBOUND trace: not comparable: trace cannot apply gr" in stderr


def three_bodies() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    sim = rebound.Simulation()
    sim.add(m=1.0)
    sim.add(m=1e-3, a=0.5, e=0.2, inc=0.1)
    sim.add(m=3e-4, a=1.3, e=0.05, inc=0.3, Omega=1.0)
    sim.move_to_com()
    return rebound_state(sim)


def _migration() -> ForceSet:
    taus = np.full((3, 3), np.inf)
    taus[0, 1:] = (-1e2, -1e3)
    return make_forces(3, [(MIGRATION, -1, {}, taus)])


FORCE_SETS = {
    "gr": make_forces(3, [(GR, 0, {P_C: 100.0}, None)]),
    "gr_potential": make_forces(3, [(GR_POTENTIAL, 0, {P_C: 100.0}, None)]),
    "migration": _migration(),
    "gr+harmonics": make_forces(3, [(GR, 0, {P_C: 100.0}, None),
                                    (HARMONICS, 0, {P_J2: 1e-2, P_R_EQ: 0.1, P_SPIN + 2: 1.0}, None)]),
    "gr_potential+gr": make_forces(3, [(GR_POTENTIAL, 0, {P_C: 100.0}, None), (GR, 0, {P_C: 100.0}, None)]),
}

PAIRED_SCHEMES = [("leapfrog", "leapfrog", {}), ("leapfrog8", "leapfrog:8", {}), ("wisdom_holman", "whfast", {}),
                  ("wisdom_holman", "whfast", {"coordinates": "democratic_heliocentric"})]

#: The (scheme, force set) pairs `make test` runs. Each pair compiles the scheme's loop for that
#: set of force types (a Numba specialisation of 10-40 s on a cold cache), so the default suite
#: keeps the pairs whose loops the suite compiles anyway and one of each arrangement: gr
#: (velocity-dependent, as operators) and gr_potential (position-only, kicked) with every scheme;
#: migration (velocity-dependent, Jacobi) and both kinds at once with Wisdom-Holman (the loops of
#: resonance_capture and tests/forces/test_forces_stepping.py). The other pairs, the same
#: arrangements on the leapfrogs, run in `make test-slow`.
FAST_PAIRS = {("leapfrog", "gr"), ("wisdom_holman", "gr"), ("leapfrog", "gr_potential"),
              ("leapfrog8", "gr_potential"), ("wisdom_holman", "gr_potential"), ("wisdom_holman", "migration"),
              ("wisdom_holman", "gr_potential+gr")}


def _paired_cases() -> list:
    cases = []
    for forces in FORCE_SETS:
        for integrator, scheme, settings in PAIRED_SCHEMES:
            if forces == "gr_potential+gr" and integrator != "wisdom_holman":
                continue  # a mixed set with the leapfrogs is gr+harmonics' case
            marks = () if (integrator, forces) in FAST_PAIRS else pytest.mark.slow
            label = f"{forces}-{integrator}" + ("-" + settings["coordinates"] if settings else "")
            cases.append(pytest.param(forces, integrator, scheme, settings, marks=marks, id=label))
    return cases


@pytest.mark.parametrize(("forces", "integrator", "scheme", "settings"), _paired_cases())
def test_step_for_step_with_the_paired_arrangement(forces: str, integrator: str, scheme: str,
                                                   settings: dict[str, str]) -> None:
    """The arrangement attach_rebound_forces makes, 1000 steps: position-only forces kicked,
    velocity-dependent ones as half-step operators (measured 5e-15 .. 3e-13; kicking gr with
    gravity instead gives 6e-3, WHFast's operators without safe mode 2e-2)."""
    m, x, v = three_bodies()
    force_set = FORCE_SETS[forces]
    dt, n = 0.01, 1000
    chunks = list(Simulation(m, x, v, integrator, dt, 1.0, settings=settings, forces=force_set)
                  .chunks(EveryPlan(n, n)))
    rebound_scheme = parse_rebound_scheme(scheme)
    assert rebound_refusal(force_set, rebound_scheme, settings) is None
    sim = rebound_simulation(m, x, v, G=1.0, softening=0.0, dt=dt, scheme=rebound_scheme, settings=settings)
    attached = attach_rebound_forces(sim, force_set, rebound_scheme)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a velocity-dependent force kicked with gravity would warn
        sim.steps(n)
    sim.synchronize()
    expected = read_state(sim)[0]
    del attached
    error = np.max(np.abs(chunks[-1].positions[-1] - expected)) / np.max(np.abs(expected))
    assert error < ROUND_OFF, (forces, integrator, error)
    assert len(rebound_force_lines(force_set, rebound_scheme)) == len(force_set.ids)


def test_refusals_name_the_reason() -> None:
    gr_about_1 = make_forces(3, [(GR, 1, {P_C: 100.0}, None)])
    assert "particle 0" in rebound_refusal(gr_about_1, ReboundScheme("ias15"))
    gr = FORCE_SETS["gr"]
    assert "trace" in rebound_refusal(gr, ReboundScheme("trace"))
    assert rebound_refusal(gr, ReboundScheme("whfast"), {"corrector": 5}).startswith("wisdom_holman's symplectic")
    assert rebound_refusal(None, ReboundScheme("trace")) is None
