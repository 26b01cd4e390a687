"""``orbitsim map``: the files it writes, every refusal (one line, exit 2, nothing written), a full disk,
and a map killed by SIGKILL that the same command finishes with bit-identical pixels."""

from __future__ import annotations

import errno
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

from orbitsim.cli.main import cli
from orbitsim.cli.map import INDICATOR_CHOICES
from orbitsim.scenario import load_scenario
from orbitsim.stability.plan import INDICATORS

SCENARIO = """\
name: tp
units: nbody
integrator: wisdom_holman
dt: 0.5
t_end: 100
bodies:
  - {name: sun, m: 1.0, x: [0, 0, 0], v: [0, 0, 0]}
  - {name: jupiter, m: 0.000954791915, primary: sun, a: 5.2, e: 0.048, M: 10}
  - {name: saturn, m: 0.000285885672, primary: sun, a: 9.54, e: 0.054, M: 200, inc: 2.5}
  - {name: planet, m: 0, primary: sun, a: 7.0, e: 0.1, M: 30}
  - {name: probe, m: 0, x: [20, 0, 0], v: [0, 0.2, 0]}
"""
AXES = ["--x", "planet.a=7.0:8.0:3", "--y", "planet.e=0:0.3:2", "--t-end", "40", "--indicator", "max_e", "--quiet"]


@pytest.fixture
def scenario(tmp_path: Path) -> Path:
    path = tmp_path / "tp.yaml"
    path.write_text(SCENARIO, encoding="utf-8")
    return path


def _map(args: list[str]) -> tuple[int, str, str]:
    result = CliRunner().invoke(cli, ["map", *args])
    return result.exit_code, result.stdout, result.stderr


def _grids(path: Path) -> dict[str, np.ndarray]:
    with h5py.File(path, "r") as f:
        out = {name: f["indicators"][name][()] for name in f["indicators"]}
        out["status"] = f["status"][()]
        out["stop_time"] = f["stop_time"][()]
        return out


def _plan(scenario: Path, chunk: int):
    """The test map's plan (3 x 2 pixels over the planet's a and e, to t = 40) in chunks of ``chunk``."""
    from orbitsim.scenario.yamlio import parse_yaml
    from orbitsim.stability.axes import parse_axis
    from orbitsim.stability.plan import make_plan

    doc, _ = parse_yaml(scenario.read_text(encoding="utf-8"), str(scenario))
    axes = [parse_axis("--x", "planet.a=7.0:8.0:3", doc), parse_axis("--y", "planet.e=0:0.3:2", doc)]
    return make_plan(load_scenario(str(scenario)), doc, axes, 40.0, None, chunk)


def test_cli_lists_the_indicators_the_plan_computes():
    assert INDICATOR_CHOICES == INDICATORS


# Compiles the Wisdom-Holman lanes kernels with MEGNO (~2 min cold). make test's maps: the full-disk test
# below, and tests/gpu_ensemble's simulator map, which compares a CPU map with the GPU's.
@pytest.mark.slow
def test_map_writes_its_file_and_figure_and_info_and_plot_read_them(scenario, tmp_path):
    out = tmp_path / "m"
    code, stdout, stderr = _map([str(scenario), *AXES, "-o", str(out)])
    assert code == 0, stderr
    assert "6 pixels: 6 complete" in stdout
    assert (out / "map.png").stat().st_size > 0
    assert not (out / "map.parts").exists()
    grids = _grids(out / "map.h5")
    assert grids["status"].shape == (2, 3)
    assert np.all(grids["survival_time"] == 40.0)
    assert np.all(grids["max_e"][1] > grids["max_e"][0])  # e0 = 0.3 stays above e0 = 0 over 40 time units
    assert np.all(np.isfinite(grids["megno"])) and np.all(grids["megno"] > 0.0)  # MEGNO from the tangent map
    assert np.all(np.isfinite(grids["lyapunov_time"]))
    info = CliRunner().invoke(cli, ["info", str(out / "map.h5")])
    assert info.exit_code == 0
    assert "6 complete, 0 escaped" in info.stdout and "max_e:" in info.stdout and "pixels/s" in info.stdout
    plot = CliRunner().invoke(cli, ["plot", str(out / "map.h5"), "--indicator", "delta_a"])
    assert plot.exit_code == 0, plot.stderr
    assert (out / "map_delta_a.png").exists()
    again = _map([str(scenario), *AXES, "-o", str(out)])
    assert again[0] == 0 and "already complete" in again[1]
    other = _map([str(scenario), *AXES[:-4], "41", "--indicator", "max_e", "-o", str(out)])
    assert other[0] == 2 and "another map" in other[2]


