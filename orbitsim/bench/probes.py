"""The measurements that are not a stepping loop: start-up, output overhead and memory.

* Start-up: the whole ``orbitsim run`` process on a tiny scenario, wall clock, with a warm
  cache, and once with a cold one (a fresh ``ORBITSIM_CACHE_DIR``). The cold run's cache files
  name every function that was compiled: only the integrator used and the shared kernels
  should appear.
* Output overhead: ``simulate(..., every=K)`` against the same run sampling only its first and
  last step, interleaved repeats; the overhead is the median over rounds of the ratio within a
  round.
* Memory: peak RSS of a fresh process running a large-N run, and the RSS of a long run
  streaming samples into an HDF5 trace (see :mod:`orbitsim.bench.memprobe`).
"""

from __future__ import annotations

import importlib.util
import json
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from orbitsim.bench.matrix import Group
from orbitsim.bench.stats import paired_median, summarise
from orbitsim.bench.systems import build_system, planets

__all__ = ["cached_functions", "run_memory", "run_sampling", "run_startup"]

#: Integrator modules whose functions every scheme may compile (helpers, not schemes).
SHARED_INTEGRATOR_MODULES = ("base", "registry")
#: Numba's cache folders of the package's top-level kernel folders (``integrators_<hash>``, ...); any
#: other folder is a subpackage, an integrator family (``ias15_<hash>``, ``trace_<hash>``).
_TOP_FOLDERS = ("orbitsim", "physics", "integrators", "events", "forces")


def _orbitsim_command() -> list[str]:
    """The console script next to this interpreter, else ``python -m orbitsim``."""
    script = Path(sys.executable).with_name("orbitsim")
    return [str(script)] if script.exists() else [sys.executable, "-m", "orbitsim"]


