"""Time per step of orbitsim's ``wisdom_holman`` beside REBOUND's WHFast and WHFast512.

Usage::

    .venv/bin/python benchmarks/wh_speed.py [--steps 200000] [--repeats 7]

Systems (DE421 at J2000.0, barycentric, G = k^2 with k the Gaussian gravitational constant):

* N = 5: Sun, Jupiter, Saturn, Uranus, Neptune; dt = 30 days (1/144 of Jupiter's period);
* N = 9: Sun and the eight planets (Earth-Moon barycentre for the Earth); dt = 5 days.

Each code advances the same system by the same number of steps of the same dt in this process:

* ``orbitsim``: the jitted ``run`` of :mod:`orbitsim.integrators.wisdom_holman` with one target
  (Jacobi, no corrector), i.e. the step loop without Python in it, plus one output at the end;
* ``whfast``: REBOUND ``sim.steps(n)`` with the matched settings of
  :func:`orbitsim.reference.wh_pairing.configure_rebound_whfast` (``safe_mode = 0``), and
  ``whfast safe``: REBOUND's default ``safe_mode = 1`` (a Jacobi round trip every step);
* ``whfast512``: REBOUND's WHFast512 (Jacobi coordinates, the 8 planets in one AVX-512 register,
  steps concatenated in registers: ``concatenate_steps = n``, ``sim.steps(1)``; it needs G = 1,
  so there time is in units of 1/k days). The record on CPUs with AVX-512.

The machine is shared and noisy: the codes are timed round-robin, ``--repeats`` times each, and
the table shows the median time per step and the ratio to REBOUND's ``whfast`` from the same run.
Warm-up runs (JIT compilation, first-touch) are excluded.
"""

from __future__ import annotations

import argparse
import statistics
import time
from collections.abc import Callable

import numpy as np

#: Gaussian gravitational constant squared: G in au^3 / (solar mass day^2).
G_GAUSS = 0.01720209895**2

SYSTEMS: dict[int, tuple[tuple[str, ...], float]] = {
    5: (("sun", "jupiter", "saturn", "uranus", "neptune"), 30.0),
    9: (("sun", "mercury", "venus", "earthmoon", "mars", "jupiter", "saturn", "uranus", "neptune"), 5.0),
}


def load_system(bodies: tuple[str, ...]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Masses (solar masses), positions (au) and velocities (au/day) from DE421 at J2000.0."""
    from orbitsim.initial_conditions.ephemeris import J2000_JD, de421_states

    states = de421_states(list(bodies), J2000_JD)
    return states.gm / G_GAUSS, np.array(states.positions), np.array(states.velocities)


def orbitsim_timer(m: np.ndarray, x: np.ndarray, v: np.ndarray, dt: float, steps: int) -> Callable[[], float]:
    """A function that advances an orbitsim WH simulation by ``steps`` and returns the seconds."""
    from orbitsim.integrators import wisdom_holman
    from orbitsim.simulation import Simulation

    sim = Simulation(m, x, v, "wisdom_holman", dt, G=G_GAUSS)
    state = (sim.pos, sim.vel, sim.acc, sim.m)
    record = np.zeros(1, dtype=np.bool_)
    empty = (np.zeros(0), np.zeros(0, dtype=np.int64), np.zeros((0, 8)), np.zeros((0, 2, 3, sim.n)), sim.rows)
    done = [0]

    def advance() -> float:
        targets = np.array([done[0] + steps], dtype=np.int64)
        start = time.perf_counter()
        _, n_done, finite = wisdom_holman.run(state, sim.force, dt, sim.work, 0.0, done[0], targets, record, empty)
        elapsed = time.perf_counter() - start
        if not finite:
            raise RuntimeError("orbitsim run diverged")
        done[0] = int(n_done)
        return elapsed

    return advance


def rebound_timer(
    m: np.ndarray, x: np.ndarray, v: np.ndarray, dt: float, steps: int, integrator: str
) -> Callable[[], float]:
    """The same for REBOUND: ``whfast`` (matched), ``whfast_safe`` (safe_mode=1) or ``whfast512``."""
    import rebound

    from orbitsim.reference.wh_pairing import configure_rebound_whfast

    # WHFast512 insists on G = 1: there, time is measured in units of 1/k days (k^2 = G_GAUSS).
    time_unit = 1.0 / np.sqrt(G_GAUSS) if integrator == "whfast512" else 1.0
    sim = rebound.Simulation()
    sim.G = G_GAUSS * time_unit**2
    for mi, xi, vi in zip(m, x, v * time_unit, strict=True):
        sim.add(m=mi, x=xi[0], y=xi[1], z=xi[2], vx=vi[0], vy=vi[1], vz=vi[2])
    sim.dt = dt / time_unit
    if integrator == "whfast512":
        sim.integrator = "whfast512"
        sim.exact_finish_time = 0
        sim.integrator.concatenate_steps = steps
        calls = 1
    else:
        configure_rebound_whfast(sim, {"coordinates": "jacobi", "corrector": 0})
        if integrator == "whfast_safe":
            sim.integrator.keep_unsynchronized = 0
            sim.integrator.safe_mode = 1
        calls = steps

    def advance() -> float:
        start = time.perf_counter()
        sim.steps(calls)
        elapsed = time.perf_counter() - start
        return elapsed

    return advance


def measure(n_bodies: int, steps: int, repeats: int) -> dict[str, float]:
    """Median microseconds per step of each code for the N-body system of :data:`SYSTEMS`."""
    bodies, dt = SYSTEMS[n_bodies]
    m, x, v = load_system(bodies)
    timers = {
        "orbitsim": orbitsim_timer(m, x, v, dt, steps),
        "whfast": rebound_timer(m, x, v, dt, steps, "whfast"),
        "whfast safe": rebound_timer(m, x, v, dt, steps, "whfast_safe"),
        "whfast512": rebound_timer(m, x, v, dt, steps, "whfast512"),
    }
    for advance in timers.values():
        advance()  # warm-up: compilation, caches
    samples: dict[str, list[float]] = {name: [] for name in timers}
    for _ in range(repeats):
        for name, advance in timers.items():
            samples[name].append(advance() / steps * 1e6)
    return {name: statistics.median(values) for name, values in samples.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--steps", type=int, default=200_000, help="steps per timed call")
    parser.add_argument("--repeats", type=int, default=7, help="timed calls per code (median reported)")
    args = parser.parse_args()
    print(f"time per step, median of {args.repeats} calls of {args.steps} steps (us; ratio to whfast)")
    names = ("orbitsim", "whfast", "whfast safe", "whfast512")
    print(f"{'N':>3} {'dt [d]':>7} " + " ".join(f"{name:>20}" for name in names))
    for n_bodies in SYSTEMS:
        result = measure(n_bodies, args.steps, args.repeats)
        ref = result["whfast"]
        cells = " ".join(f"{result[name]:>10.3f} ({result[name] / ref:5.2f}x)" for name in result)
        print(f"{n_bodies:>3} {SYSTEMS[n_bodies][1]:>7.1f} {cells}")


if __name__ == "__main__":
    main()
