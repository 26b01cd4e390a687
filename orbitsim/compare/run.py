"""``orbitsim compare`` without the CLI: run a scenario in both codes and judge the matched pairs.

Every run starts from the scenario's initial state with its G, softening and dt, and is sampled at
the scenario's sample steps (``Scenario.sample_steps()``). orbitsim runs record positions at every
sample; REBOUND's fixed-step runs are stepped whole steps to the same indices; the two IAS15s
(orbitsim's and REBOUND's, :mod:`orbitsim.compare.ias15`) land exactly on the same times,
and the one chosen with ``reference`` is the reference. For an adaptive scenario (``integrator:
ias15``) the samples are its output grid and fixed-dt schemes step by its ``dt`` to the step on
each output time. See ``docs/compare.md`` for the metrics and tolerances.

Both codes integrate the scenario's ``forces:``: REBOUND through REBOUNDx, arranged as orbitsim
applies each force (:mod:`orbitsim.reference.force_pairing`). A pair one of whose codes cannot
apply a force as the other does is not run against the other: its verdict is "not comparable",
with the reason (:func:`~orbitsim.compare.metrics.not_comparable_verdict`).

The scenario is used through these attributes only: ``name``, ``G``, ``softening``, ``dt``,
``integrator``, ``integrator_settings``, ``masses``, ``positions``, ``velocities``, ``names``,
``forces``, ``sample_steps()`` and, for an adaptive one, ``adaptive``, ``grid_dt`` and ``t_end``.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from orbitsim.compare.ias15 import (
    REFERENCE_CHOICES,
    fixed_step_plan,
    output_grid,
    rebound_ias15_refusal,
    rebound_ias15_twin,
    run_ias15_references,
)
from orbitsim.compare.metrics import (
    AGREE,
    DISAGREE,
    PairVerdict,
    RunMetrics,
    max_abs_energy_error,
    not_comparable_verdict,
    pair_verdict,
    reference_problem,
    run_metrics,
)
from orbitsim.record import RunRecord, record_from_result
from orbitsim.reference.bridge import ReboundScheme, parse_rebound_scheme
from orbitsim.reference.force_pairing import orbitsim_force_lines, orbitsim_refusal, rebound_refusal
from orbitsim.reference.pairs import (
    IAS15_PAIR,
    TWIN_PERTURBATION,
    MatchedPair,
    available_pairs,
    partner_of,
)
from orbitsim.reference.sampling import run_rebound

#: WHFast joins the default REBOUND set when the other bodies weigh at most this fraction of
#: body 0: its splitting error scales with that mass ratio, and below ~1e-2 it is the scheme a
#: REBOUND user would pick for such a system.
DOMINANT_MASS_RATIO = 1e-2

#: orbitsim integrators added to a comparison by default, besides the scenario's own: one
#: second- and one fourth-order member of the family REBOUND shares.
DEFAULT_MATCHED = ("leapfrog", "leapfrog4")

Progress = Callable[[str], None]


def has_dominant_central_mass(masses: np.ndarray) -> bool:
    """True when body 0 outweighs all others together by 1 / DOMINANT_MASS_RATIO or more."""
    m = np.asarray(masses, dtype=np.float64)
    return m.size > 1 and m[0] > 0.0 and float(m[1:].sum()) <= DOMINANT_MASS_RATIO * float(m[0])


def _registered(name: str) -> bool:
    from orbitsim.integrators.registry import UnknownIntegratorError, get_spec  # noqa: PLC0415 -- lazy: loads numba

    try:
        get_spec(name)
    except UnknownIntegratorError:
        return False
    return True


def default_candidates(scenario: Any) -> list[str]:
    """The scenario's integrator, :data:`DEFAULT_MATCHED`, and ``wisdom_holman`` (if registered)
    when body 0 dominates the mass; for an adaptive scenario only its own integrator (its ``dt`` is
    a first trial step, not a step a fixed-dt scheme was chosen for)."""
    from orbitsim.integrators.registry import canonical_name  # noqa: PLC0415 -- lazy: loads numba

    if getattr(scenario, "adaptive", False):
        return [canonical_name(scenario.integrator)]
    names = [canonical_name(scenario.integrator), *DEFAULT_MATCHED]
    if has_dominant_central_mass(scenario.masses) and _registered("wisdom_holman"):
        names.append("wisdom_holman")
    return list(dict.fromkeys(names))


def default_integrators(scenario: Any) -> list[str]:
    """:func:`default_candidates` less those that cannot apply the scenario's forces
    (:func:`defaults_left_out`)."""
    names = default_candidates(scenario)
    left_out = {name for name, _ in defaults_left_out(scenario, names)}
    return [n for n in names if n not in left_out]


def defaults_left_out(scenario: Any, names: Sequence[str]) -> list[tuple[str, str]]:
    """``(name, why)`` for each of ``names`` (other than the scenario's own integrator) that cannot
    apply the scenario's forces."""
    from orbitsim.integrators.registry import canonical_name  # noqa: PLC0415 -- lazy: loads numba
    from orbitsim.scenario_simulation import scenario_forces  # noqa: PLC0415 -- lazy: loads yaml

    forces = scenario_forces(scenario)
    own = canonical_name(scenario.integrator)
    out = []
    for name in dict.fromkeys(names):
        why = orbitsim_refusal(forces, name, settings_for(scenario, name)) if name != own else None
        if why:
            out.append((name, why))
    return out


def default_rebound(integrators: Sequence[str], masses: np.ndarray, *, whfast: bool = True) -> list[ReboundScheme]:
    """The REBOUND partners of ``integrators``, plus WHFast (unless ``whfast`` is false, as for an
    adaptive scenario) when body 0 dominates the mass."""
    schemes = [s for s in (partner_of(name) for name in integrators) if s is not None]
    if whfast and has_dominant_central_mass(masses):
        schemes.append(ReboundScheme("whfast"))
    return list(dict.fromkeys(schemes))


@dataclass
class CompareResult:
    """Everything a comparison produced; reports and the exit code are derived from it."""

    scenario: Any
    runs: list[RunRecord]
    reference: RunRecord
    twins: dict[str, RunRecord]
    metrics: dict[str, RunMetrics]
    verdicts: list[PairVerdict]
    notes: list[str] = field(default_factory=list)
    #: Why the IAS15 reference cannot be trusted (see ``metrics.reference_problem``), or "".
    reference_problem: str = ""
    #: Both IAS15s, ``{"rebound": ..., "orbitsim": ...}``; ``reference`` is one of them.
    references: dict[str, RunRecord] = field(default_factory=dict)
    #: Which of them is the reference (``--reference``).
    reference_choice: str = "rebound"

    @property
    def passed(self) -> bool:
        """True when every matched pair agrees, testably, against a trustworthy reference."""
        return self.verdict == "pass"

    @property
    def failed_pairs(self) -> list[str]:
        """Names of the pairs that disagree."""
        return [v.name for v in self.verdicts if v.verdict == DISAGREE]

    @property
    def untestable_pairs(self) -> list[str]:
        """Names of the pairs within tolerance whose agreement tests nothing (chaos, bad reference)."""
        return [v.name for v in self.verdicts if v.verdict not in (AGREE, DISAGREE)]

    def untestable_reasons(self) -> list[str]:
        """Why the comparison is not a pass although no pair disagrees, one clause per cause."""
        if self.reference_problem:  # it makes every pair untestable: say it once
            return [f"reference unreliable: {self.reference_problem}"]
        return [f"{v.name}: {v.short_reason()}" for v in self.verdicts if v.name in self.untestable_pairs]

    @property
    def verdict(self) -> str:
        """``fail`` if a pair disagrees, else ``not_testable`` if a pair (or the reference) cannot be
        judged, else ``pass``."""
        if self.failed_pairs:
            return "fail"
        return "not_testable" if self.untestable_pairs or self.reference_problem else "pass"

    def record(self, label: str) -> RunRecord:
        """The run with ``label`` (``engine/key``)."""
        for rec in [*self.runs, self.reference, *self.references.values()]:
            if rec.label == label:
                return rec
        raise KeyError(label)


def settings_for(scenario: Any, integrator: str) -> dict[str, Any]:
    """The scenario's integrator settings if ``integrator`` is its integrator, else none."""
    from orbitsim.integrators.registry import canonical_name  # noqa: PLC0415 -- lazy: loads numba

    if canonical_name(scenario.integrator) == canonical_name(integrator):
        return dict(getattr(scenario, "integrator_settings", None) or {})
    return {}


def run_orbitsim(scenario: Any, integrator: str, sample_steps: np.ndarray, *, dt: float | None = None,
                 threads: int | None = None) -> RunRecord:
    """One orbitsim run at ``sample_steps``, timed after a one-step warm-up.

    The warm-up loads (or compiles) the integrator's kernels so that the recorded wall time is
    the run's own, comparable with REBOUND's, and not Numba's start-up.
    """
    from orbitsim.integrators.registry import get_spec  # noqa: PLC0415 -- lazy: loads numba
    from orbitsim.scenario_simulation import scenario_forces  # noqa: PLC0415 -- lazy: loads yaml
    from orbitsim.simulation import simulate  # noqa: PLC0415 -- lazy: loads numba

    spec = get_spec(integrator)
    step_dt = float(scenario.dt if dt is None else dt)
    forces = scenario_forces(scenario)
    common = dict(integrator=spec.name, dt=step_dt, G=scenario.G, softening=scenario.softening,
                  threads=threads, settings=settings_for(scenario, spec.name), forces=forces)
    simulate(scenario.masses, scenario.positions, scenario.velocities, steps=1, record_positions=False,
             **common)
    result = simulate(scenario.masses, scenario.positions, scenario.velocities,
                      steps=int(sample_steps[-1]), sample_steps=sample_steps, record_positions=True,
                      **common)
    record = record_from_result(result, key=spec.name, display=f"orbitsim {spec.name}", order=spec.order)
    record.forces = orbitsim_force_lines(forces, spec.name)
    return record


def _pairs_for(integrators: Sequence[str], schemes: Sequence[ReboundScheme],
               extra: Sequence[MatchedPair]) -> list[MatchedPair]:
    builtin = [p for p in available_pairs() if p.orbitsim in integrators and p.rebound in schemes]
    return list(dict.fromkeys([*builtin, *extra]))


def run_compare(scenario: Any, *, integrators: Sequence[str], rebound: Sequence[ReboundScheme | str],
                extra_pairs: Sequence[MatchedPair] = (), threads: int | None = None,
                progress: Progress | None = None, reference: str = "rebound",
                notes: Sequence[str] = ()) -> CompareResult:
    """Run ``scenario`` under each integrator of both codes and both IAS15s.

    Parameters
    ----------
    scenario : Scenario
        A loaded scenario (dt, steps and sampling already final).
    integrators : sequence of str
        orbitsim integrator names or aliases; ``ias15`` adds the pair of the two IAS15s.
    rebound : sequence of ReboundScheme or str
        REBOUND schemes (``ias15`` is always the reference and is not run twice).
    extra_pairs : sequence of MatchedPair
        User-specified pairs (``--pair``); their two sides are added to the runs.
    threads : int, optional
        Numba threads for orbitsim.
    progress : callable, optional
        Receives one line per finished run.
    reference : str
        ``"rebound"`` or ``"orbitsim"``: whose IAS15 every run is measured against (orbitsim's
        when REBOUND cannot carry the scenario's forces; a note says so).
    notes : sequence of str
        The caller's notes for the report (e.g. default integrators left out).

    Raises
    ------
    ValueError
        For an unknown ``reference``, or fixed-dt schemes whose steps miss an adaptive
        scenario's output times.

    Returns
    -------
    CompareResult
    """
    from orbitsim.integrators.registry import canonical_name  # noqa: PLC0415 -- lazy: loads numba
    from orbitsim.scenario_simulation import scenario_forces  # noqa: PLC0415 -- lazy: loads yaml

    if reference not in REFERENCE_CHOICES:
        raise ValueError(f"reference must be one of {', '.join(REFERENCE_CHOICES)}, got {reference!r}")
    say = progress or (lambda _msg: None)
    _, _, _, plan, times = output_grid(scenario)
    names = list(dict.fromkeys([canonical_name(n) for n in integrators] + [p.orbitsim for p in extra_pairs]))
    with_ias15 = "ias15" in names
    names = [n for n in names if n != "ias15"]  # the two IAS15s always run, as the references
    schemes = [parse_rebound_scheme(s) if isinstance(s, str) else s for s in rebound]
    schemes = list(dict.fromkeys([s for s in schemes if s.fixed_step] + [p.rebound for p in extra_pairs]))
    adaptive = bool(getattr(scenario, "adaptive", False))
    fixed = fixed_step_plan(scenario, times) if adaptive and (names or schemes) else plan
    pairs = _pairs_for(names, schemes, extra_pairs)
    # What each side cannot apply of the scenario's forces: such runs are not made, and their pairs
    # are "not comparable" rather than judged.
    forces = scenario_forces(scenario)
    cannot = {f"orbitsim/{n}": orbitsim_refusal(forces, n, settings_for(scenario, n)) for n in names}
    cannot.update({f"rebound/{s.key}": rebound_refusal(forces, s, _whfast_settings(scenario, s)) for s in schemes})
    runs = [_announce(run_orbitsim(scenario, name, fixed, threads=threads), say) for name in names
            if not cannot[f"orbitsim/{name}"]]
    runs += [_announce(_run_rebound(scenario, s, fixed, names), say) for s in schemes
             if not cannot[f"rebound/{s.key}"]]
    references = {k: _announce(r, say) for k, r in run_ias15_references(scenario, threads).items()}
    ias15_why = rebound_ias15_refusal(scenario)
    notes = list(notes)
    if ias15_why:
        notes.append(f"REBOUND's IAS15 was not run: {ias15_why}" + (
            "; orbitsim's ias15 is the reference instead" if reference == "rebound" else ""))
        reference = "orbitsim"
    chosen = references[reference]
    ref_problem = reference_problem(chosen)

    def why_not(pair: MatchedPair) -> str | None:
        return cannot[f"orbitsim/{pair.orbitsim}"] or cannot[f"rebound/{pair.rebound.key}"]

    twins = {s.key: _run_rebound(scenario, s, fixed, names, twin=True)
             for s in dict.fromkeys(p.rebound for p in pairs if not why_not(p))}
    by_label = {r.label: r for r in runs}
    verdicts = [not_comparable_verdict(p, why) if (why := why_not(p)) else
                pair_verdict(p, by_label[f"orbitsim/{p.orbitsim}"], by_label[f"rebound/{p.rebound.key}"],
                             twins.get(p.rebound.key), ref_problem=ref_problem) for p in pairs]
    if with_ias15 and ias15_why:
        verdicts.insert(0, not_comparable_verdict(IAS15_PAIR, ias15_why))
    elif with_ias15:
        twins[IAS15_PAIR.rebound.key] = rebound_ias15_twin(scenario, TWIN_PERTURBATION)
        verdicts.insert(0, pair_verdict(IAS15_PAIR, references["orbitsim"], references["rebound"],
                                        twins[IAS15_PAIR.rebound.key], ref_problem=ref_problem))
    records = [*runs, *references.values()]
    metrics = {r.label: run_metrics(r, chosen) for r in records}
    notes += _skipped_notes(names, schemes)
    paired = {f"orbitsim/{p.orbitsim}" for p in pairs} | {f"rebound/{p.rebound.key}" for p in pairs}
    shown = {**{f"orbitsim/{n}": f"orbitsim {n}" for n in names}, **{f"rebound/{s.key}": s.display for s in schemes}}
    notes += [f"{shown[label]} was not run: {why}" for label, why in cannot.items() if why and label not in paired]
    if adaptive and (names or schemes):
        notes.append(f"fixed-dt integrators step by the scenario's dt = {float(scenario.dt):g} (ias15's first trial "
                     f"step): {int(fixed[-1])} steps, sampled at the step on each output time "
                     f"(every {float(scenario.grid_dt):g}, and t_end)")
    return CompareResult(scenario, runs, chosen, twins, metrics, verdicts, notes, ref_problem, references, reference)


def _whfast_settings(scenario: Any, scheme: ReboundScheme) -> dict[str, Any]:
    """WHFast gets the settings of the orbitsim scheme it is paired with, so both use the same
    coordinates and corrector; other schemes get none."""
    if scheme.name == "whfast" and _registered("wisdom_holman"):
        return settings_for(scenario, "wisdom_holman")
    return {}


def _run_rebound(scenario: Any, scheme: ReboundScheme, plan: np.ndarray, integrators: Sequence[str],
                 *, twin: bool = False) -> RunRecord:
    """A REBOUND run (or its twin from positions scaled by 1 + TWIN_PERTURBATION), with the
    scenario's forces through REBOUNDx."""
    from orbitsim.scenario_simulation import scenario_forces  # noqa: PLC0415 -- lazy: loads yaml

    positions = np.asarray(scenario.positions, dtype=np.float64)
    if twin:
        positions = positions * (1.0 + TWIN_PERTURBATION)
    record = run_rebound(scenario.masses, positions, scenario.velocities, G=scenario.G,
                         softening=scenario.softening, dt=scenario.dt, scheme=scheme, sample_steps=plan,
                         settings=_whfast_settings(scenario, scheme), forces=scenario_forces(scenario))
    if twin:
        record.engine = "rebound_twin"
        record.display += " twin"
    return record


def _announce(record: RunRecord, say: Progress) -> RunRecord:
    status = "" if record.status == "complete" else f" [{record.status}: {record.message}]"
    say(f"  {record.display:<40} {record.steps_done:>9} steps  {record.wall_time_s:8.3f} s  "
        f"max |dE/E| {max_abs_energy_error(record):.2e}{status}")
    return record


def _skipped_notes(names: Sequence[str], schemes: Sequence[ReboundScheme]) -> list[str]:
    """Why a pair the user might expect was not judged (e.g. wisdom_holman not registered yet)."""
    notes = []
    if any(s.name == "whfast" for s in schemes) and not _registered("wisdom_holman"):
        notes.append("pair wisdom_holman <-> REBOUND whfast skipped: orbitsim has no wisdom_holman "
                     "integrator in this build")
    return notes