def _tiny_scenario(folder: Path, integrator: str, n: int, steps: int) -> Path:
    """A scenario file of ``n`` bodies (a star and planets) that runs ``steps`` steps."""
    import yaml  # noqa: PLC0415 -- lazy: loads yaml

    m, x, v = planets(n, seed=1)
    doc = {"name": "bench_startup", "units": "nbody", "integrator": integrator, "dt": 0.001,
           "steps": steps, "output": {"every": max(1, steps // 100)},
           "bodies": [{"name": f"b{k}", "m": float(m[k]), "x": x[k].tolist(), "v": v[k].tolist()}
                      for k in range(n)]}
    path = folder / "bench_startup.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False), encoding="utf-8")
    return path


def _startup_command(folder: Path, p: dict[str, Any], tag: str) -> tuple[list[str], str]:
    """The command timed: ``orbitsim run`` when it exists, else a tiny ``simulate`` via ``python -c``."""
    if importlib.util.find_spec("orbitsim.cli.run") and importlib.util.find_spec("orbitsim.scenario"):
        scenario = _tiny_scenario(folder, p["integrator"], p["n"], p["steps"])
        out = folder / f"startup_{tag}.h5"
        return [*_orbitsim_command(), "run", str(scenario), "-o", str(out), "-q", "--force"], "orbitsim run"
    code = ("from orbitsim.bench.systems import planets; from orbitsim.simulation import simulate; "
            f"m, x, v = planets({p['n']}); simulate(m, x, v, integrator={p['integrator']!r}, dt=1e-3, "
            f"steps={p['steps']})")
    return [sys.executable, "-c", code], "python -c simulate(...) (orbitsim run not available)"


def _children_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def _timed(cmd: list[str], env: dict[str, str]) -> tuple[float, float]:
    """(wall, CPU) seconds of one whole process. The CPU time (user + system) is what the
    process itself needed; on a busy machine the wall time also holds the time it waited."""
    cpu = _children_cpu()
    start = time.perf_counter()
    done = subprocess.run(cmd, env=env, capture_output=True, text=True, check=False)
    elapsed = time.perf_counter() - start
    if done.returncode != 0:
        tail = (done.stderr or done.stdout).strip().splitlines()[-1:] or ["(no output)"]
        raise RuntimeError(f"start-up probe failed (exit {done.returncode}): {tail[0]}")
    return elapsed, _children_cpu() - cpu


def cached_functions(cache_dir: Path) -> list[str]:
    """``module.function`` for every index file Numba wrote under ``cache_dir``, sorted; a function of
    an integrator family's package is ``family/module.function`` (``ias15/core.step_try``)."""
    names = set()
    for index in cache_dir.rglob("*.nbi"):
        stem = index.name.split(".py")[0]  # e.g. "verlet.run-43"
        folder = index.parent.name.rsplit("_", 1)[0]  # Numba's "<folder>_<hash of its path>"
        prefix = "" if folder in _TOP_FOLDERS else f"{folder}/"
        names.add(prefix + stem.rsplit("-", 1)[0])
    return sorted(names)


def _foreign_integrators(functions: list[str], integrator: str) -> list[str]:
    """Functions of integrator modules other than the one used (and the shared helpers). A scheme
    that reuses another family's kernels (trace's full_ias15 step, the ias15 core) lists those too."""
    from orbitsim.integrators.registry import INTEGRATORS, get_spec  # noqa: PLC0415 -- lazy: loads numba

    used = get_spec(integrator).module.rsplit(".", 1)[-1]
    schemes = {spec.module.rsplit(".", 1)[-1] for spec in INTEGRATORS} - {used}
    return [f for f in functions if f.split("/", 1)[0].split(".", 1)[0] in schemes]


def run_startup(group: Group) -> dict[str, Any]:
    """Whole-process start-up with a warm cache (repeats) and a cold one (once)."""
    p = group.params
    env = dict(os.environ)
    with tempfile.TemporaryDirectory(prefix="orbitsim-bench-") as tmp:
        folder = Path(tmp)
        cmd, how = _startup_command(folder, p, "warm")
        _timed(cmd, env)  # fills the current cache if it is not already
        warm = [_timed(cmd, env) for _ in range(group.repeats)]
        out = {"command": how, "integrator": p["integrator"], "n": p["n"], "steps": p["steps"],
               "warm": summarise([w for w, _ in warm]), "warm_cpu": summarise([c for _, c in warm])}
        if p["cold"]:
            out.update(_cold_start(folder, p, env))
    return out


def _cold_start(folder: Path, p: dict[str, Any], env: dict[str, str]) -> dict[str, Any]:
    """One run with an empty cache: its time, and every function it compiled."""
    cold_env = dict(env, ORBITSIM_CACHE_DIR=str(folder / "cold-cache"))
    cold_env.pop("NUMBA_CACHE_DIR", None)  # else the child reuses this process's cache
    cmd, _ = _startup_command(folder, p, "cold")
    cold, cold_cpu = _timed(cmd, cold_env)
    functions = cached_functions(folder / "cold-cache")
    return {"cold_s": cold, "cold_cpu_s": cold_cpu, "compiled_functions": functions,
            "foreign_integrator_functions": _foreign_integrators(functions, p["integrator"])}


def run_sampling(group: Group) -> dict[str, Any]:
    """Time per step with a sample every K steps against sampling only the first and last step."""
    from orbitsim.simulation import simulate  # noqa: PLC0415 -- lazy: loads numba

    p = group.params
    s = build_system(p["system"], p["n"], seed=p["seed"])
    kwargs = {"integrator": p["integrator"], "dt": s.dt or p["dt"], "steps": p["steps"], "G": s.G,
              "softening": s.softening or 0.0}
    runs = {"every": lambda: simulate(s.masses, s.positions, s.velocities, every=p["every"], **kwargs),
            "none": lambda: simulate(s.masses, s.positions, s.velocities,
                                     sample_steps=np.array([0, p["steps"]]), **kwargs)}
    for fn in runs.values():
        for _ in range(max(1, group.warmup)):
            fn()
    times: dict[str, list[float]] = {k: [] for k in runs}
    cpu: dict[str, list[float]] = {k: [] for k in runs}
    for _ in range(group.repeats):
        for key, fn in runs.items():  # interleaved: both see the same machine load
            start, cpu0 = time.perf_counter(), time.process_time()
            fn()
            times[key].append(time.perf_counter() - start)
            cpu[key].append(time.process_time() - cpu0)
    every, none = summarise(times["every"]), summarise(times["none"])
    return {"system": p["system"], "n": s.n, "integrator": p["integrator"], "steps": p["steps"],
            "every": p["every"], "samples": p["steps"] // p["every"] + 1, "with_samples": every,
            "without_samples": none,
            # As every ratio of the suite: the median over rounds of the ratio within a round.
            "overhead": paired_median(times["every"], times["none"]) - 1.0,
            "overhead_of_medians": every["median"] / none["median"] - 1.0,
            "overhead_min": every["min"] / none["min"] - 1.0,
            # One thread: the CPU time is the cost without the waits a busy machine adds.
            "overhead_cpu": paired_median(cpu["every"], cpu["none"]) - 1.0}


def _probe(args: list[str], timeout: float | None = None) -> dict[str, Any]:
    cmd = [sys.executable, "-m", "orbitsim.bench.memprobe", *args]
    done = subprocess.run(cmd, capture_output=True, text=True, check=False, timeout=timeout)
    if done.returncode != 0:
        tail = (done.stderr or done.stdout).strip().splitlines()[-1:] or ["(no output)"]
        raise RuntimeError(f"memory probe {' '.join(args[:1])} failed (exit {done.returncode}): {tail[0]}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def rss_growth(series: list[list[float]]) -> tuple[float, float]:
    """(settled RSS, growth) in MiB of a trace run's ``[samples written, seconds, RSS]`` readings.

    Flat means the RSS does not grow with the samples written. The buffers of one call (up to
    32 MiB, and the chunk copied out of them) come and go, so single readings swing by tens of MB
    either way: the settled level is the median of the readings taken while the 10-30% of the
    samples were written (imports and buffers are allocated by then), the final level the median
    over the last 20%, and the growth their difference. Readings are by samples written, not by
    their index, so a slow start does not move the window.
    """
    if not series:
        return 0.0, 0.0
    total = series[-1][0]
    early = [row[2] for row in series if 0.1 * total <= row[0] <= 0.3 * total] or [series[0][2]]
    late = [row[2] for row in series if row[0] >= 0.8 * total] or [series[-1][2]]
    settled = statistics.median(early)
    return settled, statistics.median(late) - settled


def run_memory(group: Group) -> dict[str, Any]:
    """Peak RSS of a large-N run; RSS of a long trace-writing run over time (when asked for)."""
    p = group.params
    large = _probe(["large", str(p["n"]), str(p["steps"])])
    out: dict[str, Any] = {"limit_mb": p["limit_mb"], "large": large}
    if p["trace_samples"]:
        folder = tempfile.mkdtemp(prefix="orbitsim-bench-trace-")
        try:
            trace = _probe(["trace", str(p["trace_n"]), str(p["trace_samples"]), str(p["trace_every"]), folder])
        finally:
            shutil.rmtree(folder, ignore_errors=True)
        rss = [row[2] for row in trace["series"]]
        trace["settled_rss_mb"], trace["growth_mb"] = rss_growth(trace["series"])
        trace["median_rss_mb"] = statistics.median(rss) if rss else 0.0
        out["trace"] = trace
    return out
