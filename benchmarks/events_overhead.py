"""What the events watch costs per step, beside the same run without it.

Usage::

    .venv/bin/python benchmarks/events_overhead.py [--n 5 50 500] [--steps 200000] [--repeats 5]
    .venv/bin/python benchmarks/events_overhead.py --baseline /path/to/an/older/checkout

For each N (a star and N - 1 planets, ``orbitsim.bench.systems.planets``, verlet, dt = 1e-3) the
same steps are taken with no ``events:`` (the plain fixed-dt loop), with an events section that
watches nothing (the cost of stepping one step at a time and coming back to check), and with each
check alone and all together. Nothing happens in these systems, so this is the price of looking.
The variants run round-robin, ``--repeats`` times each, and the table shows the median time per
step and its ratio to the run without events from the same rounds (the machine is shared and
noisy; only same-run ratios mean anything).

``--baseline DIR`` instead times runs *without* events in this checkout and in another one (say,
the commit before events existed), alternating processes, so that "a run without events is as
fast as before" is measured, not assumed.

``--sampled`` times what a run *without* events adds in ``orbitsim run``: the look at each body's
orbital timescale between the jitted calls (:mod:`orbitsim.events.sampled`). The same scenario (a
softened Plummer sphere of N bodies, a sample every 100 steps, no positions) runs through
:func:`orbitsim.runner.run_scenario` with the look and with it switched off, round-robin, and the
table shows the median ratio and the share of the wall time the looks took (timed inside the
same runs).
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time

import numpy as np

DT = 1e-3


def variants() -> dict[str, object]:
    from orbitsim.events.config import Collisions, Encounters, Escape, EventsConfig

    return {"no events": None, "events: {unresolved: false}": EventsConfig(unresolved=None),
            "unresolved": EventsConfig(),
            "collisions": EventsConfig(collisions=Collisions(), unresolved=None),
            "encounters": EventsConfig(encounters=Encounters(distance=1e-3), unresolved=None),
            "escape": EventsConfig(escape=Escape(distance=1e3), unresolved=None),
            "all four": EventsConfig(collisions=Collisions(), encounters=Encounters(distance=1e-3),
                                     escape=Escape(distance=1e3))}


def time_per_step(n: int, events: object, steps: int) -> float:
    """Seconds per step of one run (after a warm-up run that compiles)."""
    from orbitsim.bench.systems import planets
    from orbitsim.sampling import EveryPlan
    from orbitsim.simulation import Simulation

    m, x, v = planets(n)
    sim = Simulation(m, x, v, "verlet", DT, events=events, radii=np.full(n, 1e-6))
    start = time.perf_counter()
    for _ in sim.chunks(EveryPlan(steps, steps), record_positions=False):
        pass
    return (time.perf_counter() - start) / steps


def table(sizes: list[int], steps: int, repeats: int) -> None:
    cases = variants()
    for n in sizes:
        work = max(1000, steps // max(1, n * n // 25))
        for events in cases.values():  # compile and warm up
            time_per_step(n, events, 100)
        times: dict[str, list[float]] = {name: [] for name in cases}
        for _ in range(repeats):
            for name, events in cases.items():
                times[name].append(time_per_step(n, events, work))
        base = statistics.median(times["no events"])
        print(f"\nN = {n} ({work} steps a run, median of {repeats})")
        print(f"  {'watch':<30} {'ns/step':>10} {'x no events':>12}")
        for name, values in times.items():
            med = statistics.median(values)
            print(f"  {name:<30} {med * 1e9:>10.0f} {med / base:>12.2f}")


_CHILD = """
import sys, time
from orbitsim.bench.systems import planets
from orbitsim.sampling import EveryPlan
from orbitsim.simulation import Simulation
n, steps = int(sys.argv[1]), int(sys.argv[2])
m, x, v = planets(n)
def once(k):
    sim = Simulation(m, x, v, "verlet", 1e-3)
    t = time.perf_counter()
    for _ in sim.chunks(EveryPlan(k, k), record_positions=False):
        pass
    return (time.perf_counter() - t) / k
once(100)
print(min(once(steps) for _ in range(3)))
"""


def baseline(other: str, sizes: list[int], steps: int, repeats: int) -> None:
    """Runs without events here and in ``other`` (a checkout), alternating processes."""
    here = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    for n in sizes:
        work = max(1000, steps // max(1, n * n // 25))
        ratios = []
        for _ in range(repeats):
            result = {}
            for label, root in (("this", here), ("baseline", other)):
                env = dict(os.environ, PYTHONPATH=root)
                out = subprocess.run([sys.executable, "-c", _CHILD, str(n), str(work)], env=env, check=True,
                                     capture_output=True, text=True)
                result[label] = float(out.stdout.strip().splitlines()[-1])
            ratios.append(result["this"] / result["baseline"])
        print(f"N = {n}: time per step without events, this checkout / baseline: median "
              f"{statistics.median(ratios):.3f} (rounds: {', '.join(f'{r:.3f}' for r in ratios)})")


def sampled(sizes: list[int], steps: int, repeats: int) -> None:
    """``orbitsim run`` without events, with and without the timescale look, round-robin."""
    import tempfile
    from pathlib import Path

    import orbitsim.events.sampled as look
    from orbitsim.runner import run_scenario
    from orbitsim.scenario import scenario_from_dict

    original, spent = look.StepCheck.look, [0.0]

    def timed(self: object, sim: object) -> None:
        start = time.perf_counter()
        original(self, sim)
        spent[0] += time.perf_counter() - start

    look.StepCheck.look = timed  # type: ignore[method-assign]
    make = look.step_check
    with tempfile.TemporaryDirectory() as folder:
        for n in sizes:
            work = max(1000, steps // max(1, n * n // 25))
            # a Plummer sphere (softened): the planets above span 1.6^N in radius, beyond a scenario's reach
            sc = scenario_from_dict({"name": "s", "integrator": "verlet", "dt": DT, "steps": work, "softening": 0.01,
                                     "output": {"every": 100, "positions": False},
                                     "generator": {"kind": "plummer", "n": n, "seed": 1}})
            times: dict[str, list[float]] = {"with the look": [], "without": []}
            shares = []
            for r in range(repeats + 1):  # round 0 compiles and warms up
                for label in times:
                    look.step_check = make if label == "with the look" else (lambda scenario, sim: None)
                    spent[0] = 0.0
                    summary = run_scenario(sc, Path(folder) / "s.h5", force=True, handle_signals=False)
                    if r:
                        times[label].append(summary.wall_time_s)
                        if label == "with the look":
                            shares.append(spent[0] / summary.wall_time_s)
            look.step_check = make
            ratio = statistics.median(a / b for a, b in zip(times["with the look"], times["without"], strict=True))
            print(f"N = {n} ({work} steps, a sample every 100): with the look / without: median {ratio:.3f}; "
                  f"the looks took {statistics.median(shares):.2%} of the run's wall time (median of {repeats})")
    look.StepCheck.look = original  # type: ignore[method-assign]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, nargs="+", default=[5, 50, 500])
    parser.add_argument("--steps", type=int, default=200_000)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--baseline", metavar="DIR", default=None)
    parser.add_argument("--sampled", action="store_true",
                        help="time the timescale look of a run without events (orbitsim.events.sampled)")
    args = parser.parse_args()
    if args.sampled:
        sampled(args.n, args.steps, args.repeats)
    elif args.baseline:
        baseline(args.baseline, args.n, args.steps, args.repeats)
    else:
        table(args.n, args.steps, args.repeats)


if __name__ == "__main__":
    main()
