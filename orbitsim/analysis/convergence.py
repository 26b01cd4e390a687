"""Convergence ladders: error at the end time against the IAS15 reference for a range of dt.

For each dt the run takes ``n = resolve_steps(T, dt)`` whole steps and is compared with the
reference stopped exactly at ``n * dt``, using the relative position error of
:mod:`orbitsim.analysis.metrics`. The order of accuracy is the slope of log(error) against
log(dt) (the diffrax-style check: the error of a p-th order scheme scales as dt^p).

Which points the fit uses (:func:`fit_order`):

* the round-off floor: once halving dt stops reducing the error (a local slope below
  :data:`STAGNATION_SLOPE`), the smallest error is taken as the floor and points within a factor
  :data:`FLOOR_MARGIN` of it are dropped, since round-off, not truncation, decides them;
* the pre-asymptotic regime: errors above :data:`CEILING` (10 % of the system's size) are
  dropped, and of the rest only the :data:`FIT_POINTS` smallest dt are fitted, where the leading
  error term dominates;
* at least :data:`MIN_FIT_POINTS` points must remain, else the order is reported as not
  measurable (e.g. Wisdom-Holman on two bodies is exact, and its error is all round-off).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from orbitsim.analysis.metrics import relative_position_difference
from orbitsim.analysis.record import RunRecord
from orbitsim.reference.bridge import ReboundScheme

#: A local slope below this means halving dt no longer helps: the round-off floor is reached.
STAGNATION_SLOPE = 0.5
#: Points with an error within this factor of the floor are round-off dominated.
FLOOR_MARGIN = 100.0
#: Relative errors above this are not in the asymptotic regime (the orbit is already wrong).
CEILING = 0.1
#: Fit the smallest-dt points only: the leading error term dominates there.
FIT_POINTS = 4
MIN_FIT_POINTS = 3
#: Default ladder: the scenario's dt times these factors (two coarser, three finer).
DEFAULT_FACTORS = (4.0, 2.0, 1.0, 0.5, 0.25, 0.125)
#: Runs shorter than this are repeated (best of up to :data:`MAX_REPEATS`) for the work-precision
#: chart: a single run of a few milliseconds is mostly timer and cache noise.
MIN_TIMED_SECONDS = 0.05
MAX_REPEATS = 5


@dataclass
class LadderPoint:
    """One rung: a run of ``steps`` steps of ``dt`` and its error at the end."""

    dt: float
    steps: int
    end_time: float
    error: float
    wall_time_s: float
    status: str


@dataclass
class ConvergenceSeries:
    """One integrator's ladder and its fitted order."""

    engine: str
    key: str
    display: str
    declared_order: int | None
    points: list[LadderPoint] = field(default_factory=list)
    fitted_order: float = math.nan
    fit_used: list[bool] = field(default_factory=list)
    note: str = ""

    def fit(self) -> None:
        """Fit the order from the points (see :func:`fit_order`)."""
        dts = np.array([p.dt for p in self.points])
        errors = np.array([p.error for p in self.points])
        self.fitted_order, used, self.note = fit_order(dts, errors)
        self.fit_used = [bool(u) for u in used]


def fit_order(dts: np.ndarray, errors: np.ndarray) -> tuple[float, np.ndarray, str]:
    """Least-squares slope of log(error) against log(dt) over the asymptotic, above-floor points.

    Returns
    -------
    order : float
        The fitted slope (nan when fewer than :data:`MIN_FIT_POINTS` points qualify).
    used : (K,) bool array
        Which points (in the input order) entered the fit.
    note : str
        Why the fit is missing or what was excluded.
    """
    dts = np.asarray(dts, dtype=np.float64)
    err = np.asarray(errors, dtype=np.float64)
    order = np.argsort(-dts)  # coarse to fine
    d, e = dts[order], err[order]
    ok = np.isfinite(e) & (e > 0.0) & (e <= CEILING)
    notes = []
    with np.errstate(divide="ignore", invalid="ignore"):
        local = np.diff(np.log(e)) / np.diff(np.log(d))
    if np.any(np.isfinite(local) & (local < STAGNATION_SLOPE)):
        floor = float(np.nanmin(np.where(e > 0.0, e, np.nan)))
        ok &= e > FLOOR_MARGIN * floor
        notes.append(f"round-off floor ~{floor:.1e} reached")
    picked = np.flatnonzero(ok)[-FIT_POINTS:]
    used_sorted = np.zeros(e.size, dtype=bool)
    used_sorted[picked] = True
    used = np.zeros(e.size, dtype=bool)
    used[order] = used_sorted
    if picked.size < MIN_FIT_POINTS:
        notes.append(f"fewer than {MIN_FIT_POINTS} points between the floor and {CEILING:g}")
        return math.nan, used, "; ".join(notes)
    slope = np.polyfit(np.log(d[picked]), np.log(e[picked]), 1)[0]
    return float(slope), used, "; ".join(notes)


