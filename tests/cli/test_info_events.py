"""``orbitsim info`` on traces with events, bodies that left the run, and orbital elements; and on a
plain trace, exactly what it printed before events existed (a golden list of lines).

Every trace is made by ``orbitsim run`` and read by ``orbitsim info`` through the real CLI. The runs
use verlet, so the first run of the module compiles one scheme's events kernels only.
"""

from __future__ import annotations

import re
import subprocess
import sys
import textwrap
from pathlib import Path

import h5py
import pytest
from click.testing import CliRunner
from test_cli import TINY  # the CLI tests' two-body scenario: its info output is pinned below

from orbitsim.cli.main import cli

#: ``info`` on TINY's trace, as the code printed it before the events section was added; ``{*}``
#: stands for what differs between machines and versions (paths, timings, provenance, hashes).
PLAIN_INFO = (
    "trace:    {*}",
    "  format               orbitsim.trace",
    "  format_version       1",
    "  orbitsim_version     {*}",
    "  status               complete",
    "  scenario_name        tiny",
    "  scenario_source      {*}",
    "  scenario_sha256      {*}",
    "  integrator           verlet",
    "  integrator_settings  {}",
    "  dt                   0.01",
    "  steps_requested      200",
    "  steps_done           200",
    "  G                    1",
    "  softening            0",
    "  units                nbody",
    "  wall_time_s          {*}",
    "  threads              {*}",
    "samples:  21, t = 0 .. 2, max |dE/E| = 9.37e-06",
    "bodies:   2",
    "datasets:",
    "  angular_momentum     (21, 3)",
    "  bodies/masses        (2,)",
    "  bodies/names         (2,)",
    "  checkpoint/acc       (3, 2)",
    "  checkpoint/pos       (3, 2)",
    "  checkpoint/vel       (3, 2)",
    "  checkpoint/work/0000 (0, 3, 2)",
    "  energy               (21,)",
    "  energy_error         (21,)",
    "  kinetic              (21,)",
    "  momentum             (21, 3)",
    "  positions            (21, 2, 3)",
    "  potential            (21,)",
    "  step                 (21,)",
    "  time                 (21,)",
    "  velocities           (21, 2, 3)",
    "attributes:",
    "  E0                                -0.0004993888889",
    "  energy_scale                      0.0004993888889",
    "  frame                             as_given",
    "  n_bodies                          2",
    "  provenance_cpu_count              {*}",
    "  provenance_cpu_model              {*}",
    "  provenance_h5py_version           {*}",
    "  provenance_hostname               {*}",
    "  provenance_llvmlite_version       {*}",
    "  provenance_numba_threads          {*}",
    "  provenance_numba_version          {*}",
    "  provenance_numpy_version          {*}",
    "  provenance_orbitsim_version       {*}",
    "  provenance_platform               {*}",
    "  provenance_python_implementation  {*}",
    "  provenance_python_version         {*}",
    "  provenance_rebound_version        {*}",
    "  sample_every                      10",
    "  scenario                          <{*} characters of YAML; see --scenario>",
    "checkpoint:",
    "  state                step 200 of 200, with the first 21 samples",
    "  resumable            no: complete; extend it with `orbitsim run --from {*} --steps N`",
)

#: Two bodies thrown at each other, and a distant third that stays: they touch near t = 1.88.
HEAD_ON = """\
name: head_on
integrator: verlet
dt: 0.01
steps: 300
output: {every: 10}
events:
  collisions: {detect: line, resolve: RESOLVE}
bodies:
  - {name: left, m: 1.0e-3, r: 0.05, x: [-1, 0, 0], v: [0.5, 0, 0]}
  - {name: right, m: 1.0e-3, r: 0.05, x: [1, 0, 0], v: [-0.5, 0, 0]}
  - {name: star, m: 1.0, x: [0, 5, 0], v: [0, 0, 0]}
"""

#: A planet on an e = 0.5 orbit: every pericentre passage (0.5) is an encounter closer than 0.8.
#: 13 orbits of 2 pi: 13 encounters, more than ``info`` lists one by one.
PERICENTRES = """\
name: pericentres
integrator: verlet
dt: 0.01
steps: 8200
output: {every: 100, elements: true, primary: star}
events:
  encounters: {distance: 0.8}
  unresolved: false
bodies:
  - {name: star, m: 1.0, x: [0, 0, 0], v: [0, 0, 0]}
  - {name: planet, m: 1.0e-3, primary: star, a: 1.0, e: 0.5, M: 180}
"""

