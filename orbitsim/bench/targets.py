"""The performance targets of orbitsim, checked against a results document.

Each target reads what it needs from the results; when the matrix did not measure it, the
target is reported as "not measured" instead of failing. Ratios against REBOUND use cases of
the same group and the same N, which the runner measured interleaved (round r times every case
once), and each ratio is the median over rounds of the ratio within a round (:func:`paired_ratio`):
the load on this shared machine changes from second to second, and a round's two timings are the
closest in time. ``margin`` is always oriented so that >= 1 means the target is met.

The IAS15 targets read the ``adaptive`` records (:mod:`orbitsim.bench.adaptive`): the two engines
integrate the same span but choose their own steps, so their ratio is of time per *accepted*
step, each engine's time over the span divided by its own count. The TRACE targets read the
``trace`` records (:mod:`orbitsim.bench.trace`): both engines take the same steps from the same
state, and the ratio is of the fastest repeat of each (the suite's paired median beside it).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from orbitsim.bench.stats import paired_median

__all__ = ["TARGETS", "evaluate_targets", "paired_ratio"]

Doc = dict[str, Any]

#: Force throughput at N = 16,384 through the stepping loop, 2 cores (pair interactions/s).
THROUGHPUT_16K = 3.5e9
#: A step at N = 4,096 at least this many times faster than REBOUND's leapfrog.
SPEEDUP_4096 = 10.0
#: Time per step at N = 5 at most this fraction of REBOUND's leapfrog.
SMALL_N_FRACTION = 0.5
#: Whole-process start-up of ``orbitsim run`` on a tiny scenario, warm cache (s).
STARTUP_WARM_S = 1.0
#: Cost of sampling every 100 steps at N = 9, relative to no sampling.
SAMPLING_OVERHEAD = 0.05
#: Peak RSS of a 16,384-body run (MiB).
MEMORY_16K_MB = 300.0
#: IAS15 at N = 5: REBOUND IAS15's time per step over orbitsim's, at least this (level or faster).
IAS15_SMALL_RATIO = 1.0
#: IAS15 at N ~ 1000 must beat REBOUND IAS15 by verlet's ratio over REBOUND leapfrog at this N, the
#: same force work per evaluation, measured in the same run ...
IAS15_VERLET_N = 1024
#: ... or, when the run has no verlet/leapfrog pair there, by this much.
IAS15_LARGE_FALLBACK = 5.0
#: TRACE on REBOUND's many-encounters set-up (the bundled scenario, t = 2000): orbitsim's time at
#: most REBOUND's TRACE's, and on a disc of ~100 planetesimals with encounters below it. Both are
#: orbitsim / REBOUND over the same steps, best repeat against best repeat.
TRACE_RATIO = 1.0
#: The systems the two TRACE targets read (``system`` of a ``trace`` group).
TRACE_ENCOUNTERS_SYSTEM = "many_encounters"
TRACE_DISC_SYSTEM = "planetesimals"
#: The 20 x 20 Jupiter-Saturn map (1e4 yr, MEGNO): REBOUND WHFast + MEGNO on Pool(2) over orbitsim's
#: computation (map.h5's ``wall_time_s``; both codes' libraries loaded before their clocks), at least this.
MAP_RATIO = 10.0
#: The map that target is about: its side in pixels and its span in years.
MAP_RATIO_MAP = (20, 1.0e4)
#: The 200 x 200 map of the same system, the whole ``orbitsim map`` command, at most this (s).
MAP_LARGE_S = 60.0
#: RSS growth allowed from the 10-30% of a long trace-writing run to its last 20% (medians of
#: the readings, :func:`orbitsim.bench.probes.rss_growth`), as a fraction of the settled RSS.
TRACE_GROWTH = 0.05


def _orbitsim_steps(doc: Doc, n: int, integrators: tuple[str, ...]) -> dict[str, Any] | None:
    """The orbitsim case at N with the most threads, preferring the order of ``integrators``."""
    found = [c for c in doc.get("cases", []) if c["engine"] == "orbitsim" and c["n"] == n
             and c["integrator"] in integrators]
    if not found:
        return None
    return max(found, key=lambda c: (c["threads"], -integrators.index(c["integrator"])))


def _rebound_twin(doc: Doc, case: dict[str, Any], scheme: str = "leapfrog") -> dict[str, Any] | None:
    for c in doc.get("cases", []):
        if c["engine"] == "rebound" and c["integrator"] == scheme and c["n"] == case["n"] \
                and c["group"] == case["group"]:
            return c
    return None


def _best_pair(doc: Doc, n: int, name: str) -> tuple[dict[str, Any], dict[str, Any]] | None:
    """The orbitsim ``name`` case at N and its REBOUND leapfrog twin, from the group with the most
    interleaved rounds (the matrix's short-round pair group, where there is one), then most threads."""
    pairs = []
    for c in doc.get("cases", []):
        if c["engine"] == "orbitsim" and c["n"] == n and c["integrator"] == name:
            twin = _rebound_twin(doc, c)
            if twin is not None:
                pairs.append((min(c["repeats"], twin["repeats"]), c["threads"], c, twin))
    if not pairs:
        return None
    _, _, case, twin = max(pairs, key=lambda p: (p[0], p[1]))
    return case, twin


def paired_ratio(case: dict[str, Any], twin: dict[str, Any], block: str = "time_s") -> float:
    """Median over interleaved rounds of case/twin time per step, each round's pair side by side.

    ``block`` is ``time_s`` (wall) or ``cpu_s``; both hold every repeat in ``values``, in round
    order. A burst of load that slows some repeats of one engine and not the other shifts the ratio
    of the two medians, but only the rounds it hit of the paired ratios.
    """
    return paired_median([v / case["steps"] for v in case[block]["values"]],
                         [v / twin["steps"] for v in twin[block]["values"]])


def _probe(doc: Doc, kind: str) -> dict[str, Any] | None:
    return next((p for p in doc.get("probes", []) if p["kind"] == kind), None)


def _row(key: str, label: str, required: str, measured: float | None, text: str, margin: float | None,
         where: str = "") -> dict[str, Any]:
    met = None if margin is None else bool(margin >= 1.0)
    return {"key": key, "target": label, "required": required, "measured": measured, "measured_text": text,
            "margin": margin, "met": met, "source": where}


def _throughput(doc: Doc) -> dict[str, Any]:
    case = _orbitsim_steps(doc, 16384, ("verlet", "semi_implicit_euler", "leapfrog"))
    label = "force throughput, N = 16,384, stepping loop, all threads"
    if case is None:
        return _row("throughput_16k", label, ">= 3.5e9 pairs/s", None, "not measured", None)
    rate = case["pairs_per_s"]["median"]
    return _row("throughput_16k", label, f">= {THROUGHPUT_16K:.2g} pairs/s", rate,
                f"{rate:.3g} pairs/s ({case['threads']} threads)", rate / THROUGHPUT_16K, case["id"])


def _speedup(doc: Doc) -> dict[str, Any]:
    label = "step at N = 4,096 vs REBOUND leapfrog"
    case = _orbitsim_steps(doc, 4096, ("verlet", "semi_implicit_euler", "leapfrog"))
    twin = _rebound_twin(doc, case) if case else None
    if twin is None:
        return _row("speedup_4096", label, ">= 10x faster", None, "not measured", None)
    ratio = paired_ratio(twin, case)
    return _row("speedup_4096", label, f">= {SPEEDUP_4096:g}x faster", ratio,
                f"{ratio:.1f}x faster (median of {min(case['repeats'], twin['repeats'])} rounds)",
                ratio / SPEEDUP_4096, f"{case['id']} vs {twin['id']}")


def _small_n(name: str) -> Callable[[Doc], dict[str, Any]]:
    def check(doc: Doc) -> dict[str, Any]:
        label = f"{name} step at N = 5 vs REBOUND leapfrog"
        pair = _best_pair(doc, 5, name)
        if pair is None:
            return _row(f"small_n_{name}", label, "<= 0.5x the time", None, "not measured", None)
        case, twin = pair
        frac = paired_ratio(case, twin)
        cpu = paired_ratio(case, twin, "cpu_s")
        text = (f"{frac:.2f}x the time (median of {min(case['repeats'], twin['repeats'])} rounds; "
                f"{case['per_step_s']['median'] * 1e9:.0f} ns vs {twin['per_step_s']['median'] * 1e9:.0f} ns "
                f"in {case['group']}; CPU time {cpu:.2f}x)")
        return _row(f"small_n_{name}", label, f"<= {SMALL_N_FRACTION:g}x the time", frac, text,
                    SMALL_N_FRACTION / frac, f"{case['id']} vs {twin['id']}")
    return check


def _ias15_case(doc: Doc, n: int, near: bool = False) -> dict[str, Any] | None:
    """The orbitsim IAS15 record paired with REBOUND at N (``near``: the closest N within a factor
    1.5), from the pair with the most interleaved rounds, then the most threads."""
    found = [c for c in doc.get("adaptive", []) if c["engine"] == "orbitsim" and "rebound_over_orbitsim" in c
             and (c["n"] == n or (near and n / 1.5 <= c["n"] <= n * 1.5))]
    if not found:
        return None
    return max(found, key=lambda c: (-abs(c["n"] - n), c["rebound_over_orbitsim"]["rounds"], c["threads"]))


def _ias15_measured(doc: Doc, case: dict[str, Any]) -> str:
    r = case["rebound_over_orbitsim"]
    twin = next(c for c in doc["adaptive"] if c["id"] == r["twin"])
    return (f"{r['wall']:.2f}x faster (median of {r['rounds']} rounds; to t = {case['t_end']:g}, "
            f"{case['steps']} steps of {case['per_step_s']['median'] * 1e6:.3g} us on {case['threads']} "
            f"thread{'s' if case['threads'] != 1 else ''} vs "
            f"{twin['steps']} of {twin['per_step_s']['median'] * 1e6:.3g} us; CPU time {r['cpu']:.2f}x)")


def _ias15_small(doc: Doc) -> dict[str, Any]:
    label = "ias15 N = 5: time per step vs REBOUND IAS15"
    required = "<= REBOUND IAS15's (>= 1x faster)"
    case = _ias15_case(doc, 5)
    if case is None:
        return _row("ias15_n5", label, required, None, "not measured", None)
    ratio = case["rebound_over_orbitsim"]["wall"]
    return _row("ias15_n5", label, required, ratio, _ias15_measured(doc, case), ratio / IAS15_SMALL_RATIO,
                f"{case['id']} vs {case['rebound_over_orbitsim']['twin']}")


def _verlet_ratio(doc: Doc, threads: int | None) -> tuple[float, str]:
    """How many times faster verlet's step is than REBOUND leapfrog's at N = 1024 in this run (the
    throughput group first, then the same thread count as the IAS15 case, then the most rounds),
    with where it comes from; else the fallback, saying so."""
    pairs = []
    for c in doc.get("cases", []):
        if c["engine"] == "orbitsim" and c["integrator"] == "verlet" and c["n"] == IAS15_VERLET_N:
            twin = _rebound_twin(doc, c)
            if twin is not None:
                pairs.append(((c["group"] == "throughput", c["threads"] == threads,
                               min(c["repeats"], twin["repeats"]), c["threads"]), c, twin))
    if not pairs:
        return IAS15_LARGE_FALLBACK, (f"{IAS15_LARGE_FALLBACK:g}x: no verlet/leapfrog pair at N = "
                                      f"{IAS15_VERLET_N} in this run, fallback")
    _, case, twin = max(pairs, key=lambda p: p[0])
    ratio = paired_ratio(twin, case)
    return ratio, f"{ratio:.1f}x, verlet's over REBOUND leapfrog ({case['id']})"


def _ias15_large(doc: Doc) -> dict[str, Any]:
    label = "ias15 N = 1000: faster than REBOUND IAS15 by at least verlet's ratio over REBOUND leapfrog"
    case = _ias15_case(doc, 1000, near=True)
    need, why = _verlet_ratio(doc, case["threads"] if case else None)
    required = f">= {why}"
    if case is None:
        return _row("ias15_n1000", label, required, None, "not measured", None)
    ratio = case["rebound_over_orbitsim"]["wall"]
    return _row("ias15_n1000", label, required, ratio, _ias15_measured(doc, case), ratio / need,
                f"{case['id']} vs {case['rebound_over_orbitsim']['twin']}")


def _trace_measured(case: dict[str, Any]) -> str:
    r, same, count = case["orbitsim_over_rebound"], case["agreement"], case["counters"]
    agree = ("final states bit-identical" if same["bitwise"] else
             f"final positions differ by {same['position']:.1e} of the system's size")
    return (f"{r['best']:.2f}x the time (best of {r['rounds']}; paired median {r['wall']:.2f}, CPU {r['cpu']:.2f}); "
            f"{case['steps']} steps to t = {case['t_end']:g}, {count.get('redone', 0)} redone, "
            f"{count.get('encounter_bs_substeps', 0)} encounter BS sub-steps; {agree}")


def _trace(key: str, label: str, system: str, strict: bool) -> Callable[[Doc], dict[str, Any]]:
    """A TRACE target on the orbitsim ``trace`` record of ``system`` paired with REBOUND (the one
    with the most rounds): orbitsim / REBOUND <= 1, or < 1 when ``strict``. A span without a close
    encounter measures only the Wisdom-Holman map and is reported, not judged."""
    required = f"orbitsim / REBOUND {'<' if strict else '<='} {TRACE_RATIO:g} (best repeats)"

    def check(doc: Doc) -> dict[str, Any]:
        found = [c for c in doc.get("trace", []) if c["engine"] == "orbitsim" and c["system"] == system
                 and "orbitsim_over_rebound" in c]
        if not found:
            return _row(key, label, required, None, "not measured", None)
        case = max(found, key=lambda c: c["orbitsim_over_rebound"]["rounds"])
        ratio, where = case["orbitsim_over_rebound"]["best"], f"{case['id']} vs {case['orbitsim_over_rebound']['twin']}"
        if not case["counters"].get("encounter_bs_substeps"):
            return _row(key, label, required, ratio, _trace_measured(case) + ": no close encounter, not judged",
                        None, where)
        row = _row(key, label, required, ratio, _trace_measured(case), TRACE_RATIO / ratio, where)
        row["met"] = bool(ratio < TRACE_RATIO if strict else ratio <= TRACE_RATIO)
        return row
    return check


def _startup_warm(doc: Doc) -> dict[str, Any]:
    p = _probe(doc, "startup")
    label = "CLI start-up, tiny scenario, warm cache"
    if p is None:
        return _row("startup_warm", label, "< 1.0 s", None, "not measured", None)
    t = p["warm"]["median"]
    text = f"{t:.2f} s wall, {p['warm_cpu']['median']:.2f} s CPU ({p['command']})"
    return _row("startup_warm", label, f"< {STARTUP_WARM_S:g} s", t, text,
                STARTUP_WARM_S / t, p["group"])


def _startup_cold(doc: Doc) -> dict[str, Any]:
    p = _probe(doc, "startup")
    label = "CLI start-up, cold cache: only the integrator used compiled"
    if p is None or "cold_s" not in p:
        return _row("startup_cold", label, "reported; no other scheme", None, "not measured", None)
    foreign = p["foreign_integrator_functions"]
    text = f"{p['cold_s']:.1f} s wall, {p['cold_cpu_s']:.1f} s CPU, {len(p['compiled_functions'])} functions" + (
        f"; also compiled: {', '.join(foreign)}" if foreign else f"; only {p['integrator']} + shared kernels")
    return _row("startup_cold", label, "reported; no other scheme", p["cold_s"], text,
                0.0 if foreign else 1.0, p["group"])


def _sampling(doc: Doc) -> dict[str, Any]:
    p = _probe(doc, "sampling")
    label = "output overhead, every 100 steps, N = 9"
    if p is None:
        return _row("sampling_overhead", label, "< 5%", None, "not measured", None)
    over = p["overhead"]
    margin = SAMPLING_OVERHEAD / over if over > 0 else float("inf")
    return _row("sampling_overhead", label, f"< {SAMPLING_OVERHEAD:.0%}", over,
                f"{over:+.1%} (CPU time {p.get('overhead_cpu', float('nan')):+.1%}; every {p['every']}, "
                f"N = {p['n']})", margin, p["group"])


def _memory_large(doc: Doc) -> dict[str, Any]:
    p = _probe(doc, "memory")
    label = "peak memory, 16,384-body run"
    if p is None:
        return _row("memory_16k", label, "< 300 MB", None, "not measured", None)
    peak = p["large"]["peak_rss_mb"]
    return _row("memory_16k", label, f"< {p['limit_mb']:g} MB", peak,
                f"{peak:.0f} MB peak RSS (N = {p['large']['n']})", p["limit_mb"] / peak, p["group"])


def _memory_trace(doc: Doc) -> dict[str, Any]:
    p = _probe(doc, "memory")
    label = "memory flat while writing many samples"
    trace = p.get("trace") if p else None
    if trace is None:
        return _row("memory_trace", label, "flat", None, "not measured", None)
    settled = max(1.0, trace["settled_rss_mb"])
    growth = trace["growth_mb"]
    margin = (TRACE_GROWTH * settled) / growth if growth > 0 else float("inf")
    return _row("memory_trace", label, f"median RSS grows < {TRACE_GROWTH:.0%} from 10-30% to the last 20%",
                growth, f"{trace['samples']:.3g} samples: {growth:+.1f} MB (settled RSS {settled:.0f} MB, "
                f"peak {trace['peak_rss_mb']:.0f} MB)", margin, p["group"])


def _map_ratio(doc: Doc) -> dict[str, Any]:
    p = _probe(doc, "ensemble")
    label = "20 x 20 Jupiter-Saturn MEGNO map vs REBOUND WHFast + MEGNO on Pool(2)"
    required = f">= {MAP_RATIO:g}x faster (its computation)"
    if p is None:
        return _row("map_ratio", label, required, None, "not measured", None)
    ratio = p["rebound_map_s"] / p["orbitsim_compute_s"]
    setup = f", {p['orbitsim_setup_s']:.2f} s readying the kernels before it" if "orbitsim_setup_s" in p else ""
    text = (f"{ratio:.1f}x ({p['map_n']} x {p['map_n']}: REBOUND {p['rebound_map_s']:.2f} s, orbitsim "
            f"{p['orbitsim_compute_s']:.2f} s{setup}; whole command {p['orbitsim_map_s']:.2f} s)")
    if (p["map_n"], p.get("years")) != MAP_RATIO_MAP:  # a quick run's smaller map: reported, not judged
        return _row("map_ratio", label, required, ratio, text + ": not the target's map, not judged", None,
                    p["group"])
    return _row("map_ratio", label, required, ratio, text, ratio / MAP_RATIO, p["group"])


def _map_large(doc: Doc) -> dict[str, Any]:
    p = _probe(doc, "ensemble")
    label = "200 x 200 Jupiter-Saturn MEGNO map, one file"
    required = f"<= {MAP_LARGE_S:g} s (whole command)"
    if p is None or not p.get("large_map_n"):
        return _row("map_large", label, required, None, "not measured", None)
    seconds = p["large_map_s"]
    text = (f"{seconds:.1f} s ({p['large_map_n']} x {p['large_map_n']}; REBOUND's estimate "
            f"{p['large_rebound_estimate_s']:.0f} s)")
    return _row("map_large", label, required, seconds, text, MAP_LARGE_S / seconds, p["group"])


#: Every target, in the order of the issue.
TARGETS: tuple[Callable[[Doc], dict[str, Any]], ...] = (
    _throughput, _speedup, _small_n("semi_implicit_euler"), _small_n("verlet"), _startup_warm,
    _startup_cold, _sampling, _memory_large, _memory_trace, _ias15_small, _ias15_large,
    _trace("trace_many_encounters", "trace on REBOUND's many-encounters set-up vs REBOUND TRACE",
           TRACE_ENCOUNTERS_SYSTEM, strict=False),
    _trace("trace_disc", "trace on a disc of ~100 planetesimals with encounters vs REBOUND TRACE", TRACE_DISC_SYSTEM,
           strict=True),
    _map_ratio, _map_large,
)


def evaluate_targets(doc: Doc) -> list[dict[str, Any]]:
    """One row per target: required, measured, margin (>= 1 met) and where it was measured."""
    return [check(doc) for check in TARGETS]
