"""Run a benchmark matrix and write ``results.json``, ``results.md`` and the figures.

Stepping cases are measured one N at a time and *interleaved*: after every case of that N has
been built, compiled and warmed up, repeat 1 of each case runs, then repeat 2, and so on. The
machine is shared and its load drifts; interleaving gives every engine the same conditions, so
the ratios between cases (orbitsim against REBOUND) are meaningful even when absolute times are
not (:mod:`orbitsim.bench.interleave`, shared with the ``adaptive`` and ``trace`` kinds).
"""

from __future__ import annotations

import dataclasses
import datetime as _dt
import json
import os
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from orbitsim.bench.interleave import by_n, prepare, rounds
from orbitsim.bench.matrix import BenchMatrix, Group, StepsCase
from orbitsim.bench.plots import write_figures
from orbitsim.bench.report import markdown
from orbitsim.bench.stats import scaled, summarise
from orbitsim.bench.targets import evaluate_targets
from orbitsim.provenance import provenance

__all__ = ["SCHEMA", "machine_info", "quick_matrix", "run_matrix", "write_results"]

#: Identifies the layout of results.json; bump it when a field changes meaning.
SCHEMA = "orbitsim.bench/1"

Progress = Callable[[str], None]


def quick_matrix(matrix: BenchMatrix) -> BenchMatrix:
    """The same matrix, cut down for ``--quick``: at most 3 repeats and 1 warm-up, a tenth of the
    work, steps (never below ``min_steps``) or span, no long trace run."""
    groups = []
    for g in matrix.groups:
        p = dict(g.params)
        if g.kind == "steps":
            p["work"], p["rebound_work"] = p["work"] / 10.0, p["rebound_work"] / 10.0
            p["steps"] = tuple(max(p["min_steps"], s // 10) for s in p["steps"])
            p["steps_by_n"] = {n: max(p["min_steps"], s // 10) for n, s in p["steps_by_n"].items()}
        elif g.kind == "sampling":
            p["steps"] = max(p["every"], p["steps"] // 10)
        elif g.kind == "memory":
            p["trace_samples"] = 0
        elif g.kind == "kernels":
            p["work"] = p["work"] / 10.0
        elif g.kind == "ensemble":
            p["map_n"], p["years"], p["k"], p["steps"] = min(p["map_n"], 8), p["years"] / 10.0, min(p["k"], 512), \
                max(1, p["steps"] // 10)
            p["large_map_n"] = 0  # the 200 x 200 map takes minutes: full runs only
        elif g.kind in ("adaptive", "trace"):
            p["t_end"] = {n: t / 10.0 for n, t in p["t_end"].items()}
        groups.append(dataclasses.replace(g, repeats=min(g.repeats, 3), warmup=min(g.warmup, 1), params=p))
    return dataclasses.replace(matrix, groups=tuple(groups))


def machine_info(threads: int) -> dict[str, Any]:
    """Host, versions and thread settings (from :func:`orbitsim.provenance.provenance`)."""
    import numba  # noqa: PLC0415 -- lazy: loads numba

    info: dict[str, Any] = dict(provenance())
    info.update(threads=threads, numba_max_threads=int(numba.config.NUMBA_NUM_THREADS),
                numba_threading_layer=_threading_layer(),
                load_average=list(os.getloadavg()) if hasattr(os, "getloadavg") else None)
    return info


def _threading_layer() -> str:
    import numba  # noqa: PLC0415 -- lazy: loads numba

    try:
        return str(numba.threading_layer())
    except ValueError:  # no parallel kernel has run yet: the layer is chosen lazily
        return "not yet initialised"


def _case_record(case: StepsCase, stepper: Any, first: float, runs: list[tuple[float, float]]) -> dict[str, Any]:
    t = summarise([wall for wall, _ in runs])
    cpu = summarise([c for _, c in runs])
    per_step = scaled(t, 1.0 / case.steps)
    pairs = case.force_evals * case.n * (case.n - 1) * case.steps
    return {
        "id": case.case_id, "group": case.group, "engine": case.engine, "integrator": case.integrator,
        "system": case.system, "n": case.n, "steps": case.steps, "threads": stepper.threads_used,
        "force_evals": case.force_evals, "repeats": len(runs), "warmup": case.warmup,
        "time_s": t, "per_step_s": per_step, "cpu_s": cpu, "cpu_per_step_s": scaled(cpu, 1.0 / case.steps),
        "pairs_per_s": scaled(t, float(pairs), invert=True),
        "first_call_s": first, "compile_s": max(0.0, first - per_step["median"]), "jit": stepper.jit,
    }


def _run_n(cases: list[StepsCase], progress: Progress, threads: tuple[int, int]) -> tuple[list[dict], list[dict]]:
    """Every case of one N: build and warm up each, then interleaved timed repeats."""
    from orbitsim.bench.engines import make_stepper  # noqa: PLC0415 -- lazy: loads numpy

    ready, skipped = prepare(cases, threads, make_stepper, key=lambda c: f"{c.case_id}/{c.steps}")
    records = []
    for (case, stepper, first), t in zip(ready, rounds(ready), strict=True):
        rec = _case_record(case, stepper, first, t)
        progress(f"{rec['id']}: {rec['per_step_s']['median'] * 1e6:.3g} us/step, "
                 f"{rec['pairs_per_s']['median']:.3g} pairs/s")
        records.append(rec)
    return records, skipped


def _run_steps_group(group: Group, matrix: BenchMatrix, progress: Progress,
                     threads: tuple[int, int]) -> tuple[list, list]:
    cases = [c for c in matrix.steps_cases() if c.group == group.name]
    return by_n(cases, lambda of_n: _run_n(of_n, progress, threads), sorted({c.n for c in cases}))


def _run_probe(group: Group, progress: Progress) -> dict[str, Any]:
    from orbitsim.bench import ensemble, kernels, probes  # noqa: PLC0415 -- lazy: loads numba

    run = {"kernels": kernels.run_kernels, "startup": probes.run_startup, "sampling": probes.run_sampling,
           "memory": probes.run_memory, "ensemble": ensemble.run_ensemble_probe}[group.kind]
    start = time.perf_counter()
    result = run(group)
    progress(f"{group.name} ({group.kind}): done in {time.perf_counter() - start:.1f} s")
    return {"group": group.name, "kind": group.kind, **result}


def _run_timed_group(group: Group, matrix: BenchMatrix, progress: Progress,
                     threads: tuple[int, int]) -> tuple[str, list[dict], list[dict]]:
    """A group of engines timed side by side: (the results key its records go to, records, skipped).

    Adaptive and TRACE records are kept apart from ``cases``: they have no fixed step count of
    the matrix's or pair rate, and the fixed-step tables and figures read every entry of ``cases``.
    """
    if group.kind == "steps":
        return ("cases", *_run_steps_group(group, matrix, progress, threads))
    if group.kind == "adaptive":
        from orbitsim.bench.adaptive import run_adaptive_group  # noqa: PLC0415 -- lazy: loads numpy

        cases = [c for c in matrix.adaptive_cases() if c.group == group.name]
        return ("adaptive", *run_adaptive_group(cases, progress, threads))
    from orbitsim.bench.trace import run_trace_group  # noqa: PLC0415 -- lazy: loads numpy

    cases = [c for c in matrix.trace_cases() if c.group == group.name]
    return ("trace", *run_trace_group(cases, progress, threads))


def run_matrix(matrix: BenchMatrix, *, threads: int | None = None, quick: bool = False,
               progress: Progress | None = None, with_ceiling: bool = True) -> dict[str, Any]:
    """Run every group of ``matrix``; returns the results document (see :data:`SCHEMA`).

    ``threads`` (else the matrix's ``threads``, else ``NUMBA_NUM_THREADS``) is the default for
    cases that do not name a thread count.
    """
    import numba  # noqa: PLC0415 -- lazy: loads numba

    from orbitsim._jit import set_num_threads  # noqa: PLC0415 -- lazy: loads numba
    from orbitsim.bench.ceiling import measure_ceiling  # noqa: PLC0415 -- lazy: loads numba

    say = progress or (lambda _msg: None)
    if quick:
        matrix = quick_matrix(matrix)
    default_threads = set_num_threads(threads if threads is not None else matrix.threads)
    max_threads = int(numba.config.NUMBA_NUM_THREADS)
    started = time.time()
    doc: dict[str, Any] = {"schema": SCHEMA, "matrix": {"name": matrix.name, "source": matrix.source,
                                                         "quick": quick}}
    doc["machine"] = machine_info(default_threads)
    doc["versions"] = {k[: -len("_version")]: v for k, v in doc["machine"].items() if k.endswith("_version")}
    doc["threads"] = default_threads
    doc["ceiling"] = measure_ceiling() if with_ceiling else None
    doc["cases"], doc["adaptive"], doc["trace"], doc["probes"], doc["skipped"] = [], [], [], [], []
    for group in matrix.groups:
        set_num_threads(default_threads)
        if group.kind in ("steps", "adaptive", "trace"):
            key, records, skipped = _run_timed_group(group, matrix, say, (default_threads, max_threads))
            doc[key] += records
            doc["skipped"] += skipped
        else:
            doc["probes"].append(_run_probe(group, say))
    set_num_threads(default_threads)
    doc["machine"]["numba_threading_layer"] = _threading_layer()
    doc["machine"]["load_average_end"] = list(os.getloadavg()) if hasattr(os, "getloadavg") else None
    doc["started"] = _dt.datetime.fromtimestamp(started, _dt.UTC).isoformat(timespec="seconds")
    doc["wall_s"] = time.time() - started

    doc["targets"] = evaluate_targets(doc)
    return doc


def write_results(doc: dict[str, Any], outdir: str | Path, *, plots: bool = True) -> list[Path]:
    """Write ``results.json``, ``results.md`` and (with ``plots``) the figures; returns the paths."""
    out = Path(outdir)
    out.mkdir(parents=True, exist_ok=True)
    written = [out / "results.json", out / "results.md"]
    written[0].write_text(json.dumps(doc, indent=1, sort_keys=False) + "\n", encoding="utf-8")
    written[1].write_text(markdown(doc), encoding="utf-8")
    if plots:
        written += write_figures(doc, out)
    return written
