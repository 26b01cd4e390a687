"""``results.md``: the targets table, the stepping, IAS15 and TRACE cases side by side, and the probes."""

from __future__ import annotations

from collections import defaultdict
from typing import Any

from orbitsim.bench.targets import paired_ratio

__all__ = ["adaptive_table", "markdown", "side_by_side", "targets_table", "trace_table"]

#: REBOUND scheme an orbitsim integrator is compared with in the side-by-side table.
PARTNER = {"leapfrog4": "leapfrog:4", "leapfrog6": "leapfrog:6", "leapfrog8": "leapfrog:8",
           "wisdom_holman": "whfast", "trace": "trace"}


def _time(seconds: float) -> str:
    for unit, scale in (("s", 1.0), ("ms", 1e-3), ("us", 1e-6)):
        if seconds >= scale:
            return f"{seconds / scale:.3g} {unit}"
    return f"{seconds * 1e9:.3g} ns"


def _spread(summary: dict[str, Any], fmt: Any = _time) -> str:
    return f"{fmt(summary['median'])} ({fmt(summary['min'])} - {fmt(summary['max'])})"


def targets_table(doc: dict[str, Any]) -> str:
    """The targets as a markdown table: required, measured, margin (>= 1 met)."""
    lines = ["| target | required | measured | margin | met |", "|---|---|---|---|---|"]
    for row in doc.get("targets", []):
        margin = "-" if row["margin"] is None else f"{row['margin']:.2f}"
        met = {True: "yes", False: "**no**", None: "-"}[row["met"]]
        lines.append(f"| {row['target']} | {row['required']} | {row['measured_text']} | {margin} | {met} |")
    return "\n".join(lines)


def side_by_side(doc: dict[str, Any]) -> str:
    """orbitsim's time per step against its REBOUND partner at the same N, measured interleaved.

    The ratios are medians over rounds of each round's ratio
    (:func:`~orbitsim.bench.targets.paired_ratio`), the times per step medians over repeats. The
    last column divides CPU times instead (all threads of the process): for one-thread cases it is
    the cost without the waiting a busy machine adds; for several threads it is not a speed.
    """
    rebound = {(c["group"], c["n"], c["integrator"]): c for c in doc.get("cases", []) if c["engine"] == "rebound"}
    lines = ["| group | N | orbitsim | threads | time/step | REBOUND | time/step | orbitsim / REBOUND | "
             "same, CPU time |", "|---|---|---|---|---|---|---|---|---|"]
    for c in doc.get("cases", []):
        if c["engine"] != "orbitsim":
            continue
        scheme = PARTNER.get(c["integrator"], "leapfrog")
        twin = rebound.get((c["group"], c["n"], scheme))
        if twin is None:
            continue
        ratio = paired_ratio(c, twin)
        cpu = paired_ratio(c, twin, "cpu_s")
        lines.append(f"| {c['group']} | {c['n']} | {c['integrator']} | {c['threads']} | "
                     f"{_time(c['per_step_s']['median'])} | {scheme} | {_time(twin['per_step_s']['median'])} | "
                     f"{ratio:.3g} ({1 / ratio:.3g}x faster) | {cpu:.3g} |")
    return "\n".join(lines) if len(lines) > 2 else "(no case has a REBOUND partner)"


