"""Figures of ``orbitsim compare``: energy error, position error, pair differences, orbits.

Each function draws one PNG into the output directory and returns its path. orbitsim and REBOUND
are drawn in side-by-side panels with shared axes and the same colour for the same scheme, so a
matched pair reads as one colour in both panels and a disagreement jumps out.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from orbitsim.compare.metrics import (
    NOT_COMPARABLE,
    TESTABLE_LIMIT,
    pair_steps,
    position_error,
    relative_position_difference,
)
from orbitsim.plots.style import (
    REFERENCE_COLOR,
    Palette,
    figure_style,
    grid_shape,
    log_time_axis,
    positive,
    save,
    unit_labels,
)
from orbitsim.record import RunRecord
from orbitsim.reference.pairs import allowed_difference

#: Above this many bodies the orbit panels show final positions instead of paths.
MAX_BODIES_WITH_PATHS = 50


def run_colors(result: Any) -> dict[str, str]:
    """Colour of each run label, stable across figures: a REBOUND run takes the colour of its
    built-in matched orbitsim partner, so a pair that agrees reads as one colour."""
    family = {r.label: r.integrator if r.engine == "orbitsim" else f"rebound {r.key}" for r in result.runs}
    family.update({r.label: "ias15" for r in getattr(result, "references", {}).values()})
    for verdict in result.verdicts:
        if verdict.pair.builtin:
            family[verdict.rebound_label] = verdict.pair.orbitsim
    palette = Palette()
    return {label: palette(name) for label, name in family.items()}


def _legend_below(ax: Any, n_entries: int) -> None:
    """Legend under the axes: error curves fill a log plot and leave no empty corner."""
    if not ax.get_legend_handles_labels()[0]:
        return  # an empty panel (e.g. no REBOUND fixed-step run): matplotlib would warn on stderr
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.16), ncol=min(3, max(1, n_entries)),
              frameon=False)


def _engine_panels(plt: Any, title: str) -> tuple[Any, Any]:
    fig, axes = plt.subplots(1, 2, figsize=(12.5, 4.6), sharey=True, constrained_layout=True)
    fig.suptitle(title)
    axes[0].set_title("orbitsim")
    axes[1].set_title("REBOUND")
    return fig, axes


def _short(record: RunRecord) -> str:
    """Legend text: the panel title already says which code."""
    return record.display.replace("REBOUND ", "").replace("orbitsim ", "")


def _draw_series(ax: Any, time: np.ndarray, values: np.ndarray, color: str, label: str,
                 **style: Any) -> None:
    """Plot ``values`` against ``time`` from the second sample on: errors at sample 0 are
    exactly zero by construction and have no place on a log axis."""
    k = min(time.size, values.size)
    t, v = time[1:k], values[1:k]
    if t.size == 0:
        ax.plot([], [], color=color, lw=1.4, label=f"{label} (stopped before its first sample)", **style)
        return
    mask = log_time_axis(ax, t)
    ax.plot(t[mask], positive(v)[mask], color=color, lw=1.4, label=label, **style)


def _other_ias15(result: Any, engine: str) -> list[RunRecord]:
    """The IAS15 of ``engine``'s code when it is not the reference (drawn in that code's panel)."""
    refs = getattr(result, "references", {})
    rec = refs.get(engine)
    return [rec] if rec is not None and rec is not result.reference else []


def energy_figure(result: Any, path: Path) -> Path:
    """|dE/E| against time on log axes, orbitsim left, REBOUND right, reference in both."""
    time_unit, _ = unit_labels(result.scenario.units)
    colors = run_colors(result)
    with figure_style() as plt:
        fig, axes = _engine_panels(plt, f"Relative energy error: {result.scenario.name}")
        for ax, engine in zip(axes, ("orbitsim", "rebound"), strict=True):
            shown = [r for r in result.runs if r.engine == engine] + _other_ias15(result, engine)
            for rec in shown:
                _draw_series(ax, rec.time, rec.energy_error, colors[rec.label], _short(rec))
            ref = result.reference
            _draw_series(ax, ref.time, ref.energy_error, REFERENCE_COLOR, "IAS15 reference", ls="--")
            ax.set_yscale("log")
            ax.set_xlabel(f"time [{time_unit}]")
            _legend_below(ax, len(shown) + 1)
        axes[0].set_ylabel("|dE/E|  (relative energy error)")
        return save(fig, path)


def position_error_figure(result: Any, path: Path) -> Path:
    """Relative position error against the IAS15 reference over time, per engine."""
    time_unit, _ = unit_labels(result.scenario.units)
    colors = run_colors(result)
    with figure_style() as plt:
        fig, axes = _engine_panels(plt, f"Position error against the IAS15 reference: {result.scenario.name}")
        for ax, engine in zip(axes, ("orbitsim", "rebound"), strict=True):
            shown = [r for r in result.runs if r.engine == engine] + _other_ias15(result, engine)
            for rec in shown:
                _draw_series(ax, rec.time, position_error(rec, result.reference), colors[rec.label], _short(rec))
            ax.set_yscale("log")
            ax.set_xlabel(f"time [{time_unit}]")
            _legend_below(ax, len(shown))
        axes[0].set_ylabel(r"max$_i$ |x$_i$ - x$_i^{ref}$| / max$_i$ |x$_i^{ref}$|")
        return save(fig, path)


def pair_figure(result: Any, path: Path) -> Path | None:
    """Each matched pair's relative position difference over time, with its tolerance (pairs that
    are not comparable have no difference to draw)."""
    verdicts = [v for v in result.verdicts if v.verdict != NOT_COMPARABLE]
    if not verdicts:
        return None
    time_unit, _ = unit_labels(result.scenario.units)
    colors = run_colors(result)
    with figure_style() as plt:
        fig, ax = plt.subplots(figsize=(9.5, 5.2), constrained_layout=True)
        for verdict in verdicts:
            ours, theirs = result.record(verdict.orbitsim_label), result.record(verdict.rebound_label)
            diff = relative_position_difference(ours.positions, theirs.positions)
            twin = result.twins.get(verdict.pair.rebound.key)
            twin_diff = relative_position_difference(twin.positions, theirs.positions) if twin else None
            allowed = allowed_difference(pair_steps(theirs)[: diff.size], twin_diff)
            color = colors[verdict.orbitsim_label]
            verdict_text = verdict.label
            t = theirs.time[: diff.size]
            mask = log_time_axis(ax, t) & (t > 0)
            ax.plot(t[mask], positive(diff)[mask], color=color, lw=1.6,
                    label=f"orbitsim {verdict.pair.orbitsim} vs {verdict.pair.rebound.display}: {verdict_text}")
            ax.plot(t[mask], allowed[mask], color=color, lw=1.0, ls=":")
        ax.plot([], [], color="0.3", ls=":", label="tolerance (dotted, in the pair's colour)")
        # Above this a tolerance no longer tests agreement (metrics.TESTABLE_LIMIT).
        ax.axhline(TESTABLE_LIMIT, color="0.5", lw=0.8, ls="--",
                   label=f"{TESTABLE_LIMIT:g}: a tolerance above this line tests nothing")
        ax.set_yscale("log")
        ax.set_xlabel(f"time [{time_unit}]")
        ax.set_ylabel("relative position difference\n(exact agreement drawn at 1e-17)")
        ax.set_title(f"Matched pairs, orbitsim vs REBOUND: {result.scenario.name}")
        fig.legend(*ax.get_legend_handles_labels(), loc="outside lower center", ncol=1, frameon=False)
        return save(fig, path)


def orbits_figure(result: Any, path: Path) -> Path:
    """Orbits in the x-y plane: the reference and every run, one panel each."""
    _, length_unit = unit_labels(result.scenario.units)
    records = [result.reference, *_other_ias15(result, "orbitsim"), *_other_ias15(result, "rebound"), *result.runs]
    rows, cols = grid_shape(len(records))
    with figure_style() as plt:
        fig, axes = plt.subplots(rows, cols, figsize=(3.6 * cols, 3.5 * rows + 0.6), squeeze=False,
                                 sharex=True, sharey=True, constrained_layout=True)
        fig.suptitle(f"Orbits in the x-y plane: {result.scenario.name}")
        names = list(getattr(result.scenario, "names", []))
        for ax, rec in zip(axes.flat, records, strict=False):
            draw_orbits(ax, rec, names)
            ax.set_title(rec.display.replace("REBOUND IAS15 reference", "IAS15 reference"), fontsize=10)
        for ax in axes.flat[len(records):]:
            ax.set_visible(False)
        for ax in axes[-1]:
            ax.set_xlabel(f"x [{length_unit}]")
        for ax in axes[:, 0]:
            ax.set_ylabel(f"y [{length_unit}]")
        if 1 < len(names) <= 10:
            handles, labels = axes.flat[0].get_legend_handles_labels()
            fig.legend(handles, labels, loc="outside lower center", ncol=min(len(labels), 6))
        return save(fig, path)


def draw_orbits(ax: Any, record: RunRecord, names: list[str], *, alpha: float = 1.0) -> None:
    """Paths of every body in the x-y plane (final positions only for large N)."""
    pos = record.positions
    ax.set_aspect("equal", adjustable="box")
    if pos.shape[0] == 0:
        return
    if pos.shape[1] > MAX_BODIES_WITH_PATHS:
        ax.scatter(pos[-1, :, 0], pos[-1, :, 1], s=1.0, color="0.2", alpha=alpha)
        return
    palette = Palette()
    for i in range(pos.shape[1]):
        label = names[i] if i < len(names) else f"body {i}"
        ax.plot(pos[:, i, 0], pos[:, i, 1], lw=1.0, color=palette(label), alpha=alpha, label=label)
        ax.plot(pos[-1, i, 0], pos[-1, i, 1], "o", ms=3.5, color=palette(label), alpha=alpha)


def compare_figures(result: Any, outdir: Path) -> dict[str, Path]:
    """Draw every comparison figure into ``outdir``; returns name -> path of those drawn."""
    figures = {
        "energy": energy_figure(result, outdir / "energy_error.png"),
        "position_error": position_error_figure(result, outdir / "position_error.png"),
        "pairs": pair_figure(result, outdir / "pair_difference.png"),
        "orbits": orbits_figure(result, outdir / "orbits.png"),
    }
    return {name: p for name, p in figures.items() if p is not None}
