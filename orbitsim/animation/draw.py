"""One movie frame as an RGB image: the bodies at their interpolated positions, their trails, and
an overlay with the time, dt, the physics steps so far and |dE/E| (matplotlib's Agg canvas).

The figure is built once and only its artists' data change from frame to frame, which is what
makes a few hundred frames take seconds rather than minutes.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np

from orbitsim.animation.states import FrameStates, Source

__all__ = ["AXES", "VIEWS", "FrameDrawer", "view_positions"]

#: The projections ``--view`` offers, as the coordinate axes each one shows.
AXES = {"xy": (0, 1), "xz": (0, 2), "yz": (1, 2), "3d": (0, 1, 2)}
VIEWS = tuple(AXES)
#: Above this many bodies, trails and a legend would be noise: bodies are dots, nothing more.
MAX_TRACKED = 50
#: Fraction of bodies whose extent sets the axes of a large system, so one escaper does not shrink
#: the cluster to a dot.
CLUSTER_QUANTILE = 0.98
#: Bodies from the first of a colour cycle that is readable on white, heaviest first.
COLORS = ("#e6a700", "#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#8c564b", "#e377c2", "#17becf", "#7f7f7f")


def view_positions(positions: np.ndarray, follow: int | None) -> np.ndarray:
    """(F, N, 3) positions, relative to body ``follow`` when one is followed."""
    return positions - positions[:, follow : follow + 1, :] if follow is not None else positions


def _half_width(positions: np.ndarray, axes: tuple[int, ...]) -> tuple[np.ndarray, float]:
    """Centre and half-width of a square (cubic) box holding the shown coordinates of every frame."""
    coords = positions[:, :, list(axes)].reshape(-1, len(axes))
    coords = coords[np.all(np.isfinite(coords), axis=1)]
    if coords.size == 0:
        return np.zeros(len(axes)), 1.0
    q = CLUSTER_QUANTILE if positions.shape[1] > MAX_TRACKED else 1.0
    lo, hi = np.quantile(coords, 1.0 - q, axis=0), np.quantile(coords, q, axis=0)
    centre = 0.5 * (lo + hi)
    half = 0.5 * float(np.max(hi - lo)) * 1.08  # a margin so markers at the edge stay whole
    return centre, half if half > 0.0 else 1.0


class FrameDrawer:
    """Draws frame k of ``states`` into a ``width`` x ``height`` pixel RGB array."""

    def __init__(self, source: Source, states: FrameStates, view: str, trail: int, follow: int | None,
                 size: tuple[int, int] = (960, 720)) -> None:
        from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: PLC0415 -- lazy: loads matplotlib
        from matplotlib.figure import Figure  # noqa: PLC0415 -- lazy: loads matplotlib

        self.source, self.states, self.trail = source, states, trail
        self.axes = AXES[view]
        self.pos = view_positions(states.positions, follow)
        self.follow = follow
        self.fig = Figure(figsize=(size[0] / 100, size[1] / 100), dpi=100)
        self.canvas = FigureCanvasAgg(self.fig)
        three_d = view == "3d"
        self.ax = self.fig.add_subplot(projection="3d" if three_d else None)
        # The overlay sits above the axes, never over an orbit (it hid the body when it was inside).
        self.fig.subplots_adjust(left=0.1, right=0.97, bottom=0.1, top=0.84)
        self._setup_axes(view, follow)
        self.tracked = self.pos.shape[1] <= MAX_TRACKED
        order = np.argsort(-np.asarray(source.masses))
        colors = {int(i): COLORS[r % len(COLORS)] for r, i in enumerate(order)}
        msize = self._marker_sizes(np.asarray(source.masses))
        self.trails: list[Any] = []
        self.dots: list[Any] = []
        if self.tracked:
            for i in range(self.pos.shape[1]):
                (line,) = self.ax.plot(*([[]] * len(self.axes)), lw=1.0, color=colors[i], alpha=0.7)
                (dot,) = self.ax.plot(*([[]] * len(self.axes)), "o", ms=msize[i], color=colors[i],
                                      mec="0.2", mew=0.5, label=source.names[i])
                self.trails.append(line)
                self.dots.append(dot)
            if len(source.names) <= 12:
                self.ax.legend(loc="upper right", fontsize=8, framealpha=0.8)
        else:
            (dot,) = self.ax.plot(*([[]] * len(self.axes)), ".", ms=1.5, color="#1f77b4", alpha=0.6)
            self.dots.append(dot)
        self.overlay = self.fig.text(0.5, 0.945, "", va="top", ha="center", family="monospace", fontsize=10,
                                     bbox={"boxstyle": "round", "fc": "white", "ec": "0.7"})

    def _setup_axes(self, view: str, follow: int | None) -> None:
        centre, half = _half_width(self.pos, self.axes)
        unit = f" (relative to {self.source.names[follow]})" if follow is not None else ""
        # Matplotlib's own axes are x, y (and z); each shows one of the view's coordinates.
        for own, axis, c in zip("xyz", self.axes, centre, strict=False):
            getattr(self.ax, f"set_{own}lim")(c - half, c + half)
            getattr(self.ax, f"set_{own}label")("xyz"[axis])
        if view == "3d":
            self.ax.set_box_aspect((1, 1, 1))
            self.ax.view_init(elev=25, azim=-60)
        else:
            self.ax.set_aspect("equal", adjustable="box")
            self.ax.grid(True, alpha=0.2)
        self.fig.suptitle(f"{self.source.label}  ({view}{unit})", fontsize=12, y=0.99)

    @staticmethod
    def _marker_sizes(masses: np.ndarray) -> np.ndarray:
        """Marker sizes growing with log mass: a star stands out from its planets, which stay visible."""
        top = float(np.max(masses)) if masses.size and np.max(masses) > 0 else 1.0
        rel = np.log10(np.clip(masses / top, 1e-12, 1.0))  # 0 for the heaviest, -12 at most
        return 12.0 + rel * (7.0 / 12.0)

    def _set(self, artist: Any, coords: np.ndarray) -> None:
        if len(self.axes) == 3:
            artist.set_data_3d(coords[:, 0], coords[:, 1], coords[:, 2])
        else:
            artist.set_data(coords[:, 0], coords[:, 1])

    def _overlay_text(self, k: int) -> str:
        s, src = self.states, self.source
        unit = f" {src.time_unit}" if src.time_unit else ""
        return (f"t = {s.time[k]:.5g}{unit}   frame {k + 1}/{s.plan.n_frames}\n"
                f"dt = {src.engine_dt:.4g}   physics steps {int(s.engine_steps[k]):,}\n"
                f"|dE/E| = {s.energy_error[k]:.2e}")

    def _trail(self, k: int) -> np.ndarray:
        """Frame k's trail in the view's frame (relative to the followed body, when one is)."""
        s = self.states
        path = s.trail(k, self.trail)
        if self.follow is None:
            return path
        return path - path[:, self.follow : self.follow + 1, :]

    def render(self, k: int) -> np.ndarray:
        """Frame k as a (height, width, 3) uint8 array."""
        cols = list(self.axes)
        now = self.pos[k][:, cols]
        if self.tracked:
            path = self._trail(k)
            for i, (line, dot) in enumerate(zip(self.trails, self.dots, strict=True)):
                self._set(line, path[:, i][:, cols] if self.trail else now[:0])
                self._set(dot, now[i : i + 1])
        else:
            self._set(self.dots[0], now)
        self.overlay.set_text(self._overlay_text(k))
        self.canvas.draw()
        return np.asarray(self.canvas.buffer_rgba())[:, :, :3].copy()

    def frames(self) -> Iterator[np.ndarray]:
        """Every frame in order."""
        for k in range(self.states.plan.n_frames):
            yield self.render(k)

    @property
    def size(self) -> tuple[int, int]:
        """(width, height) in pixels."""
        w, h = self.canvas.get_width_height()
        return int(w), int(h)
