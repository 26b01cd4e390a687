"""Files of ``orbitsim convergence``: summary.json, report.md/.html, convergence.png and
work_precision.png.

``summary.json`` (format ``orbitsim.convergence.summary``, version 2): per series its engine,
key, display, declared and fitted order, ``note`` (why the order is what it is, or missing: the
words of the report's table and lead line), ``fit_kind`` (``fitted``, ``too_coarse``, ``floor``,
``round_off``, ``no_data`` or empty for an adaptive scheme), ``adaptive``, ``forces`` and every rung
(``added``: a rung the default ladder added for this scheme); ``dts`` is every dt any ladder ran.
Version 2 added ``fit_kind``, ``adaptive``, ``forces``, ``added`` and ``notes``.

In both figures orbitsim's integrators are solid lines with circles and REBOUND's dashed with
squares; a REBOUND scheme matched with an orbitsim one shares its colour. Filled markers entered
the order fit, hollow ones did not (round-off floor or pre-asymptotic).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from orbitsim.convergence.run import ConvergenceResult, ConvergenceSeries
from orbitsim.plots.style import Palette, figure_style, save, ticks_at, unit_labels
from orbitsim.provenance import provenance
from orbitsim.reference.pairs import available_pairs
from orbitsim.report import Figure, Report, Section, Table, fmt, reproduce_section, scenario_table, write_report


def _family(series: ConvergenceSeries) -> str:
    if series.engine == "orbitsim":
        return series.key

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
        "format": "orbitsim.convergence.summary", "format_version": 2, "command": command,
        "scenario": {"name": result.scenario.name, "sha256": result.scenario.sha256,
                     "source": str(result.scenario.source)},
        "end_time": result.end_time, "dts": result.dts, "order_tolerance": tolerance,
        "series": [{
            "engine": s.engine, "key": s.key, "display": s.display, "declared_order": s.declared_order,
            "fitted_order": clean(s.fitted_order), "note": s.note, "fit_kind": s.fit_kind, "adaptive": s.adaptive,
            "forces": list(s.forces),
            "points": [{"dt": p.dt, "steps": p.steps, "end_time": p.end_time, "error": clean(p.error),
                        "wall_time_s": p.wall_time_s, "status": p.status, "used_in_fit": u, "added": p.added}
                       for p, u in zip(s.points, s.fit_used, strict=True)],
        } for s in result.series],
        "off_order": result.check(tolerance), "notes": list(result.notes), "provenance": provenance(),
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
                else "Fitted orders missing or off the declared ones by more than " f"{tolerance:g}: "
                + "; ".join(off))
    orders = Table(["integrator", "declared order", "fitted order", "points in fit", "note"], [
        [s.display, fmt(s.declared_order), fmt(s.fitted_order, 3), str(sum(s.fit_used)), s.note]
        for s in result.series])
    orders.caption = ("Fit: least-squares slope over the finest (up to 4) rungs of the asymptotic range: rungs below "
                      "10 % error and above the round-off floor, from the finest such rung as far coarser as their "
                      "local slopes agree (within 10 %, at least 0.1). The note says what was left out, or why there "
                      "is no order and which --dts to try.")

    def by_dt(s: ConvergenceSeries, value: str) -> list[str]:
        cells = {p.dt: fmt(getattr(p, value), 3) + (" (added)" if p.added and value == "error" else "")
                 for p in s.points}
        return [cells.get(dt, "") for dt in result.dts]

    errors = Table(["integrator", *[f"dt = {dt:.4g}" for dt in result.dts]], [
        [s.display, *by_dt(s, "error")] for s in result.series],
        caption="Relative position error at the end time for each dt (steps: T / dt whole steps). \"(added)\": a "
                "rung the default ladder added for this integrator to reach its asymptotic range.")
    walls = Table(["integrator", *[f"dt = {dt:.4g}" for dt in result.dts]], [
        [s.display, *by_dt(s, "wall_time_s")] for s in result.series],
        caption="Wall time in seconds (best of repeated runs when a run is shorter than 0.05 s).")
    captions = {
        "convergence": "Error at the end time against dt (log-log). Filled markers entered the fit; hollow "
                       "ones sit on the round-off floor, outside the asymptotic range, or beyond its four finest "
                       "rungs.",
        "work_precision": "Error against wall time: lower-left is better. orbitsim solid, REBOUND dashed.",
    }
    steps = round(result.end_time / abs(sc.dt)) if sc.dt else 0
    sections = [Section("Fitted orders", [orders]), Section("Errors", [errors, walls])]
    if getattr(sc, "forces", ()):
        from orbitsim.scenario.forces import describe_forces  # noqa: PLC0415 -- lazy: loads yaml

        forces = Table(["integrator", "forces and how they are applied"],
                       [[s.display, "; ".join(s.forces) or "none"] for s in result.series])
        forces.caption = (f"The scenario's forces: {describe_forces(sc.forces)}; the IAS15 reference (REBOUND) "
                          "carries every one through REBOUNDx in its equations of motion.")
        sections.append(Section("Forces", [forces]))
    if result.notes:
        sections.append(Section("Notes", list(result.notes)))
    sections += [Section("Figures", [Figure(p.name, captions[k]) for k, p in figures.items()]),
                 Section("Scenario", [scenario_table(sc, steps=steps, samples=2)]), reproduce_section(command, sc)]
    return Report(f"Convergence: {sc.name}", lead, sections)


def write_convergence_outputs(result: ConvergenceResult, outdir: Path, command: str,
                              tolerance: float) -> dict[str, Path]:
    """Write summary.json, both figures and the report into ``outdir``; returns name -> path."""
    outdir.mkdir(parents=True, exist_ok=True)
    summary = outdir / "summary.json"
    summary.write_text(json.dumps(summary_dict(result, command, tolerance), indent=2) + "\n", encoding="utf-8")
    figures = {"convergence": convergence_figure(result, outdir / "convergence.png"),
               "work_precision": work_precision_figure(result, outdir / "work_precision.png")}
    md, page = write_report(build_report(result, figures, command, tolerance), outdir)
    return {"summary": summary, **figures, "markdown": md, "html": page}
