"""The fixed-timestep render loop, as arithmetic: which physics states each frame of a movie shows.

Two clocks run side by side (Fiedler, "Fix your timestep!", 2004):

* **frames** fall at ``fps`` on the wall-clock axis: frame k is shown at ``k / fps`` seconds of
  the movie, and a movie of ``duration`` seconds has ``round(fps * duration)`` frames, whatever dt is;
* **physics** advances in whole steps of the scenario's fixed ``dt`` and nothing else.

Between them sits an accumulator. Each frame adds the simulated time that elapsed since the last
frame (its wall-clock time times ``speed``, simulated time per second of movie); the loop then
takes whole physics steps while the accumulator holds at least ``dt``, and draws the state
interpolated by ``alpha = accumulator / dt`` between the last two physics states. The drawn state
therefore lags the frame's clock by one step, the price of never extrapolating past a state the
physics has computed. Frames can fall anywhere: the physics, and so every state drawn, stays the
same sequence of fixed steps.

Everything here is pure numpy on a few numbers per frame; nothing is stepped or drawn, so the
loop's guarantees are tested directly (``tests/animation/test_animate.py``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["DEFAULT_DURATION", "MAX_FRAMES", "FramePlan", "Timing", "frame_times", "interpolate", "plan_frames",
           "resolve_timing"]

#: Movie length when neither ``--duration`` nor ``--speed`` is given: long enough to follow an
#: orbit, short enough to render in seconds.
DEFAULT_DURATION = 10.0
#: The most frames one movie may have: ten minutes at 60 fps. Past that the request is almost
#: certainly a slip (``--speed`` in the wrong units) and would run for hours.
MAX_FRAMES = 36_000
#: Relative distance below dt within which the accumulator counts as holding a whole step: far
#: above the rounding of summing frame times (~1e-16 per frame), far below anything visible.
STEP_ROUNDING = 1e-9


@dataclass(frozen=True)
class Timing:
    """How the movie's wall clock maps onto simulated time."""

    fps: float
    n_frames: int
    #: Simulated time per second of movie.
    speed: float

    @property
    def duration(self) -> float:
        """Seconds of movie: ``n_frames / fps``."""
        return self.n_frames / self.fps


def resolve_timing(fps: float, span: float, duration: float | None = None, speed: float | None = None) -> Timing:
    """The movie's timing from at most one of ``duration`` (seconds) and ``speed`` (simulated time
    per second), for a run of simulated length ``span``; raises ValueError naming what to fix.

    ``duration`` plays the whole span in that many seconds; ``speed`` plays it at that rate (the
    movie then lasts ``span / speed``); with neither, the span plays in :data:`DEFAULT_DURATION`.
    The frame count is ``round(fps * duration)``: frames = fps x duration, whatever dt is.
    """
    if duration is not None and speed is not None:
        raise ValueError("give --duration or --speed, not both (--speed sets the duration: span / speed)")
    for label, value in (("--fps", fps), ("--duration", duration), ("--speed", speed)):
        if value is not None and not (math.isfinite(value) and value > 0.0):
            raise ValueError(f"{label} must be a finite number > 0, got {value}")
    if not (math.isfinite(span) and span > 0.0):
        raise ValueError(f"nothing to animate: the run spans {span:g} time units")
    if speed is None:
        duration = DEFAULT_DURATION if duration is None else duration
        speed = span / duration
    else:
        duration = span / speed
    n_frames = round(fps * duration)
    if n_frames < 1:
        raise ValueError(f"--fps {fps:g} x {duration:g} s gives no frame; ask for a longer or faster movie")
    if n_frames > MAX_FRAMES:
        raise ValueError(f"{n_frames} frames ({duration:.4g} s at {fps:g} fps) is more than {MAX_FRAMES}; "
                         "give a shorter --duration or a larger --speed")
    return Timing(float(fps), int(n_frames), float(speed))


