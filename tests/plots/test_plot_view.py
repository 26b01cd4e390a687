"""``orbitsim plot --view``: the orbit panel on another plane, or in 3-D."""

from __future__ import annotations

from pathlib import Path

import pytest
from click.testing import CliRunner

from orbitsim.cli.main import cli


@pytest.fixture(scope="module")
def trace(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("view") / "lesson.h5"
    result = CliRunner().invoke(cli, ["run", "lesson", "-o", str(path), "-q"], catch_exceptions=False)
    assert result.exit_code == 0, result.output
    return path


@pytest.mark.parametrize("view", ["xy", "xz", "yz", "3d"])
def test_every_view_draws_its_axes(trace: Path, tmp_path: Path, view: str) -> None:
    import matplotlib.pyplot as plt

    from orbitsim.cli.plot import VIEW_AXES, _draw, _read
    from orbitsim.io.trace import open_trace_summary

    summary = open_trace_summary(str(trace))
    out = tmp_path / f"{view}.png"
    _draw(_read(str(trace), summary), summary["attrs"], out, view)
    assert out.stat().st_size > 10_000
    result = CliRunner().invoke(cli, ["plot", str(trace), "-o", str(tmp_path / "cli.png"), "--view", view])
    assert result.exit_code == 0, result.output
    assert len(VIEW_AXES[view]) == (3 if view == "3d" else 2)
    plt.close("all")


def test_the_labels_name_the_view_coordinates(trace: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from orbitsim.cli.plot import _draw_orbits, _read
    from orbitsim.io.trace import open_trace_summary

    data = _read(str(trace), open_trace_summary(str(trace)))
    fig, ax = plt.subplots()
    _draw_orbits(ax, data, "au", "yz")
    assert ax.get_xlabel().startswith("y") and ax.get_ylabel().startswith("z")
    assert "y-z" in ax.get_title()
    # The lesson's orbit lies in the x-y plane: seen edge-on, its z extent is nothing next to y's.
    ys, zs = data["positions"][:, 1, 1], data["positions"][:, 1, 2]
    assert abs(zs).max() < 1e-6 * abs(ys).max()
    plt.close(fig)


def test_an_unknown_view_is_one_line(trace: Path, tmp_path: Path) -> None:
    result = CliRunner().invoke(cli, ["plot", str(trace), "-o", str(tmp_path / "x.png"), "--view", "side"])
    assert result.exit_code == 2 and "--view" in result.output
    assert len(result.output.strip().splitlines()) == 1
    assert not (tmp_path / "x.png").exists()
