"""Comparison metrics: energy error, its secular drift, position errors and pair verdicts.

Position differences are measured relative to the size of the system:

    d(t) = max_i |x_i(t) - x_i^ref(t)| / max_i |x_i^ref(t)|

the largest body displacement divided by the largest distance of any body from the origin in the
reference state at the same sample. A per-body relative error would blow up for a body sitting
near the origin (the Sun in a heliocentric or barycentric frame); scaling by the system's extent
keeps one number meaningful for a whole planetary system or cluster.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from orbitsim.analysis.record import RunRecord
from orbitsim.reference.pairs import MatchedPair, allowed_difference, nominal_tolerance

#: A twin divergence above this means the scenario amplifies round-off so much (chaos, close
#: encounters) that agreement to round-off cannot be expected; verdicts then say so.
CHAOTIC_TWIN = 1e-6


def max_abs_energy_error(record: RunRecord) -> float:
    """max |dE/E| over the samples (nan when there are none)."""
    err = record.energy_error
    return float(np.max(np.abs(err))) if err.size else math.nan


def energy_drift_slope(time: np.ndarray, energy_error: np.ndarray) -> float:
    """Secular drift of the energy error: least-squares slope of dE/E against t (per unit time).

    A symplectic scheme's error oscillates about a constant, so its slope is small and shrinks
    with the length of the run; a non-symplectic one drifts and the slope is its rate.
    """
    t = np.asarray(time, dtype=np.float64)
    e = np.asarray(energy_error, dtype=np.float64)
    ok = np.isfinite(t) & np.isfinite(e)
    if np.count_nonzero(ok) < 3 or np.ptp(t[ok]) == 0.0:
        return math.nan
    t, e = t[ok], e[ok]
    # Centre t so the fit is well conditioned when t is large compared with its span.
    tc = t - t.mean()
    return float(np.dot(tc, e - e.mean()) / np.dot(tc, tc))


def relative_position_difference(positions: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """d_k = max_i |x_i - x_i^ref| / max_i |x_i^ref| at each sample k (see the module docstring).

    Parameters
    ----------
    positions, reference : (S, N, 3) arrays
        The same samples of two runs; ``reference`` sets the scale.
    """
    x = np.asarray(positions, dtype=np.float64)
    ref = np.asarray(reference, dtype=np.float64)
    k = min(x.shape[0], ref.shape[0])
    x, ref = x[:k], ref[:k]
    delta = np.sqrt(np.sum((x - ref) ** 2, axis=-1)).max(axis=-1) if k else np.zeros(0)
    scale = np.sqrt(np.sum(ref**2, axis=-1)).max(axis=-1) if k else np.zeros(0)
    # A system collapsed onto the origin has no scale: fall back to absolute differences.
    return delta / np.where(scale > 0.0, scale, 1.0)


def _aligned(a: RunRecord, b: RunRecord) -> int:
    """Number of leading samples the two records share; raises if their steps differ there."""
    k = min(a.n_samples, b.n_samples)
    if not np.array_equal(a.step[:k], b.step[:k]):
        raise ValueError(f"{a.label} and {b.label} are not sampled at the same steps")
    return k


def position_error(record: RunRecord, reference: RunRecord) -> np.ndarray:
    """Relative position error of ``record`` against ``reference`` at their shared samples."""
    k = _aligned(record, reference)
    return relative_position_difference(record.positions[:k], reference.positions[:k])


def final_position_error(record: RunRecord, reference: RunRecord) -> float:
    """Position error at the last sample; nan unless both runs reached it."""
    if record.status != "complete" or reference.status != "complete" or record.n_samples == 0:
        return math.nan
    if record.n_samples != reference.n_samples:
        return math.nan
    return float(position_error(record, reference)[-1])


@dataclass(frozen=True)
class RunMetrics:
    """The per-run numbers of a comparison."""

    label: str
    max_abs_energy_error: float
    energy_drift_slope: float
    final_position_error: float
    wall_time_s: float
    steps_per_second: float


def run_metrics(record: RunRecord, reference: RunRecord | None) -> RunMetrics:
    """Every per-run metric of ``record`` (position error needs the reference)."""
    final = final_position_error(record, reference) if reference is not None else math.nan
    return RunMetrics(
        label=record.label,
        max_abs_energy_error=max_abs_energy_error(record),
        energy_drift_slope=energy_drift_slope(record.time, record.energy_error),
        final_position_error=final,
        wall_time_s=record.wall_time_s,
        steps_per_second=record.steps_per_second,
    )


@dataclass(frozen=True)
class PairVerdict:
    """How closely a matched pair agreed, and whether that is within its tolerance.

    ``tolerance`` is the allowed difference at the sample where difference / allowed was
    largest (``worst_ratio``); ``allowed_at_max`` the allowed difference at the sample of the
    largest difference; ``nominal_tolerance`` the allowed value at the last step without the twin
    term; ``twin_max`` the largest twin divergence (nan without a twin run).
    """

    pair: MatchedPair
    orbitsim_label: str
    rebound_label: str
    max_difference: float
    time_of_max: float
    tolerance: float
    allowed_at_max: float
    nominal_tolerance: float
    twin_max: float
    worst_ratio: float
    agree: bool
    note: str

    @property
    def name(self) -> str:
        """The pair's name, as verdict messages print it."""
        return self.pair.name