#: A massless body leaving fast: it escapes beyond r = 3 and is removed.
LEAVER = """\
name: leaver
integrator: verlet
dt: 0.01
steps: 300
output: {every: 10}
events:
  escape: {distance: 3, action: remove}
bodies:
  - {name: star, m: 1.0, x: [0, 0, 0], v: [0, 0, 0]}
  - {name: planet, m: 1.0e-3, primary: star, a: 1.0, e: 0.0, M: 0}
  - {name: probe, m: 0.0, x: [1.5, 0, 0], v: [0, 3, 0]}
"""


def invoke(*args: str) -> tuple[int, str]:
    result = CliRunner().invoke(cli, list(args))
    assert "Traceback" not in result.output
    return result.exit_code, result.output


def run(tmp_path: Path, text: str, name: str) -> Path:
    scenario, out = tmp_path / f"{name}.yaml", tmp_path / f"{name}.h5"
    scenario.write_text(text, encoding="utf-8")
    _, output = invoke("run", str(scenario), "-o", str(out), "-q")  # a halted run exits 6: the trace is what counts
    assert out.is_file(), output
    return out


def info_lines(trace: Path) -> list[str]:
    code, text = invoke("info", str(trace))
    assert code == 0, text
    return text.splitlines()


def section(lines: list[str], title: str) -> list[str]:
    """The line starting with ``title`` and its indented lines."""
    start = next(k for k, line in enumerate(lines) if line.startswith(title))
    end = next((k for k in range(start + 1, len(lines)) if not lines[k].startswith("  ")), len(lines))
    return lines[start:end]


def test_info_on_a_plain_trace_prints_exactly_what_it_printed_before_events(tmp_path: Path) -> None:
    lines = info_lines(run(tmp_path, TINY, "tiny"))
    assert len(lines) == len(PLAIN_INFO), "\n".join(lines)
    for got, want in zip(lines, PLAIN_INFO, strict=True):
        pattern = ".+".join(re.escape(part) for part in want.split("{*}"))
        assert re.fullmatch(pattern, got), (got, want)


def test_info_lists_a_merge_and_the_body_that_left(tmp_path: Path) -> None:
    lines = info_lines(run(tmp_path, HEAD_ON.replace("RESOLVE", "merge"), "merge"))
    events = section(lines, "events:")
    assert events[0] == "events:   1 (encounter 0, collision 1, escape 0, unresolved 0, lost 0)"
    assert len(events) == 2 and re.match(r"  t = 1\.8\d* +collision  left and right touch: .*; merged into left$",
                                         events[1]), events
    removed = section(lines, "removed:")
    assert removed[0] == "removed:  1 of 3 bodies left the run"
    assert re.fullmatch(r"  right  merged into left at t = 1\.8\d* \(step 18\d\)", removed[1]), removed
    assert len(removed) == 2
    assert lines.index(events[0]) == lines.index("bodies:   3") + 1  # before the long dataset listing


def test_info_lists_a_halt_and_says_no_body_left(tmp_path: Path) -> None:
    scenario, trace = tmp_path / "halt.yaml", tmp_path / "halt.h5"
    scenario.write_text(HEAD_ON.replace("RESOLVE", "halt"), encoding="utf-8")
    code, text = invoke("run", str(scenario), "-o", str(trace), "-q")
    assert code == 6 and text.startswith("orbitsim: error: run halted at t = 1.8") and text.count("\n") == 1, text
    lines = info_lines(trace)
    assert "  status               halted" in lines
    events = section(lines, "events:")
    assert len(events) == 2 and events[1].endswith("; the run halted here")
    assert section(lines, "removed:") == ["removed:  none of the 3 bodies left the run"]


def test_info_shows_the_first_ten_events_then_how_many_more_and_the_elements(tmp_path: Path) -> None:
    lines = info_lines(run(tmp_path, PERICENTRES, "pericentres"))
    events = section(lines, "events:")
    assert events[0] == "events:   13 (encounter 13, collision 0, escape 0, unresolved 0, lost 0)"
    listed = events[1:11]
    assert all(re.match(r"  t = [0-9.]+ +encounter  star and planet: closest 0\.5", line) for line in listed), listed
    times = [float(line.split()[2]) for line in listed]
    assert times == sorted(times)
    assert events[11] == f"  ... 3 more: orbitsim info {tmp_path / 'pericentres.h5'} --events" and len(events) == 12
    assert "elements: a, e, inc, Omega, omega, f, M, each (83, 2), primary star (orbitsim plot --elements)" in lines


def test_info_shows_a_removed_body(tmp_path: Path) -> None:
    lines = info_lines(run(tmp_path, LEAVER, "leaver"))
    events = section(lines, "events:")
    assert events[0].startswith("events:   1 (encounter 0, collision 0, escape 1,")
    assert "probe escapes" in events[1] and events[1].endswith("; removed from the run")
    removed = section(lines, "removed:")
    assert removed[0] == "removed:  1 of 3 bodies left the run"
    assert re.fullmatch(r"  probe  removed at t = [0-9.]+ \(step \d+\)", removed[1]), removed


