"""Summaries of repeated timings: median with min and max, never a mean.

On a shared machine the noise is one-sided (other work only ever slows a run down), so the
median is the honest central value and the min shows what the code does undisturbed.
"""

from __future__ import annotations

import statistics
from collections.abc import Sequence

__all__ = ["paired_median", "scaled", "summarise"]


def summarise(values: Sequence[float]) -> dict[str, float | list[float]]:
    """``{"median", "min", "max", "values"}`` of a non-empty list of measurements."""
    if not values:
        raise ValueError("no measurements to summarise")
    data = [float(v) for v in values]
    return {"median": statistics.median(data), "min": min(data), "max": max(data), "values": data}


def scaled(summary: dict[str, float | list[float]], factor: float, *, invert: bool = False) -> dict[str, float]:
    """The median/min/max of ``summary`` times ``factor``, or ``factor`` divided by them.

    With ``invert`` (a rate from a time) the min and max swap: the shortest time is the fastest rate.
    """
    lo, mid, hi = float(summary["min"]), float(summary["median"]), float(summary["max"])  # type: ignore[arg-type]
    if invert:
        return {"median": factor / mid, "min": factor / hi, "max": factor / lo}
    return {"median": factor * mid, "min": factor * lo, "max": factor * hi}


def paired_median(numerators: Sequence[float], denominators: Sequence[float]) -> float:
    """Median over rounds of ``numerators[r] / denominators[r]``, for timings taken interleaved
    (round r timed both), over the rounds both have."""
    rounds = min(len(numerators), len(denominators))
    if rounds == 0:
        raise ValueError("no round has both timings")
    return statistics.median(numerators[r] / denominators[r] for r in range(rounds))
