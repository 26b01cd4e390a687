"""The two IAS15s of a comparison side by side: the table in the reports and ``summary.json``."""

from __future__ import annotations

from typing import Any

from orbitsim.compare.ias15 import escape_summary, mutual_difference
from orbitsim.report import Table, fmt

__all__ = ["MAX_BODIES_FINAL_STATE", "reference_rows", "references_table"]

#: Up to this many bodies the table says, per body, whether it ends bound or escaping.
MAX_BODIES_FINAL_STATE = 10

_CODES = {"rebound": "REBOUND", "orbitsim": "orbitsim"}


def reference_rows(result: Any) -> list[dict[str, Any]]:
    """One entry per IAS15 (the chosen one first): what ``summary.json["references"]`` holds."""
    refs = result.references
    order = [result.reference_choice, *[k for k in refs if k != result.reference_choice]]
    sc = result.scenario
    rows = []
    for choice in order:
        rec = refs[choice]
        other = next((refs[k] for k in refs if k != choice), None)
        diff, when = mutual_difference(rec, other) if other is not None else (float("nan"), float("nan"))
        final = (escape_summary(rec, sc.masses, float(sc.G), list(getattr(sc, "names", [])))
                 if len(sc.masses) <= MAX_BODIES_FINAL_STATE else "")
        rows.append({
            "choice": choice, "label": rec.label, "display": rec.display, "chosen": choice == result.reference_choice,
            "epsilon": rec.options.get("epsilon"), "first_dt": rec.options.get("first_dt"), "status": rec.status,
            "message": rec.message, "max_abs_energy_error": result.metrics[rec.label].max_abs_energy_error,
            "steps": rec.steps_done, "wall_time_s": rec.wall_time_s, "end_time": float(rec.time[-1]) if rec.n_samples
            else None, "max_relative_position_difference": diff, "time_of_max": when, "final_state": final,
        })
    return rows


def references_table(result: Any) -> Table:
    """The report's side-by-side table of both IAS15s, whichever is the reference."""
    rows = reference_rows(result)
    with_final = any(r["final_state"] for r in rows)
    header = ["IAS15", "role", "max |dE/E|", "IAS15 steps", "wall time [s]", "reached t",
              "max rel. position difference to the other", "at t", "status"]
    table = Table(header + (["final state"] if with_final else []), [])
    for r in rows:
        status = r["status"] + (f": {r['message']}" if r["message"] else "")
        role = "reference" if r["chosen"] else "compared with the reference"
        row = [r["display"], role, fmt(r["max_abs_energy_error"]), str(r["steps"]),
               fmt(r["wall_time_s"]), fmt(r["end_time"], 10), fmt(r["max_relative_position_difference"]),
               fmt(r["time_of_max"]), status]
        table.rows.append(row + ([r["final_state"]] if with_final else []))
    table.caption = (
        f"Both IAS15s run from the same state with the same epsilon and first trial step and land exactly on "
        f"the same output times (REBOUND: sim.integrate(t), exact_finish_time = 1). The reference "
        f"(--reference {result.reference_choice}) is the one every run is measured against. Position "
        "differences are relative to the system's size; through close encounters of a chaotic system they "
        "grow with the round-off amplification (see the pair's verdict). Steps: IAS15's accepted steps; wall "
        "time: orbitsim's grid loop after Numba's compile/cache load, REBOUND's time inside sim.integrate. "
        "Final state: the lighter body of each bound pair is bound to the heavier; a body in no bound pair is "
        "escaping, unbound or bound by its energy against the barycentre of the others, at the distance given.")
    return table
