"""What the stop machinery of issue 27 item 9 costs a run that is never stopped: time per step.

Usage::

    .venv/bin/python benchmarks/stop_overhead.py --baseline /path/to/an/older/checkout [--rounds 5]

Each round runs one process in this checkout and one in the other (``PYTHONPATH``), in turn
(each side first in every other round), and each process times the stepping loop
(``Simulation.chunks``, as a run steps) of

* N = 5 (a star and four planets, ``orbitsim.bench.systems.planets``), verlet, 2,000,000 steps:
  the force kernel does not look at the stop flag at all here (N <= 48), and the calls run on
  the main thread (N < ``INTERRUPTIBLE_MIN_N``);
* N = 4096 (a Plummer sphere), verlet, 100 steps, on ``--threads`` threads: the row loops look at
  the flag before every pair of rows, and every call goes through the kernel thread, with the
  state copied before it.

The table shows each side's median time per step over the rounds, and the median and range of
the rounds' ratios (the machine is shared and noisy; only the same round's ratio means anything).
Steps are timed after a warm-up that loads the kernels, so compile or cache-load time is not in them.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time

CASES = ((5, 2_000_000), (4096, 100))


def time_per_step(n: int, steps: int, threads: int) -> float:
    """Seconds per verlet step of an N-body system through Simulation.chunks (after a warm-up)."""
    import numpy as np

    from orbitsim.bench.systems import planets
    from orbitsim.initial_conditions.generators import plummer
    from orbitsim.sampling import ExplicitPlan
    from orbitsim.simulation import Simulation

    m, x, v = planets(n) if n < 48 else plummer(n, seed=1)
    sim = Simulation(m, x, v, "verlet", 1e-3, softening=0.0 if n < 48 else 0.01, threads=threads)
    for _ in sim.chunks(ExplicitPlan(np.array([2])), record_positions=False):  # warm-up
        pass
    first = sim.steps_done
    start = time.perf_counter()
    for _ in sim.chunks(ExplicitPlan(np.array([first + steps])), record_positions=False):
        pass
    return (time.perf_counter() - start) / steps


def child(threads: int) -> None:
    print(json.dumps({str(n): time_per_step(n, steps, threads) for n, steps in CASES}))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--baseline", required=True, help="an older checkout to compare with")
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        child(args.threads)
        return
    here = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    sides = {"this": here, "baseline": os.path.abspath(args.baseline)}
    times: dict[str, dict[str, list[float]]] = {side: {str(n): [] for n, _ in CASES} for side in sides}
    for round_ in range(args.rounds):
        for side in sorted(sides, reverse=round_ % 2 == 1):  # each side goes first in half the rounds
            root = sides[side]
            env = dict(os.environ, PYTHONPATH=root)
            out = subprocess.run([sys.executable, os.path.abspath(__file__), "--child", "--baseline", root,
                                  "--threads", str(args.threads)], capture_output=True, text=True, env=env,
                                 check=True, cwd=root)
            for n, seconds in json.loads(out.stdout).items():
                times[side][n].append(seconds)
    print(f"verlet, {args.threads} thread(s), median of {args.rounds} rounds (ns per step); ratio: the median of "
          "each round's this/baseline, and its range")
    print(f"{'N':>6} {'this':>12} {'baseline':>12} {'ratio':>7}  range")
    for n, _ in CASES:
        this, base = (statistics.median(times[side][str(n)]) for side in sides)
        ratios = [a / b for a, b in zip(times["this"][str(n)], times["baseline"][str(n)], strict=True)]
        print(f"{n:>6} {this * 1e9:>12,.0f} {base * 1e9:>12,.0f} {statistics.median(ratios):>7.3f}  "
              f"{min(ratios):.3f} - {max(ratios):.3f}")


if __name__ == "__main__":
    main()
