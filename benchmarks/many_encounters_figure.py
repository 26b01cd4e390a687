"""The README's figure: |dE/E| against time on the bundled ``many_encounters`` scenario (REBOUND's
many-encounters test) for ``wisdom_holman``, ``trace`` and ``ias15``, each through orbitsim's
run loop, written to ``docs/figures/many_encounters_energy.png``.

    .venv/bin/python benchmarks/many_encounters_figure.py
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from orbitsim.io.trace_reader import read_trace
from orbitsim.runner import run_scenario
from orbitsim.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[1]
OUTPUT = ROOT / "docs" / "figures" / "many_encounters_energy.png"


def main() -> None:
    base = load_scenario("many_encounters")
    runs = {
        "wisdom_holman (fixed dt)": base.with_overrides(integrator="wisdom_holman"),
        "trace (fixed dt, BS in encounters)": base,
        "ias15 (adaptive)": base.with_overrides(integrator="ias15", t_end=base.steps * base.dt, interval=base.dt * 100),
    }
    fig, ax = plt.subplots(figsize=(7.5, 4.2))
    with tempfile.TemporaryDirectory() as tmp:
        for k, (label, scenario) in enumerate(runs.items()):
            summary = run_scenario(scenario, Path(tmp) / f"{k}.h5", handle_signals=False)
            trace = read_trace(summary.output)
            err = np.abs(np.asarray(trace.energy_error))
            ax.semilogy(trace.time[1:], np.maximum(err[1:], 1e-17), label=f"{label}: max {err.max():.2g}", lw=1)
            print(f"{label}: max |dE/E| = {err.max():.3g}, {summary.wall_time_s:.2f} s")
    ax.set_xlabel("time (G = 1; an orbit at a = 1 takes 2 pi)")
    ax.set_ylabel("|dE/E|")
    ax.set_title("many_encounters: a star and six 1e-4 planets on crossing orbits")
    ax.legend(loc="lower right", fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    OUTPUT.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(OUTPUT, dpi=110)
    print(f"written {OUTPUT}")


if __name__ == "__main__":
    main()
