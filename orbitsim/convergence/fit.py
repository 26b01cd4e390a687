"""The order fit of ``orbitsim convergence``: which rungs of a dt ladder are asymptotic, and when
none are, the true reason and a ladder to try.

The error of a p-th order scheme is C dt^p only in the asymptotic range: at coarse dt higher
terms (or a wrong orbit) bend it, at fine dt round-off takes over. The local slope between
neighbouring rungs, log(e_k / e_k+1) / log(dt_k / dt_k+1), is constant only in between. So
(:func:`fit_order`, rungs ordered coarse to fine):

1. Errors above :data:`CEILING` (10 % of the system's size: the orbit is already wrong) and below
   :data:`ULP_FLOOR` (ten roundings of a position) never enter the fit.
2. The round-off floor is reached when the error stops falling (a local slope below
   :data:`STAGNATION_SLOPE`) at a level round-off can explain (below :func:`round_off_bound` of
   the finer rung's step count). Then the rungs past that first stall are round-off, and so is
   a rung within :data:`FLOOR_MARGIN` of the smallest error unless it was reached by a fall from
   a rung above that margin and lies more than :data:`FLOOR_SCATTER` above the floor (round-off
   scatters over a decade or two; a truncation error falls into it along the scheme's slope).
   A stall at larger errors is not round-off: the ladder has not reached the asymptotic range
   there (e.g. an error oscillating with the orbit's phase).
3. The asymptotic range is the run of consecutive remaining rungs that ends at the finest rung
   possible and reaches from there as far coarser as its local slopes lie within
   :func:`slope_spread` of each other; the order is the least-squares slope over its
   :data:`FIT_POINTS` finest rungs. Fewer than
   :data:`MIN_FIT_POINTS` rungs: no order, and the note says which end of the ladder is missing.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

#: A local slope below this means halving dt no longer helps (round-off, or not yet asymptotic).
STAGNATION_SLOPE = 0.5
#: Points with an error within this factor of the floor are round-off dominated ...
FLOOR_MARGIN = 100.0
#: ... unless a truncation error fell into that margin from above it, and still lies this far
#: above the floor: round-off scatters by about a decade about its floor.
FLOOR_SCATTER = 10.0
#: Relative errors above this are not in the asymptotic regime (the orbit is already wrong).
CEILING = 0.1
#: Errors below ten roundings of a unit position (2.2e-15) measure rounding, not truncation.
ULP_FLOOR = 10.0 * float(np.finfo(np.float64).eps)
#: Round-off per step that a stalled error may be blamed on: measured floors on the Kepler problem
#: (e = 0.3 ... 0.9, 40 to 5e5 steps) lie at 1e-17 ... 1e-16 per step, and a truncation error that
#: stalls (oscillating with the orbit's phase) at 1e-2 ... 1: 1e3 ulp per step sits between.
ROUND_OFF_PER_STEP = 1e3 * float(np.finfo(np.float64).eps)
#: Local slopes of the asymptotic range agree within max(SLOPE_SPREAD, SLOPE_SPREAD_REL x their
#: median): a pre-asymptotic bend or a rung touched by round-off changes them by more (measured on
#: e = 0.3 ... 0.9 Kepler orbits: leapfrog8 10.1, 7.2 then 7.9, 8.1; 7.9, 8.0 then 6.2 at the
#: floor; semi-implicit Euler 0.13, 0.66, 0.86 while its error still oscillates), a second-order
#: scheme's 1.97 .. 2.00 and rk4's settling 4.45, 4.29, 4.17 stay within.
SLOPE_SPREAD = 0.1
SLOPE_SPREAD_REL = 0.1
#: A fit whose local slopes still differ from it by more than this is drifting: finer dt would
#: move it (rk4 on e = 0.9: 4.72, 4.57, 4.39).
SETTLED = 0.15
#: Fit the finest points of the asymptotic range only: the leading error term dominates there.
FIT_POINTS = 4
MIN_FIT_POINTS = 3
#: How many dt values a suggested ladder has.
SUGGESTED_RUNGS = 5

#: ``OrderFit.kind``: fitted; dt too coarse (no asymptotic range yet: finer dt needed); round-off
#: floor reached with too few rungs above it (coarser dt needed); round-off at every dt; no data.
FITTED, TOO_COARSE, FLOOR, ROUND_OFF, NO_DATA = "fitted", "too_coarse", "floor", "round_off", "no_data"


@dataclass(frozen=True)
class OrderFit:
    """The fitted order of one ladder and what decided it.

    ``used`` marks (in the input order) the rungs that entered the fit; ``note`` says what was
    left out and why, or why there is no order; ``kind`` is one of the module's kinds;
    ``settled`` is False for a fit that more rungs could move: its local slopes still drift, or
    rungs finer than it, above the round-off floor, lie off its slope (it may be pre-asymptotic);
    ``floor`` is the round-off floor's error (0 when the ladder did not reach it);
    ``suggested`` is a ladder to try (coarse to fine; empty where none would help); ``extend``
    says whether running a rung of it would likely help (what the default ladder does).
    """

    order: float
    used: np.ndarray
    note: str
    kind: str
    settled: bool = True
    floor: float = 0.0
    suggested: tuple[float, ...] = field(default=())
    extend: bool = False


def round_off_bound(steps: np.ndarray) -> np.ndarray:
    """The largest error round-off may explain after ``steps`` steps (:data:`ROUND_OFF_PER_STEP`)."""
    return ROUND_OFF_PER_STEP * np.maximum(np.asarray(steps, dtype=np.float64), 1.0)


def _local_slopes(logd: np.ndarray, loge: np.ndarray) -> np.ndarray:
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.diff(loge) / np.diff(logd)


def slope_spread(slopes: np.ndarray) -> float:
    """How far apart the local slopes of one asymptotic range may lie."""
    return max(SLOPE_SPREAD, SLOPE_SPREAD_REL * float(np.median(slopes)))


def _asymptotic_run(slopes: np.ndarray, ok: np.ndarray) -> tuple[int, int] | None:
    """``(first, stop)``: the run of consecutive ``ok`` points (coarse to fine) that reaches the
    finest such point possible and, from there, extends coarser as far as its local slopes agree
    within :func:`slope_spread` and stay above :data:`STAGNATION_SLOPE` (the asymptotic range
    lies at small dt; a longer run at coarse dt is pre-asymptotic). None when no run has
    MIN_FIT_POINTS points."""
    for stop in range(ok.size, MIN_FIT_POINTS - 1, -1):
        best = None
        for first in range(stop - MIN_FIT_POINTS, -1, -1):
            s = slopes[first:stop - 1]
            if not ok[first:stop].all() or not np.all(np.isfinite(s)) or s.min() < STAGNATION_SLOPE:
                break
            if s.max() - s.min() <= slope_spread(s):
                best = first
        if best is not None:
            return best, stop
    return None


def _ladder_text(dts: list[float]) -> str:
    return ",".join(f"{d:.6g}" for d in dts)


def _finer(start: float, count: int = SUGGESTED_RUNGS) -> tuple[float, ...]:
    """A ladder that goes on from ``start`` by halving dt, ``count`` rungs."""
    return tuple(start * 2.0 ** -k for k in range(count))


def _denser(hi: float, lo: float) -> tuple[float, ...]:
    """A ladder from ``hi`` down to ``lo`` in steps of 2^(1/2) (at least :data:`SUGGESTED_RUNGS` rungs)."""
    count = max(SUGGESTED_RUNGS, math.ceil(2.0 * math.log2(hi / lo)) + 1) if lo < hi else SUGGESTED_RUNGS
    lo = min(lo, hi * 2.0 ** (-(count - 1) / 2.0))
    return tuple(hi * (lo / hi) ** (k / (count - 1)) for k in range(count))


def _coarser(top: float, max_dt: float) -> tuple[float, ...]:
    """A ladder that reaches up from ``top`` by doubling dt (at most ``max_dt``), ending at ``top``."""
    return tuple(x for x in (top * 2.0 ** k for k in range(SUGGESTED_RUNGS - 1, -1, -1)) if x <= max_dt)


def fit_order(dts: np.ndarray, errors: np.ndarray, steps: np.ndarray | None = None,
              max_dt: float = math.inf) -> OrderFit:
    """Fit the order over the asymptotic range of a ladder (see the module docstring).

    Parameters
    ----------
    dts, errors : (K,) arrays
        The rungs, in any order.
    steps : (K,) array, optional
        Steps of each rung, for the round-off bound (default: 10^6 each, a generous bound).
    max_dt : float
        The largest dt a suggested ladder may hold (the span T).

    Returns
    -------
    OrderFit
    """
    dts = np.asarray(dts, dtype=np.float64)
    err = np.asarray(errors, dtype=np.float64)
    n_steps = np.full(dts.size, 1e6) if steps is None else np.asarray(steps, dtype=np.float64)
    order = np.argsort(-dts)  # coarse to fine
    d, e, n = dts[order], err[order], n_steps[order]
    used = np.zeros(e.size, dtype=bool)
    finite = np.isfinite(e) & (e > 0.0)
    if not finite.any():
        return OrderFit(math.nan, used, "no rung completed with a finite error", NO_DATA)
    with np.errstate(divide="ignore", invalid="ignore"):
        logd, loge = np.log(d), np.log(np.where(finite, e, np.nan))
    slopes = _local_slopes(logd, loge)
    stalled = np.flatnonzero(np.isfinite(slopes) & (slopes < STAGNATION_SLOPE)
                             & (np.fmin(e[:-1], e[1:]) <= round_off_bound(n[1:])))
    floor = float(np.nanmin(np.where(finite, e, np.nan))) if stalled.size else 0.0
    clear = e > FLOOR_MARGIN * floor
    # Near the floor only a rung reached by a fall from a clear one is truncation (step 2 above).
    fell_into = np.zeros(e.size, dtype=bool)
    fell_into[1:] = clear[:-1] & (slopes >= STAGNATION_SLOPE) & (e[1:] > FLOOR_SCATTER * floor)
    above_floor = (clear | fell_into) & (e > ULP_FLOOR)
    if stalled.size:  # past the first stall round-off rules: it only grows with the step count
        above_floor[stalled[0] + 1:] = False
    ok = finite & (e <= CEILING) & above_floor
    run = _asymptotic_run(slopes, ok)
    notes: list[str] = []
    if floor:
        notes.append(f"round-off floor ~{floor:.1e} reached")
    if run is None:
        return _no_order(d, e, finite, ok, above_floor, floor, notes, max_dt)
    first, stop = run
    picked = np.arange(max(first, stop - FIT_POINTS), stop)
    slope = float(np.polyfit(logd[picked], loge[picked], 1)[0])
    used[order[picked]] = True
    local = slopes[picked[0]:picked[-1]]
    drifting = bool(abs(local[-1] - slope) > SETTLED)
    coarser_out = int(np.count_nonzero(finite[:first]))
    finer_clear = np.flatnonzero(ok[stop:]) + stop  # finer, on neither the floor nor above the ceiling
    finer_out = int(np.count_nonzero(finite[stop:] & above_floor[stop:]))
    if coarser_out:
        notes.append(f"{coarser_out} coarser rung(s) not yet asymptotic left out")
    suggested: tuple[float, ...] = ()
    if finer_clear.size:
        # Finer rungs clear of the floor do not continue this slope: it may be pre-asymptotic.
        suggested = _denser(float(d[stop - 1]), float(d[finer_clear[-1]]))
        notes.append(f"{finer_out} finer rung(s) above the round-off floor lie off this slope, so it may not be "
                     f"asymptotic yet: try --dts {_ladder_text(list(suggested))}")
    elif finer_out:
        notes.append(f"{finer_out} finer rung(s) off the asymptotic slope left out")
    if drifting and not finer_clear.size and floor:
        # Finer rungs are round-off: the range can only grow coarser, or denser within.
        top = int(np.flatnonzero(finite)[0])
        suggested = (_coarser(float(d[first]), max_dt) if first == top and e[first] <= CEILING
                     else _denser(float(d[first]), float(d[stop - 1])))
        notes.append(f"local slopes {', '.join(f'{s:.2f}' for s in local)} still drift near the round-off floor: "
                     f"try --dts {_ladder_text(list(suggested))}")
    elif drifting and not finer_clear.size:
        suggested = _finer(float(d[picked[-1]]))
        notes.append(f"local slopes {', '.join(f'{s:.2f}' for s in local)} still drift, so finer dt may move the "
                     f"fit: try --dts {_ladder_text(list(suggested))}")
    settled = not (drifting or finer_clear.size)
    extend = bool(finer_clear.size) or drifting
    return OrderFit(slope, used, "; ".join(notes), FITTED, settled, floor, suggested, extend)


def _no_order(d: np.ndarray, e: np.ndarray, finite: np.ndarray, ok: np.ndarray, above_floor: np.ndarray,
              floor: float, notes: list[str], max_dt: float) -> OrderFit:
    """Why no asymptotic range of MIN_FIT_POINTS rungs exists, and a ladder that would have one."""
    used = np.zeros(e.size, dtype=bool)
    if floor and not np.any(finite & above_floor):
        suggested = _coarser(float(d[0]), max_dt)
        notes.append(f"error at round-off for every dt ({np.nanmin(e[finite]):.1e} .. {np.nanmax(e[finite]):.1e}): "
                     "no truncation error to fit (exact for this problem, or the ladder starts too fine: try --dts "
                     f"{_ladder_text(list(suggested))})")
        return OrderFit(math.nan, used, "; ".join(notes), ROUND_OFF, floor=floor, suggested=suggested,
                        extend=bool(suggested))
    if floor:
        kept = np.flatnonzero(ok)
        clear = np.flatnonzero(finite & above_floor)
        if clear[0] == np.flatnonzero(finite)[0] and e[clear[0]] <= CEILING:
            # Nothing coarser was run: the range reaches up from the coarsest rung above the floor.
            suggested = _coarser(float(d[clear[0]]), max_dt)
            why = "dt below the asymptotic range"
        else:
            # Coarser rungs are not asymptotic yet: the range lies between, narrower than the ladder's steps.
            hi = float(d[max(int(kept[0]) - 1, 0)]) if kept.size else float(d[clear[0]])
            lo = float(d[kept[-1]]) if kept.size else hi
            suggested = _denser(hi, lo)
            why = "the asymptotic range is narrower than the ladder's steps"
        notes.append(f"fewer than {MIN_FIT_POINTS} rungs on one slope between it and {CEILING:g} ({kept.size} there): "
                     f"{why}, try --dts {_ladder_text(list(suggested))}")
        return OrderFit(math.nan, used, "; ".join(notes), FLOOR, floor=floor, suggested=suggested, extend=True)
    # No floor: the finest rungs are still above the asymptotic range.
    below = np.flatnonzero(finite & (e <= CEILING))
    # From the coarsest rung below the ceiling on, two rungs finer than any run so far.
    suggested = (_finer(float(d[below[0]]), max(SUGGESTED_RUNGS, e.size - int(below[0]) + 2)) if below.size
                 else _finer(float(d[-1]) / 2.0))
    if not below.size:
        why = f"every error above {CEILING:g}, the smallest {np.nanmin(e[finite]):.2g} at dt = {d[finite][-1]:.6g}"
    elif below.size < MIN_FIT_POINTS:
        why = f"only {below.size} rung(s) below {CEILING:g}"
    else:
        slopes = _local_slopes(np.log(d[below]), np.log(e[below]))
        why = "local slopes " + ", ".join(f"{s:.2f}" for s in slopes) + " not settled"
    notes.append(f"dt above the asymptotic range ({why}): try --dts {_ladder_text(list(suggested))}")
    return OrderFit(math.nan, used, "; ".join(notes), TOO_COARSE, suggested=suggested, extend=True)
