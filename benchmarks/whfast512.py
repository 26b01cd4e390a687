"""ns per system-step of 4-body systems: orbitsim's ensemble beside REBOUND's WHFast and WHFast512, one process.

Usage: ``.venv/bin/python benchmarks/whfast512.py [--k 4096] [--steps 2000] [--rounds 5]``. It runs
:func:`orbitsim.bench.ensemble.side_by_side_step_ns` (every contender in turn in each round) and prints
the Markdown table recorded in benchmarks/README.md with the CPU, the date and the load average at the
start and the end. The project's own REBOUND 5.2.2 wheel runs WHFast512: since version 5 it is hand-written
AVX-512 assembly (``src/integrator_whfast512.s``) that setup.py assembles on every x86-64 Linux build and
that checks the CPU when it steps; where it cannot run, the table says why in place of its figures.
"""

from __future__ import annotations

import argparse
import datetime
import os
import platform

import rebound

from orbitsim.bench.ensemble import side_by_side_step_ns
from orbitsim.provenance import provenance


def _spread(values: list[float]) -> str:
    return f"{min(values):.0f} ({min(values):.0f}-{max(values):.0f})"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--k", type=int, default=4096)
    parser.add_argument("--steps", type=int, default=2000)
    parser.add_argument("--single-steps", type=int, default=200_000)
    parser.add_argument("--rounds", type=int, default=5)
    args = parser.parse_args()
    load_start = os.getloadavg()
    s = side_by_side_step_ns(args.k, args.steps, args.rounds, args.single_steps)
    load_end = os.getloadavg()
    cpu = provenance().get("cpu_model") or platform.processor()
    print(f"{datetime.datetime.now(datetime.UTC):%Y-%m-%d %H:%M} UTC, {cpu}, {os.cpu_count()} cores, REBOUND "
          f"{rebound.__version__}; load average {'/'.join(f'{x:.1f}' for x in load_start)} at the start, "
          f"{'/'.join(f'{x:.1f}' for x in load_end)} at the end; {args.rounds} rounds, best (range)\n")
    print("| what | ns per system-step |\n|---|---|")
    print(f"| orbitsim ensemble, K = {s['k']} x {s['steps']} steps, {s['threads']} threads | "
          f"{_spread(s['ensemble_threads_ns'])} |")
    print(f"| orbitsim ensemble, K = {s['k']} x {s['steps']} steps, 1 thread | {_spread(s['ensemble_1_thread_ns'])} |")
    print(f"| orbitsim wisdom_holman, one system, {s['single_steps']} steps | {_spread(s['single_ns'])} |")
    print(f"| REBOUND WHFast, one system, {s['single_steps']} steps | {_spread(s['whfast_ns'])} |")
    w = s["whfast512"]
    if isinstance(w, str):
        print(f"| REBOUND WHFast512 | not run: {w} |")
    else:
        print(f"| REBOUND WHFast512, N_systems = 1, {s['single_steps']} steps in one call | "
              f"{_spread(w['n_systems_1_ns'])} |")
        print(f"| REBOUND WHFast512, N_systems = 2 (two systems in one register) | {_spread(w['n_systems_2_ns'])} |")
        print(f"\nWHFast512 against WHFast after the same {s['single_steps']} steps: largest relative distance "
              f"{w['max_rel_dx']:.2g}")


if __name__ == "__main__":
    main()
