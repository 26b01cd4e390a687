"""Convergence ladders: error at the end time against the IAS15 reference for a range of dt.

For each dt the run takes ``n = resolve_steps(T, dt)`` whole steps and is compared with the
reference stopped exactly at ``n * dt``, using the relative position error of
:mod:`orbitsim.compare.metrics`. The order of accuracy is the slope of log(error) against
log(dt) over the ladder's asymptotic range (the diffrax-style check: the error of a p-th order
scheme scales as dt^p there); :mod:`orbitsim.convergence.fit` finds that range and, when
there is none, says why.

The default ladder (the scenario's dt times :data:`DEFAULT_FACTORS`) is extended per scheme until
it reaches the scheme's asymptotic range (:func:`extend_series`): finer while dt is above it (or
the local slopes still drift), coarser when the round-off floor comes first, denser where the
range is narrower than the ladder's steps; at most :data:`MAX_EXTENSIONS` rungs and
:data:`MAX_EXTENSION_STEPS` steps per rung. A ladder given with ``--dts`` is run as given.

Both codes integrate the scenario's ``forces:``; REBOUND and its IAS15 reference through REBOUNDx,
arranged as orbitsim applies each force (:mod:`orbitsim.reference.force_pairing`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from orbitsim.compare.metrics import relative_position_difference
from orbitsim.compare.run import run_orbitsim, settings_for
from orbitsim.convergence.fit import (
    CEILING,
    FIT_POINTS,
    FITTED,
    FLOOR_MARGIN,
    MIN_FIT_POINTS,
    ROUND_OFF,
    STAGNATION_SLOPE,
    OrderFit,
    fit_order,
)
from orbitsim.record import RunRecord
from orbitsim.reference.bridge import ReboundScheme
from orbitsim.reference.force_pairing import orbitsim_refusal, rebound_refusal
from orbitsim.reference.sampling import REFERENCE_SCHEME, run_rebound, run_reference

__all__ = ["CEILING", "DEFAULT_FACTORS", "FIT_POINTS", "FLOOR_MARGIN", "MAX_EXTENSIONS", "MAX_EXTENSION_STEPS",
           "MIN_FIT_POINTS", "STAGNATION_SLOPE", "ConvergenceResult", "ConvergenceSeries", "LadderPoint",
           "WholePeriods", "extend_series", "fit_order", "ladder", "run_convergence", "whole_periods"]

#: Default ladder: the scenario's dt times these factors (two coarser, three finer).
DEFAULT_FACTORS = (4.0, 2.0, 1.0, 0.5, 0.25, 0.125)
#: Rungs the default ladder may add to one scheme's ladder to reach its asymptotic range: with
#: the six default rungs a ladder then spans 2^11 in dt, three decades of error even at first
#: order (an order-8 scheme crosses the ~11 decades between 10 % and round-off in ~4.5 halvings).
MAX_EXTENSIONS = 6
#: A finer rung is added only while it takes at most this many steps (a few seconds on a few bodies).
MAX_EXTENSION_STEPS = 2**22
#: A coarser rung must still take at least this many steps.
MIN_EXTENSION_STEPS = 8
#: T within this fraction of a period of a whole number of a body's periods is "whole periods": at
#: 0.01 P from the pericentre the error of a first-order scheme no longer cancels (it grows ~1/P
#: away from it), so the trap is real only closer than this.
WHOLE_PERIOD_TOLERANCE = 0.01
#: A fitted order this far above the declared one is explained by the whole-period trap, if T is one.
ABOVE_DECLARED = 0.5

#: Runs shorter than this are repeated (best of up to :data:`MAX_REPEATS`) for the work-precision
#: chart: a single run of a few milliseconds is mostly timer and cache noise.
MIN_TIMED_SECONDS = 0.05
MAX_REPEATS = 5


@dataclass
class LadderPoint:
    """One rung: a run of ``steps`` steps of ``dt`` and its error at the end (``added``: a rung
    the default ladder added for this scheme)."""

    dt: float
    steps: int
    end_time: float
    error: float
    wall_time_s: float
    status: str
    added: bool = False


@dataclass
class ConvergenceSeries:
    """One integrator's ladder and its fitted order.

    ``adaptive`` series (IAS15) take ``dt`` only as a first trial step: they are run and shown,
    but have no order in dt. ``note`` says why the order is what it is (or missing), ``fit_kind``
    is :func:`~orbitsim.convergence.fit.fit_order`'s kind, ``forces`` how the series
    applies the scenario's forces (one phrase per force).
    """

    engine: str
    key: str
    display: str
    declared_order: int | None
    points: list[LadderPoint] = field(default_factory=list)
    fitted_order: float = math.nan
    fit_used: list[bool] = field(default_factory=list)
    note: str = ""
    adaptive: bool = False
    forces: tuple[str, ...] = ()
    fit_kind: str = ""
    settled: bool = True

    def fit(self, max_dt: float = math.inf) -> OrderFit | None:
        """Fit the order from the points (:func:`~orbitsim.convergence.fit.fit_order`)."""
        self.points.sort(key=lambda p: -p.dt)
        if self.adaptive:
            self.note = "adaptive: dt is only its first trial step, so it has no order in dt to fit"
            self.fit_used, self.fit_kind = [False] * len(self.points), ""
            return None
        result = fit_order(np.array([p.dt for p in self.points]), np.array([p.error for p in self.points]),
                           np.array([p.steps for p in self.points]), max_dt=max_dt)
        self.fitted_order, self.note, self.fit_kind, self.settled = (result.order, result.note, result.kind,
                                                                      result.settled)
        self.fit_used = [bool(u) for u in result.used]
        added = [p.dt for p in self.points if p.added]
        if added:
            self.note = "; ".join(filter(None, [f"ladder extended to dt = {', '.join(f'{d:.6g}' for d in added)}",
                                                self.note]))
        return result

    @property
    def judged(self) -> bool:
        """True when the series has a declared order in dt to be checked against."""
        return self.declared_order is not None and not self.adaptive

    def verdict(self, tolerance: float) -> str:
        """``""`` when the fitted order is within ``tolerance`` of the declared one, else the
        one-line reason (the same words as the report's table)."""
        if not self.judged:
            return ""
        if not math.isfinite(self.fitted_order):
            return f"{self.display}: no fitted order, declared {self.declared_order} ({self.note})"
        if abs(self.fitted_order - self.declared_order) > tolerance:
            why = f" ({self.note})" if self.note else ""
            return f"{self.display}: fitted {self.fitted_order:.2f}, declared {self.declared_order}{why}"
        return ""


@dataclass(frozen=True)
class WholePeriods:
    """T is (nearly) a whole number of one body's periods about the heaviest body: over whole orbits
    of a Kepler problem the leading error of some schemes cancels (semi-implicit Euler's first-order
    term does, started at pericentre), so the fitted order comes out above the declared one."""

    body: str
    centre: str
    period: float
    periods: float  # T / P
    better_t_end: float  # 0.7 P after t_start, on the scenario's clock

    def words(self) -> str:
        return (f"T is {self.periods:.3f} periods of {self.body} about {self.centre} (P = {self.period:.6g}): over "
                "whole orbits a scheme's leading error can cancel (semi-implicit Euler's, started at an apsis), "
                f"and the order measured is the next one; measure within the first orbit: --t-end "
                f"{self.better_t_end:.6g} (0.7 P)")


def whole_periods(scenario: Any, end_time: float) -> WholePeriods | None:
    """The first body whose osculating period about the heaviest body divides T a whole number of
    times (within :data:`WHOLE_PERIOD_TOLERANCE` of a period), or None. The end time it suggests,
    0.7 P after t_start, takes in one pericentre passage, where a scheme's error is made, and is
    measured before the bounded first-order terms hide under the errors that grow secularly.
    (0.3 P from apocentre, on the bundled two_body_eccentric, never reaches the pericentre: leapfrog8
    is at round-off there at every dt.)"""
    m = np.asarray(scenario.masses, dtype=float)
    x, v = np.asarray(scenario.positions, dtype=float), np.asarray(scenario.velocities, dtype=float)
    c = int(np.argmax(m))
    for i in range(len(m)):
        gm = scenario.G * (m[c] + m[i])
        if i == c or not gm > 0.0:
            continue
        r, w = x[i] - x[c], v[i] - v[c]
        energy = 0.5 * float(w @ w) - gm / math.sqrt(float(r @ r))
        if not energy < 0.0:
            continue
        a = -gm / (2.0 * energy)
        period = 2.0 * math.pi * math.sqrt(a**3 / gm)
        k = end_time / period
        if k >= 1.0 - WHOLE_PERIOD_TOLERANCE and abs(k - round(k)) < WHOLE_PERIOD_TOLERANCE:
            names = scenario.names
            return WholePeriods(names[i], names[c], period, k, scenario.t_start + 0.7 * period)
    return None


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


def _rung_runner(series: ConvergenceSeries, rung: Any, plan: np.ndarray, scheme: ReboundScheme | None,
                 forces: Any) -> Callable[[], RunRecord]:
    """A no-argument function that runs one rung of ``series`` (so it can be repeated for timing)."""
    if series.engine == "orbitsim":
        return lambda: run_orbitsim(rung, series.key, plan)
    return lambda: run_rebound(rung.masses, rung.positions, rung.velocities, G=rung.G, softening=rung.softening,
                               dt=rung.dt, scheme=scheme, sample_steps=plan, forces=forces)


class _Rungs:
    """Runs rungs of one scenario to the span T, with one IAS15 reference per end time."""

    def __init__(self, scenario: Any, end_time: float, schemes: dict[str, ReboundScheme]) -> None:
        from orbitsim.scenario_simulation import scenario_forces  # noqa: PLC0415 -- lazy: loads yaml

        self.scenario = scenario
        self.end_time = float(end_time)
        self.schemes = schemes
        self.forces = scenario_forces(scenario)
        self.references: dict[float, RunRecord] = {}

    def steps(self, dt: float) -> int:
        """Whole steps of ``dt`` that fit in T."""
        from orbitsim.scenario import resolve_steps  # noqa: PLC0415 -- lazy: loads yaml

        return int(resolve_steps(self.end_time, dt)[0])

    def point(self, series: ConvergenceSeries, dt: float, *, added: bool = False) -> LadderPoint:
        """Run ``series`` at ``dt`` and measure its error against the reference at ``n * dt``."""
        steps = self.steps(dt)
        rung = self.scenario.with_overrides(dt=dt, steps=steps)
        plan = np.array([0, steps], dtype=np.int64)
        t_end = steps * dt
        if t_end not in self.references:
            self.references[t_end] = run_reference(rung.masses, rung.positions, rung.velocities, G=rung.G,
                                                   softening=rung.softening, dt=dt, sample_steps=plan,
                                                   forces=self.forces)
        ref = self.references[t_end]
        record, wall = _timed(_rung_runner(series, rung, plan, self.schemes.get(series.key), self.forces))
        series.forces = record.forces
        complete = record.status == "complete" and record.n_samples == 2
        error = float(relative_position_difference(record.positions, ref.positions)[-1]) if complete else math.nan
        return LadderPoint(dt, steps, t_end, error, wall, record.status, added)


def extend_series(series: ConvergenceSeries, rungs: _Rungs, say: Callable[[str], None]) -> None:
    """Add rungs to ``series`` until its ladder reaches the asymptotic range: each time the rung
    of the fit's suggested ladder nearest to those already run (finer while dt is above the range
    or the slopes drift, coarser while the round-off floor comes first, in between where the range
    is narrower than the ladder's steps), at most :data:`MAX_EXTENSIONS` rungs, each of
    :data:`MIN_EXTENSION_STEPS` .. :data:`MAX_EXTENSION_STEPS` steps. It stops once the fit is
    settled, when a finer rung falls off the fitted slope, and when a coarser rung is still all
    round-off (the scheme is exact for this problem)."""
    went_coarser = False
    for _ in range(MAX_EXTENSIONS):
        fit = series.fit(rungs.end_time)
        if fit is None or not fit.extend or (fit.kind == ROUND_OFF and went_coarser):
            break
        done = np.log([p.dt for p in series.points])
        fresh = [dt for dt in fit.suggested if np.min(np.abs(done - math.log(dt))) > 1e-9
                 and MIN_EXTENSION_STEPS <= rungs.steps(dt) <= MAX_EXTENSION_STEPS]
        if not fresh:
            break
        dt = min(fresh, key=lambda x: float(np.min(np.abs(done - math.log(x)))))
        finer = dt < min(p.dt for p in series.points)
        went_coarser = went_coarser or dt > max(p.dt for p in series.points)
        point = rungs.point(series, dt, added=True)
        series.points.append(point)
        say(f"  {series.key}: added dt = {dt:.6g} ({point.steps} steps), error {point.error:.1e}")
        if fit.kind == FITTED and finer:
            refit = series.fit(rungs.end_time)
            if refit is not None and refit.kind == FITTED and not refit.used[[p.dt for p in series.points].index(dt)]:
                break  # the finer rung fell off the asymptotic slope (round-off): finer cannot help
    series.fit(rungs.end_time)


@dataclass
class ConvergenceResult:
    """All ladders of one scenario (``dts``: every dt any ladder ran, coarse to fine)."""

    scenario: Any
    end_time: float
    dts: list[float]
    series: list[ConvergenceSeries]
    notes: list[str] = field(default_factory=list)

    def check(self, tolerance: float) -> list[str]:
        """Series whose fitted order is missing or off the declared one by more than ``tolerance``,
        one line each with the reason (:meth:`ConvergenceSeries.verdict`)."""
        return [line for line in (s.verdict(tolerance) for s in self.series) if line]


def run_convergence(scenario: Any, *, integrators: Sequence[str], rebound: Sequence[ReboundScheme],
                    dts: Sequence[float], end_time: float, progress: Callable[[str], None] | None = None,
                    extend: bool = False) -> ConvergenceResult:
    """Run every integrator at every dt to ``end_time`` and fit the orders.

    Parameters
    ----------
    scenario : Scenario
        Initial conditions, G, softening and forces (its own dt and steps are replaced).
    integrators : sequence of str
        orbitsim integrators (each must be able to apply the scenario's forces).
    rebound : sequence of ReboundScheme
        Fixed-step REBOUND schemes (IAS15 is the reference, not a rung); each must be able to carry
        the scenario's forces (:func:`orbitsim.reference.force_pairing.rebound_refusal`).
    dts : sequence of float
        The ladder.
    end_time : float
        T; each rung takes the whole steps of dt that fit in T and is compared at n * dt.
    extend : bool
        Extend each scheme's ladder to its asymptotic range (:func:`extend_series`): what the
        default ladder does.

    Raises
    ------
    ValueError
        When a scheme or the REBOUND IAS15 reference cannot apply the scenario's forces.
    """
    from orbitsim.integrators.registry import get_spec  # noqa: PLC0415 -- lazy: loads numba
    from orbitsim.scenario_simulation import scenario_forces  # noqa: PLC0415 -- lazy: loads yaml

    say = progress or (lambda _msg: None)
    forces = scenario_forces(scenario)
    specs = [get_spec(n) for n in integrators]
    fixed = [s for s in rebound if s.fixed_step]
    refusals = [why for why in [rebound_refusal(forces, REFERENCE_SCHEME),
                                *(orbitsim_refusal(forces, sp.name, settings_for(scenario, sp.name)) for sp in specs),
                                *(rebound_refusal(forces, s) for s in fixed)] if why]
    if refusals:
        raise ValueError(refusals[0])
    series = [ConvergenceSeries("orbitsim", sp.name, f"orbitsim {sp.name}", sp.order, adaptive=sp.adaptive)
              for sp in specs]
    series += [ConvergenceSeries("rebound", s.key, s.display, s.order) for s in fixed]
    rungs = _Rungs(scenario, end_time, {s.key: s for s in fixed})
    for dt in dts:
        for s in series:
            s.points.append(rungs.point(s, dt))
        say(f"  dt = {dt:<12.6g} {rungs.steps(dt):>9} steps  " + "  ".join(
            f"{s.key} {s.points[-1].error:.1e}" for s in series))
    for s in series:
        if extend:
            extend_series(s, rungs, say)
        s.fit(rungs.end_time)
    trap = whole_periods(scenario, end_time)
    notes = [trap.words()] if trap is not None else []
    for s in series:
        if trap is not None and s.judged and s.fitted_order - s.declared_order > ABOVE_DECLARED:
            s.note = "; ".join(filter(None, [s.note, f"above the declared order: {trap.words()}"]))
    union = sorted({p.dt for s in series for p in s.points}, reverse=True)
    return ConvergenceResult(scenario, float(end_time), union, series, notes)