def adaptive_table(doc: dict[str, Any]) -> str:
    """orbitsim's IAS15 against REBOUND's over the same span: accepted steps and time per step of
    each, and REBOUND / orbitsim per step (> 1: orbitsim is faster), paired by round."""
    by_id = {c["id"]: c for c in doc.get("adaptive", [])}
    lines = ["| group | N | system | to t | threads | orbitsim steps (rejected) | time/step | REBOUND steps | "
             "time/step | REBOUND / orbitsim | same, CPU time | first call (jit) |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for c in doc.get("adaptive", []):
        ratio = c.get("rebound_over_orbitsim")
        twin = by_id.get(ratio["twin"]) if ratio else None
        if ratio is None or twin is None:
            continue
        lines.append(f"| {c['group']} | {c['n']} | {c['system']} | {c['t_end']:g} | {c['threads']} | "
                     f"{c['steps']} ({c.get('steps_rejected', '-')}) | {_spread(c['per_step_s'])} | {twin['steps']} | "
                     f"{_spread(twin['per_step_s'])} | {ratio['wall']:.3g} | {ratio['cpu']:.3g} | "
                     f"{_time(c['first_call_s'])} ({c['jit']}) |")
    return "\n".join(lines) if len(lines) > 2 else "(no IAS15 case has a REBOUND partner)"


def trace_table(doc: dict[str, Any]) -> str:
    """orbitsim's trace against REBOUND's TRACE over the same steps: the best and median time of
    each, orbitsim / REBOUND (< 1: orbitsim is faster) from the best repeats and paired by round,
    the encounter work orbitsim counted and whether the final states agree."""
    by_id = {c["id"]: c for c in doc.get("trace", [])}
    lines = ["| group | N | system | to t | steps | orbitsim best (median) | REBOUND best (median) | "
             "orbitsim / REBOUND, best | paired | CPU | redone | encounter BS sub-steps | final states | "
             "first call (jit) |", "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for c in doc.get("trace", []):
        ratio = c.get("orbitsim_over_rebound")
        twin = by_id.get(ratio["twin"]) if ratio else None
        if ratio is None or twin is None:
            continue
        same = c["agreement"]
        agree = "bit-identical" if same["bitwise"] else f"differ by {same['position']:.2g}"
        count = c["counters"]
        lines.append(f"| {c['group']} | {c['n']} | {c['system']} | {c['t_end']:g} | {c['steps']} | "
                     f"{_time(c['time_s']['min'])} ({_time(c['time_s']['median'])}) | {_time(twin['time_s']['min'])} "
                     f"({_time(twin['time_s']['median'])}) | {ratio['best']:.3g} | {ratio['wall']:.3g} | "
                     f"{ratio['cpu']:.3g} | {count.get('redone', '-')} | {count.get('encounter_bs_substeps', '-')} | "
                     f"{agree} | {_time(c['first_call_s'])} ({c['jit']}) |")
    return "\n".join(lines) if len(lines) > 2 else "(no trace case has a REBOUND partner)"


def _cases_table(cases: list[dict[str, Any]]) -> str:
    lines = ["| N | engine | integrator | threads | steps | time/step median (min - max) | pairs/s | "
             "first call (jit) |", "|---|---|---|---|---|---|---|---|"]
    for c in sorted(cases, key=lambda c: (c["n"], c["engine"] != "orbitsim", c["integrator"], c["threads"])):
        lines.append(f"| {c['n']} | {c['engine']} | {c['integrator']} | {c['threads']} | {c['steps']} | "
                     f"{_spread(c['per_step_s'])} | {c['pairs_per_s']['median']:.3g} | "
                     f"{_time(c['first_call_s'])} ({c['jit']}) |")
    return "\n".join(lines)


def _kernels_table(p: dict[str, Any]) -> str:
    names = ("all_pairs", "rows", "blocked")
    lines = [f"One force evaluation, pair interactions/s; blocked = {p['threads']} threads. "
             f"all_pairs faster than rows up to N = {p['all_pairs_until']} (SMALL_N_MAX = {p['small_n_max']}); "
             f"blocked faster than rows from N = {p['blocked_from']} (PARALLEL_MIN_N = {p['parallel_min_n']}).", "",
             "| N | " + " | ".join(names) + " |", "|---|" + "---|" * len(names)]
    for row in p["rows"]:
        cells = [f"{row['pairs_per_s'][k]:.3g}" if k in row["pairs_per_s"] else "-" for k in names]
        lines.append(f"| {row['n']} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def _step_ns_side_by_side(s: dict[str, Any]) -> str:
    """One line of :func:`orbitsim.bench.ensemble.side_by_side_step_ns`'s result: the best of its rounds, and
    WHFast512's figures or the reason it has none."""
    w = s["whfast512"]
    if isinstance(w, str):
        whfast512 = f"WHFast512 not run: {w}"
    else:
        whfast512 = (f"WHFast512 N_systems = 1 {min(w['n_systems_1_ns']):.0f}, N_systems = 2 "
                     f"{min(w['n_systems_2_ns']):.0f} (agrees with WHFast to {w['max_rel_dx']:.1g} relative)")
    return (f"- ns per system-step side by side, best of {len(s['single_ns'])} rounds: ensemble of K = {s['k']} on "
            f"{s['threads']} thread{'s' if s['threads'] != 1 else ''} {min(s['ensemble_threads_ns']):.0f}, on 1 thread "
            f"{min(s['ensemble_1_thread_ns']):.0f}; one system over {s['single_steps']} steps: wisdom_holman "
            f"{min(s['single_ns']):.0f}, REBOUND WHFast {min(s['whfast_ns']):.0f}, {whfast512}")


def _probes(doc: dict[str, Any]) -> list[str]:
    out: list[str] = []
    for p in doc.get("probes", []):
        out.append(f"### {p['group']} ({p['kind']})\n")
        if p["kind"] == "kernels":
            out.append(_kernels_table(p))
        elif p["kind"] == "startup":
            out.append(f"Command: `{p['command']}`, integrator {p['integrator']}, N = {p['n']}, "
                       f"{p['steps']} steps.\n\n- warm cache: {_spread(p['warm'])} wall, "
                       f"{_spread(p['warm_cpu'])} CPU")
            if "cold_s" in p:
                out.append(f"- cold cache (fresh ORBITSIM_CACHE_DIR): {_time(p['cold_s'])} wall, "
                           f"{_time(p['cold_cpu_s'])} CPU, {len(p['compiled_functions'])} functions compiled: "
                           f"{', '.join(p['compiled_functions']) or '(none)'}")
            out.append("")
        elif p["kind"] == "ensemble":
            out.append(f"- {p['map_n']} x {p['map_n']} Jupiter-Saturn map, {p['years']:g} yr: REBOUND WHFast + MEGNO "
                       f"on Pool(2) {_time(p['rebound_map_s'])}; orbitsim map ({p['indicator']}) "
                       f"{_time(p['orbitsim_map_s'])} for the whole command, {_time(p['orbitsim_compute_s'])} for the "
                       f"map's computation (kernels {_time(p['orbitsim_kernel_s'])}"
                       + (f"; readying the kernels before it {_time(p['orbitsim_setup_s'])}"
                          if "orbitsim_setup_s" in p else "") + "); REBOUND / orbitsim = "
                       f"{p['rebound_map_s'] / p['orbitsim_compute_s']:.1f} (computation; target >= 10), "
                       f"{p['rebound_map_s'] / p['orbitsim_map_s']:.2f} (whole command)")
            if p.get("large_map_n"):
                out.append(f"- {p['large_map_n']} x {p['large_map_n']} map, one file: orbitsim map "
                           f"{_time(p['large_map_s'])} for the whole command (kernels {_time(p['large_kernel_s'])}; "
                           f"target <= 60 s); REBOUND's estimate (its {p['map_n']} x {p['map_n']} time per pixel) "
                           f"{_time(p['large_rebound_estimate_s'])}")
            out.append(f"- ns per system-step, 4 bodies: ensemble of K = {p['k']} {p['ensemble_ns']:.0f}, one system "
                       f"(wisdom_holman, 1 thread) {p['single_ns']:.0f}, REBOUND WHFast {p['rebound_ns']:.0f}")
            if "step_ns_side_by_side" in p:
                out.append(_step_ns_side_by_side(p["step_ns_side_by_side"]))
            rates = p.get("variational_pixel_steps_per_s", {})
            if rates:
                out.append(f"- pixel-steps/s with the variational equations and MEGNO, K = {p['k']} 4-body systems, "
                           "one run: " + ", ".join(f"{name} {rate:.3g}" for name, rate in rates.items()))
            if "variational_lanes_step_ns" in p:
                v = p["variational_lanes_step_ns"]
                out.append(f"- ns per system-step with the variational equations and MEGNO (wisdom_holman, whole "
                           f"systems), best of {len(v['lanes_1_thread_ns'])} rounds, K = {v['k']}: 16 lanes "
                           f"{min(v['lanes_1_thread_ns']):.0f} on 1 thread, {min(v['lanes_threads_ns']):.0f} on "
                           f"{v['threads']}; scalar kernel {min(v['scalar_1_thread_ns']):.0f} on 1 thread, "
                           f"{min(v['scalar_threads_ns']):.0f} on {v['threads']}")
            out.append("")
        elif p["kind"] == "sampling":
            out.append(f"{p['integrator']}, N = {p['n']}, {p['steps']} steps: every {p['every']} steps "
                       f"({p['samples']} samples) {_spread(p['with_samples'])}; first and last only "
                       f"{_spread(p['without_samples'])}; overhead {p['overhead']:+.1%} "
                       f"(median of the {len(p['with_samples']['values'])} rounds' ratios; "
                       f"from the medians {p.get('overhead_of_medians', float('nan')):+.1%}, "
                       f"from the minima {p['overhead_min']:+.1%}, "
                       f"from CPU time {p.get('overhead_cpu', float('nan')):+.1%}).\n")
        elif p["kind"] == "memory":
            big = p["large"]
            out.append(f"- N = {big['n']}, {big['steps']} steps: peak RSS {big['peak_rss_mb']:.0f} MB "
                       f"(after imports and a warm-up: {big['baseline_rss_mb']:.0f} MB); limit {p['limit_mb']:g} MB.")
            if "trace" in p:
                t = p["trace"]
                rss = [row[2] for row in t["series"]]
                out.append(f"- trace of {t['samples']:,} samples (N = {t['n']}, via {t['path']}, "
                           f"{t['wall_s']:.0f} s, file {t['file_mb']:.0f} MB): RSS {min(rss):.0f} - {max(rss):.0f} MB, "
                           f"median RSS {t['settled_rss_mb']:.0f} MB at 10-30% of the samples, "
                           f"{t['growth_mb']:+.1f} MB by the end.")
            out.append("")
    return out


def markdown(doc: dict[str, Any]) -> str:
    """The whole ``results.md`` text."""
    m = doc["machine"]
    ceiling = doc.get("ceiling") or {}
    parts = [f"# orbitsim benchmark: {doc['matrix']['name']}" + (" (quick)" if doc["matrix"]["quick"] else ""), ""]
    parts.append(f"{m.get('cpu_model')} ({m.get('cpu_count')} cores), {doc['threads']} threads "
                 f"({m.get('numba_threading_layer')}), started {doc.get('started')}, {doc.get('wall_s', 0):.0f} s; "
                 f"load average {_load(m.get('load_average'))} at start, {_load(m.get('load_average_end'))} at end.")
    parts.append(f"orbitsim {m.get('orbitsim_version')}, numba {m.get('numba_version')}, numpy "
                 f"{m.get('numpy_version')}, REBOUND {m.get('rebound_version')}, Python {m.get('python_version')}.")
    if ceiling:
        parts.append(f"Measured ceiling of the square-root/division unit: {ceiling['full_per_core']:.3g} "
                     f"interactions/s per core computing every pair, {ceiling['pairs_once_per_core']:.3g} "
                     "counting N(N-1) when each pair is computed once.")
    parts += ["", "## Targets", "", targets_table(doc), "", "## orbitsim beside REBOUND (same run, interleaved)",
              "", side_by_side(doc), ""]
    if doc.get("adaptive"):
        epsilon = " or ".join(f"{e:g}" for e in sorted({c["epsilon"] for c in doc["adaptive"]}))
        parts += ["## orbitsim beside REBOUND: IAS15 over the same span (interleaved)", "",
                  f"Each repeat integrates from t = 0 with epsilon = {epsilon}; the time per step is "
                  "the time over the span divided by the engine's own accepted steps.", "",
                  adaptive_table(doc), ""]
    if doc.get("trace"):
        parts += ["## orbitsim beside REBOUND: TRACE over the same steps (interleaved)", "",
                  "Each repeat integrates from the initial state over the same whole steps in both codes "
                  "(REBOUND's default TRACE settings); best is the fastest repeat, paired the median over "
                  "rounds of the ratio within a round.", "", trace_table(doc), ""]
    groups: dict[str, list[dict[str, Any]]] = defaultdict(list)
    for c in doc.get("cases", []):
        groups[c["group"]].append(c)
    for name, cases in groups.items():
        parts += [f"## {name}", "", _cases_table(cases), ""]
    if doc.get("probes"):
        parts += ["## Kernels, start-up, output and memory", "", *_probes(doc)]
    if doc.get("skipped"):
        parts += ["## Skipped", "", *(f"- {s['id']}: {s['reason']}" for s in doc["skipped"]), ""]
    return "\n".join(parts) + "\n"


def _load(values: list[float] | None) -> str:
    return "/".join(f"{v:.1f}" for v in values) if values else "n/a"
