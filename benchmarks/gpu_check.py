"""The device check: orbitsim's GPU path on a machine that has a GPU, in one short run (< 5 min on an H100).

Usage, from the repository root::

    python3 benchmarks/gpu_check.py --out gpu_check.jsonl          # on a GPU machine (PYTHONPATH=. if not installed)
    NUMBA_ENABLE_CUDASIM=1 python3 benchmarks/gpu_check.py --quick  # tiny sizes under Numba's CUDA simulator

It prints one JSON line per figure and writes the same lines to ``--out``: ``section``, ``figure``,
``value``, ``unit``, ``n``, ``target`` and ``ok`` (the target met; null where a figure has none), and
the device's name. Its imports are numpy, numba, numba-cuda and orbitsim modules that import only
those (no h5py, yaml or click: the GPU machine may have nothing else; tests/gpu/sim_runs.py runs it
with those and matplotlib and dask blocked). The plummer_16k scenario's bodies come from the same generator call the
scenario file makes (orbitsim.initial_conditions.generators.plummer), so no YAML is read.

Sections (issue 30's targets on an H100):

* direct-sum correctness against the CPU kernels at N = 4,096: accelerations and 3 verlet steps, 1e-13;
* direct-sum throughput, pair interactions/s at N = 16,384, 65,536, 262,144 (>= 4e11 at 262,144);
* a whole verlet step at N = 65,536 against one force evaluation (within 1.3x);
* plummer_16k, 10 verlet steps: energy on the GPU against the CPU (1e-12 relative);
* ensemble correctness on 64 regular Jupiter-Saturn pixels, 50 steps: the GPU's Wisdom-Holman + MEGNO
  against the CPU ensemble, its leapfrog against orbitsim's CPU leapfrog, 1e-13;
* leapfrog ensemble throughput, system-steps/s, 5-body systems at K = 16,384, 131,072, 1,048,576 (>= 2e10);
* Wisdom-Holman + tangent map + MEGNO throughput, 4-body Jupiter-Saturn pixels at K = 131,044;
* the 20 x 20 and 200 x 200 Jupiter-Saturn maps' kernels (1e4 yr of WH + MEGNO; the 200 x 200 under 2 s),
  and the 1000 x 1000 map estimated from the 200 x 200's rate (under a minute).

Timings: each kernel is launched once to compile, then timed over ``repeats`` launches between
``cuda.synchronize()`` calls; the median is reported. The ensemble's figures are of the kernel alone
(fresh systems uploaded before each timed launch), with a ``_with_copies`` figure beside each for the
whole :func:`orbitsim.gpu.ensemble.run_ensemble_gpu` call (checks, layout and copies both ways included).
"""

from __future__ import annotations

import argparse
import json
import math
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
        # quick: one timed launch per figure; under the simulator a time says only that the path runs
        self.repeats = 1 if quick else 7


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
# The Jupiter-Saturn pixels are built here from the numbers of orbitsim/data/scenarios/jupiter_saturn.yaml
# with orbitsim's element conversion, no YAML read (tests/gpu_ensemble checks them against the map's own
# pixels, bit for bit). Timings are of the kernel alone and of orbitsim.gpu.ensemble.run_ensemble_gpu
# whole (copies to and from the device included).

#: jupiter_saturn.yaml's Sun, Jupiter and Saturn (DE421 at J2000, G = 1, au, solar masses, 1/k days).
JS_MASSES = (0.9999999999999998, 0.0009547919152183977, 0.00028588567272438574)
JS_POSITIONS = ((-0.007136456395244341, -0.002647021852902184, -0.0009229478710186404),
                (3.994040712133264, 2.7339318400364547, 1.0745889511249778),
                (6.3992724071771425, 6.172010782205168, 2.273847798802086))