def test_a_damaged_events_table_is_one_line_naming_the_dataset(tmp_path: Path) -> None:
    trace = run(tmp_path, HEAD_ON.replace("RESOLVE", "merge"), "damaged")
    with h5py.File(trace, "a") as f:
        del f["events/kind"]
    code, text = invoke("info", str(trace))
    assert code == 2 and text == f"orbitsim: error: {trace}: damaged trace: dataset 'events/kind' is missing\n"


@pytest.mark.parametrize("name", ["merge", "pericentres"])
def test_info_on_an_events_trace_imports_no_numba(tmp_path: Path, name: str) -> None:
    text = HEAD_ON.replace("RESOLVE", "merge") if name == "merge" else PERICENTRES
    trace = run(tmp_path, text, name)
    code = textwrap.dedent(f"""
        import sys
        from click.testing import CliRunner
        from orbitsim.cli.main import cli
        result = CliRunner().invoke(cli, ["info", {str(trace)!r}])
        assert result.exit_code == 0 and "events:" in result.output, result.output
        heavy = sorted(m for m in ("numba", "matplotlib", "dask", "distributed") if m in sys.modules)
        assert not heavy, heavy
    """)
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr


# -- info --events [KIND]: every event, or those of one kind ----------------------------------------

def test_info_events_lists_every_event_not_the_first_ten(tmp_path: Path) -> None:
    trace = run(tmp_path, PERICENTRES, "pericentres")
    code, text = invoke("info", str(trace), "--events")
    assert code == 0, text
    lines = text.splitlines()
    assert lines[0] == "events:   13 (encounter 13, collision 0, escape 0, unresolved 0, lost 0)"
    assert len(lines) == 14
    assert all(re.match(r"  t = [0-9.]+ +encounter +star and planet: closest 0\.5", line) for line in lines[1:])
    assert lines[1:11] == section(info_lines(trace), "events:")[1:11]  # the same lines info shows first
    times = [float(line.split()[2]) for line in lines[1:]]
    assert times == sorted(times)


def test_info_events_kind_lists_only_that_kind(tmp_path: Path) -> None:
    trace = run(tmp_path, HEAD_ON.replace("RESOLVE", "merge"), "merge")
    code, text = invoke("info", str(trace), "--events", "collision")
    assert code == 0, text
    lines = text.splitlines()
    assert lines[0] == "events:   1 (encounter 0, collision 1, escape 0, unresolved 0, lost 0); 1 of kind collision:"
    assert len(lines) == 2 and re.match(r"  t = 1\.8\d* +collision +left and right touch: .*; merged into left$",
                                        lines[1]), lines
    code, text = invoke("info", str(trace), "--events", "escape")
    assert code == 0 and text.splitlines() == [
        "events:   1 (encounter 0, collision 1, escape 0, unresolved 0, lost 0); 0 of kind escape:"]


def test_info_events_reads_the_table_block_by_block(tmp_path: Path) -> None:
    from orbitsim.io.trace_events import iter_events

    trace = run(tmp_path, PERICENTRES, "pericentres")
    with h5py.File(trace, "r") as f:
        whole = list(iter_events(f))
        assert len(whole) == 13
        assert list(iter_events(f, block=4)) == whole  # 4 blocks, the last of 1 row
        assert list(iter_events(f, "collision", block=4)) == []


@pytest.mark.parametrize(("args", "words"), [
    (["--events"], "has no events table: the run had no events: section"),
    (["--events", "bogus"], "--events: 'bogus' is not an event kind (all, encounter, collision, escape, unresolved, "
                            "lost); give the trace first: orbitsim info TRACE --events [KIND]"),
    (["--events", "--scenario"], "--scenario and --events print different things; give one"),
])
def test_info_events_errors_are_one_line(tmp_path: Path, args: list[str], words: str) -> None:
    trace = run(tmp_path, TINY, "tiny")
    code, text = invoke("info", str(trace), *args)
    assert code == 2 and text.count("\n") == 1 and words in text, text
    code, text = invoke("info", "--events", str(trace))  # the option before the trace takes it as KIND
    assert code == 2 and text.count("\n") == 1 and "give the trace first" in text, text


def test_the_cli_kinds_are_the_event_kinds() -> None:
    from orbitsim.cli.info import EVENT_KIND_CHOICES
    from orbitsim.events.log import EVENT_KINDS

    assert EVENT_KIND_CHOICES == EVENT_KINDS
