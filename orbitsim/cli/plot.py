"""``orbitsim plot``: orbits on the x-y plane and |dE/E| against time, in one figure; or, with
``--elements``, every body's osculating elements against time
(:mod:`orbitsim.plots.elements`); or, with ``--resonance P:Q``, a pair's resonant angles
and period ratio (:mod:`orbitsim.plots.resonance`)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import click

from orbitsim.cli.errors import fail, reports_errors
from orbitsim.cli.options import OneLineUsageError, force_option, trace_argument

#: Samples read for the orbit panel at most (strided); enough for a smooth curve.
MAX_PLOT_SAMPLES = 4000
#: Up to this many bodies each gets a track; beyond it, the last sample is drawn as points.
MAX_TRACKS = 100
#: Bodies named in the legend at most.
MAX_LEGEND = 12


@click.command("plot")
@trace_argument()
@click.option("-o", "--output", type=click.Path(), default=None,  # a directory is refused in one line below
              help="Figure file; the format follows the suffix (.png, .pdf, .svg). Default: the trace's "
                   "name with .png. Example: -o orbit.png")
@click.option("--elements", is_flag=True,
              help="Draw every body's osculating orbital elements (a, e, inc, Omega, omega, f, M) against "
                   "time, one panel each, instead; the run must have recorded them (output.elements: true). "
                   "Default figure: the trace's name with _elements.png. Example: --elements")
@click.option("--resonance", default=None, metavar="P:Q",
              help="Draw the P:Q resonant angles of two bodies (P lambda_out - Q lambda_in - (P-Q) varpi) and "
                   "their period ratio against time, from the recorded elements (output.elements: true). "
                   "Default figure: the trace's name with _resonance.png. Example: --resonance 2:1")
@click.option("--pair", default=None, metavar="INNER,OUTER",
              help="With --resonance: the two bodies (default: the only two with elements). Example: --pair b,c")
@click.option("--view", type=click.Choice(["xy", "xz", "yz", "3d"]), default="xy", show_default=True,
              help="The orbit panel's projection: a coordinate plane, or a 3-D view, so inclined systems are "
                   "not squashed into x-y. Example: --view xz")
@click.option("--events", "show_events", is_flag=True,
              help="Mark the run's events (collisions, encounters, escapes, unresolved steps) as vertical lines "
                   "on the |dE/E| panel, or with --elements on every element panel, one colour per kind; the run "
                   "must have had an events: section. Example: --events")
@click.option("--indicator", default=None, metavar="NAME",
              help="For a map file (orbitsim map): the indicator to draw (megno, lyapunov_time, survival_time, "
                   "max_e, delta_a, energy_error; default: the one map.png shows). Example: --indicator max_e")
@force_option()
@reports_errors
def command(trace: str, output: str | None, elements: bool, resonance: str | None, pair: str | None,
            view: str, show_events: bool, indicator: str | None, force: bool) -> None:
    """Plot TRACE.h5: orbits projected on x-y (or --view xz, yz, 3d), and |dE/E| against time on a log axis.

    With --elements: each body's a, e, inc, Omega, omega, f and M against time, about the
    primary the run recorded them for (heaviest body, Jacobi, or a named body).
    With --events: the run's events marked on the |dE/E| (or element) panels.

    \b
    Examples:
      orbitsim plot two_body_circular.h5
      orbitsim plot run.h5 -o run.pdf --force
      orbitsim plot kozai.h5 --elements
      orbitsim plot disc.h5 --elements --events
      orbitsim plot resonance_capture.h5 --resonance 2:1
      orbitsim plot js/map.h5 --indicator max_e -o js_max_e.png

    A map file (orbitsim map) is drawn as its map: --indicator picks the grid.
    """
    from orbitsim.io.trace import open_trace_summary
    from orbitsim.stability.store import is_map_file

    if is_map_file(trace):
        if elements or resonance or show_events:
            raise OneLineUsageError(f"{trace} is a map file: --elements, --resonance and --events draw traces")
        _plot_map(trace, output, indicator, force)
        return
    if indicator is not None:
        raise OneLineUsageError(f"--indicator draws a map file (orbitsim map); {trace} is not one")

    stem = Path(trace).stem
    spec = _check_resonance(resonance, pair, elements)
    if show_events and spec:
        raise OneLineUsageError("--events marks the |dE/E| and --elements figures; --resonance draws neither")
    suffix = "_elements.png" if elements else "_resonance.png" if spec else ".png"
    default = Path(trace).with_name(f"{stem}{suffix}")
    target = Path(output) if output is not None else default
    _check_figure_path(output or str(target), stem)  # before the trace is read
    summary = open_trace_summary(trace)  # checks the format before anything is drawn
    if elements or spec:
        from orbitsim.plots.elements import check_elements

        check_elements(summary)  # no elements group: one line, before any drawing
    events = None
    if show_events:
        from orbitsim.plots.event_marks import read_event_times

        events = read_event_times(trace)  # no events table: one line, before any drawing
    if target.exists() and not force:
        fail(f"{target}: figure already exists; use --force to overwrite it")
    if not target.parent.is_dir():
        fail(f"{target}: directory {target.parent} does not exist")
    if elements:
        _plot_elements(trace, summary, target, events)
    elif spec:
        _plot_resonance(trace, summary, target, spec, pair)
    else:
        _draw(_read(trace, summary), summary["attrs"], target, view, events)
    marked = "" if events is None else f" ({_marked(events)})"
    click.echo(f"wrote {target}{marked}")


def _plot_map(trace: str, output: str | None, indicator: str | None, force: bool) -> None:
    """Draw one indicator of a map file (default figure: ``<map>_<indicator>.png``)."""
    from orbitsim.stability.driver import read_map
    from orbitsim.stability.figure import INDICATOR_LABELS, draw_map

    data = read_map(trace)
    name = indicator or "megno"
    if name not in INDICATOR_LABELS:
        raise OneLineUsageError(f"--indicator {name!r}: not an indicator; choose one of {', '.join(INDICATOR_LABELS)}")
    if indicator is None and not np_any_finite(data["indicators"][name]):
        name = "max_e"  # a map without variational equations has no MEGNO to draw
    target = Path(output) if output is not None else Path(trace).with_name(f"{Path(trace).stem}_{name}.png")
    _check_figure_path(str(target), Path(trace).stem)
    if target.exists() and not force:
        fail(f"{target}: figure already exists; use --force to overwrite it")
    if not target.parent.is_dir():
        fail(f"{target}: directory {target.parent} does not exist")
    draw_map(target, data, name)
    click.echo(f"wrote {target} ({name})")


def np_any_finite(values: Any) -> bool:
    import numpy as np

    return bool(np.isfinite(np.asarray(values, dtype=float)).any())


def _marked(events: dict[str, Any]) -> str:
    """``2 collision, 13 encounter events marked`` or ``no events were logged``."""
    if not events:
        return "no events were logged"
    return ", ".join(f"{t.size} {kind}" for kind, t in events.items()) + " events marked"


def _plot_elements(trace: str, summary: dict[str, Any], target: Path, events: dict[str, Any] | None = None) -> None:
    from orbitsim.plots.elements import draw_elements, read_elements

    data = read_elements(trace, summary, MAX_PLOT_SAMPLES, MAX_TRACKS)
    length, time_unit = _units(summary["attrs"])
    draw_elements(data, target, _title(summary["attrs"], target, time_unit), length, time_unit, MAX_LEGEND,
                  events)


def _check_resonance(resonance: str | None, pair: str | None, elements: bool) -> tuple[int, int] | None:
    """The parsed P:Q, or None; a bad spec or a clash of options is one usage line."""
    if resonance is None:
        if pair is not None:
            raise OneLineUsageError("--pair needs --resonance P:Q")
        return None
    if elements:
        raise OneLineUsageError("--elements and --resonance draw different figures; give one")
    from orbitsim.plots.resonance import parse_resonance

    try:
        return parse_resonance(resonance)
    except ValueError as err:
        raise OneLineUsageError(f"--resonance: {err}") from None


def _plot_resonance(trace: str, summary: dict[str, Any], target: Path, spec: tuple[int, int],
                    pair: str | None) -> None:
    from orbitsim.plots.elements import read_elements
    from orbitsim.plots.resonance import draw_resonance, pick_pair

    data = read_elements(trace, summary, MAX_PLOT_SAMPLES, MAX_TRACKS)
    try:
        columns = pick_pair(data["bodies"], data["elements"]["a"], pair)
    except ValueError as err:
        raise OneLineUsageError(f"{trace}: {err}") from None
    _, time_unit = _units(summary["attrs"])
    draw_resonance(data, spec, columns, target, _title(summary["attrs"], target, time_unit), time_unit)


def figure_formats() -> list[str]:
    """The file suffixes (without the dot) matplotlib can write a figure as."""
    from matplotlib.backend_bases import FigureCanvasBase

    return sorted(FigureCanvasBase.get_supported_filetypes())


def _check_figure_path(given: str, stem: str) -> None:
    """Refuse a directory, or a suffix matplotlib cannot write (``x.mp4``), in one line.

    A name with no suffix is refused too: matplotlib would write ``name.png``, not the file asked for.
    """
    target = Path(given)
    if target.is_dir():
        raise OneLineUsageError(f"{given}: is a directory; give a file name such as {target / stem}.png")
    suffix = target.suffix.lower().lstrip(".")
    formats = figure_formats()
    if suffix not in formats:
        what = f"cannot write .{suffix} figures" if suffix else "needs a suffix to choose the figure format"
        raise OneLineUsageError(f"{given}: matplotlib {what}; give one of {', '.join('.' + f for f in formats)}")


def _read(path: str, summary: dict[str, Any]) -> dict[str, Any]:
    """The small series in full, positions strided to at most :data:`MAX_PLOT_SAMPLES`."""
    import h5py
    import numpy as np

    with h5py.File(path, "r") as f:
        data = {"time": f["time"][()], "energy_error": f["energy_error"][()],
                "names": list(f["bodies/names"].asstr()[()]), "positions": None}
        n = summary["n_samples"]
        if "positions" in f and n:
            stride = max(1, -(-n // MAX_PLOT_SAMPLES))
            rows = np.arange(0, n, stride)
            if rows[-1] != n - 1:
                rows = np.append(rows, n - 1)  # always show where the run ended
            bodies = f["positions"].shape[1]
            if bodies > MAX_TRACKS:
                data["positions"] = f["positions"][n - 1 : n, :, :]
            else:
                data["positions"] = f["positions"][rows, :, :]
    return data


def _units(attrs: dict[str, Any]) -> tuple[str, str]:
    from orbitsim.units import UNIT_SYSTEMS

    system = UNIT_SYSTEMS.get(str(attrs.get("units", "")))
    return (system.length, system.time) if system else ("length", "time")


def _draw(data: dict[str, Any], attrs: dict[str, Any], target: Path, view: str = "xy",
          events: dict[str, Any] | None = None) -> None:
    import matplotlib

    matplotlib.use("Agg")  # files only: no display needed, and no GUI toolkit imported
    import matplotlib.pyplot as plt

    length, time_unit = _units(attrs)
    fig = plt.figure(figsize=(12, 5.5), layout="constrained")
    ax_orbit = fig.add_subplot(1, 2, 1, projection="3d" if view == "3d" else None)
    ax_energy = fig.add_subplot(1, 2, 2)
    _draw_orbits(ax_orbit, data, length, view)
    _draw_energy(ax_energy, data, time_unit)
    if events:
        from orbitsim.plots.event_marks import mark_events

        mark_events(ax_energy, events)
    fig.suptitle(_title(attrs, target, time_unit))
    fig.savefig(target, dpi=120)
    plt.close(fig)


def _title(attrs: dict[str, Any], target: Path, time_unit: str) -> str:
    """Scenario, integrator and dt, and the status when it is not ``complete``."""
    status = attrs.get("status", "?")
    title = (f"{attrs.get('scenario_name', target.stem)}: {attrs.get('integrator', '?')}, "
             f"dt = {attrs.get('dt', float('nan')):.4g} {time_unit}")
    return title if status == "complete" else f"{title} ({status})"


#: ``--view``: the coordinates the orbit panel shows.
VIEW_AXES = {"xy": (0, 1), "xz": (0, 2), "yz": (1, 2), "3d": (0, 1, 2)}


def _draw_orbits(ax: Any, data: dict[str, Any], length: str, view: str = "xy") -> None:
    axes = VIEW_AXES[view]
    pos = data["positions"]
    for own, axis in zip("xyz", axes, strict=False):  # matplotlib's x, y (z) show the view's coordinates
        getattr(ax, f"set_{own}label")(f"{'xyz'[axis]} [{length}]")
    if pos is None or pos.shape[0] == 0:
        ax.text(0.5, 0.5, "positions were not recorded", ha="center", va="center", transform=ax.transAxes)
        ax.set_title("orbits")
        return
    names = data["names"]
    if pos.shape[0] == 1:  # many bodies: one snapshot
        import numpy as np

        ax.plot(*(pos[0, :, a] for a in axes), ".", ms=1.5)
        present = int(np.count_nonzero(np.all(np.isfinite(pos[0]), axis=1)))  # merged or removed: NaN rows
        gone = pos.shape[1] - present
        ax.set_title(f"positions of {present} bodies at the last sample"
                     + (f" ({gone} of {pos.shape[1]} left the run)" if gone else ""))
    else:
        for i in range(pos.shape[1]):
            ax.plot(*(pos[:, i, a] for a in axes), lw=0.8, label=names[i] if i < MAX_LEGEND else None)
        ax.set_title("orbits in 3-D" if view == "3d" else f"orbits projected on {view[0]}-{view[1]}")
        if len(names) <= MAX_LEGEND:
            ax.legend(loc="best", fontsize="small")
    if view == "3d":
        _cube(ax, pos)
    else:
        ax.set_aspect("equal", adjustable="datalim")


def _cube(ax: Any, pos: Any) -> None:
    """Equal scales on a 3-D axes (mplot3d has no equal aspect with ``datalim``): a cube around the data."""
    import numpy as np

    lo, hi = np.nanmin(pos, axis=(0, 1)), np.nanmax(pos, axis=(0, 1))
    centre, half = (lo + hi) / 2, max(float(np.max(hi - lo)) / 2, 1e-300)
    for own, c in zip("xyz", centre, strict=True):
        getattr(ax, f"set_{own}lim")(c - half, c + half)
    ax.set_box_aspect((1, 1, 1))


def _draw_energy(ax: Any, data: dict[str, Any], time_unit: str) -> None:
    import numpy as np

    t, err = data["time"], np.abs(data["energy_error"])
    shown = err > 0  # the first sample (and any exact one) has no place on a log axis
    ax.set_xlabel(f"time [{time_unit}]")
    ax.set_ylabel("|dE/E|")
    ax.set_title("relative energy error")
    if not np.any(shown):
        ax.text(0.5, 0.5, "|dE/E| = 0 at every sample", ha="center", va="center", transform=ax.transAxes)
        return
    ax.semilogy(t[shown], err[shown], lw=0.8)
    ax.grid(True, which="both", alpha=0.3)
