"""Comparison metrics: energy error, its secular drift, position errors and pair verdicts.

Position differences are measured relative to the size of the system:

    d(t) = max_i |x_i(t) - x_i^ref(t)| / max_i |x_i^ref(t)|

the largest body displacement divided by the largest distance of any body from the origin in the
reference state at the same sample. A per-body relative error would blow up for a body sitting
near the origin (the Sun in a heliocentric or barycentric frame); scaling by the system's extent
keeps one number meaningful for a whole planetary system or cluster.

A matched pair's verdict is one of (:func:`pair_verdict`):

* ``agree``: within its tolerance everywhere, the tolerance below :data:`TESTABLE_LIMIT` of the
  system's size, and a trustworthy reference: the only pass;
* ``disagree``: beyond its tolerance somewhere (or the runs ended differently);
* ``chaotic``: within tolerance, but round-off amplification (the twin run) raised the tolerance
  above :data:`TESTABLE_LIMIT`, where agreement no longer tests the scheme;
* ``not_testable``: the same, with the nominal term grown past the limit (> 10^8 steps);
* ``reference_unreliable``: within tolerance, but the IAS15 reference fails
  :func:`reference_problem`, a sign of an encounter no run here resolves;
* ``not_comparable``: the two codes cannot integrate the same problem (a force one of them cannot
  apply as the other does, :mod:`orbitsim.reference.force_pairing`), so the pair is not run
  against each other and neither agrees nor disagrees (:func:`not_comparable_verdict`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from orbitsim.record import RunRecord
from orbitsim.reference.pairs import MatchedPair, allowed_difference, nominal_tolerance

#: A twin divergence above this means the scenario amplifies round-off so much (chaos, close
#: encounters) that agreement to round-off cannot be expected; verdicts then say so.
CHAOTIC_TWIN = 1e-6

#: The largest allowed difference, as a fraction of the system's size, at which a pair's agreement
#: still tests anything. The size is the metric's own scale (the largest distance of a body from
#: the frame's origin in the REBOUND run at that sample), so the limit reads directly against the
#: "allowed there" of a verdict. Above it a tolerance accepts runs that differ visibly on a plot of
#: the system (a line is ~1e-3 of a figure's width) and schemes of different order (verlet against
#: REBOUND's order-4 leapfrog differs by 4.1e-5 after 200 steps of two_body_circular, 3.4e-3 after
#: 10^4): it no longer tells the same scheme from a different one.
TESTABLE_LIMIT = 1e-3

#: A reference whose own max |dE/E| exceeds this is not trusted. IAS15 at epsilon 1e-9 holds the
#: energy to round-off on orbits it resolves: measured <= 4.3e-15 on the bundled scenarios and
#: 2.9e-11 on pythagorean, through encounters at 1e-4 separations; Brouwer's law (~1e-16
#: sqrt(steps)) keeps even 10^10 steps near 1e-11. Five decades above that, |dE/E| reaches 1e-6 only
#: when IAS15 steps across an encounter it cannot resolve (two bodies falling onto each other
#: without softening: 1e40), and then its positions after that encounter are meaningless.
REFERENCE_ENERGY_LIMIT = 1e-6

#: Verdict kinds of a matched pair; only AGREE is a pass.
AGREE, DISAGREE, CHAOTIC, LOOSE, NO_REFERENCE = "agree", "disagree", "chaotic", "not_testable", "reference_unreliable"
NOT_COMPARABLE = "not_comparable"
#: What reports print for each kind.
VERDICT_LABELS = {
    AGREE: "agree", DISAGREE: "DISAGREE", CHAOTIC: "chaotic: agreement not testable",
    LOOSE: "not testable: tolerance too loose", NO_REFERENCE: "not testable: reference unreliable",
    NOT_COMPARABLE: "not comparable",
}
#: The short tag that starts a verdict's terminal line.
VERDICT_TAGS = {AGREE: "agree", DISAGREE: "DISAGREE", CHAOTIC: "CHAOTIC", LOOSE: "UNTESTED", NO_REFERENCE: "UNTESTED",
                NOT_COMPARABLE: "UNTESTED"}


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


#: Sample times of two runs count as the same when they differ by at most this (relative): an
#: adaptive run lands on k * interval, a fixed-dt run on n * dt, equal up to round-off.
SAME_TIME_RTOL = 1e-9


def _aligned(a: RunRecord, b: RunRecord) -> int:
    """Number of leading samples the two records share; raises if they are sampled at other
    steps there (runs of one grid) or, across grids (an adaptive run beside fixed-dt ones), at
    other times."""
    k = min(a.n_samples, b.n_samples)
    if np.array_equal(a.step[:k], b.step[:k]):
        return k
    ta, tb = a.time[:k], b.time[:k]
    if not np.all(np.abs(ta - tb) <= SAME_TIME_RTOL * np.maximum(np.abs(ta), np.abs(tb))):
        raise ValueError(f"{a.label} and {b.label} are not sampled at the same times")
    return k


def pair_steps(record: RunRecord) -> np.ndarray:
    """Steps taken up to each sample: an adaptive run's own (``extra["steps_taken"]``), else ``step``."""
    taken = record.extra.get("steps_taken") if record.extra else None
    return np.asarray(taken if taken is not None else record.step, dtype=np.int64)


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


