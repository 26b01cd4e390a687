"""Peak-memory probes, run in a fresh process so that nothing else inflates their numbers.

``python -m orbitsim.bench.memprobe large N STEPS`` integrates a Plummer sphere of N bodies for
STEPS steps (no positions recorded, as the bundled ``plummer_16k`` scenario does) and prints
one JSON line with the peak resident set size.

``python -m orbitsim.bench.memprobe trace N SAMPLES EVERY OUTDIR`` runs a planetary system of N
bodies into an HDF5 trace of SAMPLES samples (one every EVERY steps) and prints the resident
set size as the run goes, to show that it stays flat. It goes through
:func:`orbitsim.runner.run_scenario` (what ``orbitsim run`` does) when that module exists, else
through :class:`orbitsim.simulation.Simulation` and :class:`orbitsim.io.trace.TraceWriter`.

RSS is read from ``/proc/self/status`` (``VmRSS``, ``VmHWM``); elsewhere ``resource`` gives
the peak only.
"""

from __future__ import annotations

import importlib.util
import json
import resource
import sys
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

from orbitsim.bench.systems import planets
from orbitsim.initial_conditions.generators import plummer

__all__ = ["main", "rss_mb"]


def rss_mb() -> tuple[float, float]:
    """(current, peak) resident set size of this process in MiB."""
    fields: dict[str, float] = {}
    try:
        with open("/proc/self/status", encoding="ascii") as fh:
            for line in fh:
                key, _, value = line.partition(":")
                if key in ("VmRSS", "VmHWM"):
                    fields[key] = float(value.split()[0]) / 1024.0  # kB
    except OSError:
        pass  # not Linux: fall back to the peak from getrusage (kB on Linux, bytes on macOS)
    peak = fields.get("VmHWM")
    if peak is None:
        raw = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        peak = raw / 2**20 if sys.platform == "darwin" else raw / 1024.0
    return fields.get("VmRSS", peak), peak


def probe_large(n: int, steps: int) -> dict[str, Any]:
    """Peak RSS of an N-body Plummer run of ``steps`` steps (after a warm-up that loads the kernels)."""
    from orbitsim.simulation import simulate  # noqa: PLC0415 -- lazy: loads numba

    m2, x2, v2 = plummer(2, seed=1)
    simulate(m2, x2, v2, integrator="verlet", dt=1e-3, steps=2, record_positions=False)
    baseline, _ = rss_mb()
    m, x, v = plummer(n, seed=1)
    start = time.perf_counter()
    result = simulate(m, x, v, integrator="verlet", dt=1e-3, steps=steps, softening=0.01,
                      record_positions=False)
    wall = time.perf_counter() - start
    current, peak = rss_mb()
    return {"n": n, "steps": steps, "status": result.status, "wall_s": wall,
            "baseline_rss_mb": baseline, "rss_mb": current, "peak_rss_mb": peak}


def _trace_scenario(n: int, samples: int, every: int) -> Any:
    from orbitsim.scenario import scenario_from_dict  # noqa: PLC0415 -- lazy: loads yaml

    m, x, v = planets(n, seed=1)
    bodies = [{"name": f"b{k}", "m": float(m[k]), "x": x[k].tolist(), "v": v[k].tolist()} for k in range(n)]
    return scenario_from_dict({
        "name": "memprobe_trace", "units": "nbody", "integrator": "verlet", "dt": 1e-3,
        "steps": max(1, (samples - 1) * every), "output": {"every": every, "positions": False},
        "bodies": bodies,
    })


#: Seconds between two RSS readings of the trace run. A thread reads them while the jitted calls
#: run (they release the GIL), so the series sees the sample buffers come and go inside a call;
#: reading once per call gave about 24 readings for 10^7 samples, and a window of five.
READ_PERIOD_S = 0.05


def probe_trace(n: int, samples: int, every: int, outdir: Path) -> dict[str, Any]:
    """Run into a trace of ``samples`` samples, recording RSS against samples written."""
    series: list[tuple[int, float, float]] = []
    start = time.perf_counter()
    state = {"samples": 0}
    stop = threading.Event()

    def read_rss() -> None:
        while not stop.wait(READ_PERIOD_S):
            series.append((state["samples"], time.perf_counter() - start, rss_mb()[0]))

    def watch(written: int) -> None:
        state["samples"] = written

    reader = threading.Thread(target=read_rss, name="rss-reader", daemon=True)
    reader.start()
    output = outdir / "memprobe_trace.h5"
    try:
        if importlib.util.find_spec("orbitsim.runner") and importlib.util.find_spec("orbitsim.scenario"):
            from orbitsim.runner import run_scenario  # noqa: PLC0415 -- lazy: loads yaml

            def on_chunk(_sim: Any, chunk: Any) -> None:
                watch(state["samples"] + len(chunk))

            summary = run_scenario(_trace_scenario(n, samples, every), output, force=True, on_chunk=on_chunk,
                                   handle_signals=False)
            written, path = int(summary.samples), "orbitsim.runner.run_scenario"
        else:
            written, path = _trace_fallback(n, samples, every, output, watch), "Simulation + TraceWriter"
    finally:
        stop.set()
        reader.join()
    series.append((written, time.perf_counter() - start, rss_mb()[0]))
    size = output.stat().st_size if output.exists() else 0
    output.unlink(missing_ok=True)
    return {"n": n, "samples": written, "every": every, "path": path, "wall_s": time.perf_counter() - start,
            "file_mb": size / 2**20, "series": [list(row) for row in series], "peak_rss_mb": rss_mb()[1]}


def _trace_fallback(n: int, samples: int, every: int, output: Path, watch: Any) -> int:
    from orbitsim.io.trace import TraceWriter  # noqa: PLC0415 -- lazy: loads h5py
    from orbitsim.simulation import Simulation  # noqa: PLC0415 -- lazy: loads numba

    m, x, v = planets(n, seed=1)
    sim = Simulation(m, x, v, "verlet", 1e-3)
    written = 0
    with TraceWriter(output, attrs={}, names=[f"b{k}" for k in range(n)], masses=m, n_bodies=n,
                     record_positions=False, overwrite=True) as writer:
        # The plan goes in slices of a million samples, so the plan itself stays small.
        for first in range(0, samples, 1_000_000):
            plan = np.arange(first, min(samples, first + 1_000_000), dtype=np.int64) * every
            for chunk in sim.chunks(plan, record_positions=False):
                writer.append(chunk)
                written += len(chunk)
                watch(written)
    return written


def main(argv: list[str] | None = None) -> int:
    """Entry point: ``large N STEPS`` or ``trace N SAMPLES EVERY OUTDIR``; prints one JSON line."""
    args = list(sys.argv[1:] if argv is None else argv)
    if args[:1] == ["large"] and len(args) == 3:
        result = probe_large(int(args[1]), int(args[2]))
    elif args[:1] == ["trace"] and len(args) == 5:
        result = probe_trace(int(args[1]), int(args[2]), int(args[3]), Path(args[4]))
    else:
        print("usage: memprobe large N STEPS | trace N SAMPLES EVERY OUTDIR", file=sys.stderr)
        return 2
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
