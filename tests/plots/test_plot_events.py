"""``orbitsim plot --events``: the run's events marked on the |dE/E| panel and the element panels;
and the orbit panel's count of bodies at the last sample after merges.

The trace: two bodies thrown at each other merge near t = 1.88 while a distant third stays (as in
test_info_events.py), verlet, with orbital elements recorded about the third.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

from orbitsim.cli.main import cli

HEAD_ON = """\
name: head_on
integrator: verlet
dt: 0.01
steps: 300
output: {every: 10, elements: true, primary: star}
events:
  collisions: {detect: line, resolve: merge}
bodies:
  - {name: left, m: 1.0e-3, r: 0.05, x: [-1, 0, 0], v: [0.5, 0, 0]}
  - {name: right, m: 1.0e-3, r: 0.05, x: [1, 0, 0], v: [-0.5, 0, 0]}
  - {name: star, m: 1.0, x: [0, 5, 0], v: [0, 0, 0]}
"""
PLAIN = HEAD_ON.replace("events:\n  collisions: {detect: line, resolve: merge}\n", "")


def invoke(*args: str) -> tuple[int, str, str]:
    result = CliRunner().invoke(cli, list(args))
    assert "Traceback" not in result.output, result.output
    return result.exit_code, result.stdout, result.stderr


@pytest.fixture(scope="module")
def traces(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    folder = tmp_path_factory.mktemp("plot_events")
    out = {}
    for name, text in (("merge", HEAD_ON), ("plain", PLAIN)):
        (folder / f"{name}.yaml").write_text(text, encoding="utf-8")
        out[name] = folder / f"{name}.h5"
        code, _, err = invoke("run", str(folder / f"{name}.yaml"), "-o", str(out[name]), "-q")
        assert code == 0, err
    return out


def collision_time(trace: Path) -> float:
    with h5py.File(trace, "r") as f:
        (time,) = f["events/time"][()]
    return float(time)


@pytest.fixture
def saved_figures(monkeypatch: pytest.MonkeyPatch) -> list[Any]:
    """Every matplotlib figure saved while the test runs (the CLI closes them after saving)."""
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure

    saved: list[Any] = []
    original = Figure.savefig

    def keep(self: Any, *args: Any, **kwargs: Any) -> Any:
        saved.append(self)
        return original(self, *args, **kwargs)

    monkeypatch.setattr(Figure, "savefig", keep)
    return saved


def marks(ax: Any) -> dict[str, Any]:
    """The event marks on ``ax``, by their gid."""
    return {c.get_gid(): c for c in ax.collections if str(c.get_gid()).startswith("events:")}


def test_the_energy_panel_marks_the_collision(traces: dict[str, Path], tmp_path: Path,
                                              saved_figures: list[Any]) -> None:
    target = tmp_path / "m.png"
    code, out, err = invoke("plot", str(traces["merge"]), "--events", "-o", str(target))
    assert code == 0, err
    assert out == f"wrote {target} (1 collision events marked)\n" and target.read_bytes()[:4] == b"\x89PNG"
    (fig,) = saved_figures
    orbit, energy = fig.axes[:2]
    assert marks(orbit) == {}
    (mark,) = marks(energy).values()
    assert mark.get_gid() == "events:collision" and mark.get_label() == "collision (1)"
    (segment,) = mark.get_segments()
    assert segment[:, 0].tolist() == [collision_time(traces["merge"])] * 2  # a vertical line at the event's time
    assert [t.get_text() for t in energy.get_legend().get_texts()] == ["collision (1)"]
    assert energy.get_yscale() == "log"


def test_every_element_panel_marks_it_and_one_legend_names_it(traces: dict[str, Path], tmp_path: Path,
                                                              saved_figures: list[Any]) -> None:
    target = tmp_path / "e.png"
    code, out, err = invoke("plot", str(traces["merge"]), "--elements", "--events", "-o", str(target))
    assert code == 0, err
    assert out == f"wrote {target} (1 collision events marked)\n"
    (fig,) = saved_figures
    panels = fig.axes
    assert len(panels) == 7
    for ax in panels:
        (mark,) = marks(ax).values()
        assert mark.get_segments()[0][0, 0] == collision_time(traces["merge"])
    assert [ax.get_legend() is not None for ax in panels] == [False] * 6 + [True]
    figure_legend = [t.get_text() for legend in fig.legends for t in legend.get_texts()]
    assert "left" in figure_legend and not any("collision" in text for text in figure_legend)


def test_without_events_the_figures_have_no_marks(traces: dict[str, Path], tmp_path: Path,
                                                  saved_figures: list[Any]) -> None:
    code, out, _ = invoke("plot", str(traces["merge"]), "-o", str(tmp_path / "m.png"))
    assert code == 0 and out == f"wrote {tmp_path / 'm.png'}\n"
    assert all(marks(ax) == {} for ax in saved_figures[0].axes)


def test_marks_change_no_axis_range() -> None:
    """A mark spans the panel, at its time only: the axes' data limits are the curve's alone, and a
    log axis never sees the panel-relative 0 of the line's foot."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from orbitsim.plots.event_marks import mark_events

    fig, ax = plt.subplots()
    ax.semilogy([0.0, 10.0], [1e-12, 1e-9])
    before = (ax.get_xlim(), ax.get_ylim())
    drawn = mark_events(ax, {"encounter": np.array([2.0, 3.0, 7.5]), "escape": np.array([9.0])})
    assert [c.get_label() for c in drawn] == ["encounter (3)", "escape (1)"]
    assert (ax.get_xlim(), ax.get_ylim()) == before
    assert [s[0, 0] for s in drawn[0].get_segments()] == [2.0, 3.0, 7.5]
    plt.close(fig)


@pytest.mark.parametrize(("args", "words"), [
    (["--events"], "has no events to mark: the run had no events: section"),
    (["--events", "--resonance", "2:1"], "--events marks the |dE/E| and --elements figures; --resonance draws "
                                         "neither"),
])
def test_errors_are_one_line_before_any_drawing(traces: dict[str, Path], tmp_path: Path, args: list[str],
                                                words: str) -> None:
    target = tmp_path / "x.png"
    code, out, err = invoke("plot", str(traces["plain"]), "-o", str(target), *args)
    assert code == 2 and out == "" and err.count("\n") == 1 and words in err, err
    assert not target.exists()


def test_the_last_sample_counts_the_bodies_still_in_the_run() -> None:
    """Beyond MAX_TRACKS bodies the orbit panel shows the last sample: merged bodies are NaN there."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from orbitsim.cli.plot import _draw_orbits

    positions = np.random.default_rng(1).normal(size=(1, 203, 3))
    positions[0, [5, 70]] = np.nan
    fig, ax = plt.subplots()
    _draw_orbits(ax, {"positions": positions, "names": [f"p{k}" for k in range(203)]}, "au")
    assert ax.get_title() == "positions of 201 bodies at the last sample (2 of 203 left the run)"
    positions[0, [5, 70]] = 0.0
    ax.clear()
    _draw_orbits(ax, {"positions": positions, "names": [f"p{k}" for k in range(203)]}, "au")
    assert ax.get_title() == "positions of 203 bodies at the last sample"
    plt.close(fig)


def test_export_help_says_the_clock_goes_on_from_the_sample() -> None:
    code, out, _ = invoke("export", "--help")
    text = " ".join(out.split())
    assert code == 0 and "restarts at 0" not in text
    assert "its t_start is the sample's time" in text
    assert "who merged into whom" in text
