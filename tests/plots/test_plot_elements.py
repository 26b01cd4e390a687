"""``orbitsim plot --elements``: the figure, its default name, and what the user sees when the trace
has no (or a damaged) ``elements`` group.

The traces are made here: a normal trace from :class:`TraceWriter`, then the ``elements`` group
(datasets ``a e inc Omega omega f M``, each float64 (S, N), attribute ``primary``) added with h5py
in append mode, the layout a run with ``output.elements: true`` writes.
"""

from __future__ import annotations

import os
import subprocess
import sys
import types
from pathlib import Path

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

from orbitsim.cli.main import cli
from orbitsim.initial_conditions.elements import elements_to_cartesian
from orbitsim.io.trace import open_trace_summary
from orbitsim.io.trace_writer import TraceWriter
from orbitsim.physics.orbital_elements import ELEMENT_NAMES, osculating_elements
from orbitsim.plots.elements import ELEMENTS_GROUP, _gapped, draw_elements, read_elements

G = 4.0 * np.pi**2  # au-yr-msun
PNG = b"\x89PNG\r\n\x1a\n"


def _states(n_samples: int, n_extra: int) -> tuple[list[str], np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A star, a planet, a comet on a hyperbola, and ``n_extra`` test particles; the planet is
    removed (NaN) for the second half of the samples, as an events run stores a merged body."""
    names = ["sun", "planet", "comet", *(f"rock{k}" for k in range(n_extra))]
    masses = np.concatenate([[1.0, 1e-3, 0.0], np.zeros(n_extra)])
    orbits = [(1.0, 0.2, 5.0), (-2.0, 1.4, 40.0), *((1.5 + 0.1 * k, 0.1, 3.0 * k) for k in range(n_extra))]
    time = np.linspace(0.0, 3.0, n_samples)
    pos = np.zeros((n_samples, len(names), 3))
    vel = np.zeros_like(pos)
    for i, (a, e, inc) in enumerate(orbits, start=1):
        n = np.sqrt(G * (1.0 + masses[i]) / abs(a) ** 3)
        for s, t in enumerate(time):  # Kepler orbits about the fixed sun: M advances as n t
            pos[s, i], vel[s, i] = elements_to_cartesian(G * (1.0 + masses[i]), a, e, inc, 30.0, 60.0,
                                                         M=np.degrees(n * t) - (0.0 if e < 1.0 else 30.0))
    pos[n_samples // 2:, 1] = np.nan
    vel[n_samples // 2:, 1] = np.nan
    return names, masses, time, pos, vel


def make_trace(path: Path, *, n_samples: int = 41, n_extra: int = 0, elements: bool = True,
               primary: str = "heaviest") -> Path:
    """A complete trace of :func:`_states`, with the ``elements`` group when asked."""
    names, masses, time, pos, vel = _states(n_samples, n_extra)
    attrs = {"scenario_name": "elements_demo", "integrator": "leapfrog", "dt": 0.01, "units": "au-yr-msun",
             "G": G, "softening": 0.0}
    writer = TraceWriter(path, attrs=attrs, names=names, masses=masses, n_bodies=len(names), record_positions=True)
    zeros = np.zeros(n_samples)
    writer.append(types.SimpleNamespace(
        time=time, step=np.arange(n_samples) * 100, kinetic=zeros + 1.0, potential=zeros - 2.0,
        energy=-1.0 - 1e-12 * np.arange(n_samples), momentum=np.zeros((n_samples, 3)),
        angular_momentum=np.zeros((n_samples, 3)), positions=pos, velocities=vel))
    writer.close()
    if elements:
        about = primary if primary in ("heaviest", "jacobi") else names.index(primary)  # a name is stored
        el = osculating_elements(masses, pos, vel, G, about)
        with h5py.File(path, "a") as f:
            group = f.create_group(ELEMENTS_GROUP)
            group.attrs["primary"] = primary
            for name in ELEMENT_NAMES:
                group.create_dataset(name, data=el[name])
    return path


def invoke(*args: str) -> tuple[int, str, str]:
    result = CliRunner().invoke(cli, list(args))
    assert "Traceback" not in result.output
    return result.exit_code, result.stdout, result.stderr


def test_elements_figure_is_written_with_no_warnings(tmp_path: Path) -> None:
    trace = make_trace(tmp_path / "run.h5")
    figure = tmp_path / "elements.png"
    # A real process: anything matplotlib (or numpy) prints lands on its stderr, which must stay empty.
    env = {**os.environ, "PYTHONWARNINGS": "default", "MPLBACKEND": "Agg"}
    proc = subprocess.run([sys.executable, "-m", "orbitsim", "plot", str(trace), "--elements", "-o", str(figure)],
                          capture_output=True, text=True, env=env, timeout=300, check=False)
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr == ""
    assert proc.stdout == f"wrote {figure}\n"
    assert figure.read_bytes()[:8] == PNG


@pytest.mark.filterwarnings("error")
@pytest.mark.parametrize("primary", ["heaviest", "jacobi", "sun"])
def test_default_name_formats_and_force(tmp_path: Path, primary: str) -> None:
    trace = make_trace(tmp_path / "run.h5", primary=primary)
    code, out, err = invoke("plot", str(trace), "--elements")
    default = tmp_path / "run_elements.png"  # beside, not over, the figure of a plain `plot`
    assert (code, err) == (0, "") and out == f"wrote {default}\n" and default.read_bytes()[:8] == PNG
    code, _, err = invoke("plot", str(trace), "--elements")
    assert code == 2 and "use --force" in err and err.count("\n") == 1
    assert invoke("plot", str(trace), "--elements", "--force")[0] == 0
    assert invoke("plot", str(trace), "--elements", "-o", str(tmp_path / "e.pdf"))[0] == 0
    assert (tmp_path / "e.pdf").read_bytes()[:5] == b"%PDF-"
    assert invoke("plot", str(trace))[0] == 0 and (tmp_path / "run.png").exists()  # the plain plot still works


def test_no_elements_group_is_one_line_before_any_drawing(tmp_path: Path) -> None:
    trace = make_trace(tmp_path / "run.h5", elements=False)
    code, out, err = invoke("plot", str(trace), "--elements")
    assert code == 2 and out == ""
    assert err == f"orbitsim: error: {trace}: has no orbital elements; run with output.elements: true\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.h5"]
    # Checked before the existing figure is even considered: the fix offered is the real one.
    (tmp_path / "run_elements.png").write_bytes(b"old")
    assert invoke("plot", str(trace), "--elements")[2] == err
    assert (tmp_path / "run_elements.png").read_bytes() == b"old"


@pytest.mark.parametrize(("damage", "fragment"), [
    (lambda g: g.__delitem__("M"), "dataset 'elements/M' is missing"),
    (lambda g: (g.__delitem__("e"), g.create_dataset("e", data=np.zeros((3, 3)))),
     "dataset 'elements/e' has shape (3, 3), expected (41, 3)"),
])
def test_damaged_elements_group_is_one_line(tmp_path: Path, damage, fragment: str) -> None:
    trace = make_trace(tmp_path / "run.h5")
    with h5py.File(trace, "a") as f:
        damage(f[ELEMENTS_GROUP])
    code, _, err = invoke("plot", str(trace), "--elements")
    assert code == 2 and err.count("\n") == 1
    assert err.startswith(f"orbitsim: error: {trace}: damaged trace: ") and fragment in err
    assert not (tmp_path / "run_elements.png").exists()


def test_read_skips_all_nan_bodies_strides_and_caps(tmp_path: Path) -> None:
    trace = make_trace(tmp_path / "run.h5", n_samples=101, n_extra=20)
    summary = open_trace_summary(trace)
    data = read_elements(str(trace), summary, max_samples=30, max_bodies=8)
    # The sun is the primary (NaN throughout) and is left out; the planet, removed halfway, stays.
    assert data["bodies"] == ["planet", "comet", *(f"rock{k}" for k in range(6))]
    assert data["n_bodies"] == 23 and data["primary"] == "heaviest"
    assert data["time"][0] == 0.0 and data["time"][-1] == 3.0 and data["time"].size <= 31  # the last sample kept
    with h5py.File(trace, "r") as f:
        rows = np.searchsorted(f["time"][()], data["time"])
        for name in ELEMENT_NAMES:
            np.testing.assert_array_equal(data["elements"][name], f[ELEMENTS_GROUP][name][()][rows][:, 1:9])
    everything = read_elements(str(trace), summary, max_samples=4000, max_bodies=100)
    assert len(everything["bodies"]) == 22 and everything["time"].size == 101


def test_angles_are_broken_where_they_wrap() -> None:
    t = np.arange(6.0)
    t2, y = _gapped(t, np.array([170.0, 179.0, -179.0, -170.0, np.inf, 10.0]), wraps=True)
    assert np.isnan(y[2]) and np.isnan(t2[2]) and y.size == 7  # one gap, at the wrap from 179 to -179
    assert np.isnan(y[-2])  # inf (a on an exact parabola) is not drawn
    _, y = _gapped(t, np.array([1.0, 200.0, 1.0, 2.0, 3.0, 4.0]), wraps=False)
    assert y.size == 6  # a is not an angle: no gaps


@pytest.mark.filterwarnings("error")
@pytest.mark.parametrize("n_extra", [0, 20])
def test_draw_in_process_without_warnings(tmp_path: Path, n_extra: int) -> None:
    """Many bodies (no legend) and few (a legend); warnings would be errors here."""
    trace = make_trace(tmp_path / "run.h5", n_extra=n_extra)
    data = read_elements(str(trace), open_trace_summary(trace), 4000, 100)
    target = tmp_path / "e.svg"
    draw_elements(data, target, "title", "au", "yr", max_legend=12)
    assert target.read_text()[:100].lstrip().startswith("<?xml")
