"""``output.chaos`` in a scenario: read, validated, written back to the same bits, and every bad key
refused by ``orbitsim run`` in one line naming the file and the key, exit 2, nothing written."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from orbitsim.cli.main import cli
from orbitsim.forces.compat import TANGENT_BUILT
from orbitsim.scenario import ScenarioError, load_scenario, scenario_from_dict
from orbitsim.scenario.chaos import ChaosConfig

BODIES = [
    {"name": "star", "m": 1.0, "x": [0, 0, 0], "v": [0, 0, 0]},
    {"name": "inner", "m": 1e-3, "primary": "star", "a": 1.5, "e": 0.1, "inc": 0.1},
    {"name": "outer", "m": 1e-3, "primary": "star", "a": 15.0, "e": 0.1, "inc": 0.1},
]


def doc(chaos: object, **changes: object) -> dict:
    return {"name": "pair", "integrator": "wisdom_holman", "dt": 0.1, "steps": 100,
            "output": {"every": 10, "chaos": chaos}, "bodies": BODIES, **changes}


def test_seed_defaults_to_zero_and_the_indicator_to_megno() -> None:
    sc = scenario_from_dict(doc({}))
    assert sc.chaos == ChaosConfig("megno", 0, None)
    assert scenario_from_dict(doc({"seed": 12})).chaos.seed == 12
    assert scenario_from_dict(doc(None)).chaos is None  # `chaos:` with nothing after it: no indicators


def test_an_explicit_variation_is_placed_by_body_name() -> None:
    sc = scenario_from_dict(doc({"indicator": "megno", "variation": {"outer": {"dr": [1.0, 0.0, 2.0]},
                                                                        "star": {"dv": [0.0, 3.0, 0.0]}}}))
    assert sc.chaos.seed is None
    expected = np.zeros((3, 6))
    expected[2, :3] = [1.0, 0.0, 2.0]
    expected[0, 3:] = [0.0, 3.0, 0.0]
    assert np.array_equal(sc.chaos.variation, expected)
    dpos, dvel = sc.chaos.initial_tangent(3)
    assert np.array_equal(dpos, expected[:, :3].T) and np.array_equal(dvel, expected[:, 3:].T)


@pytest.mark.parametrize("chaos", [{"seed": 7}, {"variation": {"inner": {"dr": [0.1, 1e-17, -3.3], "dv": [1 / 3, 0,
                                                                                                           0.5]}}}])
def test_the_resolved_text_loads_back_to_the_same_bits(tmp_path: Path, chaos: dict) -> None:
    sc = scenario_from_dict(doc(chaos))
    path = tmp_path / "again.yaml"
    path.write_text(sc.to_yaml(), encoding="utf-8")
    again = load_scenario(path)
    assert again.sha256 == sc.sha256 and again.chaos.seed == sc.chaos.seed
    if sc.chaos.variation is not None:
        assert again.chaos.variation.tobytes() == sc.chaos.variation.tobytes()


def test_a_scenario_without_chaos_keeps_its_text() -> None:
    plain = scenario_from_dict({**doc({}), "output": {"every": 10}})
    assert plain.chaos is None and "chaos" not in plain.to_yaml()


def test_a_seeded_variation_is_unit_length_per_body_and_fixed_by_the_seed() -> None:
    dpos, dvel = ChaosConfig("megno", 5, None).initial_tangent(4)
    norms = np.sqrt(np.sum(dpos * dpos, axis=0) + np.sum(dvel * dvel, axis=0))
    assert np.allclose(norms, 1.0, rtol=0.0, atol=1e-15)  # normalised in float64: a few ulps
    again = ChaosConfig("megno", 5, None).initial_tangent(4)
    other = ChaosConfig("megno", 6, None).initial_tangent(4)
    assert np.array_equal(dpos, again[0]) and not np.array_equal(dpos, other[0])


def test_an_override_to_a_scheme_without_variational_equations_is_refused() -> None:
    sc = scenario_from_dict(doc({}))
    with pytest.raises(ScenarioError, match="no variational equations") as err:
        sc.with_overrides(integrator="rk4")
    assert err.value.key == "output.chaos"


# -- bad input through `orbitsim run`: one line, exit 2, nothing at the output path ---------------------------

BAD = {
    "unknown indicator": (doc({"indicator": "lyapunov"}), "output.chaos.indicator", "unknown value 'lyapunov'"),
    "negative seed": (doc({"seed": -1}), "output.chaos.seed", "whole number"),
    "fractional seed": (doc({"seed": 1.5}), "output.chaos.seed", "whole number"),
    "text seed": (doc({"seed": "abc"}), "output.chaos.seed", "whole number"),
    "boolean seed": (doc({"seed": True}), "output.chaos.seed", "whole number"),
    "seed and variation": (doc({"seed": 1, "variation": {"inner": {"dr": [1, 0, 0]}}}), "output.chaos.variation",
                           "give only one of seed or variation"),
    "unknown key": (doc({"sead": 1}), "output.chaos.sead", "did you mean 'seed'"),
    "not a mapping": (doc("megno"), "output.chaos", "expected a chaos section"),
    "zero variation": (doc({"variation": {"inner": {"dr": [0, 0, 0], "dv": [0.0, 0.0, 0.0]}}}),
                       "output.chaos.variation", "the initial variation is zero"),
    "empty variation": (doc({"variation": {}}), "output.chaos.variation", "expected a mapping of body names"),
    "unknown body": (doc({"variation": {"pluto": {"dr": [1, 0, 0]}}}), "output.chaos.variation.pluto",
                     "unknown body 'pluto'"),
    "short vector": (doc({"variation": {"inner": {"dr": [1, 0]}}}), "output.chaos.variation.inner.dr",
                     "a list of 3 numbers"),
    "non-finite component": (doc({"variation": {"inner": {"dv": [1, 0, float("inf")]}}}),
                             "output.chaos.variation.inner.dv[2]", "finite"),
    "unknown variation key": (doc({"variation": {"inner": {"dx": [1, 0, 0]}}}), "output.chaos.variation.inner.dx",
                              "unknown key 'dx'"),
    "scheme without variational equations": (doc({}, integrator="rk4"), "output.chaos",
                                             "integrator 'rk4' has no variational equations"),
    "wisdom_holman in democratic heliocentric coordinates": (
        doc({}, integrator={"name": "wisdom_holman", "coordinates": "democratic_heliocentric"}), "output.chaos",
        "need coordinates 'jacobi'"),
    "wisdom_holman with a corrector": (doc({}, integrator={"name": "wisdom_holman", "corrector": 3}), "output.chaos",
                                       "without correctors"),
    "events": (doc({}, events={"escape": {"distance": 100.0}}), "events", "does not combine with events"),
}


def _yaml(document: dict) -> str:
    import yaml

    return yaml.safe_dump(document, sort_keys=False)


@pytest.mark.parametrize("case", list(BAD))
def test_each_bad_chaos_key_is_one_line_naming_the_file_and_key(tmp_path: Path, case: str) -> None:
    document, key, reason = BAD[case]
    path = tmp_path / "bad.yaml"
    path.write_text(_yaml(document), encoding="utf-8")
    out = tmp_path / "out.h5"
    result = CliRunner().invoke(cli, ["run", str(path), "-o", str(out)])
    assert result.exit_code == 2, result.output
    err = result.stderr
    assert "Traceback" not in result.output and err.count("\n") == 1, err
    assert err.startswith(f"orbitsim: error: {path}: {key}: "), err
    assert reason in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.yaml"]  # nothing written, not even a lock


#: Forces a scenario may give, each with its parameters (nbody units: c is given); those whose derivatives
#: are built (orbitsim.forces.compat.TANGENT_BUILT) run (tests/chaos/test_chaos_trace.py), the others are refused.
FORCES = {"gr_potential": {"force": "gr_potential", "source": "star", "c": 10065.32},
          "gr": {"force": "gr", "source": "star", "c": 10065.32},
          "harmonics": {"force": "harmonics", "body": "star", "J2": 1e-3, "R_eq": 0.01}}


@pytest.mark.parametrize("name", [name for name in FORCES if name not in TANGENT_BUILT])
def test_a_force_without_its_derivative_is_refused_naming_the_forces_key(tmp_path: Path, name: str) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text(_yaml(doc({}, forces=[FORCES[name]])), encoding="utf-8")
    result = CliRunner().invoke(cli, ["run", str(path), "-o", str(tmp_path / "out.h5")])
    assert result.exit_code == 2 and result.stderr.count("\n") == 1, result.output
    assert result.stderr.startswith(f"orbitsim: error: {path}: forces[0]: the variational equations would leave "
                                    f"out {name}: "), result.stderr
    assert "derivative" in result.stderr and "not built" in result.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.yaml"]


def test_validate_reports_the_same_refusal(tmp_path: Path) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text(_yaml(doc({}, integrator="euler")), encoding="utf-8")
    result = CliRunner().invoke(cli, ["validate", str(path)])
    assert result.exit_code == 2 and "output.chaos: " in result.stderr and "euler" in result.stderr
