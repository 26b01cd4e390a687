"""The ``adaptive`` kind of a benchmark matrix: its keys, their validation, its cases.

Kept apart from :mod:`orbitsim.bench.matrix` (which documents the schema and dispatches to
:func:`read_adaptive`) because its values may be given per N: IAS15's step is set by the system,
so one group that times a few planets and a 1,000-body cluster needs a span, a system and a
softening for each N. The per-N readers (:func:`per_n`, :func:`per_n_number`, :func:`per_n_system`)
serve the ``trace`` kind too (:mod:`orbitsim.bench._trace_fields`).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from orbitsim.bench._fields import GENERATED_SYSTEMS, Group, Reader

__all__ = ["ADAPTIVE_KEYS", "AdaptiveCase", "distinct_ns", "expand_adaptive", "per_n", "per_n_number", "per_n_system",
           "read_adaptive"]

#: The keys of an ``adaptive`` group (besides name, kind, repeats, warmup, description).
ADAPTIVE_KEYS = ("system", "engines", "n", "t_end", "first_dt", "softening", "epsilon", "threads", "seed")

_ENGINES = ("orbitsim", "rebound")

#: ``read(mapping, key, path, n)``: one checked value; errors name ``path.key``.
ReadOne = Callable[[Mapping[Any, Any], Any, str, int], Any]


@dataclass(frozen=True)
class AdaptiveCase:
    """One timed IAS15 case: an engine integrating a system of N bodies from t = 0 to ``t_end``."""

    group: str
    engine: str
    system: str
    n: int
    t_end: float
    first_dt: float
    softening: float
    epsilon: float
    threads: int | None
    seed: int
    repeats: int
    warmup: int
    integrator: str = "ias15"

    @property
    def case_id(self) -> str:
        """A stable, readable identifier, e.g. ``ias15/orbitsim/ias15/plummer/n1000/t2``."""
        tail = f"/t{self.threads}" if self.engine == "orbitsim" and self.threads else ""
        return f"{self.group}/{self.engine}/{self.integrator}/{self.system}/n{self.n}{tail}"


def read_adaptive(r: Reader, g: Mapping[str, Any], path: str) -> dict[str, Any]:
    """The params of an ``adaptive`` group; per-N values as ``{N: value}`` for every N."""
    ns = distinct_ns(r, g, path)
    positive, non_negative = per_n_number(r), per_n_number(r, allow_zero=True)
    return {
        "engines": tuple(r.strings(g, "engines", path, list(_ENGINES), choices=_ENGINES)),
        "n": ns,
        "system": per_n(r, g, "system", path, ns, "plummer", per_n_system(r)),
        "t_end": per_n(r, g, "t_end", path, ns, None, positive),
        "first_dt": per_n(r, g, "first_dt", path, ns, 0.01, positive),
        "softening": per_n(r, g, "softening", path, ns, 0.01, non_negative),
        "epsilon": r.number(g, "epsilon", path, 1e-9),
        "threads": tuple(r.integers(g, "threads", path, [0], minimum=0)),
        "seed": r.integer(g, "seed", path, 1, minimum=0),
    }


def distinct_ns(r: Reader, g: Mapping[str, Any], path: str) -> tuple[int, ...]:
    """The group's ``n``: one or more body counts, each at most once (values are keyed by N)."""
    ns = tuple(r.integers(g, "n", path, None, minimum=2))
    if len(set(ns)) != len(ns):
        raise r.error(f"{path}.n", f"expected each N once, got {list(ns)}")
    return ns


def per_n_number(r: Reader, *, allow_zero: bool = False) -> ReadOne:
    """A reader of one finite number > 0 (``allow_zero``: >= 0) for :func:`per_n`."""
    def read(m: Mapping[Any, Any], key: Any, where: str, _n: int) -> float:
        return r.number(m, key, where, 0.0, allow_zero=allow_zero)
    return read


def per_n(r: Reader, g: Mapping[str, Any], key: str, path: str, ns: tuple[int, ...], default: Any,
           read: ReadOne) -> dict[int, Any]:
    """``{N: value}`` for every N of the group, from one value for all or a mapping ``{N: value}``
    with one entry per N. Errors name ``path.key`` or, for an entry, ``path.key.N``."""
    where = f"{path}.{key}"
    value = g.get(key, default)
    if value is None:
        raise r.error(where, "is required: a value, or a mapping N: value with one entry per N")
    if not isinstance(value, Mapping):
        return {n: read({key: value}, key, path, n) for n in ns}
    for k in value:
        if k not in ns:
            raise r.error(f"{where}.{k}", f"not an N of this group (n: {list(ns)})")
    missing = [n for n in ns if n not in value]
    if missing:
        raise r.error(where, f"no value for N = {missing[0]}")
    return {n: read(value, n, where, n) for n in ns}


def per_n_system(r: Reader) -> ReadOne:
    """A generated system, or a bundled or file scenario of exactly N bodies."""
    def read(m: Mapping[Any, Any], key: Any, path: str, n: int) -> str:
        name, where = m[key], f"{path}.{key}"
        if not isinstance(name, str) or not name.strip():
            raise r.error(where, f"expected a system name, got {name!r}")
        name = name.strip()
        if name in GENERATED_SYSTEMS:
            return name
        try:
            from orbitsim.bench.systems import scenario_size  # noqa: PLC0415 -- lazy: loads numpy

            size = scenario_size(name)
        except Exception as err:  # any failure to load it is a matrix error at this key
            raise r.error(where, f"not {' or '.join(GENERATED_SYSTEMS)}, and not a loadable scenario: "
                          f"{err}") from None
        if size != n:
            raise r.error(where, f"the scenario has {size} bodies, not N = {n}")
        return name
    return read


def expand_adaptive(group: Group) -> list[AdaptiveCase]:
    """The cases of one ``adaptive`` group: for each N, orbitsim at each thread count, then REBOUND
    (one thread: its direct summation is serial)."""
    p = group.params
    runs: list[tuple[str, int | None]] = []
    if "orbitsim" in p["engines"]:
        runs += [("orbitsim", t or None) for t in p["threads"]]  # 0: the run's default thread count
    if "rebound" in p["engines"]:
        runs.append(("rebound", 1))
    return [AdaptiveCase(group=group.name, engine=engine, system=p["system"][n], n=n, t_end=p["t_end"][n],
                         first_dt=p["first_dt"][n], softening=p["softening"][n], epsilon=p["epsilon"],
                         threads=threads, seed=p["seed"], repeats=group.repeats, warmup=group.warmup)
            for n in p["n"] for engine, threads in runs]