def reference_problem(reference: RunRecord) -> str:
    """Why the IAS15 reference cannot be trusted, or ``""`` when it can.

    It cannot when it stopped early or when its own max |dE/E| exceeds
    :data:`REFERENCE_ENERGY_LIMIT` (or is not finite).
    """
    if reference.status != "complete":
        return f"the IAS15 reference did not complete ({reference.status}: {reference.message})"
    err = max_abs_energy_error(reference)
    if not err <= REFERENCE_ENERGY_LIMIT:  # also catches nan
        return (f"the IAS15 reference's own max |dE/E| is {err:.2e} (> {REFERENCE_ENERGY_LIMIT:g}): "
                "an encounter or collision it does not resolve")
    return ""


@dataclass(frozen=True)
class PairVerdict:
    """How closely a matched pair agreed, and whether that agreement is a pass.

    ``tolerance`` is the allowed difference at the sample where difference / allowed was
    largest (``worst_ratio``); ``allowed_at_max`` the allowed difference at the sample of the
    largest difference, ``twin_limited`` whether the twin term set it; ``max_allowed`` the largest
    allowed difference over the run; ``nominal_tolerance`` the allowed value at the last step
    without the twin term; ``twin_max`` the largest twin divergence (nan without a twin run);
    ``within_tolerance`` whether every shared sample was within its allowed difference;
    ``untestable_from`` the time from which the allowed difference exceeded
    :data:`TESTABLE_LIMIT` (nan if never); ``verdict`` one of the kinds above.
    """

    pair: MatchedPair
    orbitsim_label: str
    rebound_label: str
    max_difference: float
    time_of_max: float
    tolerance: float
    allowed_at_max: float
    twin_limited: bool
    max_allowed: float
    nominal_tolerance: float
    twin_max: float
    worst_ratio: float
    within_tolerance: bool
    untestable_from: float
    verdict: str
    note: str

    @property
    def name(self) -> str:
        """The pair's name, as verdict messages print it."""
        return self.pair.name

    @property
    def agree(self) -> bool:
        """True only for a pass: within tolerance, and a tolerance that tests something."""
        return self.verdict == AGREE

    @property
    def label(self) -> str:
        """The verdict as reports print it, e.g. ``chaotic: agreement not testable``."""
        return VERDICT_LABELS[self.verdict]

    def tolerance_source(self) -> str:
        """What set the allowed difference at the largest difference: the nominal term or the twin
        (``n/a`` for a pair that is not comparable)."""
        if self.verdict == NOT_COMPARABLE:
            return "n/a"
        return "round-off amplification (twin divergence)" if self.twin_limited else "nominal (n^1.5)"

    def terminal_line(self) -> str:
        """One line for the terminal: tag, pair, difference, what it was allowed and why."""
        if self.verdict == NOT_COMPARABLE:
            return f"{VERDICT_TAGS[self.verdict]:<8} {self.name}: {self.short_reason()}"
        source = (f", set by round-off amplification: a REBOUND twin from a 4-ulp perturbation diverged by up to "
                  f"{self.twin_max:.2e}" if self.twin_limited else "")
        line = (f"{VERDICT_TAGS[self.verdict]:<8} {self.name}: max difference {self.max_difference:.2e} "
                f"(allowed there {self.allowed_at_max:.2e}{source}; worst difference/allowed {self.worst_ratio:.2g})")
        return line if self.verdict in (AGREE, DISAGREE) else f"{line}: {self.short_reason()}"

    def short_reason(self) -> str:
        """Why a pair within tolerance is not a pass, in a clause (empty for AGREE and DISAGREE)."""
        where = f"{TESTABLE_LIMIT:g} of the system's size from t = {self.untestable_from:.6g} on"
        return {CHAOTIC: f"{self.label} (round-off amplification raises the allowed difference above {where})",
                LOOSE: f"{self.label} (the nominal tolerance grows above {where})",
                NO_REFERENCE: self.label, NOT_COMPARABLE: f"{self.label}: {self.note}"}.get(self.verdict, "")


def _twin_series(twin: RunRecord | None, theirs: RunRecord, n: int) -> np.ndarray | None:
    """The twin's divergence from ``theirs`` at the first ``n`` samples; a twin that stopped where
    ``theirs`` went on diverged without bound there (inf)."""
    if twin is None:
        return None
    series = position_error(twin, theirs)
    if series.size < n:
        series = np.concatenate([series, np.full(n - series.size, np.inf)])
    return series