@pytest.mark.parametrize(("x_spec", "message"), [
    ("nobody.a=1:2:3", "no body 'nobody'"),
    ("planet.zz=1:2:3", "unknown key 'zz'"),
    ("planet.a=2:1:3", "LO must be below HI"),
    ("planet.a=1:2:1", "N must be at least 2"),
    ("planet.a=1:2", "expected BODY.KEY=LO:HI:N"),
    ("probe.a=1:2:3", "Cartesian state"),
    ("sun.m=0.5:1:2", "central body"),
    ("planet.e=0.5:1.5:3", "pixel planet.e=1: a parabolic orbit"),
])
def test_a_bad_axis_is_one_line_exit_2_and_writes_nothing(scenario, tmp_path, x_spec, message):
    out = tmp_path / "m"
    code, _, stderr = _map([str(scenario), "--x", x_spec, "--t-end", "10", "--indicator", "max_e", "-o", str(out)])
    assert code == 2
    assert stderr.count("\n") == 1 and stderr.startswith("orbitsim: error: ") and message in stderr, stderr
    assert not out.exists()


def test_a_scheme_the_ensemble_lacks_is_refused(tmp_path):
    path = tmp_path / "v.yaml"
    path.write_text(SCENARIO.replace("wisdom_holman", "rk4"), encoding="utf-8")
    code, _, stderr = _map([str(path), "--x", "planet.a=6:8:2", "--t-end", "10", "-o", str(tmp_path / "m")])
    assert code == 2 and stderr.count("\n") == 1
    assert "integrator 'rk4': a map runs an ensemble kernel, which exists for wisdom_holman, verlet, leapfrog, " \
           "leapfrog4, leapfrog6, leapfrog8 only" in stderr
    assert not (tmp_path / "m").exists()


def test_an_events_section_is_refused_not_ignored(tmp_path):
    # A pixel stops at its own escape (--escape-distance) or collision (radii); an events section asking
    # for something else (here: an escape at 50) would otherwise be silently dropped.
    path = tmp_path / "ev.yaml"
    path.write_text(SCENARIO.replace("bodies:", "events:\n  escape: {distance: 50, action: halt}\nbodies:"),
                    encoding="utf-8")
    code, _, stderr = _map([str(path), "--x", "planet.a=6:8:2", "--t-end", "10", "-o", str(tmp_path / "m")])
    assert code == 2 and stderr.count("\n") == 1, stderr
    assert "events: a map stops each pixel at its own escape (--escape-distance)" in stderr
    assert not (tmp_path / "m").exists()


LEAPFROG4 = SCENARIO.replace("integrator: wisdom_holman", "integrator: {name: leapfrog, order: 4}")


