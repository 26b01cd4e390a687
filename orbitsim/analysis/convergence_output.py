"""Files of ``orbitsim convergence``: summary.json, report.md/.html, convergence.png and
work_precision.png.

In both figures orbitsim's integrators are solid lines with circles and REBOUND's dashed with
squares; a REBOUND scheme matched with an orbitsim one shares its colour. Filled markers entered
the order fit, hollow ones did not (round-off floor or pre-asymptotic).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from orbitsim.analysis.convergence import ConvergenceResult, ConvergenceSeries
from orbitsim.analysis.plotstyle import Palette, figure_style, save, ticks_at, unit_labels
from orbitsim.analysis.report import Figure, Report, Section, Table, fmt, reproduce_section, scenario_table
from orbitsim.provenance import provenance


def _family(series: ConvergenceSeries) -> str:
    if series.engine == "orbitsim":
        return series.key
    from orbitsim.reference.pairs import available_pairs

    for pair in available_pairs():
        if pair.rebound.key == series.key:
            return pair.orbitsim
    return f"rebound {series.key}"


def _plot_series(ax: Any, result: ConvergenceResult, x_of: str) -> None:
    palette = Palette()
    for s in result.series:
        x = np.array([getattr(p, x_of) for p in s.points])
        y = np.array([p.error for p in s.points])
        used = np.array(s.fit_used, dtype=bool)
        color = palette(_family(s))
        style = ("-", "o") if s.engine == "orbitsim" else ("--", "s")
        fit = f"p = {s.fitted_order:.2f}" if np.isfinite(s.fitted_order) else "p n/a"
        label = f"{s.display} ({fit}, declared {fmt(s.declared_order)})"
        ok = np.isfinite(y) & (y > 0)
        ax.plot(x[ok], y[ok], ls=style[0], color=color, lw=1.3, label=label)
        ax.plot(x[ok & used], y[ok & used], style[1], color=color, ms=5.5, ls="none")
        ax.plot(x[ok & ~used], y[ok & ~used], style[1], mfc="white", mec=color, ms=5.5, ls="none")
    ax.set_xscale("log")
    ax.set_yscale("log")


def convergence_figure(result: ConvergenceResult, path: Path) -> Path:
    """Error at the end time against dt, log-log, with the fitted orders in the legend."""
    time_unit, _ = unit_labels(result.scenario.units)
    with figure_style() as plt:
        fig, ax = plt.subplots(figsize=(9.0, 6.4), constrained_layout=True)
        _plot_series(ax, result, "dt")
        ticks_at(ax, np.array(result.dts))
        ax.set_xlabel(f"timestep dt [{time_unit}]")
        ax.set_ylabel("relative position error at the end time")
        ax.set_title(f"Convergence against IAS15 at t = {result.scenario.t_start + result.end_time:.6g} {time_unit}: "
                     f"{result.scenario.name}")
        fig.legend(*ax.get_legend_handles_labels(), loc="outside lower center", ncol=2, frameon=False)
        return save(fig, path)


def work_precision_figure(result: ConvergenceResult, path: Path) -> Path:
    """Error against wall time: what accuracy each code buys per second, on one chart."""
    with figure_style() as plt:
        fig, ax = plt.subplots(figsize=(9.0, 6.4), constrained_layout=True)
        _plot_series(ax, result, "wall_time_s")
        ax.set_xlabel("wall time of the run [s]")
        ax.set_ylabel("relative position error at the end time")
        ax.set_title(f"Work-precision, orbitsim and REBOUND: {result.scenario.name}")
        fig.legend(*ax.get_legend_handles_labels(), loc="outside lower center", ncol=2, frameon=False)
        return save(fig, path)


def summary_dict(result: ConvergenceResult, command: str, tolerance: float) -> dict[str, Any]:
    """The content of ``summary.json``: every rung of every ladder and the fitted orders."""
    def clean(v: float) -> float | None:
        return float(v) if np.isfinite(v) else None

    return {
        "format": "orbitsim.convergence.summary", "format_version": 1, "command": command,
        "scenario": {"name": result.scenario.name, "sha256": result.scenario.sha256,
                     "source": str(result.scenario.source)},
        "end_time": result.end_time, "dts": result.dts, "order_tolerance": tolerance,
        "series": [{
            "engine": s.engine, "key": s.key, "display": s.display, "declared_order": s.declared_order,
            "fitted_order": clean(s.fitted_order), "note": s.note,
            "points": [{"dt": p.dt, "steps": p.steps, "end_time": p.end_time, "error": clean(p.error),
                        "wall_time_s": p.wall_time_s, "status": p.status, "used_in_fit": u}
                       for p, u in zip(s.points, s.fit_used, strict=True)],
        } for s in result.series],
        "off_order": result.check(tolerance), "provenance": provenance(),
    }


def build_report(result: ConvergenceResult, figures: dict[str, Path], command: str, tolerance: float) -> Report:
    """Orders table, the error table per dt, the two figures and the reproduction section."""
    sc = result.scenario
    time_unit, _ = unit_labels(sc.units)
    off = result.check(tolerance)
    span = f"T = {result.end_time:.10g} {time_unit}"
    if sc.t_start:  # the scenario's clock starts later: T is the run's length from there
        span = f"t = {sc.t_start + result.end_time:.10g} {time_unit} ({span} after t_start = {sc.t_start:.10g})"
    lead = [f"End time {span}; error = max over bodies of |x - x_ref| "
            "divided by the largest distance from the origin, against REBOUND IAS15 stopped exactly at n dt."]
    lead.append("PASS: every fitted order is within " f"{tolerance:g} of the declared order." if not off
                else "Fitted orders off the declared ones by more than " f"{tolerance:g}: " + "; ".join(off))
    orders = Table(["integrator", "declared order", "fitted order", "points in fit", "note"], [
        [s.display, fmt(s.declared_order), fmt(s.fitted_order, 3), str(sum(s.fit_used)), s.note]
        for s in result.series])
    errors = Table(["integrator", *[f"dt = {dt:.4g}" for dt in result.dts]], [
        [s.display, *[fmt(p.error, 3) for p in s.points]] for s in result.series],
        caption="Relative position error at the end time for each dt (steps: T / dt whole steps).")
    walls = Table(["integrator", *[f"dt = {dt:.4g}" for dt in result.dts]], [
        [s.display, *[fmt(p.wall_time_s, 3) for p in s.points]] for s in result.series],
        caption="Wall time in seconds (best of repeated runs when a run is shorter than 0.05 s).")
    captions = {
        "convergence": "Error at the end time against dt (log-log). Filled markers entered the fit; hollow "
                       "ones sit on the round-off floor or outside the asymptotic regime.",
        "work_precision": "Error against wall time: lower-left is better. orbitsim solid, REBOUND dashed.",
    }
    steps = round(result.end_time / abs(sc.dt)) if sc.dt else 0
    return Report(f"Convergence: {sc.name}", lead, [
        Section("Fitted orders", [orders]),
        Section("Errors", [errors, walls]),
        Section("Figures", [Figure(p.name, captions[k]) for k, p in figures.items()]),
        Section("Scenario", [scenario_table(sc, steps=steps, samples=2)]),
        reproduce_section(command, sc),
    ])


def write_convergence_outputs(result: ConvergenceResult, outdir: Path, command: str,
                              tolerance: float) -> dict[str, Path]:
    """Write summary.json, both figures and the report into ``outdir``; returns name -> path."""
    from orbitsim.analysis.report import write_report

    outdir.mkdir(parents=True, exist_ok=True)
    summary = outdir / "summary.json"
    summary.write_text(json.dumps(summary_dict(result, command, tolerance), indent=2) + "\n", encoding="utf-8")
    figures = {"convergence": convergence_figure(result, outdir / "convergence.png"),
               "work_precision": work_precision_figure(result, outdir / "work_precision.png")}
    md, page = write_report(build_report(result, figures, command, tolerance), outdir)
    return {"summary": summary, **figures, "markdown": md, "html": page}
