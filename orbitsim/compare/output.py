"""The files ``orbitsim compare`` writes: compare.h5, summary.json, report.md/.html and figures.

``summary.json`` (format ``orbitsim.compare.summary``, version 4) holds, besides provenance:

* ``scenario``: name, source, sha256, bodies, G, softening, dt, steps, t_end, samples, adaptive
  (for an adaptive scenario ``dt`` is ias15's first trial step, ``steps`` its output intervals
  and ``output_interval`` their length);
* ``runs``: one entry per run (label, engine, integrator, display, order, options, dt, steps,
  samples, status, message, max_abs_energy_error, energy_drift_slope, final_position_error,
  wall_time_s, steps_per_second, forces: how the run applies each of the scenario's forces, one
  phrase per force), the reference last;
* ``reference``: label, choice (``rebound`` or ``orbitsim``), max_abs_energy_error, energy_limit,
  reliable, problem;
* ``references``: both IAS15s side by side, one entry each (choice, label, display, chosen,
  epsilon, first_dt, status, max_abs_energy_error, steps, wall_time_s,
  max_relative_position_difference to the other and its time_of_max, final_state);
* ``pairs``: one per matched pair (name, orbitsim, rebound, reason, builtin,
  max_relative_position_difference, time_of_max, tolerance, allowed_at_max, tolerance_source,
  max_allowed, testable_limit, untestable_from, nominal_tolerance, twin_max, worst_ratio,
  within_tolerance, verdict, verdict_label, agree, note); ``agree`` is true only for a pass;
  ``verdict`` ``not_comparable`` (its ``note`` says why, the measured fields are null) marks a
  pair whose codes cannot apply the scenario's forces alike;
* ``verdict`` (``pass``, ``fail`` or ``not_testable``), ``passed``, ``failed_pairs`` and
  ``untestable_pairs``: the verdict behind the exit code (0, 1 and 5).

Version 4 added each run's ``forces`` and the pair verdict ``not_comparable``.
Version 3 added ``references``, ``reference.choice`` and the scenario's ``adaptive`` and
``output_interval``; the reference's run in ``runs`` is the chosen one.
Version 2 added ``reference``, ``verdict``, ``untestable_pairs`` and the per-pair verdict fields,
and made ``agree`` and ``passed`` false for a comparison that agrees only within a tolerance too
loose to test anything (version 1 called that a pass).

Non-finite numbers are written as ``null`` so the file is strict JSON.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from orbitsim.compare.figures import compare_figures
from orbitsim.compare.metrics import NOT_COMPARABLE, REFERENCE_ENERGY_LIMIT, TESTABLE_LIMIT
from orbitsim.compare.references import reference_rows, references_table
from orbitsim.compare.run import CompareResult
from orbitsim.compare.tracegroup import write_file_attrs, write_trace_group
from orbitsim.io.h5safe import in_memory, new_file
from orbitsim.plots.style import unit_labels
from orbitsim.provenance import provenance
from orbitsim.reference.pairs import ENCOUNTER_CHAOS, TWIN_MARGIN
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

SUMMARY_FORMAT = "orbitsim.compare.summary"
SUMMARY_VERSION = 4

_FIGURE_CAPTIONS = {
    "energy": "Relative energy error |dE/E| against time (log axes): orbitsim left, REBOUND right, "
              "the IAS15 reference dashed in both. A matched pair has the same colour in both panels.",
    "position_error": "Position error against the IAS15 reference, relative to the system's size "
                      "(max over bodies of the displacement / max distance from the origin).",
    "pairs": "Relative position difference of each matched pair over the run (solid) and its "
             "tolerance (dotted, same colour). A pair agrees while the solid line stays below.",
    "orbits": "Paths in the x-y plane of the IAS15 reference and of every run.",
}


def _steps(result: CompareResult) -> int:
    return int(result.reference.step[-1]) if result.reference.n_samples else 0


def _end_time(result: CompareResult) -> float:
    """The comparison's end time: ``t_end`` for an adaptive scenario, else ``steps * dt``."""
    sc = result.scenario
    return float(sc.t_end) if getattr(sc, "adaptive", False) else _steps(result) * float(sc.dt)


