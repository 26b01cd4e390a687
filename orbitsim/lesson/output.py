"""Figures and report of the demo's lesson (see :mod:`orbitsim.lesson.run`).

Figure 1 (``lesson_orbits.png``): three columns, one per scheme. Top: the planet's path in the x-y
plane over the REBOUND IAS15 reference (faint), on shared axes so the sizes compare. Bottom: its
energy error against time on a linear axis of the panel's own range (printed in each panel), since
explicit Euler's error is a hundred times Verlet's and one shared axis would flatten two panels.

Figure 2 (``lesson_dt.png``): what raising dt does: max |dE/E| against dt (log-log, slopes in the
legend) and the three orbits at the coarsest dt of the sweep.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from orbitsim.lesson.page import page_runs, write_lesson_page
from orbitsim.lesson.run import COLORS, DT_FACTORS, LESSON, LessonResult, lesson_metrics
from orbitsim.plots.style import REFERENCE_COLOR, figure_style, save, ticks_at, unit_labels
from orbitsim.provenance import provenance
from orbitsim.report import (
    Figure,
    Report,
    Section,
    Table,
    fmt,
    json_safe,
    reproduce_section,
    scenario_table,
    write_report,
)


def _body(result: LessonResult) -> int:
    """The body whose orbit is shown: the lightest (the planet)."""
    return int(np.argmin(result.scenario.masses))


def orbits_figure(result: LessonResult, path: Path) -> Path:
    """Figure 1: orbit panels over energy-error panels, one column per scheme."""
    time_unit, length_unit = unit_labels(result.scenario.units)
    k = _body(result)
    ref = result.reference.positions[:, k]
    with figure_style() as plt:
        fig = plt.figure(figsize=(14.5, 8.6), constrained_layout=True)
        grid = fig.add_gridspec(2, 3, height_ratios=(1.45, 1.0))
        top = [fig.add_subplot(grid[0, 0])]
        top += [fig.add_subplot(grid[0, c], sharex=top[0], sharey=top[0]) for c in (1, 2)]
        bottom = [fig.add_subplot(grid[1, c], sharex=None) for c in range(3)]
        fig.suptitle(f"One orbit, three ways to step time (dt = {result.scenario.dt:g} {time_unit}, "
                     f"{result.scenario.steps} steps)")
        for col, (rec, (name, title, moral)) in enumerate(zip(result.runs, LESSON, strict=True)):
            ax = top[col]
            ax.plot(ref[:, 0], ref[:, 1], color=REFERENCE_COLOR, lw=3.0, alpha=0.25,
                    label="IAS15 reference" if col == 0 else None)
            pos = rec.positions[:, k]
            ax.plot(pos[:, 0], pos[:, 1], color=COLORS[name], lw=1.0, label=title)
            ax.plot(pos[0, 0], pos[0, 1], "o", color="black", ms=4, label="start" if col == 0 else None)
            star = result.reference.positions[0, int(np.argmax(result.scenario.masses))]
            ax.plot(star[0], star[1], "*", color="#bcbd22", ms=12, mec="0.3", label="star" if col == 0 else None)
            ax.set_aspect("equal", adjustable="box")
            ax.set_title(f"{title}\n{moral}", fontsize=11)
            ax.set_xlabel(f"x [{length_unit}]")
            _energy_panel(bottom[col], rec, result.reference, COLORS[name], time_unit)
        top[0].set_ylabel(f"y [{length_unit}]")
        bottom[0].set_ylabel("dE/E  (relative energy error)")
        # One legend for the whole figure: per-panel legends would sit on top of Euler's spiral.
        handles = [h for ax in top for h in ax.get_legend_handles_labels()[0]]
        labels = [lab for ax in top for lab in ax.get_legend_handles_labels()[1]]
        fig.legend(handles, labels, loc="outside lower center", ncol=len(labels), frameon=False)
        return save(fig, path)


def _energy_panel(ax: Any, rec: Any, reference: Any, color: str, time_unit: str) -> None:
    ax.axhline(0.0, color="0.6", lw=0.8)
    ax.plot(reference.time, reference.energy_error, color=REFERENCE_COLOR, lw=2.5, alpha=0.3, label="IAS15")
    ax.plot(rec.time, rec.energy_error, color=color, lw=1.1, label="dE/E")
    peak = float(np.max(np.abs(rec.energy_error)))
    # Each panel has its own y range (they differ by ~1000x), so the range is stated in the title.
    ax.set_title(f"energy error, max |dE/E| = {peak:.2g}", fontsize=10)
    ax.ticklabel_format(axis="y", style="sci", scilimits=(-2, 2))
    ax.set_xlabel(f"time [{time_unit}]")


def dt_figure(result: LessonResult, path: Path) -> Path:
    """Figure 2: max |dE/E| against dt (log-log), and the three orbits at the coarsest dt."""
    time_unit, length_unit = unit_labels(result.scenario.units)
    metrics = {m["integrator"]: m for m in lesson_metrics(result)}
    k = _body(result)
    with figure_style() as plt:
        fig = plt.figure(figsize=(16.0, 5.6), constrained_layout=True)
        grid = fig.add_gridspec(1, 4, width_ratios=(1.55, 1.0, 1.0, 1.0))
        ax = fig.add_subplot(grid[0, 0])
        fig.suptitle("What raising dt does: same end time, each point one run")
        for name, title, _ in LESSON:
            dts, emax, _ = result.sweep_of(name)
            ax.plot(dts, emax, "o-", color=COLORS[name], lw=1.5,
                    label=f"{title} (slope {metrics[name]['energy_order']:.2f} at small dt)")
        ax.axvline(result.scenario.dt, color="0.5", ls=":", lw=1.2, label="the lesson's dt")
        ax.set_xscale("log")
        ax.set_yscale("log")
        _slope_guides(ax, result.sweep_of("verlet")[0])
        ticks_at(ax, result.sweep_of("verlet")[0])
        ax.set_xlabel(f"timestep dt [{time_unit}]")
        ax.set_ylabel("max |dE/E| over the run")
        ax.set_title("Energy error against dt")
        # Under the dt panel only (the orbit panels need no legend); placed below the rotated
        # tick labels by anchoring to the figure's bottom edge in the left panel's column.
        ax.legend(loc="upper left", bbox_to_anchor=(0.0, -0.28), ncol=2, frameon=False)
        ref = result.reference.positions[:, k]
        extent = 2.2 * float(np.max(np.abs(ref[:, :2])))  # Euler's escape leaves the panel, visibly
        first = None
        for col, (rec, (name, title, _)) in enumerate(zip(result.coarse, LESSON, strict=True)):
            panel = fig.add_subplot(grid[0, col + 1], sharex=first, sharey=first)
            first = first or panel
            panel.plot(ref[:, 0], ref[:, 1], color=REFERENCE_COLOR, lw=3.0, alpha=0.25)
            panel.plot(rec.positions[:, k, 0], rec.positions[:, k, 1], color=COLORS[name], lw=1.0)
            panel.set_xlim(-extent, extent)
            panel.set_ylim(-extent, extent)
            panel.set_aspect("equal", adjustable="box")
            panel.set_title(f"{title}\nat dt = {result.coarse_dt:.3g} ({DT_FACTORS[-1]:g}x the lesson's)", fontsize=10)
            panel.set_xlabel(f"x [{length_unit}]")
        first.set_ylabel(f"y [{length_unit}] (grey: IAS15)")
        return save(fig, path)


def _slope_guides(ax: Any, dts: np.ndarray) -> None:
    """Faint lines of slope 1 and 2 starting below the lowest point, to read the orders against."""
    y_low = min(line.get_ydata().min() for line in ax.get_lines() if len(line.get_ydata()) > 2)
    x = np.array([dts.min(), dts.max()])
    for power, style in ((1, "--"), (2, "-.")):
        ax.plot(x, 0.4 * y_low * (x / x[0]) ** power, color="0.55", ls=style, lw=1.0,
                label=f"guide: slope {power} (error ∝ dt{'²' if power == 2 else ''})")


def build_report(result: LessonResult, figures: dict[str, Path], command: str) -> Report:
    """The lesson report: figures first, then the numbers and how to reproduce them."""
    sc = result.scenario
    time_unit, _ = unit_labels(sc.units)
    rows = lesson_metrics(result)
    table = Table(["scheme", "max |dE/E|", f"dE/E drift [1/{time_unit}]", "position error at end vs IAS15",
                   "largest star-planet distance", "slope of max |dE/E| against dt (small dt)"],
                  [[r["title"], fmt(r["max_abs_energy_error"]), fmt(r["energy_drift_slope"]),
                    fmt(r["final_position_error"]), fmt(r["max_separation"]), fmt(r["energy_order"])]
                   for r in rows])
    lead = [f"The bundled lesson ({sc.name}): {sc.description}. The same planet on the same orbit, stepped "
            f"with dt = {sc.dt:g} by three schemes that differ only in how they order drift and kick, "
            "beside a REBOUND IAS15 reference."]
    return Report("One orbit, three ways to step time", lead, [
        Section("Three schemes, one orbit", [
            Figure(figures["orbits"].name, "Top: the planet's path (colour) over the IAS15 reference (grey). "
                   "Bottom: the relative energy error, each panel on its own scale."),
            "Explicit Euler drifts with the old velocity and kicks with the old acceleration: each step "
            "adds energy, so the orbit spirals out. Semi-implicit Euler kicks first and drifts with the new "
            "velocity: it is symplectic, its energy error oscillates in a band and does not drift. Velocity "
            "Verlet splits the kick around the drift: symplectic and second order, its band is the narrowest."]),
        Section("Raising dt", [Figure(figures["dt"].name, "Left: the largest energy error of each run "
                                      "against its dt, to the same end time (guides: slopes 1 and 2). "
                                      "Right: the orbits at the coarsest dt over the IAS15 orbit (grey)."),
                               "Semi-implicit Euler's energy error shrinks like dt and Verlet's like dt^2: "
                               "halving dt buys Verlet four times the accuracy. Explicit Euler's error is so "
                               "large that it keeps growing through the run at every dt tried: its slope is "
                               "not yet its order."]),
        Section("Play with it", ["lesson.html, beside this report, plays these runs: the three orbits side by "
                                 "side over their energy traces, with a dt slider and a frame-rate control. It "
                                 "works offline; open it in any browser."]),
        Section("Numbers", [table]),
        Section("Scenario", [scenario_table(sc, steps=sc.steps, samples=result.reference.n_samples)]),
        reproduce_section(command, sc),
    ])


def write_lesson_outputs(result: LessonResult, outdir: Path, command: str) -> dict[str, Path]:
    """Write both figures, summary.json, report.md/.html and the page to play, lesson.html, into
    ``outdir`` (replacing them)."""
    outdir.mkdir(parents=True, exist_ok=True)
    figures = {"orbits": orbits_figure(result, outdir / "lesson_orbits.png"),
               "dt": dt_figure(result, outdir / "lesson_dt.png")}
    summary = outdir / "summary.json"
    doc = {"format": "orbitsim.demo.summary", "format_version": 1, "command": command,
           "scenario": {"name": result.scenario.name, "sha256": result.scenario.sha256},
           "schemes": lesson_metrics(result),
           "sweep": [vars(p) for p in result.sweep], "provenance": provenance()}
    summary.write_text(json.dumps(json_safe(doc), indent=2) + "\n", encoding="utf-8")
    md, page = write_report(build_report(result, figures, command), outdir)
    lesson = write_lesson_page(result, page_runs(result.scenario), outdir)
    return {**figures, "summary": summary, "markdown": md, "html": page, "lesson": lesson}
