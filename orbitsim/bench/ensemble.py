"""The ``ensemble`` benchmark kind: the Jupiter-Saturn map and the ensemble kernel, beside REBOUND, in one run.

Side by side on this machine (issue 29's throughput target):

* **map**: the bundled ``jupiter_saturn`` scenario (Sun, Jupiter, Saturn from DE421 and a massless test
  planet), a 20 x 20 grid over a = 5.8-9.0 au and e = 0-0.38, 1e4 yr at dt = 0.5 yr. REBOUND: WHFast,
  ``init_megno()``, one simulation per pixel over a ``multiprocessing.Pool(2)``, as issue 29's user did.
  orbitsim: ``orbitsim map`` (a warm cache: one untimed run first), in a subprocess, timed whole and
  for its map's computation alone (every chunk run and stored: the part REBOUND's ``pool.map`` does).
* **ensemble**: ns per system-step of K = 4096 four-body systems (Sun, Jupiter, Saturn, Uranus) in the
  ensemble kernel, beside one system stepped by orbitsim's single-system Wisdom-Holman
  (``Simulation.chunks``) and by REBOUND's WHFast (``sim.steps``).
* **variational**: pixel-steps per second of the same K systems with their variational equations (what a
  map runs), the Wisdom-Holman ensemble beside the kick-drift ones (leapfrog, leapfrog4, verlet;
  :mod:`orbitsim.ensemble.kick_drift`), in one process, alternating rounds (the best of each kept).

``orbitsim bench full --group ensemble`` runs it (:func:`run_ensemble_probe`); ``benchmarks/map_speed.py``
runs it alone and draws REBOUND's MEGNO map beside orbitsim's map.
"""

from __future__ import annotations

import functools
import multiprocessing
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from orbitsim.ensemble import run_ensemble
from orbitsim.sampling import EveryPlan
from orbitsim.scenario import load_scenario
from orbitsim.simulation import Simulation

YEAR = 365.25 * 0.01720209895  # one year in the scenario's time unit (G = 1, 1/k days)


@functools.lru_cache(maxsize=1)
def _base() -> Any:
    """The bundled scenario, read once per process (REBOUND's pixels time REBOUND, not orbitsim's reader)."""
    return load_scenario("jupiter_saturn")


def _rebound_pixel(args: tuple[float, float, float, float]) -> float:
    import rebound  # noqa: PLC0415 - lazy: REBOUND loads only in the pool's processes and where timed

    a, e, dt, t_end = args
    sc = _base()
    sim = rebound.Simulation()
    sim.G = 1.0
    for i in range(3):
        sim.add(m=float(sc.masses[i]), x=sc.positions[i, 0], y=sc.positions[i, 1], z=sc.positions[i, 2],
                vx=sc.velocities[i, 0], vy=sc.velocities[i, 1], vz=sc.velocities[i, 2])
    sim.add(primary=sim.particles[0], m=0.0, a=a, e=e)
    sim.integrator = "whfast"
    sim.dt = dt
    sim.exit_max_distance = 100.0
    sim.init_megno(seed=0)
    try:
        sim.integrate(t_end, exact_finish_time=0)
    except rebound.Escape:
        return np.nan
    return sim.megno()


def rebound_map(n: int, years: float) -> tuple[float, np.ndarray]:
    a_values, e_values = np.linspace(5.8, 9.0, n), np.linspace(0.0, 0.38, n)
    jobs = [(a, e, 0.5 * YEAR, years * YEAR) for e in e_values for a in a_values]
    started = time.perf_counter()
    with multiprocessing.Pool(2) as pool:
        megno = pool.map(_rebound_pixel, jobs)
    return time.perf_counter() - started, np.array(megno).reshape(n, n)


def orbitsim_map(n: int, years: float, out: Path, indicator: str, warm: bool = True) -> tuple[float, float, float]:
    """Wall time of the whole ``orbitsim map`` command (warm cache: a first run fills it unless ``warm`` is
    False), its map's computation (map.h5's ``wall_time_s``: every chunk run and stored, what REBOUND's
    ``pool.map`` call does, without the interpreter's start-up, the plan, map.h5 and the figure) and its
    kernels' time."""
    command = [sys.executable, "-m", "orbitsim", "map", "jupiter_saturn", "--x", f"planet.a=5.8:9.0:{n}",
               "--y", f"planet.e=0:0.38:{n}", "--t-end", repr(years * YEAR), "--indicator", indicator, "--quiet"]
    out.mkdir(parents=True, exist_ok=True)
    if warm:
        subprocess.run([*command, "-o", str(out / "warm")], check=True, capture_output=True)  # compile / load cache
    started = time.perf_counter()
    subprocess.run([*command, "-o", str(out / "timed")], check=True, capture_output=True)
    wall = time.perf_counter() - started
    with h5py.File(out / "timed" / "map.h5", "r") as f:
        return wall, float(f.attrs["wall_time_s"]), float(f.attrs["kernel_time_s"])


