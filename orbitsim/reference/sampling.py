"""Run REBOUND and sample it at exactly the steps and times at which orbitsim is sampled.

Fixed-step schemes are advanced with ``sim.steps(k)``, whole steps between samples, and each
sample is labelled with the time ``step * dt``, the very float orbitsim computes. REBOUND's own
``sim.t`` accumulates ``dt`` step by step and drifts from ``step * dt`` by round-off (measured in
REBOUND 5.2.2: ``sim.t = 499.9999999998191`` after 10^4 leapfrog steps of 0.05), and
``integrate(t, exact_finish_time=0)`` decides by comparing against that drifting ``sim.t``, so it
can take one step more or less than intended; counting steps cannot.

The IAS15 reference instead lands exactly on each sample time with
``integrate(t, exact_finish_time=1)`` (it shortens its last step to do so).
"""

from __future__ import annotations

import time as _time
import warnings
from typing import Any

import numpy as np

from orbitsim.record import RunRecord, SampleCollector, StateDiagnostics
from orbitsim.reference.bridge import ReboundScheme, parse_rebound_scheme, read_state, rebound_simulation
from orbitsim.reference.force_pairing import attach_rebound_forces, rebound_force_lines, rebound_refusal

#: The reference integrator and its accuracy parameter. REBOUND's default epsilon = 1e-9 keeps
#: IAS15's error at the level of double-precision round-off for well-resolved orbits
#: (Rein & Spiegel 2015, MNRAS 446, 1424), far below any fixed-step error measured against it.
REFERENCE_SCHEME = ReboundScheme("ias15")
REFERENCE_EPSILON = 1e-9


def _with_rebound_warnings(run: Any) -> tuple[Any, list[str]]:
    """Call ``run()`` and return its result with REBOUND's warnings as one-line notes.

    REBOUND reports trouble (e.g. WHFast's Kepler solver on a non-hierarchical system, IAS15
    hitting its minimal step) as Python warnings; they belong in the run's record, not scattered
    over the terminal.
    """
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = run()
    return result, list(dict.fromkeys(f"REBOUND warning: {w.message}" for w in caught))


def _collect_steps(sim: Any, collector: SampleCollector, sample_steps: np.ndarray,
                   dt: float) -> tuple[int, float, str, str]:
    """Advance ``sim`` through ``sample_steps``.

    Returns (steps done, seconds spent inside ``sim.steps``, status, message). Only the stepping
    is timed: reading a sample back into Python costs REBOUND tens of microseconds that orbitsim,
    which samples inside its compiled loop, does not pay, and that is not integrator speed.
    """
    done, stepping = 0, 0.0
    for target in sample_steps:
        target = int(target)
        try:
            if target > done:
                start = _time.perf_counter()
                sim.steps(target - done)
                stepping += _time.perf_counter() - start
        except Exception as err:  # REBOUND raises its own exception types for failed steps
            return done, stepping, "failed", f"REBOUND stopped before step {target}: {type(err).__name__}: {err}"
        done = target
        # WHFast/SABA without safe mode hold an unsynchronised state between steps; with
        # keep_unsynchronized = 1 synchronising for an output does not perturb the map.
        sim.synchronize()
        pos, vel = read_state(sim)
        if not collector.add(target * dt, target, pos, vel):
            return done, stepping, "diverged", f"state became non-finite by step {target} (t = {target * dt:.6g})"
    return done, stepping, "complete", ""