def _classify(within: bool, ref_problem: str, loose: np.ndarray, twin_raised: np.ndarray) -> str:
    """The verdict kind: a disagreement first, then why an agreement tests nothing, else AGREE."""
    if not within:
        return DISAGREE
    if ref_problem:
        return NO_REFERENCE
    if loose.size:
        return CHAOTIC if twin_raised[loose[0]] else LOOSE
    return AGREE


def _untestable_note(kind: str, time: float, twin_max: float, ref_problem: str) -> str:
    if kind == NO_REFERENCE:
        return ref_problem
    why = (f"round-off amplification: a REBOUND twin from a 4-ulp perturbation diverged by {twin_max:.1e}"
           if kind == CHAOTIC else "the nominal tolerance's n^1.5 growth over this many steps")
    return (f"from t = {time:.6g} on the allowed difference exceeds {TESTABLE_LIMIT:g} of the system's size "
            f"({why}), so agreement there no longer tells the same scheme from a different one")


def pair_verdict(pair: MatchedPair, ours: RunRecord, theirs: RunRecord,
                 twin: RunRecord | None, *, ref_problem: str = "") -> PairVerdict:
    """Judge a matched pair: every shared sample must be within :func:`allowed_difference`, and
    for a pass that allowed difference must stay below :data:`TESTABLE_LIMIT` and the reference
    must be trustworthy (``ref_problem``, from :func:`reference_problem`, empty).

    Runs that stop at different samples (one diverged, the other not) disagree outright.
    """
    diff = position_error(ours, theirs)
    taken = pair_steps(theirs)
    steps = taken[: diff.size]
    twin_series = _twin_series(twin, theirs, diff.size)
    allowed = allowed_difference(steps, twin_series)
    twin_raised = allowed > nominal_tolerance(steps)  # the twin term set the allowed value there
    nominal = float(nominal_tolerance(int(taken[-1]) if taken.size else 0))
    note = ""
    if diff.size == 0:
        ratio, worst, within, note = math.nan, 0, False, "no shared samples"
    else:
        ratios = np.where(np.isfinite(diff), diff / allowed, np.inf)
        worst = int(np.argmax(ratios))
        ratio = float(ratios[worst])
        within = bool(ratio <= 1.0)
    if ours.n_samples != theirs.n_samples or ours.status != theirs.status:
        within = False
        note = (f"runs ended differently: orbitsim {ours.status} after {ours.n_samples} samples, "
                f"REBOUND {theirs.status} after {theirs.n_samples}")
    elif ours.status != "complete":
        # Both stopped at the same sample: the codes agree that this scheme cannot run this system.
        note = f"both runs stopped after {ours.n_samples} samples ({ours.status}): {ours.message}"
    k_max = int(np.nanargmax(diff)) if diff.size and np.any(np.isfinite(diff)) else 0
    twin_max = float(np.nanmax(twin_series)) if twin_series is not None and twin_series.size else math.nan
    loose = np.flatnonzero(allowed > TESTABLE_LIMIT)
    untestable_from = float(theirs.time[loose[0]]) if loose.size else math.nan
    kind = _classify(within, ref_problem, loose, twin_raised)
    if kind not in (AGREE, DISAGREE):
        note = "; ".join(filter(None, [_untestable_note(kind, untestable_from, twin_max, ref_problem), note]))
    elif twin_max > CHAOTIC_TWIN and not note:
        note = (f"round-off is amplified here: REBOUND rerun from a 4-ulp perturbation diverged by "
                f"{twin_max:.1e}, so the tolerance follows that")
    return PairVerdict(
        pair=pair, orbitsim_label=ours.label, rebound_label=theirs.label,
        max_difference=float(np.nanmax(diff)) if diff.size else math.nan,
        time_of_max=float(theirs.time[k_max]) if diff.size else math.nan,
        tolerance=float(allowed[worst]) if diff.size else nominal,
        allowed_at_max=float(allowed[k_max]) if diff.size else nominal,
        twin_limited=bool(twin_raised[k_max]) if diff.size else False,
        max_allowed=float(np.max(allowed)) if diff.size else nominal, nominal_tolerance=nominal,
        twin_max=twin_max, worst_ratio=ratio, within_tolerance=within, untestable_from=untestable_from,
        verdict=kind, note=note,
    )


def not_comparable_verdict(pair: MatchedPair, why: str) -> PairVerdict:
    """The verdict of a pair whose two codes cannot integrate the same problem: ``why`` (one
    clause) is its note, and every measured field is nan (the two runs are not compared)."""
    nan = math.nan
    return PairVerdict(
        pair=pair, orbitsim_label=f"orbitsim/{pair.orbitsim}", rebound_label=f"rebound/{pair.rebound.key}",
        max_difference=nan, time_of_max=nan, tolerance=nan, allowed_at_max=nan, twin_limited=False, max_allowed=nan,
        nominal_tolerance=nan, twin_max=nan, worst_ratio=nan, within_tolerance=False, untestable_from=nan,
        verdict=NOT_COMPARABLE, note=why,
    )
