"""How a sweep scales on Dask: 64 small runs on 1 worker against 2, and the per-run overhead.

Usage::

    .venv/bin/python benchmarks/batch_scaling.py            # 64 runs of ~0.2 s, workers 1 and 2
    .venv/bin/python benchmarks/batch_scaling.py --runs 16 --steps 100000 --json out/scaling.json

What is measured (every number is the best of ``--repeat`` attempts, because the wall time of a
shared machine only ever gets worse by noise; the 1- and 2-worker clusters are both up and their
attempts alternate, so that both see the same background load):

* **throughput**: runs per second of a whole sweep (submit to summary written) on a LocalCluster of
  W worker processes with one Numba thread each, after a warm-up sweep has loaded the compiled
  kernels in every worker. The ratio W=2 / W=1 is the speed-up.
* **efficiency**: the runs' own wall time (from their traces) over W x the sweep's wall time.
* **per-run overhead**: on one worker, (sweep wall - sum of run walls) / runs: scheduling, moving
  the scenario to the worker, the result back, and reading the trace for the summary.
* **empty-run cost**: a sweep of 1-step runs, per run (the whole fixed cost: overhead, trace file
  creation and provenance, summary).
* **Dask round trip**: ``client.submit`` of a no-op task, per task, as a floor for all of the above.
* **worker CPU share**: CPU seconds the worker processes used during the sweep / its wall time, i.e.
  how many cores the workers actually got. On a machine shared with other jobs this is what
  explains a speed-up below 2: the runs are independent, so the throughput follows the cores.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from orbitsim.batch.cluster import ClusterPlan, available_cores, open_client
from orbitsim.batch.driver import run_sweep
from orbitsim.batch.sweep import Sweep, load_sweep


def make_sweep(folder: Path, runs: int, steps: int, name: str) -> Sweep:
    """``runs`` two-body verlet runs that differ in dt only (so every run id differs)."""
    dts = ", ".join(repr(0.01 * (1.0 + i / (4 * runs))) for i in range(runs))
    path = folder / f"{name}.yaml"
    path.write_text(f"name: {name}\nbase: two_body_circular\n"
                    f"overrides: {{steps: {steps}, output.every: {max(1, steps // 200)}}}\n"
                    f"grid: {{dt: [{dts}]}}\n")
    return load_sweep(path)


def noop() -> None:
    """The cheapest possible task."""


def cpu_seconds() -> float:
    """User + system CPU seconds of the calling process (run on every worker)."""
    import psutil

    times = psutil.Process().cpu_times()
    return float(times.user + times.system)


def time_sweep(client: Any, sweep: Sweep, folder: Path) -> tuple[float, float, float]:
    """Wall time of the whole sweep into a fresh directory, the sum of its runs' wall times, and the
    CPU seconds its workers used."""
    out = Path(tempfile.mkdtemp(dir=folder))
    cpu_before = sum(client.run(cpu_seconds).values())
    start = time.perf_counter()
    outcome = run_sweep(sweep, out, client=client, resume=False)
    wall = time.perf_counter() - start
    cpu = sum(client.run(cpu_seconds).values()) - cpu_before
    bad = [row for row in outcome.rows if row["status"] != "complete"]
    if bad:
        raise RuntimeError(f"{len(bad)} runs did not complete: {bad[0]['error']}")
    return wall, sum(row["wall_time_s"] for row in outcome.rows), cpu


def round_trip(client: Any, tasks: int) -> float:
    """Seconds per no-op task submitted and gathered one batch at a time."""
    from distributed import wait

    start = time.perf_counter()
    wait([client.submit(noop, pure=False) for _ in range(tasks)])
    return (time.perf_counter() - start) / tasks


def summarise(workers: int, attempts: list[tuple[float, float, float]], empty: float, trip: float,
              runs: int, empty_runs: int) -> dict[str, float]:
    """The numbers of one cluster size from its best (fastest) attempt."""
    wall, run_walls, cpu = min(attempts, key=lambda t: t[0])
    return {
        "workers": workers,
        "sweep_wall_s": wall,
        "throughput_runs_per_s": runs / wall,
        "mean_run_wall_s": run_walls / runs,
        "efficiency": run_walls / (workers * wall),
        "overhead_per_run_s": (wall * workers - run_walls) / runs,
        "empty_run_s": empty / empty_runs,
        "dask_round_trip_s": trip,
        "worker_cpu_share": cpu / wall,
    }


def measure(sweeps: dict[str, Sweep], folder: Path, repeat: int) -> tuple[list[dict[str, float]], list[float]]:
    """Both cluster sizes, their attempts interleaved (1, 2, 1, 2, ...) so that both see the same
    background load; returns the summaries and the speed-up of each (1, 2) pair of attempts."""
    with (open_client(None, ClusterPlan(workers=1, threads=1)) as one,
          open_client(None, ClusterPlan(workers=2, threads=1)) as two):
        clients = {1: one, 2: two}
        two.wait_for_workers(2, timeout=120)
        attempts: dict[int, list[tuple[float, float, float]]] = {1: [], 2: []}
        for client in clients.values():
            time_sweep(client, sweeps["warm"], folder)  # loads the cached kernels in every worker
        for _ in range(repeat):
            for w, client in clients.items():
                attempts[w].append(time_sweep(client, sweeps["main"], folder))
        empty = {w: min(time_sweep(c, sweeps["empty"], folder)[0] for _ in range(repeat)) for w, c in clients.items()}
        trip = {w: min(round_trip(c, 200) for _ in range(repeat)) for w, c in clients.items()}
    runs, empty_runs = len(sweeps["main"].cases), len(sweeps["empty"].cases)
    results = [summarise(w, attempts[w], empty[w], trip[w], runs, empty_runs) for w in (1, 2)]
    pairs = [a1[0] / a2[0] for a1, a2 in zip(attempts[1], attempts[2], strict=True)]
    return results, pairs


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=64, help="runs in the timed sweep (default 64)")
    parser.add_argument("--steps", type=int, default=2_000_000,
                        help="steps per run (default 2000000: ~0.2 s of two-body verlet on a quiet core)")
    parser.add_argument("--repeat", type=int, default=3, help="attempts per measurement; the best counts")
    parser.add_argument("--json", type=Path, default=None, help="also write the results here")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="orbitsim-scaling-") as tmp:
        folder = Path(tmp)
        sweeps = {"main": make_sweep(folder, args.runs, args.steps, "main"),
                  "warm": make_sweep(folder, 4, 1000, "warm"),
                  "empty": make_sweep(folder, args.runs, 1, "empty")}
        results, pairs = measure(sweeps, folder, args.repeat)
    speedup = results[1]["throughput_runs_per_s"] / results[0]["throughput_runs_per_s"]
    report = {"cores": available_cores(), "load_average": os.getloadavg(), "runs": args.runs,
              "steps_per_run": args.steps, "speedup_2_vs_1": speedup, "speedup_of_each_pair": pairs,
              "results": results}
    print(f"{args.runs} runs of {args.steps} two-body verlet steps; {report['cores']} cores; "
          f"load average {', '.join(f'{x:.1f}' for x in report['load_average'])}")
    keys = [k for k in results[0] if k != "workers"]
    print(f"{'':26}" + "".join(f"{w['workers']:>2} worker(s)  " for w in results))
    for key in keys:
        print(f"{key:26}" + "".join(f"{w[key]:>12.4g}  " for w in results))
    print(f"speed-up, 2 workers vs 1: {speedup:.2f}x (best against best); "
          f"pairwise: {', '.join(f'{p:.2f}' for p in pairs)}")
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(report, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