def frame_times(timing: Timing) -> tuple[np.ndarray, np.ndarray]:
    """(wall, clock): frame k is shown at ``k / fps`` s of movie, when the simulated clock reads
    ``k / fps * speed``. Neither depends on dt: two runs that differ only in dt share them."""
    wall = np.arange(timing.n_frames, dtype=np.float64) / timing.fps
    return wall, wall * timing.speed


@dataclass(frozen=True)
class FramePlan:
    """What the render loop does at each frame k (arrays of length F)."""

    #: Seconds into the movie at which frame k is shown.
    wall_time: np.ndarray
    #: The simulated clock at frame k (what the accumulator has been fed so far).
    clock: np.ndarray
    #: Whole physics steps taken by the time frame k is drawn (int64, non-decreasing).
    steps: np.ndarray
    #: Steps taken during frame k's update (``steps[k] - steps[k-1]``).
    steps_this_frame: np.ndarray
    #: ``accumulator / dt`` in [0, 1): how far frame k's state is from state ``steps - 1`` to ``steps``.
    alpha: np.ndarray
    #: The fixed physics step.
    dt: float

    @property
    def n_frames(self) -> int:
        """Number of frames F."""
        return int(self.steps.shape[0])

    @property
    def previous(self) -> np.ndarray:
        """Index of the older of the two states frame k blends (the initial state before any step)."""
        return np.maximum(self.steps - 1, 0)

    @property
    def state_time(self) -> np.ndarray:
        """Simulated time of the state drawn at frame k: ``(steps - 1 + alpha) dt``, 0 before any step."""
        return np.where(self.steps > 0, (self.steps - 1 + self.alpha) * self.dt, 0.0)


def plan_frames(timing: Timing, dt: float, max_steps: int | None = None) -> FramePlan:
    """Run the accumulator loop over the frames of ``timing`` with physics step ``dt``.

    ``max_steps`` caps the physics at the run's last state (the frames never ask for more, but a
    frame clock rounded up by one ulp must not ask the engine for a step the run does not have).
    """
    if not (math.isfinite(dt) and dt > 0.0):
        raise ValueError(f"the physics step must be a finite number > 0, got {dt}")
    wall, clock = frame_times(timing)
    steps = np.zeros(timing.n_frames, dtype=np.int64)
    taken = np.zeros(timing.n_frames, dtype=np.int64)
    alpha = np.zeros(timing.n_frames)
    accumulator, done = 0.0, 0
    for k in range(timing.n_frames):
        accumulator += clock[k] - (clock[k - 1] if k else 0.0)  # this frame's elapsed simulated time
        # "while accumulator >= dt: step" in one go: the count is the same, and a movie of
        # 10^7 steps costs one division per frame instead of 10^7 Python iterations.
        n = int(accumulator // dt)
        accumulator -= n * dt
        # A remainder a hair short of dt is a clock that landed on a step, rounded down (1.0 // 0.01
        # is 99): take that step, so a frame at t = 1 shows "100 steps", not "99 and alpha 0.99999".
        if accumulator >= dt * (1.0 - STEP_ROUNDING):
            n, accumulator = n + 1, accumulator - dt
        accumulator = max(accumulator, 0.0)
        if max_steps is not None and done + n >= max_steps:
            n, accumulator = max_steps - done, 0.0  # hold the last state: there is none after it
        done += n
        steps[k], taken[k], alpha[k] = done, n, accumulator / dt
    return FramePlan(wall, clock, steps, taken, alpha, float(dt))


def interpolate(previous: np.ndarray, current: np.ndarray, alpha: float | np.ndarray) -> np.ndarray:
    """The state drawn between two physics states: ``previous + alpha (current - previous)``.

    ``alpha`` broadcasts from the left (one weight per frame for stacked (F, ...) states)."""
    a = np.asarray(alpha, dtype=np.float64)
    a = a.reshape(a.shape + (1,) * (np.ndim(current) - a.ndim))
    return previous + a * (current - previous)