@pytest.mark.parametrize(("edit", "message"), [
    (lambda text: text.replace("dt: 0.5", "dt: 0.5\nsoftening: 0.01"), "softening: the ensemble kernel integrates "
                                                                       "unsoftened gravity; set softening: 0"),
    (lambda text: text + "forces:\n  - {force: gr_potential, source: sun, c: 100.0}\n",
     "forces: the ensemble kernel integrates gravity alone"),
    (lambda text: text + "".join(f"  - {{name: p{i}, m: 0, x: [{30 + i}, 0, 0], v: [0, 0.1, 0]}}\n"
                                 for i in range(44)),
     "bodies: the leapfrog4 ensemble takes at most 48 bodies per system (one all-pairs force kernel per pixel); "
     "the scenario has 49"),
])
def test_what_a_kick_drift_ensemble_cannot_honour_is_refused(tmp_path, edit, message):
    path = tmp_path / "lf.yaml"
    path.write_text(edit(LEAPFROG4), encoding="utf-8")
    code, _, stderr = _map([str(path), "--x", "planet.a=6:8:2", "--t-end", "10", "-o", str(tmp_path / "m")])
    assert code == 2 and stderr.count("\n") == 1 and message in stderr, stderr
    assert not (tmp_path / "m").exists()


@pytest.mark.slow  # compiles the map's leapfrog ensemble kernels (~100 s cold)
def test_a_leapfrog_map_records_its_scheme_and_resumes_bit_identically(tmp_path, monkeypatch):
    # leapfrog order 4 (the kernel tests/ensemble/test_kick_drift.py compiles too): a first run finds the
    # disk full at its second chunk, the same command with --resume finishes it, and every grid is the bits
    # of a map run straight through in chunks of another size
    import orbitsim.stability.store as store

    path = tmp_path / "lf.yaml"
    path.write_text(LEAPFROG4, encoding="utf-8")
    real_savez = np.savez
    calls = []

    def savez(file, **arrays):
        calls.append(1)
        if len(calls) == 2:
            raise OSError(errno.ENOSPC, "No space left on device", str(file.name))
        return real_savez(file, **arrays)

    monkeypatch.setattr(store.np, "savez", savez)
    out = tmp_path / "m"
    assert _map([str(path), *AXES, "--chunk", "2", "-o", str(out)])[0] == 4
    assert sorted(p.name for p in (out / "map.parts").iterdir()) == ["chunk-000000.npz", "plan.json"]
    monkeypatch.setattr(store.np, "savez", real_savez)
    code, stdout, stderr = _map([str(path), *AXES, "--chunk", "2", "--resume", "-o", str(out)])
    assert code == 0, stderr
    assert "6 pixels: 6 complete" in stdout
    straight = tmp_path / "s"
    assert _map([str(path), *AXES, "--chunk", "4", "-o", str(straight)])[0] == 0
    a, b = _grids(out / "map.h5"), _grids(straight / "map.h5")
    for name in a:
        assert np.array_equal(a[name], b[name], equal_nan=True), name
    with h5py.File(out / "map.h5", "r") as f:
        assert f.attrs["integrator"] == "leapfrog4"
    assert np.all(a["survival_time"] == 40.0)
    assert np.all(np.isfinite(a["megno"])) and np.all(a["megno"] > 0.0)  # from the leapfrog's variational equations
    assert np.all(a["energy_error"] < 1e-6)  # order 4 at dt = 0.5: far below the default bar
    assert np.all(a["max_e"][1] > a["max_e"][0])  # e0 = 0.3 stays above e0 = 0 over 40 time units
    wh = tmp_path / "wh"
    (tmp_path / "wh.yaml").write_text(SCENARIO, encoding="utf-8")
    assert _map([str(tmp_path / "wh.yaml"), *AXES, "-o", str(wh)])[0] == 0
    with h5py.File(wh / "map.h5", "r") as f:
        assert f.attrs["integrator"] == "wisdom_holman"
    assert not np.array_equal(_grids(wh / "map.h5")["megno"], a["megno"])  # another scheme, other bits
    info = CliRunner().invoke(cli, ["info", str(out / "map.h5")])
    assert info.exit_code == 0 and "leapfrog4 dt = 0.5" in info.stdout


def test_resume_without_a_killed_map_is_refused(scenario, tmp_path):
    code, _, stderr = _map([str(scenario), *AXES, "--resume", "-o", str(tmp_path / "m")])
    assert code == 2 and "no unfinished map" in stderr