def run_rebound(masses: np.ndarray, positions: np.ndarray, velocities: np.ndarray, *, G: float,
                softening: float, dt: float, scheme: ReboundScheme | str, sample_steps: np.ndarray,
                settings: dict[str, Any] | None = None, key: str | None = None, forces: Any | None = None) -> RunRecord:
    """Run a fixed-step REBOUND scheme and sample it at ``sample_steps``.

    Parameters
    ----------
    masses, positions, velocities
        (N,), (N, 3), (N, 3) initial state in the scenario's frame.
    G, softening, dt : float
        As in the orbitsim run.
    scheme : ReboundScheme or str
        e.g. ``"leapfrog:4"``, ``"whfast"``.
    sample_steps : (S,) int array
        Increasing step indices, the same as the orbitsim run's.
    settings : dict, optional
        orbitsim integrator settings of the partner run (WHFast reads them).
    key : str, optional
        Record key (default: the scheme's key).
    forces : ForceSet, optional
        The run's forces, carried by REBOUNDx as orbitsim's partner applies them
        (:mod:`orbitsim.reference.force_pairing`).

    Raises
    ------
    ValueError
        For an adaptive scheme, or forces REBOUND cannot carry for this scheme (the message says why).

    Returns
    -------
    RunRecord
        ``wall_time_s`` is the time spent inside ``sim.steps`` (see :func:`_collect_steps`).
    """
    scheme = parse_rebound_scheme(scheme) if isinstance(scheme, str) else scheme
    if not scheme.fixed_step:
        raise ValueError(f"{scheme.display} is adaptive; use run_reference for it")
    why = rebound_refusal(forces, scheme, settings)
    if why:
        raise ValueError(f"{scheme.display} cannot carry the forces: {why}")
    steps = np.asarray(sample_steps, dtype=np.int64)
    sim = rebound_simulation(masses, positions, velocities, G=G, softening=softening, dt=dt,
                             scheme=scheme, settings=settings)
    attached = attach_rebound_forces(sim, forces, scheme)  # owns the REBOUNDx forces while sim runs
    diagnostics = StateDiagnostics(masses, G, softening, forces)
    diagnostics(*read_state(sim))  # load the jitted kernels before the clock starts
    collector = SampleCollector(diagnostics)
    (done, wall, status, message), notes = _with_rebound_warnings(
        lambda: _collect_steps(sim, collector, steps, dt))
    message = "; ".join([m for m in (message, *notes) if m])
    del attached
    return RunRecord(engine="rebound", integrator=scheme.name, key=key or scheme.key,
                     display=scheme.display, order=scheme.order, options=scheme.options, dt=float(dt),
                     wall_time_s=wall, steps_done=done, status=status, message=message,
                     forces=rebound_force_lines(forces, scheme), **collector.arrays(len(np.atleast_1d(masses))))


def _collect_times(sim: Any, collector: SampleCollector, sample_steps: np.ndarray,
                   dt: float) -> tuple[float, str, str]:
    """Integrate IAS15 exactly to each ``step * dt``; returns (seconds in integrate, status, message)."""
    wall = 0.0
    for n in sample_steps:
        t = int(n) * dt
        try:
            if t != sim.t:
                start = _time.perf_counter()
                sim.integrate(t, exact_finish_time=1)
                wall += _time.perf_counter() - start
        except Exception as err:  # REBOUND's own exception types
            return wall, "failed", f"IAS15 stopped before t = {t:.6g}: {type(err).__name__}: {err}"
        if not collector.add(t, int(n), *read_state(sim)):
            return wall, "diverged", f"IAS15 state became non-finite by t = {t:.6g}"
    return wall, "complete", ""


def run_reference(masses: np.ndarray, positions: np.ndarray, velocities: np.ndarray, *, G: float,
                  softening: float, dt: float, sample_steps: np.ndarray, forces: Any | None = None) -> RunRecord:
    """The IAS15 reference, stopped exactly at the times ``sample_steps * dt``.

    ``dt`` only labels the samples (and seeds IAS15's first trial step); the reference is
    adaptive, so ``steps_done`` counts IAS15's own (variable) steps. ``wall_time_s`` is the time
    spent inside ``sim.integrate``. ``forces`` (a ForceSet) are REBOUNDx forces in its equations of
    motion; a ValueError says why when REBOUNDx cannot express them.
    """
    why = rebound_refusal(forces, REFERENCE_SCHEME)
    if why:
        raise ValueError(f"REBOUND's IAS15 cannot carry the forces: {why}")
    steps = np.asarray(sample_steps, dtype=np.int64)
    sim = rebound_simulation(masses, positions, velocities, G=G, softening=softening, dt=dt,
                             scheme=REFERENCE_SCHEME)
    sim.integrator.epsilon = REFERENCE_EPSILON
    attached = attach_rebound_forces(sim, forces, REFERENCE_SCHEME)  # owns the REBOUNDx forces while sim runs
    diagnostics = StateDiagnostics(masses, G, softening, forces)
    diagnostics(*read_state(sim))
    collector = SampleCollector(diagnostics)
    (wall, status, message), notes = _with_rebound_warnings(lambda: _collect_times(sim, collector, steps, dt))
    message = "; ".join([m for m in (message, *notes) if m])
    del attached
    arrays = collector.arrays(len(np.atleast_1d(masses)))
    record = RunRecord(engine="reference", integrator="ias15", key="ias15",
                       display=f"REBOUND IAS15 reference (epsilon {REFERENCE_EPSILON:g})", order=None,
                       options={"epsilon": REFERENCE_EPSILON, "exact_finish_time": 1}, dt=float(dt),
                       wall_time_s=wall, steps_done=int(sim.steps_done), status=status,
                       message=message, forces=rebound_force_lines(forces, REFERENCE_SCHEME), **arrays)
    return record
