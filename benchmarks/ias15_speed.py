"""orbitsim's ``ias15`` beside REBOUND's IAS15, same systems, same spans, in one run.

Usage::

    .venv/bin/python benchmarks/ias15_speed.py [--repeats 5] [--output benchmarks/results/ias15_speed.json]

Groups (each one's cases timed round-robin, ``--repeats`` rounds; every ratio is the median over
rounds of the ratio within a round, as in ``orbitsim.bench.stats.paired_median``):

* ``giants_api``: the bundled ``giants`` (Sun and the four giants, G = 1, epsilon = 1e-9, first
  trial step 0.01) to t = 1e4, a sample every 100 time units. orbitsim through
  ``Simulation.chunks`` (no positions recorded; the energy of each of the 101 samples is computed,
  as every run does); REBOUND ``sim.integrate(t, exact_finish_time=1)`` at each sample time. The
  time per *accepted* step of each code, its step count, and REBOUND / orbitsim.
* ``giants_cli``: the same system through ``orbitsim run SCENARIO -o X.h5 -q`` (a copy of the
  scenario with ``t_end`` and ``output.interval`` changed), to t = 1e5 (about 50,000 steps, 1,001
  samples with positions, written to HDF5). Start-up (interpreter, imports, loading the cached
  jitted functions, the first ``refresh`` of Numba's target context) is about 1 s and swings by
  0.1-0.4 s here, so it is *subtracted*: each round also runs the same scenario to t = 1 (5 steps,
  2 samples), and time per step = (long - short) / (steps long - steps short). This is done with
  two clocks: the trace's ``wall_time_s`` (the run loop only: it starts after the imports but
  still holds the cache loading and the HDF5 file, ~0.35 s, so it needs the subtraction too, and
  it is the steadier of the two because the import jitter is outside it), and the whole process's
  wall time. The first is the headline; the second shows the whole CLI path agrees. REBOUND runs
  the same span in this process in the same round.
* ``plummer_ias15``: the bundled ``plummer_1k`` (N = 1000, G = 1, softening 0.01, given to
  REBOUND as ``sim.softening``, the same Plummer form), IAS15 from t = 0 to 0.025 (about 30
  steps, first trial step 0.01 as the scenario's dt), orbitsim on 1 and on 2 threads (its blocked
  parallel force kernel either way), REBOUND ``gravity = "basic"`` (serial).
* ``plummer_verlet``: the same system, 100 steps of dt = 0.01, orbitsim ``verlet`` (1 and 2
  threads) against REBOUND ``leapfrog`` (``gravity = "basic"``): the fixed-step ratio that IAS15's
  ratio at N >= 1000 is held to.

Warm-up calls (JIT compilation or cache loading, first touch, the CLI's first cache fill) come
before the timed rounds and are excluded. The machine is shared: the load average is recorded at
the start and the end, and the hash of ``orbitsim/integrators/ias15/core.py`` too (the CLI
processes import the file as it is when they start).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from orbitsim.data import SCENARIOS, bundled_dir

ROOT = Path(__file__).resolve().parent.parent
GIANTS = bundled_dir(SCENARIOS) / "giants.yaml"
PLUMMER = bundled_dir(SCENARIOS) / "plummer_1k.yaml"
EPSILON = 1e-9
API_T_END, CLI_T_END, CLI_T_SHORT, INTERVAL = 1e4, 1e5, 1.0, 100.0
PLUMMER_T_END, VERLET_STEPS = 0.025, 100

#: A timed call returns (wall seconds, CPU seconds, accepted steps, extra numbers to keep).
Timed = tuple[float, float, int, dict[str, Any]]


def load(path: Path) -> dict[str, Any]:
    """Masses, positions, velocities (fresh writable copies), G, softening and dt of a scenario."""
    from orbitsim.scenario import load_scenario

    sc = load_scenario(str(path))
    return {"m": np.array(sc.masses, dtype=np.float64), "x": np.array(sc.positions, dtype=np.float64),
            "v": np.array(sc.velocities, dtype=np.float64), "G": float(sc.G), "softening": float(sc.softening),
            "dt": float(sc.dt)}


def orbitsim_ias15(s: dict[str, Any], t_end: float, interval: float, threads: int) -> Callable[[], Timed]:
    """Integrate ``s`` with orbitsim's IAS15 from 0 to ``t_end``, a sample every ``interval``."""
    from orbitsim.integrators.ias15 import counters
    from orbitsim.sampling import EveryPlan
    from orbitsim.simulation import Simulation

    n_intervals = round(t_end / interval)

    def call() -> Timed:
        sim = Simulation(s["m"].copy(), s["x"].copy(), s["v"].copy(), "ias15", interval, s["G"], s["softening"],
                         0.0, threads, {"epsilon": EPSILON, "first_dt": s["dt"], "t_end": t_end})
        cpu, start = time.process_time(), time.perf_counter()
        for _ in sim.chunks(EveryPlan(n_intervals, 1), record_positions=False):
            pass
        wall, cpu = time.perf_counter() - start, time.process_time() - cpu
        c = counters(sim.work)
        return wall, cpu, c["steps_accepted"], {k: c[k] for k in ("steps_rejected", "force_evaluations")}

    return call