JS_VELOCITIES = ((0.0003126629391042447, -0.00039286985793597916, -0.0001763069330956741),
                 (-0.2652545511040943, 0.34151088775410426, 0.1528458777689615),
                 (-0.24921222846014715, 0.20471841234629262, 0.09527317954896801))
JS_DT = 3.14153332074375  # 0.5 yr
JS_T_END = 62830.666414875006  # 1e4 yr
#: The map's axes: the test planet's a (au) and e.
JS_A = (5.8, 9.0)
JS_E = (0.0, 0.38)


def js_pixels(a_values: np.ndarray, e_values: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(K, 4) masses and (K, 3, 4) states of the Jupiter-Saturn map's pixels, row-major over (e, a), as
    ``orbitsim map jupiter_saturn --x planet.a=... --y planet.e=...`` builds them: the planet massless, on
    the orbit (a, e, inc 0, Omega 0, omega 0, M 0) about the Sun, added to the Sun's state."""
    from orbitsim.initial_conditions.elements import elements_to_cartesian

    sun_x, sun_v = np.array(JS_POSITIONS[0]), np.array(JS_VELOCITIES[0])
    masses, pos, vel = [], [], []
    for e in e_values:
        for a in a_values:
            r, v = elements_to_cartesian(1.0 * (JS_MASSES[0] + 0.0), float(a), float(e), 0.0, 0.0, 0.0, M=0.0)
            masses.append([*JS_MASSES, 0.0])
            pos.append(np.column_stack([*(np.array(p) for p in JS_POSITIONS), sun_x + r]))
            vel.append(np.column_stack([*(np.array(u) for u in JS_VELOCITIES), sun_v + v]))
    return np.array(masses), np.array(pos), np.array(vel)


def js_grid(nx: int, ny: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    return js_pixels(np.linspace(*JS_A, nx), np.linspace(*JS_E, ny))


def five_body(k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """K 5-body systems: the Sun, Jupiter, Saturn and two planets of 1e-5 at 12 au (e = 0) and 16 au
    (e = 0.02), the outer one's orbit turned about the z axis by a different angle in each system (numpy,
    no Python per system: a million systems are built in a second)."""
    from orbitsim.initial_conditions.elements import elements_to_cartesian

    m = np.array([*JS_MASSES, 1e-5, 1e-5])
    x = np.zeros((k, 3, 5))
    v = np.zeros((k, 3, 5))
    x[:, :, :3] = np.array(JS_POSITIONS).T
    v[:, :, :3] = np.array(JS_VELOCITIES).T
    r, u = elements_to_cartesian(JS_MASSES[0] + 1e-5, 12.0, 0.0, 1.0, 0.0, 0.0, M=0.0)
    x[:, :, 3], v[:, :, 3] = r, u
    r, u = elements_to_cartesian(JS_MASSES[0] + 1e-5, 16.0, 0.02, 2.0, 0.0, 0.0, M=0.0)
    turn = 2.0 * np.pi * np.arange(k) / k
    cos, sin = np.cos(turn), np.sin(turn)
    for state, vec in ((x, r), (v, u)):
        state[:, 0, 4] = cos * vec[0] - sin * vec[1]
        state[:, 1, 4] = sin * vec[0] + cos * vec[1]
        state[:, 2, 4] = vec[2]
    return np.tile(m, (k, 1)), x, v


def _variation(k: int, n: int) -> tuple[np.ndarray, np.ndarray]:
    from orbitsim.chaos.megno import random_initial_variation

    dpos, dvel = random_initial_variation(n, 0)
    return np.tile(dpos, (k, 1, 1)), np.tile(dvel, (k, 1, 1))


def _repeats(sizes: Sizes) -> int:
    """Timed launches per figure: at most 3 (gpu_check.py's Sizes asks 7 of its shorter kernels)."""
    return max(1, min(int(getattr(sizes, "repeats", 3)), 3))


def _state_rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.max(np.max(np.abs(a - b), axis=(1, 2)) / np.max(np.abs(b), axis=(1, 2))))


def ensemble_correctness(sizes: Sizes) -> list[Figure]:
    """64 Jupiter-Saturn pixels in the map's regular middle (a 6.8-7.6 au, e 0-0.1), 50 steps (quick: 20): GPU
    against CPU. Regular orbits, because a close encounter amplifies the round-off in which the two differ
    (FMA, rsqrt) exponentially: over the whole map's a and e, 200 steps took some pixels' leapfrog to 5e-11."""
    from orbitsim.ensemble import run_ensemble
    from orbitsim.ensemble.status import LYAPUNOV, MEGNO
    from orbitsim.gpu.ensemble import run_ensemble_gpu
    from orbitsim.integrators.leapfrog import LEAPFROG
    from orbitsim.physics.force_context import make_force

    m, x, v = js_pixels(np.linspace(6.8, 7.6, 8), np.linspace(0.0, 0.1, 8))
    k, n = m.shape
    steps = 20 if sizes.quick else 50
    common = {"G": 1.0, "dt": JS_DT, "n_steps": steps, "watch": 3, "escape_distance": 100.0}
    gpu = run_ensemble_gpu(m, x, v, variation=_variation(k, n), **common)
    cpu = run_ensemble(m, x, v, variation=_variation(k, n), shared_massive=False, **common)
    out = [figure("ensemble", "wh_megno_positions_vs_cpu_rel", _state_rel(gpu.pos, cpu.pos), "relative", k, 1e-13),
           figure("ensemble", "wh_megno_velocities_vs_cpu_rel", _state_rel(gpu.vel, cpu.vel), "relative", k, 1e-13),
           figure("ensemble", "wh_statuses_equal_cpu", float(np.array_equal(gpu.status, cpu.status)), "bool", k, 1.0,
                  higher_is_better=True)]
    for column, name in ((MEGNO, "megno"), (LYAPUNOV, "lyapunov")):
        rel = np.abs(gpu.indicators[:, column] - cpu.indicators[:, column]) / np.abs(cpu.indicators[:, column])
        out.append(figure("ensemble", f"wh_{name}_vs_cpu_rel", float(np.max(rel)), "relative", k, 1e-13))
    lf = run_ensemble_gpu(m, x, v, scheme="leapfrog", **common)
    ref_x, ref_v = x.copy(), v.copy()
    for j in range(k):
        force, work, acc = make_force(1.0, 0.0, n), LEAPFROG.make_work(m[j], 1.0), np.zeros((3, n))
        for _ in range(steps):
            LEAPFROG.step(ref_x[j], ref_v[j], acc, m[j], force, JS_DT, work)
    out.append(figure("ensemble", "leapfrog_positions_vs_cpu_rel", _state_rel(lf.pos, ref_x), "relative", k, 1e-13))
    return out


def kernel_seconds(upload: Callable[[], Any], repeats: int) -> float:
    """Median seconds of one ensemble kernel alone: each repeat uploads fresh systems (untimed; a relaunch
    would go on from the stops, where escaped systems stop at once), then times ``launch`` to the kernel's end."""
    cuda = require_cuda()
    upload().launch()
    cuda.synchronize()  # compiled and warm
    times = []
    for _ in range(repeats):
        ensemble = upload()
        cuda.synchronize()
        start = time.perf_counter()
        ensemble.launch()
        cuda.synchronize()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def _whole_call(upload: Callable[[], Any]) -> Callable[[], None]:
    """What :func:`orbitsim.gpu.ensemble.run_ensemble_gpu` does: upload (with the checks), launch, copy back."""

    def whole() -> None:
        ensemble = upload()
        ensemble.launch()
        ensemble.result()

    return whole


def _ensemble_rates(section: str, name: str, k: int, steps: int, upload: Callable[[], Any], repeats: int,
                    target: float | None) -> list[Figure]:
    """The kernel's system-steps/s (the target's figure) and the whole call's, copies and checks included."""
    kernel = kernel_seconds(upload, repeats)
    call = median_seconds(_whole_call(upload), repeats)
    return [figure(section, f"{name}_system_steps_per_s", k * steps / kernel, "system-steps/s", k, target,
                   higher_is_better=True),
            figure(section, f"{name}_with_copies_system_steps_per_s", k * steps / call, "system-steps/s", k)]


def leapfrog_throughput(sizes: Sizes) -> list[Figure]:
    """5-body leapfrog systems, system-steps per second: the kernel alone, and with the copies."""
    from orbitsim.gpu.ensemble import upload_ensemble

    plan = ((64, 20),) if sizes.quick else ((16_384, 20_000), (131_072, 4_000), (1_048_576, 1_000))
    out = []
    for k, steps in plan:
        m, x, v = five_body(k)

        def upload(m=m, x=x, v=v, steps=steps) -> Any:
            return upload_ensemble(m, x, v, G=1.0, dt=JS_DT, n_steps=steps, scheme="leapfrog", watch=3)

        target = 2e10 if k == 1_048_576 else None  # the figure: a GPU filled (16,384 threads are not)
        out += _ensemble_rates("ensemble", "leapfrog_5body", k, steps, upload, _repeats(sizes), target)
    return out


def wh_megno_throughput(sizes: Sizes) -> list[Figure]:
    """Jupiter-Saturn pixels (4 bodies) with the tangent map and MEGNO, system-steps per second."""
    from orbitsim.gpu.ensemble import upload_ensemble

    side, steps = (4, 20) if sizes.quick else (362, 2_000)  # 362^2 = 131,044 pixels
    m, x, v = js_grid(side, side)
    k, n = m.shape
    variation = _variation(k, n)
    return _ensemble_rates("ensemble", "wh_megno_4body", k, steps, lambda: upload_ensemble(
        m, x, v, G=1.0, dt=JS_DT, n_steps=steps, watch=3, variation=variation), _repeats(sizes), None)


def js_maps(sizes: Sizes) -> list[Figure]:
    """The Jupiter-Saturn map's pixels over 1e4 yr (quick: 10 steps): 20 x 20 and 200 x 200 measured (the kernel
    alone, the target's "GPU time", and the whole call with its copies), the 1000 x 1000 estimated from the
    200 x 200's kernel rate (a lower bound on the rate: it fills more of the GPU)."""
    from orbitsim.gpu.ensemble import upload_ensemble

    steps = 10 if sizes.quick else math.ceil(JS_T_END / JS_DT - 1e-9)
    sides = (4, 8) if sizes.quick else (20, 200)
    out = []
    rate = math.nan
    for side, target in zip(sides, (None, None if sizes.quick else 2.0), strict=True):
        m, x, v = js_grid(side, side)
        k, n = m.shape
        variation = _variation(k, n)

        def upload(m=m, x=x, v=v, variation=variation) -> Any:
            return upload_ensemble(m, x, v, G=1.0, dt=JS_DT, n_steps=steps, watch=3, variation=variation,
                                   escape_distance=100.0)

        repeats = 1 if side > 50 else _repeats(sizes)
        seconds = kernel_seconds(upload, repeats)
        rate = k * steps / seconds
        out.append(figure("js_map", f"js_map_{side}x{side}_s", seconds, "s", k, target))
        out.append(figure("js_map", f"js_map_{side}x{side}_with_copies_s", median_seconds(_whole_call(upload), repeats),
                          "s", k))
    estimate = 1_000_000 * steps / rate
    out.append(figure("js_map", "js_map_1000x1000_estimate_s", estimate, "s", 1_000_000,
                      None if sizes.quick else 60.0))
    return out


ENSEMBLE_SECTIONS: list[Callable[[Sizes], list[Figure]]] = [ensemble_correctness, leapfrog_throughput,
                                                            wh_megno_throughput, js_maps]

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
