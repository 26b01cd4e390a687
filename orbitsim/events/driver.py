"""What a :class:`~orbitsim.simulation.Simulation` with events does between its jitted calls.

:class:`Watcher` owns the watch arrays and everything the events change: which of the scenario's
bodies are still in the run (``alive``), their radii and merged masses, the energy carried off
(``energy_offset``), the log, and each body's fate. After every call it drains the logged events
and, when the call stopped for it, resolves them:

* **merge** (``collisions.resolve: merge``): the pair becomes one body at the lower index, with
  the summed mass (bit-exact: one addition), the mass-weighted position and velocity (so the
  momentum is conserved to round-off) and the volume-conserving radius (r_i^3 + r_j^3)^(1/3);
* **remove** (``escape.action: remove``): the body leaves the run;
* **halt**: the run ends there (:attr:`Watcher.halted`).

Bodies that already overlap in the state a run starts from are a collision at that step
(:meth:`Watcher.contacts_at_start`), resolved by the same rule: the watch itself only checks the
end of each step, and a body placed inside its star was never seen to touch it.

The energy a merge or a removal takes out is the total energy just before minus just after
(kinetic and every pair's potential, so the pairs with third bodies count too; REBOUND's
``track_energy_offset`` counts the merging pair only); it is added to ``energy_offset``, so
E + offset stays what the integrator keeps it (``energy_error`` is computed from E + offset).
The system then continues with fewer bodies, as if it had started so: the kernels never see a
removed body, so they need no mask and a run without events is unchanged. Samples keep the
scenario's N: a removed body's position and velocity are NaN from its removal on.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any, Protocol

import numpy as np

from orbitsim.events import layout as wl
from orbitsim.events.config import EventsConfig
from orbitsim.events.kernels import after_step
from orbitsim.events.log import Event, RunEvents, log_arrays, log_from_arrays
from orbitsim.events.overlap import overlapping_pairs
from orbitsim.events.watch import build_watch, drain, open_encounters, shrink_watch, watch_arrays, watch_from_arrays
from orbitsim.integrators.base import IntegratorSpec
from orbitsim.integrators.trace.collide import H_DIST, H_ENERGY, H_KEEP, H_LOSE, H_REACH, H_SPEED, H_TIME
from orbitsim.results import SampleChunk

__all__ = ["WatchedRun", "Watcher"]


class WatchedRun(Protocol):
    """What a :class:`Watcher` reads and changes of the simulation it watches.

    :class:`orbitsim.simulation.Simulation` is one. It is declared here, by what is used, so that the
    driver does not import the simulation that creates it: the state (N,) ``m`` and (3, N) ``pos``,
    ``vel``, ``acc``; the contexts handed to the scheme's ``run_watched``; the step count and clock.
    """

    n: int
    m: np.ndarray
    pos: np.ndarray
    vel: np.ndarray
    acc: np.ndarray
    G: float
    dt: float
    t0: float
    steps_done: int
    spec: IntegratorSpec
    settings: dict[str, Any]
    force: Any  # the context the scheme's run_watched takes (orbitsim.physics.force_context.make_force)
    work: Any  # the scheme's work arrays

    @property
    def module(self) -> Any:
        """The integrator's module (``run_watched``, and ``take_merges``/``handoff`` where it has them)."""

    @property
    def time(self) -> float:
        """Time of the current state."""

    def total_energy(self) -> float:
        """Total energy of the current state."""

    def replace_bodies(self, m: np.ndarray, pos: np.ndarray, vel: np.ndarray) -> None:
        """Go on with these bodies: (N,) masses, (3, N) positions and velocities."""