def rebound_sim(s: dict[str, Any], scheme: str, dt: float) -> Any:
    from orbitsim.reference.bridge import rebound_simulation

    sim = rebound_simulation(s["m"], s["x"], s["v"], G=s["G"], softening=s["softening"], dt=dt, scheme=scheme)
    sim.gravity = "basic"
    if scheme == "ias15":
        sim.integrator.epsilon = EPSILON
    return sim


def rebound_ias15(s: dict[str, Any], t_end: float, interval: float) -> Callable[[], Timed]:
    """The same with REBOUND: ``integrate`` exactly to each sample time."""
    times = [interval * k for k in range(1, round(t_end / interval) + 1)]

    def call() -> Timed:
        sim = rebound_sim(s, "ias15", s["dt"])
        cpu, start = time.process_time(), time.perf_counter()
        for t in times:
            sim.integrate(t, exact_finish_time=1)
        wall, cpu = time.perf_counter() - start, time.process_time() - cpu
        return wall, cpu, int(sim.steps_done), {}

    return call


def orbitsim_verlet(s: dict[str, Any], steps: int, threads: int) -> Callable[[], Timed]:
    from orbitsim.sampling import EveryPlan
    from orbitsim.simulation import Simulation

    def call() -> Timed:
        sim = Simulation(s["m"].copy(), s["x"].copy(), s["v"].copy(), "verlet", s["dt"], s["G"], s["softening"],
                         0.0, threads)
        cpu, start = time.process_time(), time.perf_counter()
        for _ in sim.chunks(EveryPlan(steps, steps), record_positions=False):
            pass
        return time.perf_counter() - start, time.process_time() - cpu, steps, {}

    return call


def rebound_leapfrog(s: dict[str, Any], steps: int) -> Callable[[], Timed]:
    def call() -> Timed:
        sim = rebound_sim(s, "leapfrog", s["dt"])
        cpu, start = time.process_time(), time.perf_counter()
        sim.steps(steps)
        return time.perf_counter() - start, time.process_time() - cpu, steps, {}

    return call


def orbitsim_cli(workdir: Path, t_end: float, interval: float) -> Callable[[], Timed]:
    """``orbitsim run`` of the giants scenario to ``t_end``; wall = the whole process, CPU = its
    children's CPU time; extra: the trace's ``wall_time_s`` and IAS15 counters."""
    import h5py
    import yaml

    doc = yaml.safe_load(GIANTS.read_text())
    doc["t_end"], doc["output"] = t_end, {"interval": interval}
    scenario = workdir / f"giants_{t_end:g}.yaml"
    scenario.write_text(yaml.safe_dump(doc, sort_keys=False))
    trace = workdir / f"giants_{t_end:g}.h5"
    # `--t-end` on the command line is not used: with an adaptive scheme it re-derives a step
    # count from the scenario's dt that then disagrees with output.interval (exit status 2).
    command = [sys.executable, "-m", "orbitsim", "run", str(scenario), "-o", str(trace), "--force", "-q"]

    def call() -> Timed:
        before = os.times()
        start = time.perf_counter()
        subprocess.run(command, check=True, cwd=ROOT)
        wall = time.perf_counter() - start
        after = os.times()
        cpu = (after.children_user - before.children_user) + (after.children_system - before.children_system)
        with h5py.File(trace, "r") as f:
            a = f.attrs
            extra = {"wall_time_s": float(a["wall_time_s"]), "steps_rejected": int(a["ias15_steps_rejected"]),
                     "force_evaluations": int(a["ias15_force_evaluations"]), "samples": int(f["time"].shape[0])}
            return wall, cpu, int(a["ias15_steps_accepted"]), extra

    return call


def group(runs: dict[str, list[Timed]], reference: str, busy: float, **info: Any) -> dict[str, Any]:
    """A group's record: its settings, the 1-minute load average when it began, every case, and
    ``reference`` / case per step for the others."""
    return {**info, "load_average": busy, "cases": {k: record(v) for k, v in runs.items()},
            "speedup": speedups(runs, reference)}


def rounds(cases: dict[str, Callable[[], Timed]], repeats: int, warm: tuple[str, ...] = ("orbitsim",)
           ) -> dict[str, list[Timed]]:
    """One warm-up call of each case whose name starts with one of ``warm`` (REBOUND needs none),
    then ``repeats`` rounds of one call of each case in turn."""
    for name, call in cases.items():
        if name.startswith(warm):
            call()
    runs: dict[str, list[Timed]] = {name: [] for name in cases}
    for _ in range(repeats):
        for name, call in cases.items():
            runs[name].append(call())
    return runs


