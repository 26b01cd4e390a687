"""REBOUND's IAS15 sampled at given output times, matched to an orbitsim ``ias15`` run.

Matched means: the same ``epsilon`` and ``min_dt``, the first trial step ``sim.dt`` equal to
orbitsim's ``first_dt`` (a scenario's ``dt``), REBOUND's default step control (``adaptive_mode``
2, Pham, Rein & Spiegel 2024, which orbitsim's IAS15 implements), and every output time reached
with ``sim.integrate(t)`` and REBOUND's default ``exact_finish_time = 1``, which shortens the
last step onto ``t`` and resumes with the step before it, as orbitsim's grid loop does.

Besides the samples, the record keeps ``extra["steps_taken"]``: IAS15's accepted steps up to each
sample, the ``n`` of a matched pair's n^1.5 tolerance (:mod:`orbitsim.reference.pairs`).
"""

from __future__ import annotations

import time as _time
from typing import Any

import numpy as np

from orbitsim.record import RunRecord, SampleCollector, StateDiagnostics
from orbitsim.reference.bridge import ReboundScheme, read_state, rebound_simulation
from orbitsim.reference.force_pairing import attach_rebound_forces, rebound_force_lines, rebound_refusal
from orbitsim.reference.sampling import _with_rebound_warnings

__all__ = ["IAS15_DEFAULTS", "run_rebound_ias15"]

#: IAS15 settings when the scenario's own integrator is not ias15: REBOUND's defaults.
IAS15_DEFAULTS: dict[str, float] = {"epsilon": 1e-9, "min_dt": 0.0}


def _collect(sim: Any, collector: SampleCollector, times: np.ndarray, labels: np.ndarray,
             taken: list[int]) -> tuple[float, str, str]:
    """``sim.integrate(t)`` for each time; returns (seconds inside integrate, status, message)."""
    wall = 0.0
    for t, label in zip(times, labels, strict=True):
        t = float(t)
        try:
            if t != sim.t:
                start = _time.perf_counter()
                sim.integrate(t)  # exact_finish_time = 1, REBOUND's default
                wall += _time.perf_counter() - start
        except Exception as err:  # REBOUND's own exception types
            return wall, "failed", f"IAS15 stopped before t = {t:.6g}: {type(err).__name__}: {err}"
        if not collector.add(float(sim.t), int(label), *read_state(sim)):  # the time reached
            return wall, "diverged", f"IAS15 state became non-finite by t = {t:.6g}"
        taken.append(int(sim.steps_done))
    return wall, "complete", ""


def run_rebound_ias15(masses: np.ndarray, positions: np.ndarray, velocities: np.ndarray, *, G: float,
                      softening: float, first_dt: float, times: np.ndarray, labels: np.ndarray,
                      settings: dict[str, Any] | None = None, engine: str = "reference", key: str = "ias15",
                      display: str | None = None, forces: Any | None = None) -> RunRecord:
    """REBOUND IAS15 from the given state, sampled exactly at ``times``.

    Parameters
    ----------
    masses, positions, velocities
        (N,), (N, 3), (N, 3) initial state in the scenario's frame.
    G, softening : float
    first_dt : float
        IAS15's first trial step (``sim.dt``).
    times : (S,) array
        Increasing output times, the first normally 0.
    labels : (S,) int array
        The sample's step index in the comparison's plan (the record's ``step``).
    settings : dict, optional
        ``epsilon`` and ``min_dt`` (default :data:`IAS15_DEFAULTS`).
    engine, key, display : str
        How the record is labelled (``engine/key``) and shown.
    forces : ForceSet, optional
        The run's forces, REBOUNDx forces in IAS15's equations of motion.

    Raises
    ------
    ValueError
        When REBOUNDx cannot express the forces (the message says why).

    Returns
    -------
    RunRecord
        ``steps_done`` counts IAS15's accepted steps, ``wall_time_s`` the time inside
        ``sim.integrate``; ``extra["steps_taken"]`` the accepted steps up to each sample.
    """
    scheme = ReboundScheme("ias15")
    why = rebound_refusal(forces, scheme)
    if why:
        raise ValueError(f"REBOUND's IAS15 cannot carry the forces: {why}")
    config = {**IAS15_DEFAULTS, **{k: v for k, v in (settings or {}).items() if k in IAS15_DEFAULTS}}
    sim = rebound_simulation(masses, positions, velocities, G=G, softening=softening, dt=float(first_dt),
                             scheme=scheme)
    sim.integrator.epsilon = float(config["epsilon"])
    sim.integrator.min_dt = float(config["min_dt"])
    attached = attach_rebound_forces(sim, forces, scheme)  # owns the REBOUNDx forces while sim runs
    diagnostics = StateDiagnostics(masses, G, softening, forces)
    diagnostics(*read_state(sim))  # load the jitted kernels before the clock starts
    collector = SampleCollector(diagnostics)
    taken: list[int] = []
    (wall, status, message), notes = _with_rebound_warnings(
        lambda: _collect(sim, collector, np.asarray(times, dtype=np.float64),
                         np.asarray(labels, dtype=np.int64), taken))
    message = "; ".join([m for m in (message, *notes) if m])
    del attached
    options = {"epsilon": float(config["epsilon"]), "min_dt": float(config["min_dt"]),
               "first_dt": float(first_dt), "exact_finish_time": 1}
    return RunRecord(engine=engine, integrator="ias15", key=key,
                     display=display or f"REBOUND IAS15 (epsilon {config['epsilon']:g})", order=None,
                     options=options, dt=float(first_dt), wall_time_s=wall, steps_done=int(sim.steps_done),
                     status=status, message=message, extra={"steps_taken": np.asarray(taken, dtype=np.int64)},
                     forces=rebound_force_lines(forces, scheme), **collector.arrays(len(np.atleast_1d(masses))))
