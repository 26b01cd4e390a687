"""The device check: orbitsim's GPU path on a machine that has a GPU, in one short run (< 5 min on an H100).

Usage, from the repository root::

    python3 benchmarks/gpu_check.py --out gpu_check.jsonl          # on a GPU machine (PYTHONPATH=. if not installed)
    NUMBA_ENABLE_CUDASIM=1 python3 benchmarks/gpu_check.py --quick  # tiny sizes under Numba's CUDA simulator

It prints one JSON line per figure and writes the same lines to ``--out``: ``section``, ``figure``,
``value``, ``unit``, ``n``, ``target`` and ``ok`` (the target met; null where a figure has none), and
the device's name. Its imports are numpy, numba, numba-cuda and orbitsim modules that import only
those (no h5py, yaml or click: the GPU machine may have nothing else; tests/gpu/sim_runs.py runs it
with those three blocked). The plummer_16k scenario's bodies come from the same generator call the
scenario file makes (orbitsim.initial_conditions.generators.plummer), so no YAML is read.

Sections (issue 30's targets on an H100):

* direct-sum correctness against the CPU kernels at N = 4,096: accelerations and 3 verlet steps, 1e-13;
* direct-sum throughput, pair interactions/s at N = 16,384, 65,536, 262,144 (>= 4e11 at 262,144);
* a whole verlet step at N = 65,536 against one force evaluation (within 1.3x);
* plummer_16k, 10 verlet steps: energy on the GPU against the CPU (1e-12 relative).

Timings: each kernel is launched once to compile, then timed over ``repeats`` launches between
``cuda.synchronize()`` calls; the median is reported.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the project, where it is not installed

from orbitsim.gpu.device import device_name, require_cuda

Figure = dict[str, Any]


class Sizes:
    """The sizes of a full check, or of ``--quick`` (under the simulator: seconds, not hours)."""

    def __init__(self, quick: bool) -> None:
        self.quick = quick
        self.correctness_n = 48 if quick else 4096
        self.throughput_n = (64,) if quick else (16_384, 65_536, 262_144)
        self.step_n = 64 if quick else 65_536
        self.plummer_n = 48 if quick else 16_384
        self.plummer_steps = 2 if quick else 10
        self.repeats = 2 if quick else 7


def figure(section: str, name: str, value: float, unit: str, n: int, target: float | None = None,
           higher_is_better: bool = False) -> Figure:
    """One JSON line's record; ``ok`` says whether ``value`` meets ``target`` (None without one)."""
    ok = None if target is None else bool(value >= target if higher_is_better else value <= target)
    return {"section": section, "figure": name, "value": float(value), "unit": unit, "n": int(n),
            "target": target, "ok": ok}


def plummer_system(n: int, seed: int = 7) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(m, x, v) of an equal-mass Plummer sphere: x, v (3, N)."""
    from orbitsim.initial_conditions.generators import plummer

    m, x, v = plummer(n, seed=seed, total_mass=1.0, scale_radius=0.5890486225480862)
    return np.ascontiguousarray(m), np.ascontiguousarray(np.asarray(x).T), np.ascontiguousarray(np.asarray(v).T)


def median_seconds(call: Callable[[], None], repeats: int) -> float:
    """Median wall time of ``call`` (kernels queued), each timed to the device's last kernel."""
    cuda = require_cuda()
    call()
    cuda.synchronize()  # compiled and warm
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        call()
        cuda.synchronize()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def rel_per_body(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.max(np.linalg.norm(a - b, axis=0) / np.linalg.norm(b, axis=0)))


# -- direct sum --------------------------------------------------------------------------------------


def direct_correctness(sizes: Sizes) -> list[Figure]:
    from orbitsim.gpu.simulation import GPUSimulation
    from orbitsim.gpu.stepping import DeviceSystem
    from orbitsim.physics.gravity import accelerations, force_scratch
    from orbitsim.simulation import Simulation

    n, eps = sizes.correctness_n, 0.01
    m, x, v = plummer_system(n)
    ref = np.zeros_like(x)
    slabs, bounds = force_scratch(n)
    accelerations(x, m, 1.0, eps * eps, ref, slabs, bounds)
    gpu_acc = DeviceSystem(m, x, v, "verlet", 1.0, eps * eps).download()[2]
    out = [figure("direct", "accelerations_vs_cpu_rel", rel_per_body(gpu_acc, ref), "relative", n, 1e-13)]
    plan = np.array([3], dtype=np.int64)
    cpu = Simulation(m, x.T, v.T, "verlet", 1e-3, 1.0, eps)
    gpu = GPUSimulation(m, x.T, v.T, "verlet", 1e-3, 1.0, eps)
    for _ in cpu.chunks(plan, record_positions=False):
        pass
    for _ in gpu.chunks(plan, record_positions=False):
        pass
    out.append(figure("direct", "verlet_3_steps_positions_vs_cpu_rel", rel_per_body(gpu.pos, cpu.pos), "relative",
                      n, 1e-13))
    return out


