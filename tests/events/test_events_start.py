"""Bodies that overlap at t = 0 (issue 27, item 3).

A planet placed inside its star (radii given) used to run: it was flung out, |dE/E| grew past 10
and no collision was ever logged, because the events watch checks the end of each step, never
the state a run starts from. Now ``validate`` and ``run`` refuse such a start in one line that
names both bodies and their distance, unless ``events.collisions`` is set; then the overlap is a
collision at step 0, resolved by the scenario's rule.
"""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

from orbitsim.cli.main import cli
from orbitsim.events.overlap import overlapping_pairs

#: The issue's case: the planet's centre 0.003 au from the Sun's, inside its radius (0.00465 au).
INSIDE = """\
name: inside
units: au-yr-msun
integrator: verlet
dt: 0.001
t_end: 0.1
output: {{every: 10}}
{events}bodies:
  - {{name: sun, m: 1.0, r: 0.00465, x: [0, 0, 0], v: [0, 0, 0]}}
  - {{name: planet, m: 1.0e-3, r: 0.0005, x: [0.003, 0, 0], v: [0, 0, 0]}}
  - {{name: earth, m: 3.0e-6, r: 4.3e-5, x: [1, 0, 0], v: [0, 6.283185307, 0]}}
"""


def invoke(*args: str) -> tuple[int, str, str]:
    result = CliRunner().invoke(cli, list(args))
    assert "Traceback" not in result.output, result.output
    return result.exit_code, result.stdout, result.stderr


def write(tmp_path: Path, events: str = "") -> Path:
    path = tmp_path / "inside.yaml"
    path.write_text(INSIDE.format(events=events), encoding="utf-8")
    return path


def events_table(path: Path) -> dict[str, np.ndarray]:
    with h5py.File(path, "r") as f:
        return {name: f["events"][name][()] for name in f["events"]}


def text(values: np.ndarray) -> list[str]:
    return [v.decode() if isinstance(v, bytes) else str(v) for v in values]


def test_overlapping_pairs_is_every_pair_closer_than_its_radii() -> None:
    """The sweep finds exactly the pairs a brute-force O(N^2) search finds, with their distances."""
    rng = np.random.default_rng(27)
    for n, spread in ((2, 0.01), (60, 1.0), (300, 3.0)):
        x = rng.normal(scale=spread, size=(n, 3))
        r = np.where(rng.random(n) < 0.5, rng.random(n) * 0.3, 0.0)  # half the bodies are points
        want = []
        for i in range(n):
            for j in range(i + 1, n):
                d = x[i] - x[j]
                if d @ d < (r[i] + r[j]) ** 2:
                    want.append((i, j))
        got = overlapping_pairs(x, r)
        assert [(i, j) for i, j, _, _ in got] == want
        for i, j, distance, reach in got:
            assert distance == pytest.approx(np.linalg.norm(x[i] - x[j]), rel=1e-15)  # one rounding apart
            assert reach == r[i] + r[j]
    assert overlapping_pairs(np.zeros((3, 3)), None) == []
    assert overlapping_pairs(np.zeros((3, 3)), np.zeros(3)) == []  # points never touch, even coincident


@pytest.mark.parametrize("command", ["validate", "run"])
def test_overlap_at_the_start_is_refused_without_collisions(tmp_path: Path, command: str) -> None:
    scenario = write(tmp_path)
    out = tmp_path / "inside.h5"
    args = ("run", str(scenario), "-o", str(out)) if command == "run" else ("validate", str(scenario))
    code, stdout, stderr = invoke(*args)
    assert code == 2 and stdout == ""
    lines = stderr.strip().splitlines()
    assert len(lines) == 1, stderr
    assert "bodies[1]" in lines[0] and "'sun' and 'planet' overlap at the start" in lines[0]
    assert "0.003 apart" in lines[0] and "r_i + r_j = 0.00515" in lines[0] and "events: {collisions:" in lines[0]
    assert list(tmp_path.iterdir()) == [scenario]  # nothing written, not even a lock or a side file


