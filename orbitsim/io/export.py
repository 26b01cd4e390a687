"""One sample of a trace in other formats: a REBOUND file, or a scenario that continues the run.

* :func:`export_rebound`: one sample's state as a REBOUND snapshot (:mod:`orbitsim.io.rebound_file`),
  bits unchanged.
* :func:`export_scenario`: the stored (fully resolved) scenario with its initial state replaced by
  one sample's, for the steps left to the original end. Same integrator, settings, dt, units and
  sampling, floats written as their shortest round-trip text, so for a fixed-dt scheme the new run
  from a sample continues the original bit for bit (``wisdom_holman`` through the map's own
  coordinates, :mod:`orbitsim.scenario.integrator_state`). Its ``t_start`` is the sample's time, so its
  samples continue the original's times (``t0 + n * dt`` against the original's
  ``t_start + (K + n) * dt``: equal to round-off, a few ulp, not bit for bit).

(The per-sample series as CSV: :mod:`orbitsim.io.csv_export`.)

After a merge or a removal (``events:``) the REBOUND file and the scenario hold the bodies still in
the run at the sample, with their masses and radii then (the trace's ``bodies/final_masses`` and
``final_radii``, which hold from the last removal on; between two removals, by running the trace's
scenario again to the sample, accepted only when that lands on the sample's exact state), and say who
merged into whom (:attr:`SampleState.departed`, :func:`departure_note`).

Every file is written to a temporary name beside its target and renamed once complete, so a failure
leaves nothing half-written (:func:`orbitsim.io.durable.write_atomically`).
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from orbitsim.checkpoint.plan import read_trace_state, stored_scenario
from orbitsim.io.durable import write_atomically
from orbitsim.io.rebound_file import write_rebound_file
from orbitsim.io.schema import TraceError, py_value
from orbitsim.io.stored_scenario import read_scenario_bodies
from orbitsim.io.trace_reader import open_trace

__all__ = ["Departure", "ExportNotes", "SampleState", "departure_note", "export_rebound", "export_scenario",
           "read_sample"]


@dataclass(frozen=True)
class Departure:
    """A body that left the run before a sample: merged into ``into`` (a name), or removed (``into`` "")."""

    name: str
    into: str
    step: int
    time: float

    def describe(self) -> str:
        """``b merged into a at t = 2.211 (step 2211)`` or ``comet removed at t = ... (step ...)``."""
        what = f"merged into {self.into}" if self.into else "removed"
        return f"{self.name} {what} at t = {self.time:.10g} (step {self.step})"


@dataclass(frozen=True, eq=False)
class SampleState:
    """One sample of a trace: the state, where it lies in the run, and the run's attributes.

    ``names``, ``masses``, ``positions``, ``velocities`` are those of the bodies still in the run at
    the sample (all of the scenario's unless ``departed``); ``kept`` their scenario indices.
    ``radii`` is the radii then when bodies departed (a merged body's grew), else None (the
    scenario's own).
    """

    index: int
    step: int
    time: float
    names: tuple[str, ...]
    masses: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray
    attrs: dict[str, Any]
    kept: np.ndarray | None = None
    radii: np.ndarray | None = None
    departed: tuple[Departure, ...] = ()


@dataclass(frozen=True)
class ExportNotes:
    """What an export has to say: ``note``, a caveat (stderr), and ``departed``, which bodies the
    export leaves out because they merged or were removed before the sample (stdout); '' when none."""

    note: str = ""
    departed: str = ""


def read_sample(path: str | os.PathLike[str], sample: int = -1) -> SampleState:
    """Sample ``sample`` (Python indexing: -1 is the last) of a trace that recorded positions.

    The bodies that had merged or been removed by the sample (their state there is NaN; the trace's
    ``bodies/removed_step`` says when they left) are left out and listed in ``departed``.

    Raises
    ------
    TraceError
        Naming the trace: no positions recorded, no samples, an index out of range, a body whose
        state is NaN without having left the run (it diverged), or a sample between two removals
        whose masses a rerun of the trace's scenario does not give.
    """
    name = os.fspath(path)
    with open_trace(name) as f:
        count = int(f["time"].shape[0])
        if "positions" not in f:
            raise TraceError(f"{name}: the run did not record positions (output.positions: false), so it holds no "
                             "state to export; rerun with --positions")
        if count == 0:
            raise TraceError(f"{name}: the trace holds no samples")
        if not -count <= sample < count:
            raise TraceError(f"{name}: sample {sample} is out of range: the trace holds {count} samples "
                             f"(0 to {count - 1}, or -1 for the last)")
        k = sample % count
        x, v = f["positions"][k], f["velocities"][k]
        state = SampleState(index=k, step=int(f["step"][k]), time=float(f["time"][k]),
                            names=tuple(f["bodies/names"].asstr()[()]), masses=f["bodies/masses"][()],
                            positions=x, velocities=v, attrs={a: py_value(b) for a, b in f.attrs.items()})
        finite = np.all(np.isfinite(x), axis=1) & np.all(np.isfinite(v), axis=1)
        if np.all(finite):
            return state
        fates = {key: f[f"bodies/{key}"][()] for key in _FATES if f"bodies/{key}" in f}
    return _survivors(name, state, finite, fates)


#: The bodies' fates a run with ``events:`` stores (docs/trace.md); ``final_radii`` only with radii.
_FATES = ("removed_step", "removed_time", "merged_into", "final_masses", "final_radii")


def _survivors(name: str, state: SampleState, finite: np.ndarray, fates: dict[str, np.ndarray]) -> SampleState:
    """``state`` restricted to the bodies still in the run (``finite``), with their masses and radii then."""
    removed = np.asarray(fates.get("removed_step", np.full(len(finite), -1)), dtype=np.int64)
    diverged = [n for n, ok, step in zip(state.names, finite, removed, strict=True)
                if not ok and not 0 <= step <= state.step]
    if diverged or "final_masses" not in fates:
        lost = diverged[0] if diverged else state.names[int(np.flatnonzero(~finite)[0])]
        raise TraceError(f"{name}: sample {state.index} has no finite state for {lost!r} (the run diverged by then); "
                         "export an earlier sample")
    into = np.asarray(fates["merged_into"], dtype=np.int64)
    times = np.asarray(fates["removed_time"], dtype=np.float64)
    gone = sorted(np.flatnonzero(~finite), key=lambda i: (int(removed[i]), int(i)))
    departed = tuple(Departure(state.names[i], state.names[into[i]] if 0 <= into[i] < len(state.names) else "",
                               int(removed[i]), float(times[i])) for i in gone)
    kept = np.flatnonzero(finite)
    masses, radii = np.asarray(fates["final_masses"])[kept], fates.get("final_radii")
    radii = None if radii is None else np.asarray(radii)[kept]
    if np.any(removed > state.step):  # between removals: the trace stores the masses at the start and end only
        masses, radii = _masses_by_replay(name, state, kept, removed)
    return replace(state, names=tuple(state.names[i] for i in kept), masses=masses,
                   positions=state.positions[kept], velocities=state.velocities[kept], kept=kept,
                   radii=radii, departed=departed)


def _masses_by_replay(name: str, state: SampleState, kept: np.ndarray,
                      removed: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
    """The masses and radii of the bodies ``kept`` at a sample between two removals, by running the
    trace's scenario again to the sample's step (same input, same bits, the same merges); used only
    when that rerun lands on the sample's exact state, so the masses are the run's own."""
    from orbitsim.scenario_simulation import scenario_simulation  # noqa: PLC0415 -- lazy: loads yaml

    later = int(removed[removed > state.step].min())
    first = int(removed[(removed >= 0) & (removed <= state.step)].min())
    refusal = (f"{name}: sample {state.index} (step {state.step}) lies between removals (steps {first} and {later}): "
               "the trace holds the masses only at the start and after the last removal, and {why}; export a sample "
               f"from step {int(removed.max())} on, or before step {first}")
    if state.attrs.get("integrator_history"):
        raise TraceError(refusal.format(why="the run changed scheme or dt (run --from), so no rerun gives them"))
    scenario = stored_scenario_of(state, name)
    sim = scenario_simulation(scenario)
    for _ in sim.chunks(np.array([state.step], dtype=np.int64), record_positions=False):
        pass
    watcher = sim.watcher
    same = (watcher is not None and sim.steps_done == state.step and np.array_equal(watcher.alive, kept)
            and np.array_equal(sim.pos.T, state.positions[kept]) and np.array_equal(sim.vel.T, state.velocities[kept]))
    if not same:
        raise TraceError(refusal.format(why=f"a rerun of its scenario to step {state.step} does not reproduce the "
                                            "sample's state"))
    return watcher.final_masses[kept].copy(), None if scenario.radii is None else watcher.radii.copy()


def departure_note(state: SampleState, where: str) -> str:
    """One line on the bodies an export leaves out (merged or removed before the sample); '' when none."""
    if not state.departed:
        return ""
    n = len(state.names) + len(state.departed)
    left = "; ".join(d.describe() for d in state.departed)
    return (f"{where}: {len(state.departed)} of {n} bodies left the run before sample {state.index} (t = "
            f"{state.time:.10g}): {left}; exported the {len(state.names)} still in it")


def stored_scenario_of(state: SampleState, where: str) -> Any:
    """The fully resolved scenario the trace stores (checked against its SHA-256; a large one's
    bodies are datasets beside its text, :mod:`orbitsim.io.stored_scenario`)."""
    text = state.attrs.get("scenario")
    if not isinstance(text, str) or not text:
        raise TraceError(f"{where}: the trace stores no scenario")
    _refuse_before_a_switch(state, where)
    with open_trace(where) as f:
        try:
            bodies = read_scenario_bodies(f)
        except (KeyError, OSError) as err:
            raise TraceError(f"{where}: damaged trace ({err})") from None
    return stored_scenario(text, str(state.attrs.get("scenario_sha256", "")), Path(where), bodies=bodies)


def _refuse_before_a_switch(state: SampleState, where: str) -> None:
    """The stored scenario is the run's scheme and dt after its last ``run --from`` switch: a sample
    taken before that was made by another (``integrator_history``), which one scenario cannot hold."""
    history = json.loads(state.attrs.get("integrator_history") or "[]")
    later = [record for record in history if state.step < record["step"]]
    if later:
        was, last = later[0]["from"], history[-1]
        raise TraceError(f"{where}: sample {state.index} (step {state.step}) was taken by {was['integrator']} at "
                         f"dt = {was['dt']:g}, before the run switched to {last['to']['integrator']} at dt = "
                         f"{last['to']['dt']:g} at step {last['step']} (run --from); export a sample from step "
                         f"{last['step']} on")


def _sample_radii(state: SampleState, scenario: Any) -> np.ndarray | None:
    """The radii at the sample: the scenario's, or after a departure those of the bodies left then."""
    if not state.departed or scenario.radii is None:
        return scenario.radii
    return state.radii if state.radii is not None else np.asarray(scenario.radii)[state.kept]


def export_rebound(trace: str | os.PathLike[str], output: str | os.PathLike[str], sample: int = -1) -> ExportNotes:
    """Write sample ``sample`` of ``trace`` as a REBOUND file (the bodies still in the run then)."""
    where = os.fspath(trace)
    state = read_sample(where, sample)
    scenario = stored_scenario_of(state, where)
    note = write_rebound_file(output, state.masses, state.positions, state.velocities, G=scenario.G,
                              t=state.time, dt=scenario.dt, softening=scenario.softening,
                              radii=_sample_radii(state, scenario), integrator=scenario.integrator,
                              settings=scenario.integrator_settings)
    return ExportNotes(note, departure_note(state, where))


def export_scenario(trace: str | os.PathLike[str], output: str | os.PathLike[str], sample: int = -1) -> ExportNotes:
    """Write the scenario that continues ``trace`` from sample ``sample`` (see the module docstring).

    It runs the steps left to the original run's end (or its end time, for an adaptive scheme);
    from the last sample, as many again as the original run. For ``wisdom_holman`` it also holds
    the map's own coordinates at the sample (:mod:`orbitsim.scenario.integrator_state`), so it
    continues bit for bit; where they cannot be had the note says it continues to round-off only.
    After a merge or removal its bodies are those left, and its ``description`` says who left.
    """
    where = os.fspath(trace)
    state = read_sample(where, sample)
    scenario = stored_scenario_of(state, where)
    left = "".join(f"; before it {d.describe()}" for d in state.departed)
    changes: dict[str, Any] = {"positions": state.positions, "velocities": state.velocities,
                               "masses": state.masses, "source": where,
                               "description": f"continues {Path(where).name} from sample {state.index} (step "
                                              f"{state.step}, t = {state.time!r}){left}; "
                                              f"{scenario.description}".rstrip("; ")}
    if state.departed:
        changes.update(names=state.names, radii=_sample_radii(state, scenario))
    changes["t_start"] = state.time  # the continuation's clock goes on from the sample's
    if scenario.adaptive:  # t_end is absolute: the original's, or from its end as long again as the original
        left = float(scenario.t_end) > state.time
        changes["t_end"] = scenario.t_end if left else state.time + (scenario.t_end - scenario.t_start)
    else:
        left_steps = scenario.steps - state.step
        changes["steps"] = left_steps if left_steps > 0 else scenario.steps
    following = _continuation(scenario, changes, state, where)
    following, note = _with_integrator_state(following, scenario, where, state)
    text = following.to_yaml()
    write_atomically(output, lambda f: f.write(text))
    if scenario.chaos is not None:
        note = "; ".join(filter(None, (note, _chaos_restarts(state, where))))
    return ExportNotes(note, departure_note(state, where))


def _chaos_restarts(state: SampleState, where: str) -> str:
    """A scenario holds the bodies, not the variational state: its ``output.chaos`` starts the indicators
    again at the sample (REBOUND's MEGNO after a restart from an archive, its #839, does so silently)."""
    return (f"the run's chaos indicators (output.chaos) start again in the exported scenario: a run of it draws its "
            f"tangent vector afresh and starts MEGNO's sums from zero at t = {state.time!r}, so its MEGNO and mLCE "
            f"are not the trace's; `orbitsim run --from {where} --steps N` continues them bit for bit")


def _continuation(scenario: Any, changes: dict[str, Any], state: SampleState, where: str) -> Any:
    """``scenario`` with ``changes``; after a departure a setting that names a body gone (a force's
    source, an encounter pair, the elements' primary) is refused in one line naming it."""
    from orbitsim.scenario.errors import ScenarioError  # noqa: PLC0415 -- lazy: loads yaml

    try:
        return scenario.with_overrides(**changes)
    except ScenarioError as err:
        if not state.departed:
            raise
        gone = ", ".join(d.name for d in state.departed)
        raise TraceError(f"{where}: sample {state.index}: the run's scenario does not hold without the bodies that "
                         f"left before it ({gone}): {': '.join(p for p in (err.key, err.reason) if p)}") from None


def _with_integrator_state(scenario: Any, stored: Any, where: str, state: SampleState) -> tuple[Any, str]:
    """``scenario`` with the scheme's own coordinates at ``state``, when it keeps any: from the trace's
    checkpoint (the last sample), else by running the stored scenario again to the sample's step."""
    from orbitsim.scenario.integrator_state import STATEFUL, state_fingerprint  # noqa: PLC0415 -- lazy: loads yaml
    from orbitsim.scenario_simulation import state_by_replay, state_from_checkpoint  # noqa: PLC0415 -- lazy: loads yaml

    if scenario.integrator not in STATEFUL:
        return scenario, ""

    checkpoint = read_trace_state(Path(where)).checkpoint
    kept = None if checkpoint is None else state_from_checkpoint(scenario, checkpoint, state.step, state.positions,
                                                                 state.velocities)
    if kept is None and not state.attrs.get("integrator_history"):  # one run of the stored scenario: replay it
        kept = state_by_replay(stored, state.step, state.positions, state.velocities)
    if kept is None:
        return scenario, (f"{scenario.integrator} steps in its own coordinates, which neither the trace's checkpoint "
                          f"nor a rerun of its scenario gives for sample {state.index} (the run changed scheme or dt, "
                          "or was continued from another state): the exported scenario starts from the Cartesian "
                          "state and continues the run to round-off, not bit for bit")
    return scenario.with_overrides(integrator_state={"of": state_fingerprint(scenario), **kept}), ""