def med(values: list[float]) -> float:
    return float(np.median(values))


def record(runs: list[Timed]) -> dict[str, Any]:
    """Per-step wall and CPU time (median, min, max, every round) and the step counts."""
    per_step = [w / n for w, _, n, _ in runs]
    cpu_step = [c / n for _, c, n, _ in runs]
    out: dict[str, Any] = {"steps": sorted({n for _, _, n, _ in runs}), "per_step_s": _summary(per_step),
                           "cpu_per_step_s": _summary(cpu_step)}
    for key in runs[0][3]:
        out[key] = sorted({e[key] for *_, e in runs}) if key != "wall_time_s" else [e[key] for *_, e in runs]
    return out


def _summary(values: list[float]) -> dict[str, Any]:
    return {"median": med(values), "min": min(values), "max": max(values), "values": values}


def paired(num: list[float], den: list[float]) -> float:
    """Median over rounds of num[r] / den[r]."""
    return med([a / b for a, b in zip(num, den, strict=True)])


def speedups(runs: dict[str, list[Timed]], reference: str) -> dict[str, dict[str, float]]:
    """reference / case per step, wall and CPU, paired by round, for every other case."""
    ref = runs[reference]
    out = {}
    for name, case in runs.items():
        if name != reference:
            out[name] = {"wall": paired([w / n for w, _, n, _ in ref], [w / n for w, _, n, _ in case]),
                         "cpu": paired([c / n for _, c, n, _ in ref], [c / n for _, c, n, _ in case])}
    return out


def cli_group(workdir: Path, giants: dict[str, Any], repeats: int) -> dict[str, Any]:
    cases = {"orbitsim run, long": orbitsim_cli(workdir, CLI_T_END, INTERVAL),
             "orbitsim run, short": orbitsim_cli(workdir, CLI_T_SHORT, CLI_T_SHORT),
             "rebound": rebound_ias15(giants, CLI_T_END, INTERVAL)}
    busy = os.getloadavg()[0]
    runs = rounds(cases, repeats, warm=("orbitsim run, short",))  # fills the cache if it is cold
    long, short, reb = runs["orbitsim run, long"], runs["orbitsim run, short"], runs["rebound"]
    loop, process, raw = [], [], []
    for (lw, _, ln, le), (sw, _, sn, se) in zip(long, short, strict=True):
        loop.append((le["wall_time_s"] - se["wall_time_s"]) / (ln - sn))
        process.append((lw - sw) / (ln - sn))
        raw.append(le["wall_time_s"] / ln)
    reb_step = [w / n for w, _, n, _ in reb]
    return {
        "t_end": CLI_T_END, "t_short": CLI_T_SHORT, "interval": INTERVAL, "load_average": busy,
        "cases": {k: record(v) for k, v in runs.items()},
        "orbitsim_per_step_s": {"run loop (wall_time_s, long - short)": _summary(loop),
                                "process wall (long - short)": _summary(process),
                                "wall_time_s of the long run alone": _summary(raw)},
        "rebound_per_step_s": _summary(reb_step),
        "rebound_over_orbitsim": {"run loop": paired(reb_step, loop), "process wall": paired(reb_step, process),
                                  "long run's wall_time_s alone": paired(reb_step, raw)},
    }


def wait_for_quiet(limit: float | None, timeout: float) -> None:
    """Wait (up to ``timeout`` seconds) until the 1-minute load average is below ``limit``."""
    deadline = time.monotonic() + timeout
    while limit is not None and os.getloadavg()[0] >= limit and time.monotonic() < deadline:
        print(f"load average {os.getloadavg()[0]:.2f} >= {limit}: waiting", file=sys.stderr)
        time.sleep(10.0)


def source_hash() -> str:
    path = ROOT / "orbitsim" / "integrators" / "ias15" / "core.py"
    return hashlib.sha256(path.read_bytes()).hexdigest()[:12]


def fmt(seconds: float) -> str:
    for unit, scale in (("ms", 1e-3), ("us", 1e-6)):
        if seconds >= scale:
            return f"{seconds / scale:.3g} {unit}"
    return f"{seconds * 1e9:.3g} ns"