def test_an_events_section_without_collisions_does_not_excuse_the_overlap(tmp_path: Path) -> None:
    code, _, stderr = invoke("validate", str(write(tmp_path, "events: {escape: {distance: 50}}\n")))
    assert code == 2 and "overlap at the start" in stderr


def test_overlap_with_merge_is_a_collision_at_step_0(tmp_path: Path) -> None:
    scenario = write(tmp_path, "events: {collisions: {resolve: merge}}\n")
    assert invoke("validate", str(scenario))[0] == 0
    out = tmp_path / "inside.h5"
    code, stdout, stderr = invoke("run", str(scenario), "-o", str(out))
    assert code == 0, stderr
    assert "1 collision (sun and planet, merged at t = 0)" in stdout
    table = events_table(out)
    assert text(table["kind"]) == ["collision"] and text(table["outcome"]) == ["merged"]
    assert (table["step"][0], table["i"][0], table["j"][0]) == (0, 0, 1)
    assert table["distance"][0] == pytest.approx(0.003, rel=1e-12) and table["extra"][0] == 0.00465 + 0.0005
    with h5py.File(out, "r") as f:
        positions, masses = f["positions"][()], f["bodies/final_masses"][()]
        removed = f["bodies/removed_step"][()]
        error = f["energy_error"][()]
    assert list(removed) == [-1, 0, -1]
    assert np.isnan(positions[:, 1]).all() and np.isfinite(positions[:, [0, 2]]).all()  # gone from sample 0 on
    assert masses[0] == 1.0 + 1.0e-3
    # momentum-conserving merge at rest: the Earth keeps a well-resolved orbit about the merged body
    assert np.max(np.abs(error)) < 1e-6  # a resolved verlet orbit at P/1000 keeps |dE/E| ~ 1e-8


def test_overlap_with_halt_ends_the_run_at_step_0(tmp_path: Path) -> None:
    scenario = write(tmp_path, "events: {collisions: {resolve: halt}}\n")
    out = tmp_path / "inside.h5"
    code, _, stderr = invoke("run", str(scenario), "-o", str(out))
    assert code == 6
    assert "halted at t = 0 (step 0)" in stderr and "sun and planet touch" in stderr
    with h5py.File(out, "r") as f:
        assert f.attrs["status"] == "halted" and int(f.attrs["steps_done"]) == 0
        assert list(f["step"][()]) == [0]
    assert text(events_table(out)["outcome"]) == ["halted"]


def test_overlap_with_log_is_logged_once_while_it_lasts(tmp_path: Path) -> None:
    """A pair that starts at rest, overlapping, and stays in contact for the 20 steps of the run
    (free fall from 0.5 to 0 takes ~0.55 time units): one collision, at step 0, never again."""
    scenario = tmp_path / "touching.yaml"
    scenario.write_text("name: touching\nintegrator: verlet\ndt: 0.001\nsteps: 20\noutput: {every: 1}\n"
                        "events: {collisions: {resolve: log}, unresolved: false}\nbodies:\n"
                        "  - {name: a, m: 1.0, r: 0.4, x: [0, 0, 0], v: [0, 0, 0]}\n"
                        "  - {name: b, m: 1.0e-3, r: 0.2, x: [0.5, 0, 0], v: [0, 0, 0]}\n", encoding="utf-8")
    out = tmp_path / "touching.h5"
    code, stdout, stderr = invoke("run", str(scenario), "-o", str(out))
    assert code == 0, stderr
    assert "1 collision (a and b at t = 0)" in stdout
    table = events_table(out)
    assert text(table["kind"]) == ["collision"] and list(table["step"]) == [0]
    with h5py.File(out, "r") as f:
        separation = np.linalg.norm(f["positions"][:, 0] - f["positions"][:, 1], axis=1)
    assert len(separation) == 21 and (separation < 0.6).all()  # in contact at every sample
