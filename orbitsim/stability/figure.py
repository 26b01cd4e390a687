"""``map.png``: one indicator over the map's axes, stopped pixels in their own colours.

The indicator's colour map covers the pixels that completed; escaped, collided and diverged pixels
are drawn in fixed colours named in a legend (never as an indicator value), and pixels whose
energy error exceeds the map's ``max_energy_error`` are hatched. A one-axis map is a line over x
with the stopped pixels marked.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["INDICATOR_LABELS", "draw_map"]

#: Colour-bar labels; ``{t}`` is the time unit.
INDICATOR_LABELS = {
    "megno": "MEGNO <Y>: 2 regular, > 2 chaotic (clipped to 1.8-4)",
    "lyapunov_time": "Lyapunov time [{t}]",
    "survival_time": "survival time [{t}]",
    "max_e": "largest eccentricity",
    "delta_a": "largest |a - a0| / a0",
    "energy_error": "|dE/E| at the end",
}
#: Colours of the stopped pixels, by status name.
STATUS_COLOURS = {"escaped": "#d62728", "collided": "#ff7f0e", "diverged": "#7f7f7f"}
#: Colour ranges that clip an indicator as the literature draws it (REBOUND's MEGNO maps: 1.8 to 4), so
#: that the few pixels with MEGNO in the hundreds do not wash the regular-chaotic boundary out; the values
#: in map.h5 are never clipped, and the colour bar's ends say that the range was.
_CLIPPED = {"megno": (1.8, 4.0)}
#: Indicators drawn on a logarithmic colour scale.
_LOG = ("lyapunov_time", "delta_a", "energy_error", "survival_time")


def _edges(values: np.ndarray, log: bool) -> np.ndarray:
    v = np.log(values) if log else values
    mids = 0.5 * (v[1:] + v[:-1])
    edges = np.concatenate([[v[0] - (mids[0] - v[0])], mids, [v[-1] + (v[-1] - mids[-1])]])
    return np.exp(edges) if log else edges


def draw_map(path: str | os.PathLike, data: dict[str, Any], indicator: str) -> None:
    """Draw ``indicator`` of a map's ``data`` (:func:`orbitsim.stability.driver.read_map`) into ``path``."""
    import matplotlib  # noqa: PLC0415 - lazy: loads matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415 - lazy: as above
    from matplotlib.collections import PolyCollection  # noqa: PLC0415 - lazy: as above
    from matplotlib.colors import ListedColormap, LogNorm, Normalize  # noqa: PLC0415 - lazy: as above
    from matplotlib.patches import Patch  # noqa: PLC0415 - lazy: as above

    grid = np.asarray(data["indicators"][indicator], dtype=np.float64)
    status = np.asarray(data["status"])
    names = list(data["status_names"])
    unreliable = np.asarray(data["unreliable"], dtype=bool)
    x = data["x"]
    label = INDICATOR_LABELS[indicator].format(t=data.get("time_unit", "time"))
    complete = status == names.index("complete")
    shown = np.where(complete & np.isfinite(grid), grid, np.nan)
    use_log = indicator in _LOG and np.nanmin(np.where(shown > 0, shown, np.nan), initial=np.inf) < np.inf
    fig, ax = plt.subplots(figsize=(7.0, 5.0), constrained_layout=True)
    handles = []
    if "y" not in data:
        ax.plot(x["values"], shown[0], "-o", ms=3, color="#1f77b4", label=label)
        for name, colour in STATUS_COLOURS.items():
            hit = status[0] == names.index(name)
            if hit.any():
                ax.plot(x["values"][hit], np.zeros(hit.sum()), "s", color=colour, label=name)
        if use_log:
            ax.set_yscale("log")
        ax.set_ylabel(label)
        ax.legend(loc="best", fontsize="small")
    else:
        y = data["y"]
        xe, ye = _edges(x["values"], bool(x["log"])), _edges(y["values"], bool(y["log"]))
        positive = shown[np.isfinite(shown) & (shown > 0)]
        norm = LogNorm(vmin=positive.min(), vmax=positive.max()) if use_log and positive.size else None
        extend = "neither"
        if indicator in _CLIPPED:
            norm = Normalize(*_CLIPPED[indicator], clip=False)
            extend = "both"
        mesh = ax.pcolormesh(xe, ye, shown if norm is None or not use_log else np.where(shown > 0, shown, np.nan),
                             cmap="viridis", norm=norm, shading="flat")
        fig.colorbar(mesh, ax=ax, label=label, extend=extend)
        for name, colour in STATUS_COLOURS.items():
            hit = status == names.index(name)
            if hit.any():
                ax.pcolormesh(xe, ye, np.where(hit, 1.0, np.nan), cmap=ListedColormap([colour]), shading="flat")
                handles.append(Patch(color=colour, label=f"{name} ({int(hit.sum())})"))
        if unreliable.any():
            iy, ix = np.nonzero(unreliable)  # one collection: a patch per pixel took seconds on a 200 x 200 map
            cells = np.stack([np.column_stack([xe[ix], ye[iy]]), np.column_stack([xe[ix + 1], ye[iy]]),
                              np.column_stack([xe[ix + 1], ye[iy + 1]]), np.column_stack([xe[ix], ye[iy + 1]])], axis=1)
            ax.add_collection(PolyCollection(cells, facecolors="none", edgecolors="black", linewidths=0.0,
                                             hatch="///"))
            handles.append(Patch(facecolor="none", edgecolor="black", hatch="///",
                                 label=f"|dE/E| > {data['max_energy_error']:g} ({int(unreliable.sum())})"))
        if y["log"]:
            ax.set_yscale("log")
        ax.set_ylabel(_axis_label(y))
        if handles:
            ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(0.0, -0.12), ncol=3, fontsize="small",
                      frameon=False)
    if x["log"]:
        ax.set_xscale("log")
    ax.set_xlabel(_axis_label(x))
    ax.set_title(f"{data.get('scenario_name', 'map')}: {indicator}, {data.get('integrator', 'wisdom_holman')}, "
                 f"t = {data['t_end']:g}", fontsize="medium")  # maps written before the attribute were all WH
    target = Path(path)
    tmp = target.with_name(target.name + ".tmp.png")
    try:
        fig.savefig(tmp, dpi=120)
        os.replace(tmp, target)
    finally:
        tmp.unlink(missing_ok=True)
        plt.close(fig)


def _axis_label(axis: dict[str, Any]) -> str:
    unit = axis.get("unit") or ""
    return f"{axis['body']}.{axis['key']} [{unit}]" if unit else f"{axis['body']}.{axis['key']}"
