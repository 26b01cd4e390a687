"""The demo's lesson: one orbit, three ways to step time (``orbitsim demo``).

The same planet on the same orbit is stepped with explicit Euler, semi-implicit (symplectic)
Euler and velocity Verlet, at the same dt, beside a REBOUND IAS15 reference:

* explicit Euler is not symplectic: every step adds energy, the orbit spirals out;
* semi-implicit Euler is symplectic but first order: its energy error oscillates within a band
  of width ~dt and does not drift;
* velocity Verlet is symplectic and second order: its band is ~dt^2, the flattest of the three.

A dt sweep shows the orders: max |dE/E| and the final position error grow like dt for both
Eulers and like dt^2 for Verlet as the step is raised.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from orbitsim.compare.metrics import energy_drift_slope, max_abs_energy_error, position_error
from orbitsim.compare.run import run_orbitsim
from orbitsim.record import RunRecord
from orbitsim.reference.sampling import run_reference

#: The three schemes of the lesson, left to right, with the one-line moral of each panel.
LESSON: tuple[tuple[str, str, str], ...] = (
    ("euler", "explicit Euler", "not symplectic: energy climbs, the orbit spirals out"),
    ("semi_implicit_euler", "semi-implicit Euler", "symplectic, 1st order: energy oscillates in a band"),
    ("verlet", "velocity Verlet", "symplectic, 2nd order: the flattest energy"),
)
#: One colour per scheme of the lesson, the same in both figures and on the page: warm for the
#: unstable, cool for the good.
COLORS = {"euler": "#d62728", "semi_implicit_euler": "#ff7f0e", "verlet": "#1f77b4"}
#: The sweep of the second figure: the lesson's dt times these factors. Down to dt/16 so that
#: semi-implicit Euler and Verlet reach their asymptotic slopes; up to 4 dt (about 37 steps per
#: orbit), where the orbits of the coarsest runs are drawn.
DT_FACTORS = (1 / 16, 1 / 8, 1 / 4, 1 / 2, 1.0, 2.0, 4.0)
#: Samples per sweep run: max |dE/E| is taken over these (about the lesson's own count).
SWEEP_SAMPLES = 1000
#: Slopes in the second figure are fitted over the smallest dt values only (asymptotic regime).
SLOPE_POINTS = 4


@dataclass
class SweepPoint:
    """One integrator at one dt of the sweep."""

    integrator: str
    dt: float
    max_abs_energy_error: float
    final_position_error: float


@dataclass
class LessonResult:
    """The three runs at the lesson's dt, the reference, the dt sweep and its coarsest runs."""

    scenario: Any
    runs: list[RunRecord]
    reference: RunRecord
    sweep: list[SweepPoint]
    coarse: list[RunRecord]
    coarse_dt: float

    def sweep_of(self, integrator: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(dt, max |dE/E|, final position error) of one integrator, by increasing dt."""
        pts = sorted((p for p in self.sweep if p.integrator == integrator), key=lambda p: p.dt)
        return (np.array([p.dt for p in pts]), np.array([p.max_abs_energy_error for p in pts]),
                np.array([p.final_position_error for p in pts]))


def _final_error(record: RunRecord, reference: RunRecord) -> float:
    err = position_error(record, reference)
    return float(err[-1]) if err.size == reference.n_samples and err.size else math.nan


def run_lesson(scenario: Any, *, progress: Any = None) -> LessonResult:
    """Run the lesson's three schemes, the IAS15 reference and the dt sweep.

    The sweep keeps the end time: at ``dt * f`` it takes the whole steps that fit in the lesson's
    end time and is compared with IAS15 stopped at exactly that many steps' time.
    """
    from orbitsim.scenario import resolve_steps  # noqa: PLC0415 -- lazy: loads yaml
    from orbitsim.simulation import sample_steps_every  # noqa: PLC0415 -- lazy: loads numba

    say = progress or (lambda _msg: None)
    plan = scenario.sample_steps()

    def reference_for(sc: Any, steps: np.ndarray) -> RunRecord:
        return run_reference(sc.masses, sc.positions, sc.velocities, G=sc.G, softening=sc.softening,
                             dt=sc.dt, sample_steps=steps)

    reference = reference_for(scenario, plan)
    runs = [run_orbitsim(scenario, name, plan) for name, _, _ in LESSON]
    for rec in runs:
        say(f"  {rec.integrator:<20} max |dE/E| {max_abs_energy_error(rec):.2e}")
    sweep: list[SweepPoint] = []
    coarse: list[RunRecord] = []
    end_time = scenario.steps * scenario.dt
    for factor in DT_FACTORS:
        dt = scenario.dt * factor
        steps = resolve_steps(end_time, dt)[0]
        rung = scenario.with_overrides(dt=dt, steps=steps)
        rung_plan = sample_steps_every(steps, max(1, steps // SWEEP_SAMPLES))
        ref = reference_for(rung, rung_plan)
        records = [run_orbitsim(rung, name, rung_plan) for name, _, _ in LESSON]
        sweep += [SweepPoint(r.integrator, dt, max_abs_energy_error(r), _final_error(r, ref)) for r in records]
        coarse = records  # the last, coarsest rung is kept for its orbits
    say(f"  dt sweep: {len(DT_FACTORS)} values of dt from {DT_FACTORS[0]:g} to {DT_FACTORS[-1]:g} x {scenario.dt:g}")
    return LessonResult(scenario, runs, reference, sweep, coarse, scenario.dt * DT_FACTORS[-1])


def fitted_slope(x: np.ndarray, y: np.ndarray) -> float:
    """Slope of log(y) against log(x) over the :data:`SLOPE_POINTS` smallest x with finite,
    positive y (nan if fewer than 2): the small-dt end is where a scheme's order shows."""
    ok = np.flatnonzero(np.isfinite(y) & (y > 0) & (x > 0))
    ok = ok[np.argsort(x[ok])][:SLOPE_POINTS]
    if ok.size < 2:
        return math.nan
    return float(np.polyfit(np.log(x[ok]), np.log(y[ok]), 1)[0])


def lesson_metrics(result: LessonResult) -> list[dict[str, Any]]:
    """Per scheme: max |dE/E|, drift slope, final position error, largest orbital radius."""
    rows = []
    for rec, (_, title, moral) in zip(result.runs, LESSON, strict=True):
        sep = np.linalg.norm(rec.positions[:, 1] - rec.positions[:, 0], axis=-1)
        dts, emax, perr = result.sweep_of(rec.integrator)
        rows.append({
            "integrator": rec.integrator, "title": title, "moral": moral,
            "max_abs_energy_error": max_abs_energy_error(rec),
            "energy_drift_slope": energy_drift_slope(rec.time, rec.energy_error),
            "final_position_error": _final_error(rec, result.reference),
            "max_separation": float(sep.max()), "energy_order": fitted_slope(dts, emax),
            "position_order": fitted_slope(dts, perr), "wall_time_s": rec.wall_time_s,
        })
    return rows