def test_a_full_disk_is_one_line_and_keeps_the_finished_chunks(scenario, tmp_path, monkeypatch):
    import orbitsim.stability.store as store

    real_savez = np.savez
    calls = []

    def savez(file, **arrays):
        calls.append(1)
        if len(calls) == 2:  # the second chunk finds the disk full
            raise OSError(errno.ENOSPC, "No space left on device", str(file.name))
        return real_savez(file, **arrays)

    monkeypatch.setattr(store.np, "savez", savez)
    out = tmp_path / "m"
    code, _, stderr = _map([str(scenario), *AXES, "--chunk", "2", "-o", str(out)])
    assert code == 4, stderr  # orbitsim's exit code for an I/O error (orbitsim.cli.errors)
    assert stderr.count("\n") == 1 and "No space left on device" in stderr
    assert not (out / "map.h5").exists()
    parts = sorted(p.name for p in (out / "map.parts").iterdir())
    assert parts == ["chunk-000000.npz", "plan.json"]  # the finished chunk kept, no temporary left
    monkeypatch.setattr(store.np, "savez", real_savez)
    code, _, stderr = _map([str(scenario), *AXES, "--chunk", "2", "-o", str(out)])
    assert code == 0, stderr
    straight = tmp_path / "s"
    assert _map([str(scenario), *AXES, "-o", str(straight)])[0] == 0
    a, b = _grids(out / "map.h5"), _grids(straight / "map.h5")
    for name in a:
        assert np.array_equal(a[name], b[name], equal_nan=True), name


