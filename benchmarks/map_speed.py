"""The Jupiter-Saturn stability map: orbitsim's ``orbitsim map`` beside REBOUND WHFast + MEGNO, in one run.

Side by side on this machine (issue 29's throughput target):

* **map**: the bundled ``jupiter_saturn`` scenario (Sun, Jupiter, Saturn from DE421 and a massless test
  planet), a 20 x 20 grid over a = 5.8-9.0 au and e = 0-0.38, 1e4 yr at dt = 0.5 yr. REBOUND: WHFast,
  ``init_megno()``, one simulation per pixel over a ``multiprocessing.Pool(2)``, as issue 29's user did.
  orbitsim: ``orbitsim map`` (a warm cache: one untimed run first), in a subprocess.
* **ensemble**: ns per system-step of K = 4096 four-body systems (Sun, Jupiter, Saturn, Uranus) in the
  ensemble kernel, beside one system stepped by orbitsim's single-system Wisdom-Holman
  (``Simulation.chunks``) and by REBOUND's WHFast (``sim.steps``).

Usage: ``.venv/bin/python benchmarks/map_speed.py [--n 20] [--years 1e4] [--figure FILE]``. It prints a
Markdown table (recorded in benchmarks/README.md) and, with ``--figure``, draws REBOUND's MEGNO map
beside orbitsim's map.
"""

from __future__ import annotations

import argparse
import multiprocessing
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

YEAR = 365.25 * 0.01720209895  # one year in the scenario's time unit (G = 1, 1/k days)


def _base():
    from orbitsim.scenario import load_scenario

    return load_scenario("jupiter_saturn")


def _rebound_pixel(args: tuple[float, float, float, float]) -> float:
    import rebound

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


def orbitsim_map(n: int, years: float, out: Path, indicator: str) -> float:
    command = [sys.executable, "-m", "orbitsim", "map", "jupiter_saturn", "--x", f"planet.a=5.8:9.0:{n}",
               "--y", f"planet.e=0:0.38:{n}", "--t-end", repr(years * YEAR), "--indicator", indicator, "--quiet"]
    subprocess.run([*command, "-o", str(out / "warm")], check=True, capture_output=True)  # compile / load cache
    started = time.perf_counter()
    subprocess.run([*command, "-o", str(out / "timed")], check=True, capture_output=True)
    return time.perf_counter() - started


def ensemble_step_ns(k: int, steps: int) -> dict[str, float]:
    import rebound

    from orbitsim.ensemble import run_ensemble
    from orbitsim.sampling import EveryPlan
    from orbitsim.scenario import load_scenario
    from orbitsim.simulation import Simulation

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
    list(sim.chunks(EveryPlan(10 + single_steps, single_steps)))
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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=20)
    parser.add_argument("--years", type=float, default=1e4)
    parser.add_argument("--k", type=int, default=4096)
    parser.add_argument("--steps", type=int, default=2000)
    parser.add_argument("--indicator", default="max_e")
    parser.add_argument("--figure", type=Path, default=None)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp)
        reb_s, megno = rebound_map(args.n, args.years)
        ours_s = orbitsim_map(args.n, args.years, out, args.indicator)
        if args.figure is not None:
            _figure(args.figure, megno, out / "timed" / "map.h5", args.indicator)
    ns = ensemble_step_ns(args.k, args.steps)
    print(f"| {args.n} x {args.n} map, {args.years:g} yr | REBOUND WHFast + MEGNO, Pool(2) | {reb_s:.2f} s |")
    print(f"| | orbitsim map ({args.indicator}, warm, whole command) | {ours_s:.2f} s ({reb_s / ours_s:.2f}x) |")
    print(f"| K = {args.k} 4-body ensemble | ns per system-step | {ns['ensemble']:.0f} ns |")
    print(f"| one 4-body system | orbitsim wisdom_holman, 1 thread | {ns['single']:.0f} ns |")
    print(f"| one 4-body system | REBOUND WHFast | {ns['rebound']:.0f} ns |")


def _figure(path: Path, megno: np.ndarray, ours: Path, indicator: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from orbitsim.stability.driver import read_map

    data = read_map(ours)
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.8), constrained_layout=True)
    extent = (5.8, 9.0, 0.0, 0.38)
    im = axes[0].imshow(np.clip(megno, 1.5, 8), origin="lower", extent=extent, aspect="auto", cmap="viridis")
    fig.colorbar(im, ax=axes[0], label="MEGNO (clipped to 1.5-8; white: escaped)")
    axes[0].set_title("REBOUND WHFast + init_megno")
    grid = np.where(data["status"] == 0, data["indicators"][indicator], np.nan)
    im = axes[1].imshow(grid, origin="lower", extent=extent, aspect="auto", cmap="viridis")
    fig.colorbar(im, ax=axes[1], label=f"orbitsim {indicator} (white: escaped)")
    axes[1].set_title("orbitsim map")
    for ax in axes:
        ax.set_xlabel("a [au]")
        ax.set_ylabel("e")
    fig.savefig(path, dpi=110)


if __name__ == "__main__":
    main()