class Watcher:
    """The events of one simulation: the watch, the bodies left, the offset, the log, the fates."""

    def __init__(self, sim: WatchedRun, config: EventsConfig, radii: Any) -> None:
        n = sim.n
        self.config = config
        self.n0 = n
        self.alive = np.arange(n, dtype=np.int64)
        self.radii = np.zeros(n) if radii is None else np.array(radii, dtype=np.float64).reshape(-1)
        if self.radii.shape != (n,) or not np.all(np.isfinite(self.radii)) or np.any(self.radii < 0.0):
            raise ValueError(f"radii must be {n} finite numbers >= 0")
        self.offset = 0.0
        self.log: list[Event] = []
        self.removed_step = np.full(n, -1, dtype=np.int64)
        self.removed_time = np.full(n, np.nan)
        self.merged_into = np.full(n, -1, dtype=np.int64)
        self.final_masses = sim.m.copy()
        self.initial_radii = self.radii.copy()
        self.final_radii = self.radii.copy()
        self.halted: Event | None = None
        # the scheme and its settings (defaults filled in), which word an unresolved step's fix
        self.scheme = sim.spec.name
        self.settings = {**sim.scheme.default_settings(), **sim.settings}
        self.watch = build_watch(config, sim.m, self.radii, sim.G)
        self._handoff: tuple[np.ndarray, np.ndarray, int] | None = None  # of a step whose merges are taken out
        self._kept = np.arange(n)

    # -- the state a run starts from ---------------------------------------------------------

    def contacts_at_start(self, sim: WatchedRun) -> None:
        """Log the pairs that overlap in ``sim``'s state as collisions at its step, and resolve
        them by the scenario's rule: ``merge`` joins them before the first step, ``halt`` ends the
        run there (:meth:`Simulation.chunks` then takes no step), ``log`` records each once and
        leaves it open, so the first step's check continues the contact rather than logging it
        again. A merge here leaves ``energy_offset`` at 0: the run's E0 is the merged system's.
        Only for a new run: a continuation's state was checked when its run reached it.

        Uses the watch's ``direct`` test on the same numbers (:func:`~.overlap.overlapping_pairs`),
        whatever ``detect`` says: at the start there is no step whose segment could be drawn.
        """
        collisions = self.config.collisions
        if collisions is None:
            return

        pairs = overlapping_pairs(sim.pos.T, self.radii)
        if not pairs:
            return
        step, time = sim.steps_done, sim.time
        events = []
        for i, j, distance, reach in pairs:
            dvx, dvy, dvz = (float(sim.vel[c, i] - sim.vel[c, j]) for c in range(3))
            speed = math.sqrt(dvx * dvx + dvy * dvy + dvz * dvz)
            events.append(Event("collision", step, step, time, int(self.alive[i]), int(self.alive[j]), distance, speed,
                                reach))
        if collisions.resolve == "merge":
            events = self._resolve(sim, events)
            # The run starts from the merged bodies: E0 is their energy, as for any first sample,
            # and the merge's energy (the contact's binding, however deep) is no error of the run's.
            self.offset = 0.0
        elif collisions.resolve == "halt":
            self._halt(events, step)
        else:
            self._open_contacts(pairs, step)
        self.log.extend(events)

    def _open_contacts(self, pairs: list[tuple[int, int, float, float]], step: int) -> None:
        """Open a contact episode for each pair, as the jitted ``_contact`` does for a logged one."""
        pair_i, pair_f, counts = self.watch.pair_i, self.watch.pair_f, self.watch.counts
        for i, j, _, _ in pairs:
            p = int(counts[wl.N_PAIRS])
            if p >= pair_i.shape[0]:  # the table is sized for 4 episodes a body: only then
                counts[wl.N_LOST] += 1
                continue
            pair_i[p, [wl.P_I, wl.P_J, wl.P_START, wl.P_LAST, wl.P_KIND]] = (i, j, step, step, wl.PAIR_CONTACT)
            pair_f[p, [wl.PF_DMIN, wl.PF_TMIN, wl.PF_VMIN, wl.PF_LIMIT]] = (np.inf, np.nan, np.nan, np.nan)
            counts[wl.N_PAIRS] = p + 1

    # -- around each jitted call -------------------------------------------------------------

    def call(self, sim: WatchedRun, targets: np.ndarray, record: np.ndarray, out: tuple[np.ndarray, ...],
             ) -> tuple[int, int, bool, bool]:
        """One jitted call of the scheme's ``run_watched``; ``(written, n_done, finite, acted)``."""
        state = (sim.pos, sim.vel, sim.acc, sim.m)
        written, n_done, finite, acted = sim.scheme.run_watched(
            state, sim.force, sim.dt, sim.work, sim.t0, sim.steps_done, targets, record, out, self.watch)
        return int(written), int(n_done), bool(finite), bool(acted)

    def expand(self, chunk: SampleChunk) -> SampleChunk:
        """The chunk with the scenario's N bodies (NaN for those no longer in the run) and the
        energy offset of its samples."""
        offset = np.full(len(chunk), self.offset)
        extra = dict(chunk.extra or {})
        extra["energy_offset"] = offset
        if chunk.positions is None or len(self.alive) == self.n0:
            return _with(chunk, extra=extra)
        shape = (len(chunk), self.n0, 3)
        pos, vel = np.full(shape, np.nan), np.full(shape, np.nan)
        pos[:, self.alive] = chunk.positions
        vel[:, self.alive] = chunk.velocities
        return _with(chunk, positions=pos, velocities=vel, extra=extra)

    def scenario_masses(self) -> np.ndarray:
        """(N_scenario,) masses now: merged masses, NaN for bodies out of the run."""
        masses = np.full(self.n0, np.nan)
        masses[self.alive] = self.final_masses[self.alive]
        return masses

    def to_scenario_bodies(self, rows: np.ndarray) -> np.ndarray:
        """(N_now, ...) rows of the bodies still in the run as (N_scenario, ...), NaN for the others."""
        out = np.full((self.n0, *rows.shape[1:]), np.nan)
        out[self.alive] = rows
        return out

    def after_call(self, sim: WatchedRun, acted: bool) -> None:
        """Drain the call's events and, when it stopped for them, resolve them."""
        events, self.watch = drain(self.watch, self.alive)
        stop = int(self.watch.counts[wl.STOP]) if acted else wl.STOP_NONE
        self.watch.counts[wl.STOP] = wl.STOP_NONE
        if stop == wl.STOP_RESOLVE:
            merged = self._take_in_step_merges(sim)
            if merged:
                # The step's own checks were left for now: they run on the bodies that are left.
                self.log.extend(events)
                self.log.extend(merged)
                stop = self._check_step(sim)
                events, self.watch = drain(self.watch, self.alive)
        if stop == wl.STOP_HALT:
            self._halt(events, sim.steps_done)
        elif stop == wl.STOP_RESOLVE:
            events = self._resolve(sim, events)
        self.log.extend(events)

    def _halt(self, events: list[Event], step: int) -> None:
        for k in range(len(events) - 1, -1, -1):
            if events[k].step == step and self._halts(events[k]):
                events[k] = _replace(events[k], outcome="halted")
                self.halted = events[k]
                return

    def _halts(self, event: Event) -> bool:
        c, enc, esc = self.config.collisions, self.config.encounters, self.config.escape
        return bool((event.kind == "collision" and c is not None and c.resolve == "halt")
                    or (event.kind == "encounter" and enc is not None and enc.halt)
                    or (event.kind == "escape" and esc is not None and esc.action == "halt"))

    # -- merges and removals -----------------------------------------------------------------

    def _resolve(self, sim: WatchedRun, events: list[Event]) -> list[Event]:
        """Apply the merges and removals logged at the last step; return the events, annotated."""
        step, time = sim.steps_done, sim.time
        index = {int(orig): k for k, orig in enumerate(self.alive)}  # scenario index -> current index
        m, pos, vel = sim.m.copy(), sim.pos.copy(), sim.vel.copy()
        radii = self.radii.copy()
        gone = np.zeros(len(m), dtype=bool)
        into = np.arange(len(m))  # where each current body went (itself unless merged)
        merge = self.config.collisions is not None and self.config.collisions.resolve == "merge"
        remove = self.config.escape is not None and self.config.escape.action == "remove"
        for k, event in enumerate(events):
            if event.step != step:
                continue
            if event.kind == "collision" and merge:
                a, b = _root(into, index[event.i]), _root(into, index[event.j])
                if a == b:
                    continue
                keep, lose = min(a, b), max(a, b)
                _merge_into(keep, lose, m, pos, vel, radii)
                gone[lose], into[lose] = True, keep
                events[k] = _replace(event, outcome="merged", into=int(self.alive[keep]))
            elif event.kind == "escape" and remove and not gone[index[event.i]]:
                gone[index[event.i]] = True
                events[k] = _replace(event, outcome="removed")
        if gone.any():
            events.extend(open_encounters(self.watch, self.alive, involving=gone))
            self._take_out(sim, gone, into, m, pos, vel, radii, step, time)
        return events

    def _take_in_step_merges(self, sim: WatchedRun) -> list[Event]:
        """Take out the bodies the integrator merged inside the last step (TRACE's encounters,
        :func:`orbitsim.integrators.trace.take_merges`); return their events (none for a scheme
        that merges nothing inside its steps).

        The integrator has merged them already, each into the lower index, leaving a massless
        husk, and measured the energy each merge took out at the moment it happened.
        """
        taken = sim.scheme.take_merges(sim.work)
        if taken is None or len(taken[0]) == 0:
            return []
        rows, radii = taken

        step = sim.steps_done
        gone = np.zeros(len(sim.m), dtype=bool)
        into = np.arange(len(sim.m))
        self._handoff = sim.scheme.handoff(sim.work)  # the step's, for _check_step
        for row in rows:
            keep, lose = int(row[H_KEEP]), int(row[H_LOSE])
            gone[lose], into[lose] = True, keep
            self.offset += float(row[H_ENERGY])
        # A body that merged and was then merged into another ended in the last one.
        events = [Event("collision", step, step, float(row[H_TIME]), int(self.alive[int(row[H_KEEP])]),
                        int(self.alive[int(row[H_LOSE])]), float(row[H_DIST]), float(row[H_SPEED]),
                        float(row[H_REACH]), outcome="merged", into=int(self.alive[_root(into, int(row[H_KEEP]))]))
                  for row in rows]
        events.extend(open_encounters(self.watch, self.alive, involving=gone))
        self._take_out(sim, gone, into, sim.m.copy(), sim.pos.copy(), sim.vel.copy(), radii, step, sim.time,
                       husks=True)
        return events

    def _check_step(self, sim: WatchedRun) -> int:
        """The end-of-step checks of the last step, on the bodies left after its merges; the
        stop code they ask for."""
        self.watch.counts[wl.STOP] = wl.STOP_NONE
        handoff, self._handoff = self._handoff, None
        if handoff is not None:  # what the step handed to its own sub-steps, for the bodies left
            keep = self._kept
            pairs, bodies, flags = handoff
            handoff = (np.ascontiguousarray(pairs[np.ix_(keep, keep)]), bodies[keep].copy(), flags)
        after_step(self.watch, sim.pos, sim.vel, sim.m, sim.steps_done, sim.t0, sim.dt, handoff)
        stop = int(self.watch.counts[wl.STOP])
        self.watch.counts[wl.STOP] = wl.STOP_NONE
        return stop

    def _take_out(self, sim: WatchedRun, gone: np.ndarray, into: np.ndarray, m: np.ndarray, pos: np.ndarray,
                  vel: np.ndarray, radii: np.ndarray, step: int, time: float, husks: bool = False) -> None:
        """Remove the bodies ``gone``; unless they are ``husks`` (massless leftovers of merges the
        integrator made and accounted for), the energy their removal changes goes to the offset."""
        before = 0.0 if husks else sim.total_energy()
        keep = np.flatnonzero(~gone)
        self._kept = keep
        for k in np.flatnonzero(gone):
            orig = int(self.alive[k])
            self.removed_step[orig], self.removed_time[orig] = step, time
            if into[k] != k:
                self.merged_into[orig] = int(self.alive[_root(into, k)])
        for k in keep:
            self.final_masses[self.alive[k]] = m[k]
            self.final_radii[self.alive[k]] = radii[k]
        self.watch = shrink_watch(self.watch, keep, radii[keep], m[keep])
        self.alive, self.radii = self.alive[keep], radii[keep]
        sim.replace_bodies(m[keep], pos[:, keep], vel[:, keep])
        if not husks:
            self.offset += before - sim.total_energy()

    def outcome(self, final_run: bool = True) -> RunEvents:
        """The run's events and the bodies' fates. At the end of a run (``final_run``) the
        encounters still in progress are added, marked ``open``; they are not added to the log,
        which a checkpoint keeps, so a run extended from here logs each of them once, when it ends."""
        events = list(self.log)
        if final_run:
            seen = {(e.i, e.j, e.step_start) for e in events if e.kind == "encounter"}
            events.extend(_replace(e, outcome="open") for e in open_encounters(self.watch, self.alive)
                          if (e.i, e.j, e.step_start) not in seen)
        fates = {"radii": self.initial_radii.copy(), "final_radii": self.final_radii.copy(),
                 "final_masses": self.final_masses.copy(), "removed_step": self.removed_step.copy(),
                 "removed_time": self.removed_time.copy(), "merged_into": self.merged_into.copy()}
        return RunEvents(tuple(events), fates, self.scheme, self.settings)

    # -- checkpoints -------------------------------------------------------------------------

    def arrays(self) -> dict[str, np.ndarray]:
        """Everything to continue from, as arrays (stored in a checkpoint, bit for bit)."""
        out = {f"watch/{k}": v for k, v in watch_arrays(self.watch).items()}
        out.update({f"log/{k}": v for k, v in log_arrays(self.log).items()})
        out.update(alive=self.alive.copy(), radii=self.radii.copy(), offset=np.array(self.offset),
                   removed_step=self.removed_step.copy(), removed_time=self.removed_time.copy(),
                   merged_into=self.merged_into.copy(), final_masses=self.final_masses.copy(),
                   initial_radii=self.initial_radii.copy(), final_radii=self.final_radii.copy())
        return out

    def restore(self, arrays: dict[str, np.ndarray]) -> None:
        """Continue from :meth:`arrays` (the simulation already holds the bodies left)."""
        self.watch = watch_from_arrays({k[6:]: v for k, v in arrays.items() if k.startswith("watch/")})
        self.log = log_from_arrays({k[4:]: v for k, v in arrays.items() if k.startswith("log/")})
        self.alive = np.array(arrays["alive"], dtype=np.int64)
        self.radii = np.array(arrays["radii"], dtype=np.float64)
        self.n0 = int(arrays["final_masses"].shape[0])
        self.offset = float(arrays["offset"])
        for name in ("removed_step", "removed_time", "merged_into", "final_masses", "initial_radii", "final_radii"):
            setattr(self, name, np.array(arrays[name]))


def _root(into: np.ndarray, k: int) -> int:
    """The body ``k`` ended up in, following merges within one step."""
    while into[k] != k:
        k = int(into[k])
    return k


def _merge_into(keep: int, lose: int, m: np.ndarray, pos: np.ndarray, vel: np.ndarray, radii: np.ndarray) -> None:
    """Body ``lose`` joins ``keep``: mass and momentum conserved, volume-conserving radius."""
    total = m[keep] + m[lose]
    if total > 0.0:
        pos[:, keep] = (m[keep] * pos[:, keep] + m[lose] * pos[:, lose]) / total
        vel[:, keep] = (m[keep] * vel[:, keep] + m[lose] * vel[:, lose]) / total
    else:  # two massless bodies: the midpoint, the mean velocity
        pos[:, keep] = 0.5 * (pos[:, keep] + pos[:, lose])
        vel[:, keep] = 0.5 * (vel[:, keep] + vel[:, lose])
    m[keep] = total
    radii[keep] = np.cbrt(radii[keep] ** 3 + radii[lose] ** 3)


def _replace(event: Event, **changes: Any) -> Event:
    return replace(event, **changes)


def _with(chunk: SampleChunk, **changes: Any) -> SampleChunk:
    return replace(chunk, **changes)
