"""Figure of ``orbitsim plot --elements``: every body's osculating elements against time.

The trace holds them as the group ``elements`` (datasets ``a e inc Omega omega f M``, each float64
(S, N), attribute ``primary``: ``heaviest``, ``jacobi`` or a body name), written by a run with
``output.elements: true`` from :func:`orbitsim.physics.orbital_elements.osculating_elements`.
One panel per element over a shared time axis, one line per body, in the body's colour in every
panel. Bodies whose elements are NaN at every sample drawn (the primary; body 0 in Jacobi
elements; a body removed before the first sample) are left out.

matplotlib and h5py are imported inside the functions: the CLI imports this module only when
``--elements`` is given.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from orbitsim.io.schema import TraceError
from orbitsim.physics.orbital_elements import ELEMENT_NAMES  # the datasets, in panel order
from orbitsim.plots.event_marks import mark_events

__all__ = ["ELEMENTS_GROUP", "check_elements", "draw_elements", "read_elements"]

#: The trace group that holds the elements.
ELEMENTS_GROUP = "elements"
#: Angles that wrap: a jump of more than half a turn between samples is drawn as a gap, not a
#: vertical line across the panel. (inc lives in [0, 180] and never wraps.)
WRAPPING = frozenset({"Omega", "omega", "f", "M"})
#: Axis labels (mathtext); ``{length}`` is the trace's length unit.
LABELS = {"a": "a [{length}]", "e": "e", "inc": "inc [deg]", "Omega": r"$\Omega$ [deg]",
          "omega": r"$\omega$ [deg]", "f": "f [deg]", "M": "M [deg]"}
#: Panel height in inches: seven panels stay readable on one screen.
PANEL_HEIGHT = 1.9


def check_elements(summary: dict[str, Any]) -> None:
    """Raise :class:`TraceError` (one line) unless the trace holds a complete ``elements`` group.

    Uses only :func:`orbitsim.io.trace.open_trace_summary`'s dataset shapes, so it runs before
    anything is read or drawn.
    """
    path, shapes = summary["path"], summary["shapes"]
    datasets = {name: shapes.get(f"{ELEMENTS_GROUP}/{name}") for name in ELEMENT_NAMES}
    if all(shape is None for shape in datasets.values()):
        raise TraceError(f"{path}: has no orbital elements; run with output.elements: true")
    expected = (summary["n_samples"], summary["n_bodies"])
    for name, shape in datasets.items():
        if shape is None:
            raise TraceError(f"{path}: damaged trace: dataset '{ELEMENTS_GROUP}/{name}' is missing")
        if tuple(shape) != expected:
            raise TraceError(f"{path}: damaged trace: dataset '{ELEMENTS_GROUP}/{name}' has shape {tuple(shape)}, "
                             f"expected {expected} (samples, bodies)")


def _rows(n_samples: int, max_samples: int) -> np.ndarray:
    """At most ``max_samples`` evenly strided sample indices, always with the last one."""
    rows = np.arange(0, n_samples, max(1, -(-n_samples // max_samples)))
    return rows if rows.size == 0 or rows[-1] == n_samples - 1 else np.append(rows, n_samples - 1)


def read_elements(path: str, summary: dict[str, Any], max_samples: int, max_bodies: int) -> dict[str, Any]:
    """Time and elements at strided samples, for the first ``max_bodies`` bodies with any finite ``a``.

    Bodies are read in blocks of ``max_bodies`` columns until enough are found, so a trace of many
    bodies is never read whole. A body has a finite ``a`` at a sample exactly when any of its
    elements is defined there (see :func:`~orbitsim.physics.orbital_elements.osculating_elements`).
    """
    import h5py  # noqa: PLC0415 -- lazy: loads h5py

    rows = _rows(summary["n_samples"], max_samples)
    n_bodies = summary["n_bodies"]
    picked: list[int] = []
    blocks: list[dict[str, np.ndarray]] = []
    with h5py.File(path, "r") as f:
        group = f[ELEMENTS_GROUP]
        primary = group.attrs.get("primary", "")
        names = list(f["bodies/names"].asstr()[()])
        time = f["time"][rows] if rows.size else np.empty(0)
        for start in range(0, n_bodies if rows.size else 0, max_bodies):
            block = {name: group[name][rows, start:start + max_bodies] for name in ELEMENT_NAMES}
            keep = np.flatnonzero(np.isfinite(block["a"]).any(axis=0))[: max_bodies - len(picked)]
            picked.extend(start + int(i) for i in keep)
            blocks.append({name: values[:, keep] for name, values in block.items()})
            if len(picked) == max_bodies:
                break
    values = {name: np.concatenate([b[name] for b in blocks], axis=1) if blocks else np.empty((rows.size, 0))
              for name in ELEMENT_NAMES}
    return {"time": time, "elements": values, "bodies": [names[i] for i in picked], "n_bodies": n_bodies,
            "primary": primary.decode() if isinstance(primary, bytes) else str(primary)}


def _gapped(time: np.ndarray, values: np.ndarray, wraps: bool) -> tuple[np.ndarray, np.ndarray]:
    """Non-finite values as NaN (a = inf on an exact parabola), and a NaN where an angle wraps."""
    y = np.where(np.isfinite(values), values, np.nan)
    if not wraps or y.size < 2:
        return time, y
    with np.errstate(invalid="ignore"):  # NaN neighbours compare False: no gap needed there
        jumps = np.flatnonzero(np.abs(np.diff(y)) > 180.0) + 1
    return np.insert(time.astype(np.float64), jumps, np.nan), np.insert(y, jumps, np.nan)


def _primary_text(primary: str) -> str:
    if primary == "jacobi":
        return "Jacobi elements: each body about the centre of mass of the bodies before it"
    if primary == "heaviest":
        return "elements about the heaviest body"
    return f"elements about {primary}" if primary else "osculating elements"


def draw_elements(data: dict[str, Any], target: Path, title: str, length: str, time_unit: str,
                  max_legend: int, events: dict[str, np.ndarray] | None = None) -> None:
    """Draw one panel per element against time into ``target`` (format from its suffix); with
    ``events`` (kind -> times, :func:`orbitsim.plots.event_marks.read_event_times`) each panel
    marks them, and the last panel's legend names the kinds."""
    import matplotlib  # noqa: PLC0415 -- lazy: loads matplotlib

    matplotlib.use("Agg")  # files only: no display needed, and no GUI toolkit imported
    import matplotlib.pyplot as plt  # noqa: PLC0415 -- lazy: loads matplotlib

    time, bodies = data["time"], data["bodies"]
    fig, axes = plt.subplots(len(ELEMENT_NAMES), 1, sharex=True, layout="constrained",
                             figsize=(10, PANEL_HEIGHT * len(ELEMENT_NAMES) + 0.8))
    for ax, name in zip(axes, ELEMENT_NAMES, strict=True):
        wraps = name in WRAPPING
        for k, body in enumerate(bodies):
            t, y = _gapped(time, data["elements"][name][:, k], wraps)
            # Dots keep a sample visible when gaps at wraps leave it with no line to a neighbour.
            ax.plot(t, y, lw=0.8, color=f"C{k % 10}", marker="." if wraps else None, ms=2,
                    label=body if k < max_legend else None)
        ax.set_ylabel(LABELS[name].format(length=length))
        ax.grid(True, alpha=0.3)
        if events:
            mark_events(ax, events, legend=ax is axes[-1])
    shown = f"{len(bodies)} of {data['n_bodies']} bodies" if len(bodies) < data["n_bodies"] else "every body"
    axes[0].set_title(f"{_primary_text(data['primary'])} ({shown})", fontsize="medium")
    axes[-1].set_xlabel(f"time [{time_unit}]")
    if not bodies:
        axes[0].text(0.5, 0.5, "no body has defined elements", ha="center", va="center",
                     transform=axes[0].transAxes)
    elif len(bodies) <= max_legend:
        fig.legend(*axes[0].get_legend_handles_labels(), loc="outside right upper", fontsize="small")
    fig.suptitle(title)
    fig.savefig(target, dpi=120)
    plt.close(fig)