def direct_throughput(sizes: Sizes) -> list[Figure]:
    from orbitsim.gpu.stepping import DeviceSystem

    out = []
    for n in sizes.throughput_n:
        m, x, v = plummer_system(n)
        system = DeviceSystem(m, x, v, "verlet", 1.0, 1e-4)
        seconds = median_seconds(system.evaluate_accelerations, sizes.repeats)
        target = 4e11 if n == 262_144 and not sizes.quick else None
        out.append(figure("direct", "pair_interactions_per_s", n * (n - 1) / seconds, "pairs/s", n, target,
                          higher_is_better=True))
    return out


def verlet_step_vs_force(sizes: Sizes) -> list[Figure]:
    from orbitsim.gpu.stepping import DeviceSystem

    n = sizes.step_n
    m, x, v = plummer_system(n)
    system = DeviceSystem(m, x, v, "verlet", 1.0, 1e-4)
    force = median_seconds(system.evaluate_accelerations, sizes.repeats)
    step = median_seconds(lambda: system.advance(1, 1e-6), sizes.repeats)
    return [figure("direct", "verlet_step_s", step, "s", n), figure("direct", "force_evaluation_s", force, "s", n),
            figure("direct", "verlet_step_over_force", step / force, "ratio", n, None if sizes.quick else 1.3)]


def plummer_16k_energy(sizes: Sizes) -> list[Figure]:
    """plummer_16k's bodies (generator plummer, n 16384, seed 2, as the scenario file), verlet, dt 0.001,
    softening 0.01; the GPU's energy after the steps against the CPU's."""
    from orbitsim.gpu.simulation import GPUSimulation
    from orbitsim.simulation import Simulation

    n, steps = sizes.plummer_n, sizes.plummer_steps
    m, x, v = plummer_system(n, seed=2)
    plan = np.array([0, steps], dtype=np.int64)
    energies = []
    for engine in (Simulation, GPUSimulation):
        sim = engine(m, x.T, v.T, "verlet", 0.001, 1.0, 0.01)
        chunks = list(sim.chunks(plan, record_positions=False))
        energies.append(np.concatenate([c.energy for c in chunks]))
    cpu, gpu = energies
    return [figure("plummer_16k", "energy_after_steps_vs_cpu_rel", abs(gpu[-1] - cpu[-1]) / abs(cpu[-1]), "relative",
                   n, 1e-12),
            figure("plummer_16k", "gpu_energy_error_rel", abs(gpu[-1] - gpu[0]) / abs(gpu[0]), "relative", n)]


#: The direct-sum sections, in order.
DIRECT_SECTIONS: list[Callable[[Sizes], list[Figure]]] = [direct_correctness, direct_throughput,
                                                          verlet_step_vs_force, plummer_16k_energy]

# -- ensemble sections (orbitsim map --device gpu) ----------------------------------------------------
# The ensemble's sections go in this block, in their own list, added to SECTIONS below.
ENSEMBLE_SECTIONS: list[Callable[[Sizes], list[Figure]]] = []

SECTIONS = DIRECT_SECTIONS + ENSEMBLE_SECTIONS


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=None, help="also write the JSON lines to this file")
    parser.add_argument("--quick", action="store_true", help="tiny sizes (the simulator, the suite's test)")
    args = parser.parse_args(argv)
    require_cuda()
    sizes = Sizes(args.quick)
    name = device_name()
    lines = []
    failed = 0
    for section in SECTIONS:
        try:
            figures = section(sizes)
        except Exception as exc:  # one section's failure is a line of its own; the others still run
            figures = [{"section": section.__name__, "figure": "error", "value": None, "unit": None, "n": None,
                        "target": None, "ok": False, "error": f"{type(exc).__name__}: {exc}"}]
        for record in figures:
            record["device"] = name
            line = json.dumps(record, sort_keys=True)
            print(line, flush=True)
            lines.append(line)
            failed += record["ok"] is False
    if args.out is not None:
        args.out.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return 1 if failed else 0


if __name__ == "__main__":
    raise SystemExit(main())
