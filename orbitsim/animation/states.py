"""The physics states a movie draws: from a scenario, stepped as the frames need them, or from a
trace's recorded samples; and the state of every frame, interpolated by the render loop's alpha.

A scenario is stepped once, by the ordinary engine (:class:`orbitsim.simulation.Simulation`),
stopping at exactly the steps the frames blend (``steps - 1`` and ``steps`` of each frame): the
movie shows the run ``orbitsim run`` would make, sample for sample. A trace's samples play the
physics states instead, so its loop step is the sample spacing, which must be even.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from orbitsim.animation.loop import FramePlan, Timing, interpolate, plan_frames
from orbitsim.io.schema import TraceError, py_value
from orbitsim.units import UNIT_SYSTEMS

__all__ = ["TRAIL_POINTS", "FrameStates", "Source", "body_index", "frame_states", "scenario_source", "trace_source"]

#: Physics states kept per frame for the trails: a smooth curve even when one frame spans a whole
#: orbit, at a cost of a few engine stops per frame.
TRAIL_POINTS = 32


@dataclass(frozen=True)
class Source:
    """What a movie animates: its names, units and physics clock."""

    label: str  # scenario name and integrator, for the title
    names: tuple[str, ...]
    masses: np.ndarray
    time_unit: str
    #: The engine's own step, shown in the overlay.
    engine_dt: float
    #: The render loop's physics step: the engine's dt, or a trace's sample spacing.
    loop_dt: float
    #: Physics states available after the initial one (the loop never asks for more).
    max_states: int
    #: Engine steps per loop step (1 for a scenario; a trace's sampling stride).
    stride: int
    scenario: Any = None
    trace: str | None = None

    @property
    def span(self) -> float:
        """Simulated time covered by the states."""
        return self.max_states * self.loop_dt


@dataclass(frozen=True)
class FrameStates:
    """Every frame's drawn state and overlay numbers (arrays of length F)."""

    plan: FramePlan
    positions: np.ndarray  # (F, N, 3), interpolated between the last two physics states
    time: np.ndarray  # simulated time of the drawn state
    engine_steps: np.ndarray  # physics (engine) steps taken so far
    energy_error: np.ndarray  # |dE/E| of the latest physics state
    #: Physics states the trails are drawn through (U, N, 3), at loop steps ``track_steps`` (U,):
    #: whole steps only, so a trail is the same path whatever the frame rate.
    track: np.ndarray
    track_steps: np.ndarray
    note: str = ""  # e.g. where a diverged run stopped

    def trail(self, k: int, frames: int) -> np.ndarray:
        """(M, N, 3): the physics states of the last ``frames`` frames up to frame k's older state,
        then frame k's drawn state, so the trail ends at the body."""
        plan = self.plan
        lo = np.searchsorted(self.track_steps, plan.previous[max(0, k - frames)])
        hi = np.searchsorted(self.track_steps, plan.previous[k], side="right")
        return np.concatenate([self.track[lo:hi], self.positions[k : k + 1]])


def scenario_source(scenario: Any) -> Source:
    """A loaded scenario as a movie's source; its loop step is its fixed dt (an adaptive scheme's:
    its output grid, on which its states land exactly)."""
    system = UNIT_SYSTEMS.get(str(scenario.units))
    return Source(f"{scenario.name}: {scenario.integrator}", tuple(scenario.names), np.asarray(scenario.masses),
                  system.time if system else "", float(scenario.dt), float(scenario.grid_dt), int(scenario.steps),
                  1, scenario=scenario)


def trace_source(path: str) -> Source:
    """A trace as a movie's source; raises TraceError (one line) when it cannot play one."""
    import h5py  # noqa: PLC0415 -- lazy: loads h5py

    from orbitsim.io.trace import open_trace_summary  # noqa: PLC0415 -- lazy: loads h5py

    summary = open_trace_summary(path)
    attrs = summary["attrs"]
    with h5py.File(path, "r") as f:
        if "positions" not in f:
            raise TraceError(f"{path}: positions were not recorded; re-run with output.positions: true, "
                             "or animate the scenario instead")
        step, time = f["step"][()], f["time"][()]
        names = tuple(f["bodies/names"].asstr()[()])
        masses = f["bodies/masses"][()]
    if step.size < 2:
        raise TraceError(f"{path}: {step.size} sample(s); a movie needs at least two")
    gaps = np.diff(step)
    # The last sample is the run's final state, which may come sooner than the sampling stride.
    even = gaps[:-1] if gaps.size > 1 and gaps[-1] < gaps[0] else gaps
    if np.any(even != even[0]) or even[0] <= 0:
        raise TraceError(f"{path}: samples are not evenly spaced in steps ({int(gaps.min())} to {int(gaps.max())} "
                         "apart), so they are not a fixed-step run; sample with output.every, or animate the scenario")
    stride = int(even[0])
    loop_dt = float(time[1] - time[0])
    system = UNIT_SYSTEMS.get(str(attrs.get("units", "")))
    label = f"{py_value(attrs.get('scenario_name')) or path}: {py_value(attrs.get('integrator')) or '?'}"
    return Source(label, names, masses, system.time if system else "", float(attrs.get("dt", loop_dt / stride)),
                  loop_dt, int(even.size), stride, trace=path)