def summary_dict(result: CompareResult, command: str) -> dict[str, Any]:
    """The content of ``summary.json`` (see the module docstring)."""
    sc = result.scenario
    runs = []
    for rec in [*result.runs, result.reference]:
        m = result.metrics[rec.label]
        runs.append({
            "label": rec.label, "engine": rec.engine, "integrator": rec.integrator, "display": rec.display,
            "order": rec.order, "options": rec.options, "dt": rec.dt, "steps": rec.steps_done,
            "samples": rec.n_samples, "status": rec.status, "message": rec.message,
            "max_abs_energy_error": m.max_abs_energy_error, "energy_drift_slope": m.energy_drift_slope,
            "final_position_error": m.final_position_error, "wall_time_s": m.wall_time_s,
            "steps_per_second": m.steps_per_second, "forces": list(rec.forces),
        })
    pairs = [{
        "name": v.name, "orbitsim": v.orbitsim_label, "rebound": v.rebound_label, "reason": v.pair.reason,
        "builtin": v.pair.builtin, "max_relative_position_difference": v.max_difference,
        "time_of_max": v.time_of_max, "tolerance": v.tolerance, "allowed_at_max": v.allowed_at_max,
        "tolerance_source": None if v.verdict == NOT_COMPARABLE else "twin" if v.twin_limited else "nominal",
        "max_allowed": v.max_allowed,
        "testable_limit": TESTABLE_LIMIT, "untestable_from": v.untestable_from,
        "nominal_tolerance": v.nominal_tolerance, "twin_max": v.twin_max, "worst_ratio": v.worst_ratio,
        "within_tolerance": v.within_tolerance, "verdict": v.verdict, "verdict_label": v.label,
        "agree": v.agree, "note": v.note,
    } for v in result.verdicts]
    ref = result.reference
    reference = {"label": ref.label, "choice": result.reference_choice,
                 "max_abs_energy_error": result.metrics[ref.label].max_abs_energy_error,
                 "energy_limit": REFERENCE_ENERGY_LIMIT, "reliable": not result.reference_problem,
                 "problem": result.reference_problem}
    steps = _steps(result)
    scenario = {"name": sc.name, "source": str(getattr(sc, "source", "")), "sha256": getattr(sc, "sha256", ""),
                "bodies": len(sc.masses), "G": sc.G, "softening": sc.softening, "dt": sc.dt, "steps": steps,
                "t_end": _end_time(result), "samples": result.reference.n_samples,
                "adaptive": bool(getattr(sc, "adaptive", False))}
    if scenario["adaptive"]:
        scenario["output_interval"] = float(sc.grid_dt)
    return json_safe({"format": SUMMARY_FORMAT, "format_version": SUMMARY_VERSION, "command": command,
                   "scenario": scenario, "runs": runs, "reference": reference,
                   "references": reference_rows(result), "pairs": pairs,
                   "verdict": result.verdict, "passed": result.passed, "failed_pairs": result.failed_pairs,
                   "untestable_pairs": result.untestable_pairs, "notes": result.notes,
                   "provenance": provenance()})


def write_h5(result: CompareResult, path: Path, command: str) -> Path:
    """``compare.h5``: one trace-layout group per run, the twins and the reference."""
    sc = result.scenario
    yaml_text = sc.to_yaml() if hasattr(sc, "to_yaml") else ""
    attrs = {"scenario": yaml_text, "scenario_sha256": str(getattr(sc, "sha256", "")),
             "G": float(sc.G), "softening": float(sc.softening), "units": str(getattr(sc, "units", ""))}
    tmp = path.with_name(path.name + ".tmp")
    # Each group is built in memory and copied in whole, so that a full disk is one clean error.
    with new_file(tmp) as f:
        write_file_attrs(f, {**attrs, "command": command, "passed": result.passed, "verdict": result.verdict})
        for rec in [*result.runs, *result.twins.values(), *(result.references.values() or [result.reference])]:
            with in_memory() as memory:
                group = write_trace_group(memory, rec.label, rec, names=list(sc.names), masses=sc.masses,
                                          attrs=attrs)
                f.copy(group, rec.label)
    tmp.replace(path)  # a compare.h5 that exists is complete
    return path


def build_report(result: CompareResult, figures: dict[str, Path], command: str) -> Report:
    """The comparison report: verdict, scenario, runs, pairs, figures, reproduction."""
    sc = result.scenario
    time_unit = _time_unit(sc)
    lead = [_verdict_line(result)]  # names an unreliable reference too
    runs = Table(["run", "order", "steps", "max |dE/E|", f"dE/E drift [1/{time_unit}]",
                  "final pos. error vs ref.", "wall time [s]", "steps/s", "status"], [])
    for rec in [*result.runs, result.reference]:
        m = result.metrics[rec.label]
        status = rec.status + (f": {rec.message}" if rec.message else "")
        if rec is result.reference and result.reference_problem:
            status += f"; UNRELIABLE as a reference (max |dE/E| > {REFERENCE_ENERGY_LIMIT:g})"
        runs.rows.append([rec.display, fmt(rec.order), str(rec.steps_done), fmt(m.max_abs_energy_error),
                          fmt(m.energy_drift_slope), fmt(m.final_position_error), fmt(m.wall_time_s),
                          fmt(m.steps_per_second), status])
    runs.caption = ("Reference steps are IAS15's adaptive steps. Wall time: orbitsim, the whole sampled run "
                    "(its diagnostics are computed inside the compiled loop), after Numba's compile/cache "
                    "load; REBOUND, the time inside sim.steps() (IAS15: sim.integrate) only, without reading "
                    "samples back.")
    pairs = Table(["pair", "max rel. position difference", f"at t [{time_unit}]", "allowed there",
                   "allowed set by", "worst difference / allowed", "twin divergence", "verdict",
                   "why they should agree"], [
        [v.name, fmt(v.max_difference), fmt(v.time_of_max), fmt(v.allowed_at_max), v.tolerance_source(),
         fmt(v.worst_ratio, 2), fmt(v.twin_max), v.label + (f" ({v.note})" if v.note else ""), v.pair.reason]
        for v in result.verdicts])
    pairs.caption = ("Tolerance: max(1e-9 (n/1e4)^1.5, 100 x twin divergence), where the twin is REBOUND "
                     "rerun from positions scaled by 1 + 2^-50; differences are relative to the system's size "
                     "(the largest distance of a body from the origin). Where the tolerance exceeds "
                     f"{TESTABLE_LIMIT:g} of that size the agreement is not testable, and where the IAS15 "
                     f"reference's |dE/E| exceeds {REFERENCE_ENERGY_LIMIT:g} neither is any verdict "
                     "(see docs/compare.md).")
    pair_blocks: list[str | Table] = [pairs, *encounter_sentences(result)] if result.verdicts else [
        "No matched pairs were run."]
    table = scenario_table(sc, steps=_steps(result), samples=result.reference.n_samples, end_time=_end_time(result))
    sections = [Section("Scenario", [table]), Section("Runs", [runs])]
    if getattr(sc, "forces", ()):
        sections.append(Section("Forces", [forces_table(result)]))
    if result.references:
        sections.append(Section("IAS15 references", [references_table(result)]))
    sections.append(Section("Matched pairs", pair_blocks))
    sections.append(Section("Figures", [Figure(p.name, _FIGURE_CAPTIONS[name]) for name, p in figures.items()]))
    if result.notes:
        sections.append(Section("Notes", list(result.notes)))
    sections.append(reproduce_section(command, sc))
    return Report(f"orbitsim vs REBOUND: {sc.name}", lead, sections)