def ladder(base_dt: float, dts: Sequence[float] | None) -> list[float]:
    """The dt values to run, coarse to fine: ``dts`` if given, else base_dt x DEFAULT_FACTORS."""
    values = list(dts) if dts else [base_dt * f for f in DEFAULT_FACTORS]
    if any(not (math.isfinite(v) and v > 0.0) for v in values):
        raise ValueError(f"every dt must be a positive number, got {values}")
    return sorted(set(values), reverse=True)


def _timed(run: Callable[[], RunRecord]) -> tuple[RunRecord, float]:
    """Run, repeating short runs, and return the last record and the best wall time."""
    record = run()
    best, total, reps = record.wall_time_s, record.wall_time_s, 1
    while total < MIN_TIMED_SECONDS and reps < MAX_REPEATS:
        record = run()
        best, total, reps = min(best, record.wall_time_s), total + record.wall_time_s, reps + 1
    return record, best


def _rung_runner(series: ConvergenceSeries, rung: Any, plan: np.ndarray,
                 scheme: ReboundScheme | None) -> Callable[[], RunRecord]:
    """A no-argument function that runs one rung of ``series`` (so it can be repeated for timing)."""
    from orbitsim.analysis.compare import run_orbitsim
    from orbitsim.reference.sampling import run_rebound

    if series.engine == "orbitsim":
        return lambda: run_orbitsim(rung, series.key, plan)
    return lambda: run_rebound(rung.masses, rung.positions, rung.velocities, G=rung.G, softening=rung.softening,
                               dt=rung.dt, scheme=scheme, sample_steps=plan)


@dataclass
class ConvergenceResult:
    """All ladders of one scenario."""

    scenario: Any
    end_time: float
    dts: list[float]
    series: list[ConvergenceSeries]

    def check(self, tolerance: float) -> list[str]:
        """Series whose fitted order is missing or off the declared one by more than ``tolerance``."""
        bad = []
        for s in self.series:
            if s.declared_order is None:
                continue
            if not math.isfinite(s.fitted_order) or abs(s.fitted_order - s.declared_order) > tolerance:
                bad.append(f"{s.display}: fitted {s.fitted_order:.2f}, declared {s.declared_order}")
        return bad


def run_convergence(scenario: Any, *, integrators: Sequence[str], rebound: Sequence[ReboundScheme],
                    dts: Sequence[float], end_time: float,
                    progress: Callable[[str], None] | None = None) -> ConvergenceResult:
    """Run every integrator at every dt to ``end_time`` and fit the orders.

    Parameters
    ----------
    scenario : Scenario
        Initial conditions, G and softening (its own dt and steps are replaced).
    integrators : sequence of str
        orbitsim integrators.
    rebound : sequence of ReboundScheme
        Fixed-step REBOUND schemes (IAS15 is the reference, not a rung).
    dts : sequence of float
        The ladder.
    end_time : float
        T; each rung takes the whole steps of dt that fit in T and is compared at n * dt.
    """
    from orbitsim.integrators.registry import get_spec
    from orbitsim.reference.sampling import run_reference
    from orbitsim.scenario import resolve_steps

    say = progress or (lambda _msg: None)
    references: dict[float, RunRecord] = {}
    series = [ConvergenceSeries("orbitsim", get_spec(n).name, f"orbitsim {get_spec(n).name}", get_spec(n).order)
              for n in integrators]
    series += [ConvergenceSeries("rebound", s.key, s.display, s.order) for s in rebound if s.fixed_step]
    schemes = {s.key: s for s in rebound}
    for dt in dts:
        steps = resolve_steps(end_time, dt)[0]
        rung = scenario.with_overrides(dt=dt, steps=steps)
        plan = np.array([0, steps], dtype=np.int64)
        t_end = steps * dt
        if t_end not in references:
            references[t_end] = run_reference(rung.masses, rung.positions, rung.velocities, G=rung.G,
                                              softening=rung.softening, dt=dt, sample_steps=plan)
        ref = references[t_end]
        for s in series:
            record, wall = _timed(_rung_runner(s, rung, plan, schemes.get(s.key)))
            complete = record.status == "complete" and record.n_samples == 2
            error = float(relative_position_difference(record.positions, ref.positions)[-1]) if complete else math.nan
            s.points.append(LadderPoint(dt, steps, t_end, error, wall, record.status))
        say(f"  dt = {dt:<12.6g} {steps:>9} steps  " + "  ".join(
            f"{s.key} {s.points[-1].error:.1e}" for s in series))
    for s in series:
        s.fit()
    return ConvergenceResult(scenario, float(end_time), list(dts), series)
