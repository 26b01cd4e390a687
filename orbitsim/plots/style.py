"""Shared look of every orbitsim figure: Agg backend, readable fonts, unit labels, colours.

matplotlib is imported inside the functions (a report pulls it in; nothing else should), and
always with the non-interactive Agg backend, so figures render on servers and in CI without a
display.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from orbitsim.units import get_unit_system

#: Base font size in points: legible when a PNG is shown at its natural width in a report.
FONT_SIZE = 11
#: Resolution of saved PNGs: sharp on high-density screens, a few hundred KiB per figure.
DPI = 130
#: Smallest |dE/E| or error drawn on a log axis: exact zeros (the first sample) have no log.
LOG_FLOOR = 1e-17

_STYLE = {
    "font.size": FONT_SIZE,
    "axes.titlesize": FONT_SIZE + 1,
    "axes.labelsize": FONT_SIZE,
    "legend.fontsize": FONT_SIZE - 2,
    "xtick.labelsize": FONT_SIZE - 1,
    "ytick.labelsize": FONT_SIZE - 1,
    "figure.titlesize": FONT_SIZE + 3,
    "axes.grid": True,
    "grid.alpha": 0.3,
    "axes.spines.top": False,
    "axes.spines.right": False,
    "savefig.bbox": "tight",
    "savefig.facecolor": "white",
    "figure.facecolor": "white",
}


@contextlib.contextmanager
def figure_style() -> Iterator[Any]:
    """Context with the Agg backend and orbitsim's rcParams; yields ``matplotlib.pyplot``."""
    import matplotlib  # noqa: PLC0415 -- lazy: loads matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt  # noqa: PLC0415 -- lazy: loads matplotlib

    with plt.rc_context(_STYLE):
        yield plt


def save(fig: Any, path: Path) -> Path:
    """Save ``fig`` as PNG at :data:`DPI` and close it (figures are not kept open)."""
    import matplotlib.pyplot as plt  # noqa: PLC0415 -- lazy: loads matplotlib

    fig.savefig(path, dpi=DPI)
    plt.close(fig)
    return path


def unit_labels(units: Any) -> tuple[str, str]:
    """Short (time, length) unit labels for axes, from a unit-system name or object."""
    system = units
    if isinstance(units, str):
        try:
            system = get_unit_system(units)
        except KeyError:
            return ("time", "length")
    time_unit = str(getattr(system, "time", "time"))
    length_unit = str(getattr(system, "length", "length"))
    # "Gaussian year (2 pi / k = ...)" is right in a table and too long for an axis.
    if time_unit.startswith("Gaussian year"):
        time_unit = "yr"
    elif time_unit.startswith("day"):
        time_unit = "d"
    return time_unit, length_unit


def positive(values: np.ndarray) -> np.ndarray:
    """|values| with zeros lifted to :data:`LOG_FLOOR` and non-finite values masked (nan)."""
    v = np.abs(np.asarray(values, dtype=np.float64))
    v = np.where(np.isfinite(v), v, np.nan)
    return np.where(v > 0.0, np.maximum(v, LOG_FLOOR), LOG_FLOOR)


class Palette:
    """Stable colours by family: a matched pair shares one colour in every figure."""

    def __init__(self) -> None:
        import matplotlib  # noqa: PLC0415 -- lazy: loads matplotlib

        self._cycle = [matplotlib.colors.to_hex(c) for c in matplotlib.colormaps["tab10"].colors]
        self._assigned: dict[str, str] = {}

    def __call__(self, family: str) -> str:
        if family not in self._assigned:
            self._assigned[family] = self._cycle[len(self._assigned) % len(self._cycle)]
        return self._assigned[family]


#: Colour of the reference in every figure: it is the backdrop, not a contender.
REFERENCE_COLOR = "0.35"


def grid_shape(n_panels: int, max_cols: int = 4) -> tuple[int, int]:
    """(rows, cols) for ``n_panels`` panels, at most ``max_cols`` wide."""
    cols = min(max_cols, max(1, n_panels))
    return math.ceil(n_panels / cols), cols


def log_time_axis(ax: Any, time: np.ndarray) -> np.ndarray:
    """Use a log time axis when times span decades; returns the mask of plottable samples."""
    t = np.asarray(time, dtype=np.float64)
    positive_t = t > 0.0
    if np.count_nonzero(positive_t) >= 2 and t[positive_t].max() / t[positive_t].min() >= 20.0:
        ax.set_xscale("log")
        return positive_t
    return np.ones_like(t, dtype=bool)


def ticks_at(ax: Any, values: np.ndarray) -> None:
    """Label the x axis at ``values`` (e.g. a dt ladder) only: on a log axis spanning a decade or
    two, matplotlib's minor labels collide."""
    from matplotlib.ticker import NullFormatter  # noqa: PLC0415 -- lazy: loads matplotlib

    ticks = np.unique(np.asarray(values, dtype=np.float64))
    ax.set_xticks(ticks)
    ax.set_xticklabels([f"{v:.2g}" for v in ticks], rotation=35, ha="right")
    ax.xaxis.set_minor_formatter(NullFormatter())
