"""Two scenario defects of issue 14, item 9: unit names in any case, and unknown-key messages that
list each valid key once."""

from __future__ import annotations

import math
import re
from pathlib import Path

import pytest
from click.testing import CliRunner

from orbitsim.cli.main import cli
from orbitsim.scenario import ScenarioError, load_scenario, scenario_from_dict

HEAD = "integrator: verlet\ndt: 0.01\nsteps: 10\n"
BODIES = "bodies:\n  - {name: sun, m: 1.0, x: [0, 0, 0], v: [0, 0, 0]}\n  - {name: p, m: 0, primary: sun, a: 1, M: 0}\n"


@pytest.mark.parametrize("spelling", ["AU-yr-Msun", "au-yr-msun", "AU-YR-MSUN"])
def test_unit_system_names_are_case_insensitive_and_stored_canonical(tmp_path: Path, spelling: str) -> None:
    path = tmp_path / "s.yaml"
    path.write_text(f"units: {spelling}\n" + HEAD + BODIES, encoding="utf-8")
    result = CliRunner().invoke(cli, ["validate", str(path)])
    assert result.exit_code == 0 and result.output.startswith(f"ok: {path}: "), result.output
    scenario = load_scenario(path)
    assert scenario.units == "au-yr-msun" and scenario.G == 4.0 * math.pi**2
    assert 'units: "au-yr-msun"' in scenario.to_yaml()


def test_scenario_built_in_code_normalises_the_unit_name() -> None:
    doc = {"units": "SI", "integrator": "verlet", "dt": 1.0, "steps": 1,
           "bodies": [{"name": "a", "m": 1.0, "x": [0, 0, 0], "v": [0, 0, 0]}]}
    assert scenario_from_dict(doc).units == "si"


@pytest.mark.parametrize(("generator", "expected"), [
    ("{kind: plummer, n: 10, seed: 1, bogus: 3}", ["kind", "n", "seed", "total_mass", "scale_radius", "prefix"]),
    ("{n: 10, seed: 1, bogus: 3}", None),  # no kind yet: every generator's keys, each once
])
def test_unknown_generator_key_lists_each_valid_key_once(tmp_path: Path, generator: str,
                                                          expected: list[str] | None) -> None:
    path = tmp_path / "s.yaml"
    path.write_text(HEAD + f"generator: {generator}\n", encoding="utf-8")
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    assert info.value.key == "generator.bogus"
    listed = re.search(r"valid keys here: ([^(]+)", str(info.value)).group(1).strip().split(", ")
    assert len(listed) == len(set(listed)), listed
    if expected is not None:
        assert listed == expected
    else:
        assert {"kind", "n", "seed", "total_mass", "central_mass", "r_min", "star"} <= set(listed)
