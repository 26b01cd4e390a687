"""The ``trace`` kind of a benchmark matrix: its keys, their validation, its cases.

A ``trace`` group times orbitsim's ``trace`` beside REBOUND's TRACE, each repeat integrating one
system from its initial state over the same whole steps (:mod:`orbitsim.bench.trace`). Its values
are given per N, as an ``adaptive`` group's are (the readers are shared,
:mod:`orbitsim.bench._adaptive_fields`): REBOUND's many-encounters set-up (7 bodies) and a disc
of ~100 planetesimals need their own span and step. A scenario brings its own ``dt`` and
``softening``; the group's are for generated systems.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from orbitsim.bench._adaptive_fields import distinct_ns, per_n, per_n_number, per_n_system
from orbitsim.bench._fields import Group, Reader

__all__ = ["TRACE_KEYS", "TraceCase", "expand_trace", "read_trace"]

#: The keys of a ``trace`` group (besides name, kind, repeats, warmup, description).
TRACE_KEYS = ("system", "engines", "n", "t_end", "dt", "softening", "seed")

_ENGINES = ("orbitsim", "rebound")


@dataclass(frozen=True)
class TraceCase:
    """One timed TRACE case: an engine integrating a system of N bodies from t = 0 to ``t_end``."""

    group: str
    engine: str
    system: str
    n: int
    t_end: float
    dt: float
    softening: float
    seed: int
    repeats: int
    warmup: int
    integrator: str = "trace"
    threads: int | None = 1  # TRACE's kernels are serial in both codes

    @property
    def case_id(self) -> str:
        """A stable, readable identifier, e.g. ``trace/orbitsim/trace/many_encounters/n7``."""
        return f"{self.group}/{self.engine}/{self.integrator}/{self.system}/n{self.n}"


def read_trace(r: Reader, g: Mapping[str, Any], path: str) -> dict[str, Any]:
    """The params of a ``trace`` group; per-N values as ``{N: value}`` for every N."""
    ns = distinct_ns(r, g, path)
    return {
        "engines": tuple(r.strings(g, "engines", path, list(_ENGINES), choices=_ENGINES)),
        "n": ns,
        "system": per_n(r, g, "system", path, ns, None, per_n_system(r)),
        "t_end": per_n(r, g, "t_end", path, ns, None, per_n_number(r)),
        "dt": per_n(r, g, "dt", path, ns, 0.01, per_n_number(r)),
        "softening": per_n(r, g, "softening", path, ns, 0.0, per_n_number(r, allow_zero=True)),
        "seed": r.integer(g, "seed", path, 1, minimum=0),
    }


def expand_trace(group: Group) -> list[TraceCase]:
    """The cases of one ``trace`` group: for each N, orbitsim then REBOUND."""
    p = group.params
    return [TraceCase(group=group.name, engine=engine, system=p["system"][n], n=n, t_end=p["t_end"][n],
                      dt=p["dt"][n], softening=p["softening"][n], seed=p["seed"], repeats=group.repeats,
                      warmup=group.warmup)
            for n in p["n"] for engine in _ENGINES if engine in p["engines"]]