def body_index(source: Source, body: str) -> int:
    """A body by name or 0-based index; raises ValueError listing the names."""
    if body in source.names:
        return source.names.index(body)
    if body.lstrip("-").isdigit() and -len(source.names) <= int(body) < len(source.names):
        return int(body) % len(source.names)
    shown = ", ".join(source.names[:12]) + (", ..." if len(source.names) > 12 else "")
    raise ValueError(f"--follow {body}: no such body; give a name ({shown}) or an index from 0 to "
                     f"{len(source.names) - 1}")


def frame_states(source: Source, timing: Timing, trail_points: int = TRAIL_POINTS) -> FrameStates:
    """Run the render loop over ``source`` and interpolate every frame's state; between frames,
    ``trail_points`` evenly spread physics states are kept for the trails."""
    plan = plan_frames(timing, source.loop_dt, source.max_states)
    between = [np.linspace(a, b, trail_points + 1, dtype=np.int64) for a, b in zip(plan.previous[:-1],
                                                                                  plan.previous[1:], strict=True)]
    wanted = np.unique(np.concatenate([[0], plan.previous, plan.steps, *between]))
    if source.trace is not None:
        states, energy, reached = _trace_states(source, wanted)
        note = ""
    else:
        states, energy, reached, note = _scenario_states(source.scenario, wanted)
    # A run that stopped early (diverged, halted) holds its last state for the frames after it.
    where = np.minimum(np.searchsorted(wanted, plan.steps), reached - 1)
    before = np.minimum(np.searchsorted(wanted, plan.previous), reached - 1)
    positions = interpolate(states[before], states[where], plan.alpha)
    return FrameStates(plan, positions, plan.state_time, plan.steps * source.stride, np.abs(energy[where]),
                       states[:reached], wanted[:reached], note)


def _trace_states(source: Source, wanted: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    """The samples at loop states ``wanted`` (sample indices), read row by row set."""
    import h5py  # noqa: PLC0415 -- lazy: loads h5py

    with h5py.File(source.trace, "r") as f:
        positions = f["positions"][np.asarray(wanted), :, :]
        energy = f["energy_error"][np.asarray(wanted)]
    return positions, energy, int(wanted.size)


def _scenario_states(scenario: Any, wanted: np.ndarray) -> tuple[np.ndarray, np.ndarray, int, str]:
    """Step the scenario's engine to each of the ``wanted`` steps, recording the states there."""
    from orbitsim.results import energy_scale, relative_energy_error  # noqa: PLC0415 -- lazy: loads numba
    from orbitsim.scenario_simulation import scenario_simulation  # noqa: PLC0415 -- lazy: loads yaml

    sc = scenario
    sim = scenario_simulation(sc)  # the engine `orbitsim run` steps, so the frames show the run's states
    positions = np.empty((wanted.size, sc.n_bodies, 3))
    energy = np.empty(wanted.size)
    done, scale = 0, 1.0
    for chunk in sim.chunks(wanted, record_positions=True):
        keep = np.flatnonzero(np.isin(chunk.step, wanted))  # not the extra state a halted run adds
        if done == 0 and keep.size:
            scale = energy_scale(float(chunk.kinetic[0]), float(chunk.potential[0]))
        positions[done : done + keep.size] = chunk.positions[keep]
        energy[done : done + keep.size] = chunk.conserved_energy[keep]
        done += keep.size
    note = ""
    if done < wanted.size:
        why = "diverged" if sim.diverged else "halted"
        note = f"the run {why} at step {sim.steps_done}; the last frames hold its last state"
    return positions, relative_energy_error(energy, float(energy[0]), scale), max(done, 1), note
