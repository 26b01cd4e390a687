"""``orbitsim compare`` without the CLI: run a scenario in both codes and judge the matched pairs.

Every run starts from the scenario's initial state with its G, softening and dt, and is sampled at
the scenario's sample steps (``Scenario.sample_steps()``). orbitsim runs record positions at every
sample; REBOUND's fixed-step runs are stepped whole steps to the same indices; the two IAS15s
(orbitsim's and REBOUND's, :mod:`orbitsim.analysis.compare_ias15`) land exactly on the same times,
and the one chosen with ``reference`` is the reference. For an adaptive scenario (``integrator:
ias15``) the samples are its output grid and fixed-dt schemes step by its ``dt`` to the step on
each output time. See ``docs/compare.md`` for the metrics and tolerances.

The scenario is used through these attributes only: ``name``, ``G``, ``softening``, ``dt``,
``integrator``, ``integrator_settings``, ``masses``, ``positions``, ``velocities``, ``names``,
``sample_steps()`` and, for an adaptive one, ``adaptive``, ``grid_dt`` and ``t_end``.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from orbitsim.analysis.metrics import (
    AGREE,
    DISAGREE,
    PairVerdict,
    RunMetrics,
    pair_verdict,
    reference_problem,
    run_metrics,
)
from orbitsim.analysis.record import RunRecord, record_from_result
from orbitsim.reference.bridge import ReboundScheme, parse_rebound_scheme
from orbitsim.reference.pairs import (
    IAS15_PAIR,
    TWIN_PERTURBATION,
    MatchedPair,
    available_pairs,
    partner_of,
)

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
    from orbitsim.integrators.registry import UnknownIntegratorError, get_spec

    try:
        get_spec(name)
    except UnknownIntegratorError:
        return False
    return True


def default_integrators(scenario: Any) -> list[str]:
    """The scenario's integrator, :data:`DEFAULT_MATCHED`, and ``wisdom_holman`` (if registered)
    when body 0 dominates the mass; for an adaptive scenario only its own integrator (its ``dt`` is
    a first trial step, not a step a fixed-dt scheme was chosen for)."""
    from orbitsim.integrators.registry import canonical_name

    if getattr(scenario, "adaptive", False):
        return [canonical_name(scenario.integrator)]
    names = [canonical_name(scenario.integrator), *DEFAULT_MATCHED]
    if has_dominant_central_mass(scenario.masses) and _registered("wisdom_holman"):
        names.append("wisdom_holman")
    return list(dict.fromkeys(names))


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
    from orbitsim.integrators.registry import canonical_name

    if canonical_name(scenario.integrator) == canonical_name(integrator):
        return dict(getattr(scenario, "integrator_settings", None) or {})
    return {}


def run_orbitsim(scenario: Any, integrator: str, sample_steps: np.ndarray, *, dt: float | None = None,
                 threads: int | None = None) -> RunRecord:
    """One orbitsim run at ``sample_steps``, timed after a one-step warm-up.

    The warm-up loads (or compiles) the integrator's kernels so that the recorded wall time is
    the run's own, comparable with REBOUND's, and not Numba's start-up.
    """
    from orbitsim.integrators.registry import get_spec
    from orbitsim.scenario_simulation import scenario_forces
    from orbitsim.simulation import simulate

    spec = get_spec(integrator)
    step_dt = float(scenario.dt if dt is None else dt)
    common = dict(integrator=spec.name, dt=step_dt, G=scenario.G, softening=scenario.softening,
                  threads=threads, settings=settings_for(scenario, spec.name), forces=scenario_forces(scenario))
    simulate(scenario.masses, scenario.positions, scenario.velocities, steps=1, record_positions=False,
             **common)
    result = simulate(scenario.masses, scenario.positions, scenario.velocities,
                      steps=int(sample_steps[-1]), sample_steps=sample_steps, record_positions=True,
                      **common)
    return record_from_result(result, key=spec.name, display=f"orbitsim {spec.name}", order=spec.order)


def _pairs_for(integrators: Sequence[str], schemes: Sequence[ReboundScheme],
               extra: Sequence[MatchedPair]) -> list[MatchedPair]:
    builtin = [p for p in available_pairs() if p.orbitsim in integrators and p.rebound in schemes]
    return list(dict.fromkeys([*builtin, *extra]))


def run_compare(scenario: Any, *, integrators: Sequence[str], rebound: Sequence[ReboundScheme | str],
                extra_pairs: Sequence[MatchedPair] = (), threads: int | None = None,
                progress: Progress | None = None, reference: str = "rebound") -> CompareResult:
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
        ``"rebound"`` or ``"orbitsim"``: whose IAS15 every run is measured against.

    Raises
    ------
    ValueError
        For an unknown ``reference``, or fixed-dt schemes whose steps miss an adaptive
        scenario's output times.

    Returns
    -------
    CompareResult
    """
    from orbitsim.analysis.compare_ias15 import (
        REFERENCE_CHOICES,
        fixed_step_plan,
        output_grid,
        rebound_ias15_twin,
        run_ias15_references,
    )
    from orbitsim.integrators.registry import canonical_name

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
    runs = [_announce(run_orbitsim(scenario, name, fixed, threads=threads), say) for name in names]
    runs += [_announce(_run_rebound(scenario, s, fixed, names), say) for s in schemes]
    references = {k: _announce(r, say) for k, r in run_ias15_references(scenario, threads).items()}
    chosen = references[reference]
    ref_problem = reference_problem(chosen)
    twins = {s.key: _run_rebound(scenario, s, fixed, names, twin=True)
             for s in dict.fromkeys(p.rebound for p in pairs)}
    by_label = {r.label: r for r in runs}
    verdicts = [pair_verdict(p, by_label[f"orbitsim/{p.orbitsim}"], by_label[f"rebound/{p.rebound.key}"],
                             twins.get(p.rebound.key), ref_problem=ref_problem) for p in pairs]
    if with_ias15:
        twins[IAS15_PAIR.rebound.key] = rebound_ias15_twin(scenario, TWIN_PERTURBATION)
        verdicts.insert(0, pair_verdict(IAS15_PAIR, references["orbitsim"], references["rebound"],
                                        twins[IAS15_PAIR.rebound.key], ref_problem=ref_problem))
    records = [*runs, *references.values()]
    metrics = {r.label: run_metrics(r, chosen) for r in records}
    notes = _skipped_notes(names, schemes)
    if adaptive and (names or schemes):
        notes.append(f"fixed-dt integrators step by the scenario's dt = {float(scenario.dt):g} (ias15's first trial "
                     f"step): {int(fixed[-1])} steps, sampled at the step on each output time "
                     f"(every {float(scenario.grid_dt):g}, and t_end)")
    return CompareResult(scenario, runs, chosen, twins, metrics, verdicts, notes, ref_problem, references, reference)


def _run_rebound(scenario: Any, scheme: ReboundScheme, plan: np.ndarray, integrators: Sequence[str],
                 *, twin: bool = False) -> RunRecord:
    """A REBOUND run (or its twin from positions scaled by 1 + TWIN_PERTURBATION)."""
    from orbitsim.reference.sampling import run_rebound

    # WHFast gets the settings of the orbitsim scheme it is paired with, so both use the same
    # coordinates and corrector.
    settings = settings_for(scenario, "wisdom_holman") if scheme.name == "whfast" and _registered(
        "wisdom_holman") else {}
    positions = np.asarray(scenario.positions, dtype=np.float64)
    if twin:
        positions = positions * (1.0 + TWIN_PERTURBATION)
    record = run_rebound(scenario.masses, positions, scenario.velocities, G=scenario.G,
                         softening=scenario.softening, dt=scenario.dt, scheme=scheme, sample_steps=plan,
                         settings=settings)
    if twin:
        record.engine = "rebound_twin"
        record.display += " twin"
    return record


def _announce(record: RunRecord, say: Progress) -> RunRecord:
    from orbitsim.analysis.metrics import max_abs_energy_error

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
