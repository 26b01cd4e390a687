"""The ``ensemble`` benchmark kind: the Jupiter-Saturn map and the ensemble kernel, beside REBOUND, in one run.

Side by side on this machine (issue 29's throughput target):

* **map**: the bundled ``jupiter_saturn`` scenario (Sun, Jupiter, Saturn from DE421 and a massless test
  planet), a 20 x 20 grid over a = 5.8-9.0 au and e = 0-0.38, 1e4 yr at dt = 0.5 yr. REBOUND: WHFast,
  ``init_megno()``, one simulation per pixel over a ``multiprocessing.Pool(2)``, as issue 29's user did.
  orbitsim: ``orbitsim map`` (a warm cache: one untimed run first), in a subprocess, timed whole and
  for its map's computation alone (every chunk run and stored: the part REBOUND's ``pool.map`` does).
* **ensemble**: ns per system-step of K = 4096 four-body systems (Sun, Jupiter, Saturn, Uranus) in the
  ensemble kernel, beside one system stepped by orbitsim's single-system Wisdom-Holman
  (``Simulation.chunks``) and by REBOUND's WHFast (``sim.steps``): the best rounds (:func:`best_step_ns`) of
* **side by side**: every contender in turn in each of a few rounds
  (:func:`side_by_side_step_ns`): the ensemble on all of Numba's threads and on one, the single-system
  step, REBOUND's WHFast and REBOUND's WHFast512 (:func:`whfast512_step_ns`, ``N_systems`` 1 and 2: one
  system, or two side by side in one AVX-512 register) where the REBOUND in use can run it; where it
  cannot, the reason takes the figure's place.
* **variational**: pixel-steps per second of the same K systems with their variational equations (what a
  map runs), the Wisdom-Holman ensemble beside the kick-drift ones (leapfrog, leapfrog4, verlet;
  :mod:`orbitsim.ensemble.kick_drift`), in one process, alternating rounds (the best of each kept); and ns per
  system-step of the Wisdom-Holman one in SIMD lanes beside its scalar kernel (:func:`variational_lanes_step_ns`).

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
from typing import Any, NamedTuple

import h5py
import numpy as np

from orbitsim.ensemble import run_ensemble
from orbitsim.sampling import EveryPlan
from orbitsim.scenario import load_scenario
from orbitsim.simulation import Simulation

YEAR = 365.25 * 0.01720209895  # one year in the scenario's time unit (G = 1, 1/k days)


@functools.lru_cache(maxsize=1)
def _base() -> Any:
    """The bundled scenario, read once per process (:func:`rebound_map` reads it before its clock starts, so
    REBOUND's pixels time REBOUND, not orbitsim's reader)."""
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
    _base()  # read here, before the clock: the pool's forked processes inherit it and time REBOUND alone
    started = time.perf_counter()
    with multiprocessing.Pool(2) as pool:
        megno = pool.map(_rebound_pixel, jobs)
    return time.perf_counter() - started, np.array(megno).reshape(n, n)


class MapTimes(NamedTuple):
    """The times of one ``orbitsim map`` command (:func:`orbitsim_map`), in seconds."""

    whole: float  #: the whole command: the interpreter's start-up, imports, plan, set-up, pixels, map.h5, figure
    computation: float  #: map.h5's ``wall_time_s``: every chunk run and stored (what REBOUND's ``pool.map`` does)
    kernels: float  #: map.h5's ``kernel_time_s``: the ensemble calls alone
    setup: float  #: map.h5's ``setup_time_s``: Numba's start and the kernels' load, before the computation


def orbitsim_map(n: int, years: float, out: Path, indicator: str, warm: bool = True) -> MapTimes:
    """The times of the whole ``orbitsim map`` command (warm cache: a first run fills it unless ``warm`` is
    False): the whole, its map's computation (map.h5's ``wall_time_s``: every chunk run and stored, what
    REBOUND's ``pool.map`` call does, without the interpreter's start-up, the plan, map.h5 and the figure, and
    without readying the kernels: Numba's start and the kernels' load from its cache, the counterpart of
    ``import rebound`` before REBOUND's clock, reported as ``setup``) and its kernels' time."""
    command = [sys.executable, "-m", "orbitsim", "map", "jupiter_saturn", "--x", f"planet.a=5.8:9.0:{n}",
               "--y", f"planet.e=0:0.38:{n}", "--t-end", repr(years * YEAR), "--indicator", indicator, "--quiet"]
    out.mkdir(parents=True, exist_ok=True)
    if warm:
        subprocess.run([*command, "-o", str(out / "warm")], check=True, capture_output=True)  # compile / load cache
    started = time.perf_counter()
    subprocess.run([*command, "-o", str(out / "timed")], check=True, capture_output=True)
    wall = time.perf_counter() - started
    with h5py.File(out / "timed" / "map.h5", "r") as f:
        return MapTimes(wall, float(f.attrs["wall_time_s"]), float(f.attrs["kernel_time_s"]),
                        float(f.attrs["setup_time_s"]))


def _giants(k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """One 4-body system (Sun, Jupiter, Saturn, Uranus of the bundled ``giants``: ``m`` (N,), ``x``, ``v``
    (3, N)) and K copies of it (masses (K, N), positions, velocities (K, 3, N)), Uranus's x stretched by
    up to 1e-3 across the copies so that no two systems are the same."""
    sc = load_scenario("giants")
    m, x, v = sc.masses[:4], sc.positions[:4].T, sc.velocities[:4].T
    masses, pos, vel = np.tile(m, (k, 1)), np.tile(x, (k, 1, 1)), np.tile(v, (k, 1, 1))
    pos[:, 0, 3] *= 1.0 + 1e-3 * np.arange(k) / k
    return m, x, v, masses, pos, vel


#: Largest relative distance (the bodies' distance from WHFast's over the system's largest distance) allowed
#: between WHFast512's and WHFast's states after the same steps from the same start, above which a WHFast512
#: time is not reported. The two are the same map in different arithmetic (hand-written AVX-512 assembly,
#: its own Kepler solver and Jacobi transforms): for these systems at dt = 0.5 they differ by 2e-13 after
#: 2e3 steps, 2e-12 after 2e4 and 1.4e-10 after 2e5 (round-off growing by Brouwer's law), while the scheme's
#: own error at that dt (WHFast at dt against dt/2) is 2.5e-6, 3e-5 and 3e-4.
WHFAST512_TOLERANCE = 1e-8


def _rebound_systems(rebound: Any, m: np.ndarray, x: np.ndarray, v: np.ndarray, copies: int) -> Any:
    """A REBOUND simulation (G = 1, dt = 0.5) holding ``copies`` copies of one system (``m`` (N,), ``x``,
    ``v`` (3, N)), one after the other, central body first in each (WHFast512's ``N_systems`` layout)."""
    sim = rebound.Simulation()
    for _ in range(copies):
        for i in range(m.size):
            sim.add(m=float(m[i]), x=x[0, i], y=x[1, i], z=x[2, i], vx=v[0, i], vy=v[1, i], vz=v[2, i])
    sim.dt = 0.5
    return sim


def whfast512_unavailable() -> str | None:
    """Why the REBOUND in this process cannot run WHFast512 (None where it can): it is missing, too old,
    or its CPU lacks AVX-512F/DQ. One step of a two-body system, as REBOUND's own tests check it."""
    try:
        import rebound  # noqa: PLC0415 - lazy: as above
    except ImportError:
        return "REBOUND is not installed"
    version = getattr(rebound, "__version__", "(unknown version)")
    if not getattr(rebound, "avx512_available", True):
        return f"REBOUND {version}: this CPU lacks AVX-512F/DQ (rebound.avx512_available is False)"
    try:
        sim = rebound.Simulation()
        sim.add(m=1.0)
        sim.add(m=1e-3, x=1.0, vy=1.0)
        sim.integrator = "whfast512"
        sim.dt = 0.01
        sim.exact_finish_time = 0
        sim.integrator.concatenate_steps = 1
        sim.steps(1)
    except (RuntimeError, AttributeError, ValueError, getattr(rebound, "GenericError", RuntimeError)) as exc:
        return f"REBOUND {version} cannot run WHFast512 here: {exc}"
    return None


def whfast512_step_ns(steps: int, tolerance: float = WHFAST512_TOLERANCE) -> dict[str, float] | str:
    """ns per system-step of REBOUND's WHFast512 on one system of :func:`_giants` (``N_systems`` = 1) and
    on two copies of it in one register (``N_systems`` = 2): ``steps`` steps in one call
    (``concatenate_steps``, the state kept in registers, as REBOUND's docs advise), wall / (steps x
    N_systems). Each system's end state is checked against WHFast's after the same steps (untimed).

    Returns
    -------
    dict or str
        ``n_systems_1_ns``, ``n_systems_2_ns`` and ``max_rel_dx`` (the largest disagreement with WHFast, see
        :data:`WHFAST512_TOLERANCE`); or, where WHFast512 cannot run here or disagrees with WHFast by more
        than ``tolerance``, one line saying why (no figure).
    """
    reason = whfast512_unavailable()
    if reason is not None:
        return reason
    import rebound  # noqa: PLC0415 - lazy: as above

    m, x, v = _giants(1)[:3]
    reference = _rebound_systems(rebound, m, x, v, 1)
    reference.integrator = "whfast"
    reference.steps(steps)
    expected = np.array([[p.x, p.y, p.z] for p in reference.particles])
    result: dict[str, float] = {"max_rel_dx": 0.0}
    for n_systems in (1, 2):
        sim = _rebound_systems(rebound, m, x, v, n_systems)
        sim.integrator = "whfast512"
        sim.exact_finish_time = 0
        sim.integrator.N_systems = n_systems
        sim.integrator.concatenate_steps = steps
        started = time.perf_counter()
        sim.steps(1)
        result[f"n_systems_{n_systems}_ns"] = (time.perf_counter() - started) / (steps * n_systems) * 1e9
        got = np.array([[p.x, p.y, p.z] for p in sim.particles]).reshape(n_systems, m.size, 3)
        scale = np.max(np.linalg.norm(expected, axis=1))
        worst = float(np.max(np.linalg.norm(got - expected, axis=2)) / scale)
        result["max_rel_dx"] = max(result["max_rel_dx"], worst)
        if not worst <= tolerance:
            return (f"WHFast512 (N_systems = {n_systems}) disagrees with WHFast by {worst:.2g} (relative) after "
                    f"{steps} steps, more than {tolerance:g}: not timed")
    return result


def side_by_side_step_ns(k: int, steps: int, rounds: int = 3, single_steps: int = 200_000) -> dict[str, Any]:
    """ns per system-step of the 4-body systems of :func:`_giants`, every contender in turn in each of
    ``rounds`` rounds in this process (lists, one value a round): orbitsim's ensemble of K systems x
    ``steps`` (:func:`~orbitsim.ensemble.run_ensemble`, whatever kernel it runs) on all of Numba's threads
    (``NUMBA_NUM_THREADS``, whatever the caller set) and on one thread, orbitsim's single-system
    ``wisdom_holman`` and REBOUND's WHFast over ``single_steps``, and :func:`whfast512_step_ns` over
    ``single_steps`` (under ``whfast512``: its lists and largest disagreement with WHFast, or the reason it
    did not run)."""
    import numba  # noqa: PLC0415 - lazy: loads numba
    import rebound  # noqa: PLC0415 - lazy: as above

    m, x, v, masses, pos, vel = _giants(k)
    previous, threads = numba.get_num_threads(), int(numba.config.NUMBA_NUM_THREADS)
    run_ensemble(masses[:2], pos[:2], vel[:2], G=1.0, dt=0.5, n_steps=2)  # compile / load
    out: dict[str, Any] = {"k": k, "steps": steps, "single_steps": single_steps, "threads": threads,
                           "ensemble_threads_ns": [], "ensemble_1_thread_ns": [], "single_ns": [], "whfast_ns": []}
    whfast512: dict[str, Any] | str = {"n_systems_1_ns": [], "n_systems_2_ns": [], "max_rel_dx": 0.0}
    for _ in range(rounds):
        for key, n_threads in (("ensemble_threads_ns", threads), ("ensemble_1_thread_ns", 1)):
            numba.set_num_threads(n_threads)
            try:
                started = time.perf_counter()
                run_ensemble(masses, pos, vel, G=1.0, dt=0.5, n_steps=steps)
                out[key].append((time.perf_counter() - started) / (k * steps) * 1e9)
            finally:
                numba.set_num_threads(previous)
        sim = Simulation(m, x.T, v.T, "wisdom_holman", 0.5, 1.0, threads=1)
        list(sim.chunks(EveryPlan(10, 10)))  # compile / load, outside the clock
        started = time.perf_counter()
        list(sim.chunks(np.array([10 + single_steps])))
        out["single_ns"].append((time.perf_counter() - started) / single_steps * 1e9)
        rsim = _rebound_systems(rebound, m, x, v, 1)
        rsim.integrator = "whfast"
        started = time.perf_counter()
        rsim.steps(single_steps)
        out["whfast_ns"].append((time.perf_counter() - started) / single_steps * 1e9)
        if isinstance(whfast512, dict):
            measured = whfast512_step_ns(single_steps)
            if isinstance(measured, str):
                whfast512 = measured
            else:
                for key in ("n_systems_1_ns", "n_systems_2_ns"):
                    whfast512[key].append(measured[key])
                whfast512["max_rel_dx"] = max(whfast512["max_rel_dx"], measured["max_rel_dx"])
    out["whfast512"] = whfast512
    return out


def best_step_ns(side: dict[str, Any]) -> dict[str, float]:
    """The best round of :func:`side_by_side_step_ns`'s ensemble (all threads), single-system and WHFast
    times: the ``ensemble_ns``, ``single_ns`` and ``rebound_ns`` of the bench group and of map_speed.py."""
    return {"ensemble": min(side["ensemble_threads_ns"]), "single": min(side["single_ns"]),
            "rebound": min(side["whfast_ns"])}


#: The schemes whose variational ensembles :func:`variational_pixel_steps` times side by side.
VARIATIONAL_SCHEMES = ("wisdom_holman", "leapfrog", "leapfrog4", "verlet")


def variational_pixel_steps(k: int, steps: int, rounds: int = 2) -> dict[str, float]:
    """Pixel-steps per second (system-steps with the variational equations and MEGNO) of K four-body
    systems for each of :data:`VARIATIONAL_SCHEMES`, run in turn ``rounds`` times in this process; the
    best round of each. The systems are those of :func:`_giants`; every one has four massive
    bodies, so the Wisdom-Holman ensemble runs its whole-system kernel, as the kick-drift ones do."""
    from orbitsim.chaos.megno import random_initial_variation  # noqa: PLC0415 - lazy: beside its use

    _, _, _, masses, pos, vel = _giants(k)
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


def variational_lanes_step_ns(k: int, steps: int, rounds: int = 2) -> dict[str, Any]:
    """ns per system-step of the K systems of :func:`_giants` with their variational equations and MEGNO in the
    whole-system Wisdom-Holman ensemble (what a map over a massive body's parameter runs): the 16-lane kernel
    (:mod:`orbitsim.ensemble.system_tangent_lanes`) and the scalar one (``run_ensemble(lanes=False)``), on all
    of Numba's threads and on one, every contender in turn in each of ``rounds`` rounds in this process
    (lists, one value a round)."""
    import numba  # noqa: PLC0415 - lazy: loads numba

    from orbitsim.chaos.megno import random_initial_variation  # noqa: PLC0415 - lazy: beside its use

    _, _, _, masses, pos, vel = _giants(k)
    dpos, dvel = random_initial_variation(4, 0)
    variation = (np.tile(dpos, (k, 1, 1)), np.tile(dvel, (k, 1, 1)))
    previous, threads = numba.get_num_threads(), int(numba.config.NUMBA_NUM_THREADS)
    for lanes in (True, False):  # compile / load
        run_ensemble(masses[:2], pos[:2], vel[:2], G=1.0, dt=0.5, n_steps=2, lanes=lanes,
                     variation=(variation[0][:2], variation[1][:2]))
    out: dict[str, Any] = {"k": k, "steps": steps, "threads": threads, "lanes_threads_ns": [],
                           "scalar_threads_ns": [], "lanes_1_thread_ns": [], "scalar_1_thread_ns": []}
    for _ in range(rounds):
        for suffix, n_threads in (("threads_ns", threads), ("1_thread_ns", 1)):
            for name, lanes in (("lanes", True), ("scalar", False)):
                numba.set_num_threads(n_threads)
                try:
                    started = time.perf_counter()
                    run_ensemble(masses, pos, vel, G=1.0, dt=0.5, n_steps=steps, lanes=lanes, variation=variation)
                    out[f"{name}_{suffix}"].append((time.perf_counter() - started) / (k * steps) * 1e9)
                finally:
                    numba.set_num_threads(previous)
    return out


def run_ensemble_probe(group: Any) -> dict[str, Any]:
    """The ``ensemble`` group of a benchmark matrix: the map race and the per-system-step times."""
    p = group.params
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp)
        rebound_s, _ = rebound_map(p["map_n"], p["years"])
        small = orbitsim_map(p["map_n"], p["years"], out, p["indicator"])
        large = p.get("large_map_n", 0)
        # the large map alone: REBOUND's time for it is the small map's per pixel times its pixels
        large_times = (orbitsim_map(large, p["years"], out / "large", p["indicator"], warm=False)
                       if large else MapTimes(0.0, 0.0, 0.0, 0.0))
    side_by_side = side_by_side_step_ns(p["k"], p["steps"], rounds=2)
    ns = best_step_ns(side_by_side)
    variational = variational_pixel_steps(p["k"], p["steps"])
    variational_lanes = variational_lanes_step_ns(p["k"], p["steps"])
    return {"map_n": p["map_n"], "years": p["years"], "indicator": p["indicator"], "rebound_map_s": rebound_s,
            "orbitsim_map_s": small.whole, "orbitsim_compute_s": small.computation,
            "orbitsim_kernel_s": small.kernels, "orbitsim_setup_s": small.setup, "k": p["k"], "steps": p["steps"],
            "ensemble_ns": ns["ensemble"], "single_ns": ns["single"], "rebound_ns": ns["rebound"],
            "large_map_n": large, "large_map_s": large_times.whole, "large_kernel_s": large_times.kernels,
            "large_rebound_estimate_s": rebound_s * (large / p["map_n"]) ** 2,
            "variational_pixel_steps_per_s": variational, "step_ns_side_by_side": side_by_side,
            "variational_lanes_step_ns": variational_lanes}
