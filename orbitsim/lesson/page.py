"""``lesson.html``: the demo's lesson as a page to play with (written by ``orbitsim demo``).

The three schemes of the lesson side by side, each an animated orbit above its energy trace, a
dt slider and a frame-rate control. The physics is orbitsim's: every scheme is run here at every
dt of :data:`PAGE_DT_FACTORS`, every step recorded, and the runs are embedded in the page as JSON.
The page's JavaScript only plays them back, through the same accumulator loop as
``orbitsim animate`` (:mod:`orbitsim.animation.loop`), so changing the frame rate changes how
often the orbit is drawn, never the orbit. The page loads nothing from the network.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from orbitsim.compare.run import run_orbitsim
from orbitsim.lesson.page_template import PAGE_TEMPLATE
from orbitsim.lesson.run import COLORS, LESSON, LessonResult
from orbitsim.plots.style import unit_labels

__all__ = ["PAGE_DT_FACTORS", "PLAY_SECONDS", "page_data", "page_runs", "write_lesson_page"]

#: The slider's dt values, as multiples of the lesson's dt: from a quarter (600 steps per orbit) to
#: four times (37 per orbit), where Euler escapes. Every step is embedded, so the finest rung sets
#: the page's size (about 0.5 MB in all).
PAGE_DT_FACTORS = (0.25, 0.5, 1.0, 2.0, 4.0)
#: Seconds the page takes to play the whole run at every dt: the orbit moves at one speed, and a
#: smaller dt only means more physics steps per second.
PLAY_SECONDS = 24.0
#: Decimals kept of positions (orbit radius ~1; a canvas pixel is ~0.01) and significant digits of
#: dE/E: enough to draw, small enough to embed.
POSITION_DECIMALS = 4
ENERGY_DIGITS = 3
#: Points of the IAS15 reference orbit drawn as the faint guide.
REFERENCE_POINTS = 400


def page_runs(scenario: Any) -> dict[str, list[Any]]:
    """Every scheme of the lesson at every dt of the slider, to the lesson's end time, every step
    recorded: {integrator: [RunRecord per dt]}."""
    from orbitsim.scenario import resolve_steps  # noqa: PLC0415 -- lazy: loads yaml

    end_time = scenario.steps * scenario.dt
    runs: dict[str, list[Any]] = {name: [] for name, _, _ in LESSON}
    for factor in PAGE_DT_FACTORS:
        dt = scenario.dt * factor
        steps = resolve_steps(end_time, dt)[0]
        rung = scenario.with_overrides(dt=dt, steps=steps)
        for name, _, _ in LESSON:
            runs[name].append(run_orbitsim(rung, name, np.arange(steps + 1, dtype=np.int64)))
    return runs


def _rounded(values: np.ndarray, decimals: int) -> list[float]:
    return [float(v) for v in np.round(np.asarray(values, dtype=np.float64), decimals)]


def _significant(values: np.ndarray, digits: int) -> list[float]:
    return [float(f"{v:.{digits - 1}e}") for v in np.asarray(values, dtype=np.float64)]


def page_data(result: LessonResult, runs: dict[str, list[Any]]) -> dict[str, Any]:
    """The JSON the page plays: per scheme and dt, the planet's x, y and dE/E at every step."""
    sc = result.scenario
    planet = int(np.argmin(sc.masses))
    ref = result.reference.positions[:, planet, :2]
    pick = np.unique(np.linspace(0, ref.shape[0] - 1, REFERENCE_POINTS).astype(int))
    time_unit, length_unit = unit_labels(sc.units)
    dts = [float(r.time[1] - r.time[0]) for r in runs[LESSON[0][0]]]
    return {
        "schemes": [{"key": key, "title": title, "moral": moral, "color": COLORS[key]} for key, title, moral in LESSON],
        "dts": dts, "lesson_index": PAGE_DT_FACTORS.index(1.0), "factors": list(PAGE_DT_FACTORS),
        "speed": float(sc.steps * sc.dt) / PLAY_SECONDS, "time_unit": time_unit, "length_unit": length_unit,
        "extent": 1.9 * float(np.max(np.abs(ref))),  # Euler's spiral leaves the panel, visibly
        "reference": {"x": _rounded(ref[pick, 0], 3), "y": _rounded(ref[pick, 1], 3)},
        "runs": {key: [{"x": _rounded(r.positions[:, planet, 0], POSITION_DECIMALS),
                        "y": _rounded(r.positions[:, planet, 1], POSITION_DECIMALS),
                        "e": _significant(r.energy_error, ENERGY_DIGITS)} for r in records]
                 for key, records in runs.items()},
        "scenario": sc.name, "steps_per_orbit": [_period(sc, planet) / dt for dt in dts],
    }


def _period(sc: Any, planet: int) -> float:
    """The planet's Kepler period about the star, from its initial state (vis-viva)."""
    star = int(np.argmax(sc.masses))
    mu = sc.G * float(sc.masses[star] + sc.masses[planet])
    r = float(np.linalg.norm(sc.positions[planet] - sc.positions[star]))
    v2 = float(np.sum((sc.velocities[planet] - sc.velocities[star]) ** 2))
    a = 1.0 / (2.0 / r - v2 / mu)
    return 2.0 * np.pi * float(np.sqrt(a**3 / mu))


def write_lesson_page(result: LessonResult, runs: dict[str, list[Any]], outdir: Path) -> Path:
    """Write ``lesson.html`` into ``outdir``: the template with the runs embedded as JSON."""
    # "</" inside a <script> would end it early; JSON allows the escaped form "<\/".
    data = json.dumps(page_data(result, runs), separators=(",", ":")).replace("</", "<\\/")
    path = outdir / "lesson.html"
    path.write_text(PAGE_TEMPLATE.replace("__LESSON_DATA__", data), encoding="utf-8")
    return path
