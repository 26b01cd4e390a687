"""A continued run (``run --from``, ``resume``) reports the steps this process took and their rate
(issue 27, item 7), not the whole run's steps over the whole run's wall time.

The earlier part's wall time is made enormous (a million seconds, written into the trace's stored
state) so that a rate taken over the whole run would be visibly wrong; the process itself takes
well under a million seconds on any machine, which is the only bound on time these tests use.
"""

from __future__ import annotations

import re
from pathlib import Path

import h5py
from click.testing import CliRunner
from test_cli import TINY

from orbitsim.cli.main import cli

#: The wall time the earlier part of the run claims, in seconds (11.6 days).
EARLIER_WALL_S = 1.0e6


def invoke(*args: str) -> tuple[int, str]:
    result = CliRunner().invoke(cli, list(args))
    assert "Traceback" not in result.output
    return result.exit_code, result.stdout


def _claim_a_long_earlier_part(trace: Path) -> None:
    """Make the trace say its run took EARLIER_WALL_S (the state's digest does not cover the wall time)."""
    with h5py.File(trace, "r+") as f:
        f.attrs["wall_time_s"] = EARLIER_WALL_S
        f["checkpoint"].attrs["wall_time_s"] = EARLIER_WALL_S


def _seconds_and_rate(out: str) -> tuple[float, str]:
    """The wall time and the rate a continued run's summary gives for its own steps."""
    found = re.search(r" of them \(from step \d+\) in ([0-9.e+]+) s \(([^)]*)\)", out)
    assert found is not None, out
    return float(found.group(1)), found.group(2)


def test_run_from_reports_its_own_steps_and_rate(tmp_path: Path) -> None:
    scenario = tmp_path / "tiny.yaml"
    scenario.write_text(TINY, encoding="utf-8")
    trace = tmp_path / "tiny.h5"
    assert invoke("run", str(scenario), "-o", str(trace), "-q")[0] == 0
    _claim_a_long_earlier_part(trace)
    code, out = invoke("run", "--from", str(trace), "--steps", "100")
    assert code == 0, out
    assert "tiny: complete, 300 of 300 steps, 100 of them (from step 200) in " in out
    seconds, rate = _seconds_and_rate(out)
    assert seconds < EARLIER_WALL_S  # this process's time, not the earlier part's as well
    assert rate.endswith("steps/s") and not rate.startswith("-"), rate  # 100 steps in < 1e6 s: >= 1e-4 steps/s
    with h5py.File(trace) as f:  # the trace keeps the whole run's wall time
        assert f.attrs["wall_time_s"] >= EARLIER_WALL_S and int(f.attrs["steps_done"]) == 300


def test_resume_reports_its_own_steps(tmp_path: Path) -> None:
    from orbitsim.runner import run_scenario
    from orbitsim.scenario import load_scenario

    scenario = tmp_path / "tiny.yaml"
    scenario.write_text(TINY, encoding="utf-8")
    trace = tmp_path / "tiny.h5"
    polls = [0]

    def stop() -> bool:
        polls[0] += 1
        return polls[0] > 1

    sc = load_scenario(scenario).with_overrides(steps=60_000, every=250)  # long enough to stop between calls
    first = run_scenario(sc, trace, stop=stop, handle_signals=False)
    assert first.status == "interrupted" and 0 < first.steps_done < 60_000
    _claim_a_long_earlier_part(trace)
    code, out = invoke("resume", str(trace))
    assert code == 0, out
    left = 60_000 - first.steps_done
    assert f"60000 of 60000 steps, {left} of them (from step {first.steps_done}) in " in out
    assert _seconds_and_rate(out)[0] < EARLIER_WALL_S


def test_a_fresh_run_reads_as_before(tmp_path: Path) -> None:
    scenario = tmp_path / "tiny.yaml"
    scenario.write_text(TINY, encoding="utf-8")
    code, out = invoke("run", str(scenario), "-o", str(tmp_path / "tiny.h5"))
    assert code == 0 and "tiny: complete, 200 of 200 steps in " in out and "of them" not in out
