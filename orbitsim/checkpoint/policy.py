"""The runner's checkpoint bookkeeping: when one is due, what it holds, which state a trace keeps."""

from __future__ import annotations

import math
import time
from typing import TYPE_CHECKING, Any

from orbitsim.checkpoint.state import capture_state
from orbitsim.io.checkpoint import Checkpoint

if TYPE_CHECKING:
    from orbitsim.checkpoint.sinks import RunStart
    from orbitsim.scenario import Scenario

__all__ = ["Checkpointer"]


class Checkpointer:
    """Checkpoints of one run, taken by the runner's loop at points where state and samples agree.

    ``loop`` arguments are the runner's loop: ``sim``, ``samples``, ``last_step``, ``last_time``,
    ``e0``, ``scale``, ``max_err``, ``safe``, ``diverged`` and ``wall()``.
    """

    def __init__(self, scenario: Scenario, sink: Any, start: RunStart | None, force: bool) -> None:
        self.scenario, self.sink, self.start, self.force = scenario, sink, start, force
        self.published: Checkpoint | None = start.checkpoint if start is not None and start.journal else None
        self.resumes = start.resumes if start is not None else 0
        self.prior_wall = start.checkpoint.wall_time_s if start is not None else 0.0
        self.step = start.checkpoint.steps_done if start is not None else -1
        self.clock = time.monotonic()

    def initial(self, loop: Any) -> None:
        """The first checkpoint, before any step: from then on a kill loses nothing already done."""
        if self.sink.periodic and self.published is None:
            self.take(loop)

    def maybe(self, loop: Any) -> None:
        """Checkpoint if ``output.checkpoint``'s steps or seconds have passed since the last one."""
        sc = self.scenario
        if not self.sink.periodic:
            return
        due = sc.checkpoint_every is not None and loop.sim.steps_done - self.step >= sc.checkpoint_every
        late = sc.checkpoint_seconds is not None and time.monotonic() - self.clock >= sc.checkpoint_seconds
        if due or late:
            self.take(loop)

    def take(self, loop: Any) -> None:
        """Publish a checkpoint of the current state."""
        ckpt = self.build(loop)
        self.sink.checkpoint(ckpt)
        self.published = ckpt
        self.step, self.clock = ckpt.steps_done, time.monotonic()

    def build(self, loop: Any) -> Checkpoint:
        """A checkpoint of the loop's current state (which must agree with its samples)."""
        sc = self.scenario
        text, bodies = sc.stored_form()  # built once per run: a large scenario's rows are arrays
        return Checkpoint(
            state=capture_state(loop.sim), steps_requested=sc.steps, samples_written=self.sink.samples_written,
            last_sample_step=loop.last_step if loop.samples else -1, integrator=sc.integrator,
            scenario_sha256=sc.sha256, scenario=text, scenario_bodies=bodies, scenario_name=sc.name,
            scenario_source=sc.source,
            resumes=self.resumes, force=self.force, E0=math.nan if loop.e0 is None else loop.e0,
            energy_scale=loop.scale,
            max_abs_energy_error=loop.max_err if loop.samples else math.nan, last_sample_time=loop.last_time,
            wall_time_s=loop.wall(), t0=float(loop.sim.t0), history=loop.history)

    def kept(self) -> Checkpoint | None:
        """The newest state known to agree with the samples: on disk, or the one the run started from."""
        if self.published is not None:
            return self.published
        return self.start.checkpoint if self.start is not None else None

    def final(self, loop: Any) -> Checkpoint | None:
        """The state a trace keeps: the current one where it agrees with the samples, else :meth:`kept`;
        none after a divergence."""
        if loop.diverged:
            return None
        if loop.safe and loop.sim is not None:
            return self.build(loop)
        return self.kept()
