"""Figures of a results document (matplotlib, Agg backend: no display needed).

* ``throughput.png``: pair interactions per second against N, log-log, one line per engine,
  integrator and thread count, with the measured hardware ceiling for each thread count drawn in.
* ``small_n.png``: time per step at small N for every integrator, orbitsim beside REBOUND,
  with min-max error bars.
"""

from __future__ import annotations

from collections import defaultdict
from pathlib import Path
from typing import Any

__all__ = ["SMALL_N_MAX", "write_figures"]

#: Cases up to this N go into the small-N figure; larger ones into the throughput figure.
SMALL_N_MAX = 16


def _label(case: dict[str, Any]) -> str:
    if case["engine"] == "rebound":
        return f"REBOUND {case['integrator']}"
    return f"orbitsim {case['integrator']} ({case['threads']} thr)"


def _throughput(doc: dict[str, Any], path: Path) -> Path | None:
    import matplotlib.pyplot as plt  # noqa: PLC0415 -- lazy: loads matplotlib

    lines: dict[str, list[tuple[int, dict[str, float]]]] = defaultdict(list)
    for c in doc.get("cases", []):
        if c["n"] > SMALL_N_MAX:
            lines[_label(c)].append((c["n"], c["pairs_per_s"]))
    if not lines:
        return None
    fig, ax = plt.subplots(figsize=(7.5, 5))
    for label, points in sorted(lines.items()):
        points.sort(key=lambda p: p[0])
        ns = [p[0] for p in points]
        med = [p[1]["median"] for p in points]
        err = [[p[1]["median"] - p[1]["min"] for p in points], [p[1]["max"] - p[1]["median"] for p in points]]
        ax.errorbar(ns, med, yerr=err, marker="o" if label.startswith("orbitsim") else "s", capsize=3,
                    label=label, linestyle="--" if label.startswith("REBOUND") else "-")
    ax.set_xscale("log", base=2)
    ax.set_yscale("log")
    ceiling = doc.get("ceiling")
    if ceiling:
        threads = sorted({c["threads"] for c in doc["cases"] if c["engine"] == "orbitsim" and c["n"] > SMALL_N_MAX})
        for t in threads:
            level = t * ceiling["pairs_once_per_core"]
            ax.axhline(level, color="grey", linewidth=1, linestyle=":")
            ax.text(0.01, level, f" hardware ceiling, {t} thread{'s' if t > 1 else ''} (sqrt/div unit, each pair once)",
                    transform=ax.get_yaxis_transform(), fontsize=8, color="grey", va="bottom")
    ax.set_xlabel("N (bodies)")
    ax.set_ylabel("pair interactions / s  (N(N-1) per force evaluation)")
    ax.set_title("Force throughput through the stepping loop (median, min-max)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def _small_n(doc: dict[str, Any], path: Path) -> Path | None:
    import matplotlib.pyplot as plt  # noqa: PLC0415 -- lazy: loads matplotlib
    import numpy as np  # noqa: PLC0415 -- lazy: loads numpy

    cases = [c for c in doc.get("cases", []) if c["n"] <= SMALL_N_MAX]
    if not cases:
        return None
    labels: list[str] = []
    for c in sorted(cases, key=lambda c: (c["engine"] != "orbitsim",)):
        name = _label(c).replace(f" ({c['threads']} thr)", "")
        if name not in labels:
            labels.append(name)
    sizes = sorted({c["n"] for c in cases})
    width = 0.8 / len(sizes)
    fig, ax = plt.subplots(figsize=(max(7.5, 0.9 * len(labels)), 5))
    for k, n in enumerate(sizes):
        at: dict[str, Any] = {}
        for c in cases:  # the first group that measured a scheme at N (the matrix's all-scheme group)
            if c["n"] == n:
                at.setdefault(_label(c).replace(f" ({c['threads']} thr)", ""), c["per_step_s"])
        xs = [i + (k - (len(sizes) - 1) / 2) * width for i, lab in enumerate(labels) if lab in at]
        vals = [at[lab] for lab in labels if lab in at]
        med = np.array([v["median"] for v in vals]) * 1e9
        err = np.array([[v["median"] - v["min"] for v in vals], [v["max"] - v["median"] for v in vals]]) * 1e9
        ax.bar(xs, med, width, yerr=err, capsize=2, label=f"N = {n}")
    ax.set_xticks(range(len(labels)))
    ax.set_xticklabels(labels, rotation=35, ha="right", fontsize=8)
    ax.set_yscale("log")
    ax.set_ylabel("time per step (ns), median with min-max")
    ax.set_title("Small-N step cost: orbitsim beside REBOUND (same run)")
    ax.grid(True, axis="y", which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def write_figures(doc: dict[str, Any], outdir: Path) -> list[Path]:
    """Write the figures that the results have data for; returns their paths."""
    import matplotlib  # noqa: PLC0415 -- lazy: loads matplotlib

    matplotlib.use("Agg")
    made = [_throughput(doc, outdir / "throughput.png"), _small_n(doc, outdir / "small_n.png")]
    return [p for p in made if p is not None]