def forces_table(result: CompareResult) -> Table:
    """How each run applies each of the scenario's forces: orbitsim's runs and REBOUND's side by side."""
    from orbitsim.scenario.forces import describe_forces  # noqa: PLC0415 -- lazy: loads yaml

    records = [*result.runs, *result.references.values()] or [*result.runs, result.reference]
    table = Table(["run", "forces and how they are applied"],
                  [[rec.display, "; ".join(rec.forces) or "none"] for rec in records])
    table.caption = (f"The scenario's forces: {describe_forces(result.scenario.forces)}. REBOUND carries them "
                     "through REBOUNDx, arranged as orbitsim applies each: position-only forces with gravity, "
                     "velocity-dependent ones as their own operator over dt/2 before and after each step "
                     "(Tamayo et al. 2020), every force in IAS15's equations of motion (docs/compare.md).")
    return table


def encounter_sentences(result: CompareResult) -> list[str]:
    """For each pair of hybrids that switch at close encounters (TRACE), one sentence: encounters
    are chaotic, so the codes agree bit for bit or diverge as round-off grows, and the
    twin-divergence tolerance this run allowed, with the difference measured against it."""
    out = []
    for v in result.verdicts:
        if not v.pair.encounters:
            continue
        twin = (f"{TWIN_MARGIN:g} x the divergence of a REBOUND twin started 4 ulp away, up to "
                f"{TWIN_MARGIN * v.twin_max:.3g} of the system's size here" if math.isfinite(v.twin_max)
                else f"{TWIN_MARGIN:g} x the divergence of a REBOUND twin started 4 ulp away (no twin run here)")
        out.append(f"{v.name}: {ENCOUNTER_CHAOS}, which the twin-divergence tolerance allows for: {twin} "
                   f"(measured difference {fmt(v.max_difference)}; allowed there {fmt(v.allowed_at_max)}, "
                   f"set by the {'twin' if v.twin_limited else 'nominal'} term).")
    return out


def _time_unit(scenario: Any) -> str:
    return unit_labels(getattr(scenario, "units", ""))[0]


def _verdict_line(result: CompareResult) -> str:
    untestable = "; ".join(result.untestable_reasons())
    if result.verdict == "fail":
        failed = [f"{name} disagrees" for name in result.failed_pairs]
        return "FAIL: " + "; ".join([*failed, f"not testable: {untestable}"] if untestable else failed)
    if result.verdict == "not_testable":
        return f"NOT TESTABLE: no matched pair disagrees, but this comparison cannot pass: {untestable}."
    if not result.verdicts:
        return "PASS (no matched pairs to judge)"
    return f"PASS: all {len(result.verdicts)} matched pairs agree within their tolerances."


def write_compare_outputs(result: CompareResult, outdir: Path, command: str) -> dict[str, Path]:
    """Write every output file into ``outdir`` (created if missing); returns name -> path."""
    outdir.mkdir(parents=True, exist_ok=True)
    paths: dict[str, Path] = {"h5": write_h5(result, outdir / "compare.h5", command)}
    summary = outdir / "summary.json"
    summary.write_text(json.dumps(summary_dict(result, command), indent=2) + "\n", encoding="utf-8")
    paths["summary"] = summary
    figures = compare_figures(result, outdir)
    paths.update(figures)

    paths["markdown"], paths["html"] = write_report(build_report(result, figures, command), outdir)
    return paths
