"""What forces cost runs without forces: this tree's integrators beside a tree from before them.

Usage::

    git archive <commit before forces> orbitsim | tar -x -C /tmp/base
    .venv/bin/python benchmarks/forces_overhead.py --baseline /tmp/base [--rounds 3]

The forces reach every scheme's own loop, and the sample recorder, through hooks that compile to
nothing for a run without forces (:mod:`orbitsim.forces.hooks`). This script checks that claim on
a 5-body and a 64-body system: for every integrator it runs the same steps in a fresh process of
each tree (round-robin, ``--rounds`` times, on a noisy shared machine), and prints the fastest time
per step of each (the least disturbed by other load), the ratio this/baseline,
and whether the final states are bit-identical. With ``--forced`` it also times this tree's run
with a ``gr_potential`` force, for scale.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import subprocess
import sys
import time
from pathlib import Path

#: (integrator, steps) per system size: each run takes a few tenths of a second.
CASES = {5: [("euler", 400_000), ("semi_implicit_euler", 400_000), ("verlet", 400_000), ("leapfrog", 400_000),
             ("leapfrog4", 150_000), ("rk4", 100_000), ("wisdom_holman", 200_000), ("ias15", 2_000)],
         64: [("verlet", 4_000), ("leapfrog", 4_000), ("rk4", 1_000), ("wisdom_holman", 4_000), ("ias15", 100)]}
REPEATS = 3


def _system(n: int):
    """A star and n - 1 planets on near-circular, slightly inclined orbits (deterministic)."""
    import numpy as np

    rng = np.random.default_rng(n)
    m = np.concatenate([[1.0], rng.uniform(1e-6, 1e-4, n - 1)])
    a = 1.0 + 0.6 * np.arange(n - 1)
    phase = rng.uniform(0, 2 * np.pi, n - 1)
    x = np.zeros((n, 3))
    v = np.zeros((n, 3))
    x[1:, 0], x[1:, 1], x[1:, 2] = a * np.cos(phase), a * np.sin(phase), 0.01 * a * np.sin(2 * phase)
    speed = np.sqrt(1.0 / a)
    v[1:, 0], v[1:, 1] = -speed * np.sin(phase), speed * np.cos(phase)
    v[0] = -(m[1:, None] * v[1:]).sum(axis=0) / m[0]
    return m, x, v


def worker(forced: bool, only: str) -> None:
    """Time every case in this process (its ``orbitsim`` is the first on sys.path); print JSON."""
    import numpy as np

    from orbitsim.simulation import Simulation

    results = {}
    for n, cases in CASES.items():
        m, x, v = _system(n)
        for name, steps in cases:
            if only and f"{name} N={n}" not in only.split(","):
                continue
            kwargs = {}
            if forced:
                sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
                from forces_helpers import make_forces

                from orbitsim.forces.table import GR_POTENTIAL, P_C

                kwargs["forces"] = make_forces(n, [(GR_POTENTIAL, 0, {P_C: 1e4}, None)])
            dt = 1e-3 if name != "ias15" else 0.05
            times = []
            for _ in range(REPEATS + 1):  # the first run loads (or compiles) the kernels
                sim = Simulation(m, x, v, name, dt, **kwargs)
                start = time.perf_counter()
                for _chunk in sim.chunks(np.array([steps]), record_positions=False):
                    pass
                times.append((time.perf_counter() - start) / steps)
            digest = hashlib.sha256(sim.pos.tobytes() + sim.vel.tobytes()).hexdigest()[:16]
            results[f"{name} N={n}"] = {"s_per_step": times[1:], "sha": digest}
    print(json.dumps(results))


def _run_tree(tree: Path, forced: bool = False, only: str = "") -> dict:
    env = dict(os.environ, PYTHONPATH=str(tree), NUMBA_NUM_THREADS="1")
    cmd = [sys.executable, __file__, "--worker", "--only", only] + (["--forced"] if forced else [])
    out = subprocess.run(cmd, env=env, capture_output=True, text=True, check=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--baseline", type=Path, help="a tree holding the orbitsim package from before forces")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--forced", action="store_true", help="also time runs with a gr_potential force")
    parser.add_argument("--only", default="", help='comma-separated cases, e.g. "rk4 N=5,verlet N=64"')
    parser.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.worker:
        worker(args.forced, args.only)
        return
    here = Path(__file__).resolve().parents[1]
    trees = {"this": here} | ({"baseline": args.baseline} if args.baseline else {})
    samples: dict[str, dict[str, list[float]]] = {k: {} for k in trees}
    shas: dict[str, dict[str, str]] = {k: {} for k in trees}
    for _ in range(args.rounds):
        for label, tree in trees.items():
            for case, res in _run_tree(tree, only=args.only).items():
                samples[label].setdefault(case, []).extend(res["s_per_step"])
                shas[label][case] = res["sha"]
    forced = _run_tree(here, forced=True, only=args.only) if args.forced else {}
    header = f"{'case':<28}{'this ns/step':>14}{'baseline':>12}{'ratio':>8}  same bits"
    print(header + ("  forced ns" if forced else ""))
    for case, values in samples["this"].items():
        this = min(values) * 1e9
        line = f"{case:<28}{this:>14.1f}"
        if "baseline" in trees:
            base = min(samples["baseline"][case]) * 1e9
            line += f"{base:>12.1f}{this / base:>8.3f}  {shas['this'][case] == shas['baseline'][case]}"
        if forced:
            line += f"  {min(forced[case]['s_per_step']) * 1e9:.1f}"
        print(line)


if __name__ == "__main__":
    main()