def show(title: str, rec: dict[str, Any], reference: str) -> None:
    print(f"\n{title} (load average {rec['load_average']:.2f})")
    for name, case in rec["cases"].items():
        rej = f", {case['steps_rejected']} rejected" if "steps_rejected" in case else ""
        ratio = rec["speedup"].get(name)
        tail = f"   {reference} / this: {ratio['wall']:.2f} (CPU {ratio['cpu']:.2f})" if ratio else ""
        print(f"  {name:<24} {fmt(case['per_step_s']['median']):>9}/step  steps {case['steps']}{rej}{tail}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--repeats", type=int, default=5, help="interleaved rounds per group (medians reported)")
    parser.add_argument("--quiet-load", type=float, default=None, help="start only below this load average")
    parser.add_argument("--wait", type=float, default=300.0, help="longest wait for a quiet machine (s)")
    parser.add_argument("--output", type=Path, default=ROOT / "benchmarks" / "results" / "ias15_speed.json")
    args = parser.parse_args()

    import rebound

    from orbitsim.bench.runner import machine_info

    wait_for_quiet(args.quiet_load, args.wait)
    began, hash_start = time.perf_counter(), source_hash()
    load_start = list(os.getloadavg())
    giants, plummer = load(GIANTS), load(PLUMMER)
    result: dict[str, Any] = {"rebound_version": rebound.__version__, "epsilon": EPSILON, "repeats": args.repeats}

    api = {"orbitsim": orbitsim_ias15(giants, API_T_END, INTERVAL, 1),
           "rebound": rebound_ias15(giants, API_T_END, INTERVAL)}
    busy = os.getloadavg()[0]
    runs = rounds(api, max(args.repeats, 7))
    result["giants_api"] = group(runs, "rebound", busy, t_end=API_T_END, interval=INTERVAL)
    show(f"N = 5, giants, Simulation API, t = 0 .. {API_T_END:g}, a sample every {INTERVAL:g}",
         result["giants_api"], "rebound")

    with tempfile.TemporaryDirectory(prefix="ias15_speed_") as tmp:
        cli = cli_group(Path(tmp), giants, args.repeats)
    result["giants_cli"] = cli
    print(f"\nN = 5, giants, `orbitsim run`, t = 0 .. {CLI_T_END:g} minus t = 0 .. {CLI_T_SHORT:g} "
          f"(load average {cli['load_average']:.2f})")
    for name, s in cli["orbitsim_per_step_s"].items():
        print(f"  orbitsim, {name:<36} {fmt(s['median']):>9}/step  ({fmt(s['min'])} - {fmt(s['max'])})")
    print(f"  rebound (in this process){'':<20} {fmt(cli['rebound_per_step_s']['median']):>9}/step  steps "
          f"{cli['cases']['rebound']['steps']} (orbitsim {cli['cases']['orbitsim run, long']['steps']})")
    print("  rebound / orbitsim: " + ", ".join(f"{k} {v:.2f}" for k, v in cli["rebound_over_orbitsim"].items()))

    ias = {"orbitsim 1 thread": orbitsim_ias15(plummer, PLUMMER_T_END, PLUMMER_T_END, 1),
           "orbitsim 2 threads": orbitsim_ias15(plummer, PLUMMER_T_END, PLUMMER_T_END, 2),
           "rebound": rebound_ias15(plummer, PLUMMER_T_END, PLUMMER_T_END)}
    busy = os.getloadavg()[0]
    runs = rounds(ias, args.repeats)
    result["plummer_ias15"] = group(runs, "rebound", busy, n=1000, t_end=PLUMMER_T_END,
                                    softening=plummer["softening"])
    show(f"N = 1000 Plummer, IAS15, t = 0 .. {PLUMMER_T_END:g}, softening {plummer['softening']:g}",
         result["plummer_ias15"], "rebound")

    fixed = {"verlet 1 thread": orbitsim_verlet(plummer, VERLET_STEPS, 1),
             "verlet 2 threads": orbitsim_verlet(plummer, VERLET_STEPS, 2),
             "rebound leapfrog": rebound_leapfrog(plummer, VERLET_STEPS)}
    busy = os.getloadavg()[0]
    runs = rounds(fixed, args.repeats)
    result["plummer_verlet"] = group(runs, "rebound leapfrog", busy, n=1000, steps=VERLET_STEPS, dt=plummer["dt"])
    show(f"N = 1000 Plummer, verlet vs leapfrog, {VERLET_STEPS} steps of {plummer['dt']:g}",
         result["plummer_verlet"], "rebound leapfrog")

    hash_end = source_hash()
    result.update(machine=machine_info(2), load_average_start=load_start, load_average_end=list(os.getloadavg()),
                  ias15_core_sha256={"start": hash_start, "end": hash_end}, runtime_s=time.perf_counter() - began)
    if hash_start != hash_end:
        print("\nnote: orbitsim/integrators/ias15/core.py changed during the run")
    print(f"\nload average {load_start[0]:.2f} -> {result['load_average_end'][0]:.2f}; "
          f"{result['runtime_s']:.0f} s; written to {args.output}")
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text(json.dumps(result, indent=1) + "\n")


if __name__ == "__main__":
    main()
