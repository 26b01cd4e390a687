"""``orbitsim compare`` on a TRACE scenario: the report says why the trace pair may diverge, and
by how much it was allowed to (the twin-divergence tolerance)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from click.testing import CliRunner

from orbitsim.cli.main import cli
from orbitsim.reference.pairs import ENCOUNTER_CHAOS, TWIN_MARGIN

rebound = pytest.importorskip("rebound")


@pytest.fixture(scope="module")
def trace_compare(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, int]:
    """many_encounters for 300 steps (t = 10.2: encounters and a redone step among them), the
    trace pair beside the leapfrog pair, which switches nothing."""
    out = tmp_path_factory.mktemp("cmp_trace") / "me"
    result = CliRunner().invoke(cli, ["compare", "many_encounters", "-o", str(out), "--steps", "300",
                                      "--integrators", "trace,leapfrog", "--rebound", "trace,leapfrog"],
                                catch_exceptions=False)
    return out, result.exit_code


def test_the_trace_pair_states_encounter_chaos_and_its_twin_tolerance(trace_compare: tuple[Path, int]) -> None:
    out, code = trace_compare
    summary = json.loads((out / "summary.json").read_text())
    pair = next(p for p in summary["pairs"] if p["orbitsim"] == "orbitsim/trace")
    assert code == 0 and pair["verdict"] == "agree", pair
    if rebound.__version__ == "5.2.2":  # the port does REBOUND 5.2.2's operations in its order
        assert pair["max_relative_position_difference"] == 0.0
    twin_tolerance = f"{TWIN_MARGIN * pair['twin_max']:.3g}"
    assert pair["twin_max"] > 0.0  # a 4-ulp twin does diverge, so the number shown is a real one
    for name in ("report.md", "report.html"):
        text = (out / name).read_text()
        sentence = next(line for line in text.splitlines() if ENCOUNTER_CHAOS in line)
        assert "orbitsim trace" in sentence and "REBOUND trace" in sentence, sentence
        assert "twin-divergence tolerance" in sentence and f"up to {twin_tolerance} of the system" in sentence
        assert f"{TWIN_MARGIN:g} x the divergence of a REBOUND twin" in sentence
        assert text.count(ENCOUNTER_CHAOS) == 1, name  # the leapfrog pair switches nothing: no such sentence


def test_docs_name_the_sentence() -> None:
    words = (Path(__file__).resolve().parents[2] / "docs" / "compare.md").read_text().split()
    assert ENCOUNTER_CHAOS in " ".join(w for w in words if w != ">")  # the quoted sentence, line breaks aside