def pair_verdict(pair: MatchedPair, ours: RunRecord, theirs: RunRecord,
                 twin: RunRecord | None) -> PairVerdict:
    """Judge a matched pair: every shared sample must be within :func:`allowed_difference`.

    Runs that stop at different samples (one diverged, the other not) disagree outright.
    """
    diff = position_error(ours, theirs)
    twin_series = position_error(twin, theirs) if twin is not None else None
    allowed = allowed_difference(theirs.step[: diff.size], twin_series)
    nominal = float(nominal_tolerance(int(theirs.step[-1]) if theirs.n_samples else 0))
    note = ""
    if diff.size == 0:
        ratio, worst, agree, note = math.nan, 0, False, "no shared samples"
    else:
        ratios = np.where(np.isfinite(diff), diff / allowed, np.inf)
        worst = int(np.argmax(ratios))
        ratio = float(ratios[worst])
        agree = bool(ratio <= 1.0)
    if ours.n_samples != theirs.n_samples or ours.status != theirs.status:
        agree = False
        note = (f"runs ended differently: orbitsim {ours.status} after {ours.n_samples} samples, "
                f"REBOUND {theirs.status} after {theirs.n_samples}")
    elif ours.status != "complete":
        # Both stopped at the same sample: the codes agree that this scheme cannot run this system.
        note = f"both runs stopped after {ours.n_samples} samples ({ours.status}): {ours.message}"
    k_max = int(np.nanargmax(diff)) if diff.size and np.any(np.isfinite(diff)) else 0
    twin_max = float(np.nanmax(twin_series)) if twin_series is not None and twin_series.size else math.nan
    if twin_max > CHAOTIC_TWIN and not note:
        note = (f"round-off is amplified here: REBOUND rerun from a 4-ulp perturbation diverged by "
                f"{twin_max:.1e}, so the tolerance follows that")
    return PairVerdict(
        pair=pair, orbitsim_label=ours.label, rebound_label=theirs.label,
        max_difference=float(np.nanmax(diff)) if diff.size else math.nan,
        time_of_max=float(theirs.time[k_max]) if diff.size else math.nan,
        tolerance=float(allowed[worst]) if diff.size else nominal,
        allowed_at_max=float(allowed[k_max]) if diff.size else nominal, nominal_tolerance=nominal,
        twin_max=twin_max, worst_ratio=ratio, agree=agree, note=note,
    )