def ensemble_step_ns(k: int, steps: int) -> dict[str, float]:
    import rebound  # noqa: PLC0415 - lazy: as above

    sc = load_scenario("giants")
    m, x, v = sc.masses[:4], sc.positions[:4].T, sc.velocities[:4].T
    masses, pos, vel = np.tile(m, (k, 1)), np.tile(x, (k, 1, 1)), np.tile(v, (k, 1, 1))
    pos[:, 0, 3] *= 1.0 + 1e-3 * np.arange(k) / k
    run_ensemble(masses[:2], pos[:2], vel[:2], G=1.0, dt=0.5, n_steps=2)  # compile / load
    started = time.perf_counter()
    run_ensemble(masses, pos, vel, G=1.0, dt=0.5, n_steps=steps)
    ensemble = (time.perf_counter() - started) / (k * steps) * 1e9
    single_steps = 200_000
    sim = Simulation(m, x.T, v.T, "wisdom_holman", 0.5, 1.0, threads=1)
    list(sim.chunks(EveryPlan(10, 10)))
    started = time.perf_counter()
    list(sim.chunks(np.array([10 + single_steps])))
    single = (time.perf_counter() - started) / single_steps * 1e9
    rsim = rebound.Simulation()
    for i in range(4):
        rsim.add(m=float(m[i]), x=x[0, i], y=x[1, i], z=x[2, i], vx=v[0, i], vy=v[1, i], vz=v[2, i])
    rsim.integrator = "whfast"
    rsim.dt = 0.5
    started = time.perf_counter()
    rsim.steps(single_steps)
    reb = (time.perf_counter() - started) / single_steps * 1e9
    return {"ensemble": ensemble, "single": single, "rebound": reb}


#: The schemes whose variational ensembles :func:`variational_pixel_steps` times side by side.
VARIATIONAL_SCHEMES = ("wisdom_holman", "leapfrog", "leapfrog4", "verlet")


def variational_pixel_steps(k: int, steps: int, rounds: int = 2) -> dict[str, float]:
    """Pixel-steps per second (system-steps with the variational equations and MEGNO) of K four-body
    systems for each of :data:`VARIATIONAL_SCHEMES`, run in turn ``rounds`` times in this process; the
    best round of each. The systems are those of :func:`ensemble_step_ns`; every one has four massive
    bodies, so the Wisdom-Holman ensemble runs its whole-system kernel, as the kick-drift ones do."""
    from orbitsim.chaos.megno import random_initial_variation  # noqa: PLC0415 - lazy: beside its use

    sc = load_scenario("giants")
    m, x, v = sc.masses[:4], sc.positions[:4].T, sc.velocities[:4].T
    masses, pos, vel = np.tile(m, (k, 1)), np.tile(x, (k, 1, 1)), np.tile(v, (k, 1, 1))
    pos[:, 0, 3] *= 1.0 + 1e-3 * np.arange(k) / k
    dpos, dvel = random_initial_variation(4, 0)
    variation = (np.tile(dpos, (k, 1, 1)), np.tile(dvel, (k, 1, 1)))
    for name in VARIATIONAL_SCHEMES:  # compile / load
        run_ensemble(masses[:2], pos[:2], vel[:2], G=1.0, dt=0.5, n_steps=2, integrator=name,
                     variation=(variation[0][:2], variation[1][:2]))
    best = dict.fromkeys(VARIATIONAL_SCHEMES, 0.0)
    for _ in range(rounds):
        for name in VARIATIONAL_SCHEMES:
            started = time.perf_counter()
            run_ensemble(masses, pos, vel, G=1.0, dt=0.5, n_steps=steps, integrator=name, variation=variation)
            best[name] = max(best[name], k * steps / (time.perf_counter() - started))
    return best


def run_ensemble_probe(group: Any) -> dict[str, Any]:
    """The ``ensemble`` group of a benchmark matrix: the map race and the per-system-step times."""
    p = group.params
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp)
        rebound_s, _ = rebound_map(p["map_n"], p["years"])
        orbitsim_s, compute_s, kernel_s = orbitsim_map(p["map_n"], p["years"], out, p["indicator"])
        large = p.get("large_map_n", 0)
        # the large map alone: REBOUND's time for it is the small map's per pixel times its pixels
        large_s, _, large_kernel_s = (orbitsim_map(large, p["years"], out / "large", p["indicator"], warm=False)
                                      if large else (0.0, 0.0, 0.0))
    ns = ensemble_step_ns(p["k"], p["steps"])
    variational = variational_pixel_steps(p["k"], p["steps"])
    return {"map_n": p["map_n"], "years": p["years"], "indicator": p["indicator"], "rebound_map_s": rebound_s,
            "orbitsim_map_s": orbitsim_s, "orbitsim_compute_s": compute_s,
            "orbitsim_kernel_s": kernel_s, "k": p["k"], "steps": p["steps"],
            "ensemble_ns": ns["ensemble"], "single_ns": ns["single"], "rebound_ns": ns["rebound"],
            "large_map_n": large, "large_map_s": large_s, "large_kernel_s": large_kernel_s,
            "large_rebound_estimate_s": rebound_s * (large / p["map_n"]) ** 2,
            "variational_pixel_steps_per_s": variational}