@pytest.mark.slow  # compiles the map's Wisdom-Holman lanes kernels (~100 s cold)
def test_a_map_killed_mid_way_is_finished_bit_identically(scenario, tmp_path):
    axes = ["--x", "planet.a=5.8:9.0:4", "--y", "planet.e=0:0.3:4", "--t-end", "4000", "--indicator", "max_e",
            "--quiet", "--threads", "1"]
    out = tmp_path / "killed"
    command = [sys.executable, "-m", "orbitsim", "map", str(scenario), *axes, "--chunk", "1", "-o", str(out)]
    proc = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    deadline = time.monotonic() + 300
    while time.monotonic() < deadline and proc.poll() is None:
        if out.joinpath("map.parts").is_dir() and len(list(out.joinpath("map.parts").glob("chunk-*.npz"))) >= 3:
            break
        time.sleep(0.005)
    assert proc.poll() is None, proc.stderr.read() if proc.stderr else ""
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    kept = sorted((out / "map.parts").glob("chunk-*.npz"))
    assert 3 <= len(kept) < 16
    assert not (out / "map.h5").exists()
    done = subprocess.run([*command[:-2], "--resume", "-o", str(out)], capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    straight = tmp_path / "straight"
    subprocess.run([*command[:-4], "--chunk", "5", "-o", str(straight)], check=True, capture_output=True, timeout=600)
    a, b = _grids(out / "map.h5"), _grids(straight / "map.h5")
    for name in a:
        assert np.array_equal(a[name], b[name], equal_nan=True), name


@pytest.mark.slow
def test_a_map_on_dask_workers_has_the_bits_of_a_local_one(scenario, tmp_path):
    from orbitsim.batch.cluster import ClusterPlan, open_client

    local = tmp_path / "local"
    assert _map([str(scenario), *AXES, "-o", str(local)])[0] == 0
    with open_client(None, ClusterPlan(workers=2, threads=1)) as client:
        address = client.scheduler.address
        code, _, stderr = _map([str(scenario), *AXES, "--chunk", "1", "--scheduler", address, "-o",
                                str(tmp_path / "dask")])
    assert code == 0, stderr
    a, b = _grids(local / "map.h5"), _grids(tmp_path / "dask" / "map.h5")
    for name in a:
        assert np.array_equal(a[name], b[name], equal_nan=True), name


@pytest.mark.slow
def test_a_killed_dask_worker_loses_no_pixel(scenario, tmp_path):
    import threading

    from orbitsim.batch.cluster import ClusterPlan, open_client

    axes = ["--x", "planet.a=7.0:8.0:4", "--y", "planet.e=0:0.3:3", "--t-end", "20000", "--quiet"]
    local = tmp_path / "local"
    assert _map([str(scenario), *axes, "-o", str(local)])[0] == 0
    out = tmp_path / "dask"
    with open_client(None, ClusterPlan(workers=2, threads=1)) as client:
        pids = list(client.run(os.getpid).values())
        outcome = {}
        runner = threading.Thread(target=lambda: outcome.update(result=_map(
            [str(scenario), *axes, "--chunk", "1", "--scheduler", client.scheduler.address, "-o", str(out)])))
        runner.start()
        deadline = time.monotonic() + 300
        while time.monotonic() < deadline and not list((out / "map.parts").glob("chunk-*.npz")):
            time.sleep(0.01)
        os.kill(pids[0], signal.SIGKILL)  # a worker dies mid-map; its nanny starts another
        assert not (out / "map.h5").exists()  # it died with chunks still to run (both workers were busy)
        runner.join(600)
    code, _, stderr = outcome["result"]
    assert code == 0, stderr
    a, b = _grids(local / "map.h5"), _grids(out / "map.h5")
    for name in a:
        assert np.array_equal(a[name], b[name], equal_nan=True), name


def test_a_massless_axis_body_gets_told_why_every_pixel_is_unreliable(scenario: Path, tmp_path: Path) -> None:
    # a bar below the massive bodies' own |dE/E| flags every pixel; the note must say it is one shared number
    code, _, err = _map([str(scenario), *AXES, "--max-energy-error", "1e-16", "-o", str(tmp_path / "m")])
    assert code == 0
    with h5py.File(tmp_path / "m" / "map.h5", "r") as f:
        assert f["unreliable"][()].all()
    assert "6 pixels have |dE/E| > 1e-16 (hatched); every one has" in err
    assert "the massive bodies' error" in err


def test_a_massless_varied_body_not_listed_last_gets_the_one_line_hint(scenario: Path, tmp_path: Path, capsys):
    loud = [a for a in AXES if a != "--quiet"]  # the hint is not printed with --quiet
    code, _, err = _map([str(scenario), *loud, "-o", str(tmp_path / "middle")])
    assert code == 0, err
    assert "planet is massless but not the last body" in err  # the probe comes after it
    # listed last: nothing to say (the plan alone: running it would compile the shared-massive kernel,
    # which tests/ensemble/test_restricted.py runs)
    from orbitsim.cli.map import _hint_shared_massive
    from orbitsim.scenario.yamlio import parse_yaml
    from orbitsim.stability.axes import parse_axis
    from orbitsim.stability.plan import make_plan

    for text, said in ((SCENARIO, True),
                       (SCENARIO.replace("  - {name: probe, m: 0, x: [20, 0, 0], v: [0, 0.2, 0]}\n", ""), False),
                       (LEAPFROG4, False)):  # the shared massive bodies are a Wisdom-Holman shortcut only
        path = tmp_path / "s.yaml"
        path.write_text(text, encoding="utf-8")
        doc, _ = parse_yaml(text, str(path))
        axes = [parse_axis("--x", "planet.a=7.0:8.0:3", doc), parse_axis("--y", "planet.e=0:0.3:2", doc)]
        _hint_shared_massive(make_plan(load_scenario(str(path)), doc, axes, 40.0, None, 256))
        assert ("not the last body" in capsys.readouterr().err) is said


def test_a_gpu_map_of_a_scheme_without_a_gpu_variational_kernel_is_refused_in_one_line(tmp_path: Path):
    # The GPU ensemble carries the variational equations for wisdom_holman only (its leapfrog and verlet run
    # without them), so a GPU map of a kick-drift scheme is refused when planned, before any pixel runs.
    from orbitsim.scenario.yamlio import parse_yaml
    from orbitsim.stability.axes import MapSpecError, parse_axis
    from orbitsim.stability.plan import make_plan

    path = tmp_path / "lf.yaml"
    path.write_text(LEAPFROG4, encoding="utf-8")
    doc, _ = parse_yaml(LEAPFROG4, str(path))
    axes = [parse_axis("--x", "planet.a=7.0:8.0:3", doc)]
    with pytest.raises(MapSpecError) as info:
        make_plan(load_scenario(str(path)), doc, axes, 40.0, None, 256, 0, "gpu")
    assert "\n" not in str(info.value) and "integrator 'leapfrog4'" in str(info.value)
    assert "wisdom_holman only" in str(info.value) and "without --device gpu" in str(info.value)
    assert make_plan(load_scenario(str(path)), doc, axes, 40.0, None, 256).integrator == "leapfrog4"  # the CPU runs it


def test_the_plans_start_states_are_the_ones_each_chunk_would_build(scenario: Path):
    # make_plan builds every pixel's start state once (its validation) and the chunks slice them; a Dask
    # task's plan travels without them and builds its own chunk: the same bits either way, the last,
    # partial chunk included (6 pixels in chunks of 4).
    from orbitsim.stability.plan import chunk_states, fingerprint, without_states

    plan = _plan(scenario, 4)
    light = without_states(plan)
    assert plan.states is not None and light.states is None and plan.states.masses.shape == (6, 5)
    assert fingerprint(light) == fingerprint(plan)  # derived data: resuming on Dask finds the same map
    for index in range(plan.n_chunks):
        for kept, built in zip(chunk_states(plan, index), chunk_states(light, index), strict=True):
            assert kept.shape[0] == (4 if index == 0 else 2)
            assert np.array_equal(kept, built)


def test_start_states_read_by_forked_readers_are_the_bits_of_one_process(scenario: Path):
    # A large map reads its start states in forked processes (make_plan's workers), four pixel ranges each:
    # states and the escape distance (from the farthest start) must be what one process reads, bit for bit.
    from orbitsim.scenario.yamlio import parse_yaml
    from orbitsim.stability.axes import parse_axis
    from orbitsim.stability.plan import make_plan

    doc, _ = parse_yaml(scenario.read_text(encoding="utf-8"), str(scenario))
    axes = [parse_axis("--x", "planet.a=7.0:8.0:5", doc), parse_axis("--y", "planet.e=0:0.3:4", doc)]
    one, forked = (make_plan(load_scenario(str(scenario)), doc, axes, 40.0, None, 4, workers=w) for w in (1, 2))
    assert one.states is not None and forked.states is not None and one.states.masses.shape == (20, 5)
    assert one.escape_distance == forked.escape_distance and np.isfinite(one.escape_distance)
    for a, b in zip(one.states, forked.states, strict=True):
        assert a.tobytes() == b.tobytes()


def test_a_bad_pixel_found_by_forked_readers_is_the_first_one_as_one_process_finds_it(scenario: Path):
    # e = 1.16 and 1.4 are not orbits for a > 0: pixels 12-17 are bad, in three of the eight ranges the two
    # readers take; the message names the first of them (a = 7, e = 1.16), the one a single reader meets.
    from orbitsim.scenario.yamlio import parse_yaml
    from orbitsim.stability.axes import MapSpecError, parse_axis
    from orbitsim.stability.plan import make_plan

    doc, _ = parse_yaml(scenario.read_text(encoding="utf-8"), str(scenario))
    axes = [parse_axis("--x", "planet.a=7.0:8.0:3", doc), parse_axis("--y", "planet.e=0.2:1.4:6", doc)]
    said = []
    for workers in (1, 2):
        with pytest.raises(MapSpecError) as info:
            make_plan(load_scenario(str(scenario)), doc, axes, 40.0, None, 4, workers=workers)
        said.append(str(info.value))
    assert said[0] == said[1] and said[0].startswith("pixel planet.a=7, planet.e=1.16: ") and "\n" not in said[0]


@pytest.mark.parametrize("x_spec", ["planet.a=7.0:8.0:3", "jupiter.a=5.0:5.4:3", "jupiter.m=0.0005:0.002:3"])
def test_a_pixel_reads_only_the_varied_bodies_with_the_bits_of_a_whole_read(scenario: Path, x_spec: str):
    # The pixels reread only the bodies from the first varied one on (the bodies before it read once); a
    # varied Jupiter is followed by Saturn and the planet, read again for every pixel: each pixel's state must
    # be, bit for bit, what the scenario reader gives the whole edited document (as pixels were read before).
    from orbitsim.scenario.bodies import read_bodies, shift_to_barycentre
    from orbitsim.scenario.fields import Fields
    from orbitsim.scenario.loader import TOP_KEYS
    from orbitsim.scenario.yamlio import parse_yaml
    from orbitsim.stability.axes import parse_axis
    from orbitsim.stability.plan import make_plan

    text = scenario.read_text(encoding="utf-8").replace("units: nbody", "units: nbody\nframe: barycentric")
    scenario.write_text(text, encoding="utf-8")
    doc, _ = parse_yaml(text, str(scenario))
    axes = [parse_axis("--x", x_spec, doc), parse_axis("--y", "planet.e=0:0.3:2", doc)]
    plan = make_plan(load_scenario(str(scenario)), doc, axes, 40.0, None, 4)
    assert plan.barycentric and plan.states is not None
    for pixel in range(plan.n_pixels):
        edited = dict(doc)
        edited["bodies"] = [dict(b) for b in doc["bodies"]]
        iy, ix = divmod(pixel, 3)
        axes[0].apply(edited["bodies"][axes[0].index], float(axes[0].values[ix]))
        axes[1].apply(edited["bodies"][axes[1].index], float(axes[1].values[iy]))
        m, x, v = read_bodies(Fields(edited, "", TOP_KEYS, "scenario"), plan.G, "nbody").arrays()
        x, v = shift_to_barycentre(m, x, v)
        assert np.array_equal(plan.states.masses[pixel], m)
        assert np.array_equal(plan.states.positions[pixel], x.T)
        assert np.array_equal(plan.states.velocities[pixel], v.T)
    assert len({plan.states.positions[p][0, plan.axes[0].index] for p in range(3)}) == 3  # the axis did vary the body


def test_ready_kernels_takes_the_chunks_path_so_a_chunk_then_compiles_nothing(scenario: Path):
    # The kernels a map's chunks call are made ready (loaded, or compiled on a first run) by running chunk
    # 0's pixels for no step: the same kernel choice and argument types as a chunk's, so no chunk compiles
    # anything after it (the last, partial chunk included), and the plan's start states are left as they were.
    from orbitsim._jit import CompileWatch, watch_compiles
    from orbitsim.stability.plan import ready_kernels, run_chunk

    plan = _plan(scenario, 4)
    before = [a.copy() for a in plan.states]
    ready_kernels(plan)
    assert all(a.tobytes() == b.tobytes() for a, b in zip(before, plan.states, strict=True))
    watch = CompileWatch()
    with watch_compiles(watch):
        results = [run_chunk(plan, index) for index in range(plan.n_chunks)]
    assert watch.count == 0
    assert [len(r.status) for r in results] == [4, 2] and all(np.all(r.stop_time == 40.0) for r in results)


def test_a_first_map_says_once_that_it_compiles_and_keeps_compiling_out_of_the_pixels_time(scenario: Path,
                                                                                        tmp_path: Path, monkeypatch):
    # A first run compiles while its kernels are readied and may compile again mid-map (a kernel only some
    # chunk needs). Both are Numba's compile events here, of known length (0.1 s in the set-up, 0.3 s in
    # chunk 1; a real first map compiles for ~45 s). The note comes once, before the first compilation;
    # map.h5 keeps both out of wall_time_s (the pixels' own time) and records them in compile_time_s and
    # setup_time_s.
    from numba.core import event

    import orbitsim.stability.driver as driver
    from orbitsim.stability.plan import ready_kernels

    plan = _plan(scenario, 2)
    ready_kernels(plan)  # this map's own kernels, loaded or compiled before the run: the run compiles only ours
    no_function = {"dispatcher": None, "args": None, "return_type": None}

    def compiling(seconds: float) -> None:
        with event.trigger_event("numba:compile", data=no_function):
            time.sleep(seconds)

    readied = []

    def ready_and_compile(p):
        ready_kernels(p)
        compiling(0.1)
        readied.append(p)

    spans = []

    def run_chunk(p, index, states=None):
        started = time.perf_counter()
        if index == 1:
            compiling(0.3)
        result = real_run_chunk(p, index, states)
        spans.append(time.perf_counter() - started)
        return result

    real_run_chunk = driver.run_chunk
    monkeypatch.setattr(driver, "ready_kernels", ready_and_compile)
    monkeypatch.setattr(driver, "run_chunk", run_chunk)
    notes = []
    data = driver.run_map(plan, tmp_path, max_energy_error=1e-6, indicator="max_e", attrs={}, on_compile=notes.append)
    assert notes == ["compiling the map's kernels for wisdom_holman (first run only)"]
    assert len(spans) == 3 and len(readied) == 1 and readied[0] is plan
    assert data["compile_time_s"] >= 0.4  # both compilations counted
    assert data["setup_time_s"] >= 0.1
    # without the mid-map compilation the pixels' time is less than the chunks' spans (0.1 s: the parts' writes)
    assert data["wall_time_s"] < sum(spans) - 0.2
    assert data["pixels_computed"] == 6 and np.all(data["status"] == 0)


def test_a_map_whose_kernels_are_ready_says_nothing_and_a_dask_map_readies_none_here(scenario: Path, tmp_path: Path,
                                                                                     monkeypatch):
    # A warm cache: nothing compiles, nothing is announced, compile_time_s is 0. On Dask the workers ready
    # their own kernels in their first chunk: the client readies none (run here by a stand-in for Dask).
    import orbitsim.stability.driver as driver
    from orbitsim.stability.plan import ready_kernels

    plan = _plan(scenario, 4)
    ready_kernels(plan)
    notes = []
    data = driver.run_map(plan, tmp_path / "warm", max_energy_error=1e-6, indicator="max_e", attrs={},
                          on_compile=notes.append)
    assert notes == [] and data["compile_time_s"] == 0.0 and data["setup_time_s"] > 0.0
    readied = []
    monkeypatch.setattr(driver, "ready_kernels", readied.append)
    monkeypatch.setattr(driver, "_on_dask", lambda p, todo, scheduler: driver._local(p, todo))
    dask = driver.run_map(plan, tmp_path / "dask", max_energy_error=1e-6, indicator="max_e", attrs={},
                          scheduler="tcp://stand-in:8786")
    assert readied == [] and dask["setup_time_s"] < 0.1  # 0.1 s: nothing runs in its set-up but two clock reads
    for name in ("status", "stop_time"):
        assert np.array_equal(dask[name], data[name])


def test_info_on_a_map_imports_no_numba(scenario: Path, tmp_path: Path) -> None:
    # orbitsim info reads map.h5 only: neither it nor the map driver it reads with may load numba
    out = tmp_path / "m"
    assert _map([str(scenario), *AXES, "-o", str(out)])[0] == 0
    code = (f"import sys\nfrom click.testing import CliRunner\nfrom orbitsim.cli.main import cli\n"
            f"result = CliRunner().invoke(cli, ['info', {str(out / 'map.h5')!r}])\n"
            f"assert result.exit_code == 0 and 'set-up before the pixels' in result.output, result.output\n"
            f"heavy = sorted(m for m in ('numba', 'matplotlib', 'dask', 'distributed') if m in sys.modules)\n"
            f"assert not heavy, heavy\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
