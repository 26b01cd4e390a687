"""Wisdom-Holman + ``gr`` on the Solar System beside REBOUND's WHFast + REBOUNDx ``gr`` (issue 28).

Usage::

    .venv/bin/python benchmarks/forced_speed.py [--repeats 9]

The bundled scenario ``mercury_gr_planets`` (DE421 Sun and eight planets, one-day steps, 36,525
steps, ``gr`` about the Sun) is run to its end by both codes in this process, round-robin:

* ``orbitsim``: :meth:`orbitsim.simulation.Simulation.chunks` with a sample every 37 steps (the
  scenario's 0.1-year output interval), and with one sample at the end;
* ``rebound``: WHFast with the REBOUNDx ``gr`` operators over dt/2 before and after each step
  (implicit midpoint) in safe mode, as :mod:`orbitsim.reference.force_pairing` pairs it;
* ``rebound, no forces``: the same WHFast in safe mode without REBOUNDx, so that the difference
  is what REBOUNDx's operators cost.

Each prints the fastest of ``--repeats`` in wall time and in this thread's CPU time: on a shared
machine the CPU time is the steadier of the two (another process's load stretches the wall
time of whichever code it lands on). The first run of each (compilation, first touch) is left
out.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable

import numpy as np


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=9)
    args = parser.parse_args()

    from orbitsim.reference.bridge import parse_rebound_scheme, rebound_simulation
    from orbitsim.reference.force_pairing import attach_rebound_forces
    from orbitsim.scenario import load_scenario
    from orbitsim.scenario_simulation import scenario_forces, scenario_simulation

    sc = load_scenario("mercury_gr_planets")
    steps = sc.steps
    samples = np.append(np.arange(0, steps, 37), steps)

    def orbitsim_run(plan: np.ndarray) -> Callable[[], None]:
        def run() -> None:
            sim = scenario_simulation(sc)
            for _ in sim.chunks(plan, record_positions=plan.size > 1):
                pass
        return run

    def rebound_run(forces: bool) -> Callable[[], None]:
        def run() -> None:
            scheme = parse_rebound_scheme("whfast")
            sim = rebound_simulation(sc.masses, sc.positions, sc.velocities, G=sc.G, softening=sc.softening,
                                     dt=sc.grid_dt, scheme=scheme, settings=sc.run_settings)
            if forces:
                attached = attach_rebound_forces(sim, scenario_forces(sc), scheme)  # noqa: F841 -- owns the forces
            else:
                sim.integrator.keep_unsynchronized = 0
                sim.integrator.safe_mode = 1
            sim.steps(steps)
        return run

    cases = {"orbitsim, samples every 37 steps": orbitsim_run(samples),
             "orbitsim, one sample at the end": orbitsim_run(np.array([steps])),
             "rebound + reboundx": rebound_run(True),
             "rebound, no forces (safe mode)": rebound_run(False)}
    best = {name: [np.inf, np.inf] for name in cases}
    for run in cases.values():
        run()  # compile / first touch
    for _ in range(args.repeats):
        for name, run in cases.items():
            wall, cpu = time.perf_counter(), time.thread_time()
            run()
            best[name][0] = min(best[name][0], time.perf_counter() - wall)
            best[name][1] = min(best[name][1], time.thread_time() - cpu)
    reference = best["rebound + reboundx"]
    print(f"mercury_gr_planets, {steps} steps, fastest of {args.repeats}: wall s, CPU s, ratio to rebound + reboundx")
    for name, (wall, cpu) in best.items():
        print(f"  {name:34s} {wall:7.4f} {cpu:7.4f}   {wall / reference[0]:5.2f} {cpu / reference[1]:5.2f}")


if __name__ == "__main__":
    main()
