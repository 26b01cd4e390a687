"""Benchmark matrices: load a YAML file, validate it, expand it into cases.

A matrix is a list of *groups*; each group has a ``kind`` that says what it measures::

    name: full                    # optional; default: the file's stem
    repeats: 5                    # timed repeats per case (median, min and max are reported)
    warmup: 1                     # untimed calls first (the first one compiles or loads the cache)
    threads: null                 # default Numba threads (null: NUMBA_NUM_THREADS or --threads)
    groups:
      - name: throughput
        kind: steps               # time whole steps through each engine's own stepping loop
        system: plummer           # plummer | planets | a bundled scenario name | a path
        engines: [orbitsim, rebound]
        integrators: [verlet]     # orbitsim registry names, or "all"
        rebound_integrators: [leapfrog]   # leapfrog, leapfrog:4, leapfrog:6, leapfrog:8, whfast, trace
        n: [256, 1024, 4096, 16384]
        rebound_n: [256, 1024, 4096]      # optional subset of n for REBOUND (it is slow at large N)
        threads: [1, 2]           # orbitsim only; REBOUND's basic gravity is serial
        work: 4.0e9               # pair interactions per timed repeat (steps derived from it) ...
        steps_by_n: {16384: 40}   # ... except at these N (orbitsim cases) ...
        # steps: [1000]           # ... or explicit step counts for every N (a list is another axis)
      - {name: crossover, kind: kernels, n: [16, 64, 256, 1024]}   # the bare force kernels
      - {name: startup, kind: startup, integrator: verlet}
      - {name: sampling, kind: sampling, n: 9, steps: 200000, every: 100}
      - {name: memory, kind: memory, n: 16384, steps: 3, trace_samples: 10000000}
      - name: ias15
        kind: adaptive            # IAS15 over one time span: orbitsim's ias15 beside REBOUND's
        system: {5: planets, 1000: plummer}   # plummer | planets | a scenario; one, or one per N
        n: [5, 1000]
        t_end: {5: 300.0, 1000: 0.05}         # the span from t = 0; one, or one per N
        first_dt: 0.01            # first trial step of both engines; one, or one per N
        softening: {5: 0.0, 1000: 0.01}       # one, or one per N
        epsilon: 1.0e-9           # IAS15's tolerance in both engines
        engines: [orbitsim, rebound]
        threads: [1, 0]           # orbitsim only
      - name: trace
        kind: trace               # TRACE over the same steps: orbitsim's trace beside REBOUND's
        system: {7: many_encounters, 103: planetesimals}   # a scenario, or a generated system
        n: [7, 103]
        t_end: {7: 2000.0, 103: 100.0}        # whole steps of dt while t < t_end, in both engines
        dt: 0.02                  # generated systems; a scenario brings its own dt and softening
        softening: 0.0
        engines: [orbitsim, rebound]

A value given "per N" is a mapping ``{N: value}`` with one entry for each N of ``n``. An
``adaptive`` group counts the accepted steps each engine took over the span: the time per step
is the time over the span divided by that count (a fixed-step ``steps`` group cannot measure an
adaptive scheme, so ``integrators: all`` there leaves it out and naming it is an error). A
``trace`` group takes the same whole steps in both engines, each repeat from the initial state,
and records whether the final states agree to the bit.

Every error is one line naming the file and the key, e.g.
``my_bench.yaml: groups[1].n[2]: expected an integer >= 1, got 'many'``.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from orbitsim.bench._adaptive_fields import ADAPTIVE_KEYS, AdaptiveCase, expand_adaptive, read_adaptive
from orbitsim.bench._fields import GENERATED_SYSTEMS, BenchMatrixError, Group, Reader
from orbitsim.bench._trace_fields import TRACE_KEYS, TraceCase, expand_trace, read_trace
from orbitsim.data import MATRICES, locate

__all__ = [
    "GENERATED_SYSTEMS",
    "KINDS",
    "REBOUND_INTEGRATORS",
    "AdaptiveCase",
    "BenchMatrix",
    "BenchMatrixError",
    "Group",
    "StepsCase",
    "TraceCase",
    "load_matrix",
    "matrix_from_dict",
]

#: What a group can measure (see :mod:`orbitsim.bench.runner` for how each is timed).
KINDS = ("steps", "kernels", "startup", "sampling", "memory", "adaptive", "trace", "ensemble")

#: REBOUND schemes and their force evaluations per step: leapfrog of order 2k composes
#: 1, 3, 9, 17 substeps (the tables in :mod:`orbitsim.integrators.leapfrog`); WHFast uses one.
REBOUND_INTEGRATORS: dict[str, int] = {
    "leapfrog": 1, "leapfrog:4": 3, "leapfrog:6": 9, "leapfrog:8": 17, "whfast": 1, "trace": 1,
}

_ENGINES = ("orbitsim", "rebound")
_TOP_KEYS = ("name", "description", "repeats", "warmup", "threads", "groups")
_GROUP_KEYS: dict[str, tuple[str, ...]] = {
    "steps": ("system", "engines", "integrators", "rebound_integrators", "n", "rebound_n",
              "threads", "steps", "steps_by_n", "work", "rebound_work", "min_steps", "max_steps", "dt",
              "softening", "seed"),
    "kernels": ("n", "threads", "work"),
    "startup": ("integrator", "n", "steps", "cold"),
    "sampling": ("system", "integrator", "n", "steps", "every", "dt", "seed"),
    "memory": ("n", "steps", "trace_n", "trace_samples", "trace_every", "limit_mb"),
    "adaptive": ADAPTIVE_KEYS,
    "trace": TRACE_KEYS,
    "ensemble": ("map_n", "years", "indicator", "k", "steps", "large_map_n"),
}
_COMMON_GROUP_KEYS = ("name", "kind", "repeats", "warmup", "description")


@dataclass(frozen=True)
class StepsCase:
    """One timed stepping case: an engine, a scheme, a system of N bodies, a step count."""

    group: str
    engine: str
    integrator: str
    system: str
    n: int
    steps: int
    threads: int | None
    force_evals: int
    dt: float
    softening: float
    seed: int
    repeats: int
    warmup: int

    @property
    def case_id(self) -> str:
        """A stable, readable identifier, e.g. ``throughput/orbitsim/verlet/plummer/n4096/t2``."""
        tail = f"/t{self.threads}" if self.engine == "orbitsim" and self.threads else ""
        return f"{self.group}/{self.engine}/{self.integrator}/{self.system}/n{self.n}{tail}"


@dataclass(frozen=True)
class BenchMatrix:
    """A validated benchmark matrix; :meth:`steps_cases` expands its ``steps`` groups."""

    name: str
    source: str
    repeats: int
    warmup: int
    threads: int | None
    groups: tuple[Group, ...]

    def steps_cases(self, orbitsim_names: Callable[[str], tuple[str, int]] | None = None) -> list[StepsCase]:
        """Every (engine, integrator, N, threads, steps) case of every ``steps`` group, in order.

        ``orbitsim_names`` maps an orbitsim integrator name to (canonical name, force evaluations
        per step); the default asks the registry.
        """
        lookup = orbitsim_names or _registry_lookup
        cases: list[StepsCase] = []
        for group in self.groups:
            if group.kind == "steps":
                cases.extend(_expand_steps(group, lookup))
        return cases

    def adaptive_cases(self) -> list[AdaptiveCase]:
        """Every (N, engine, threads) case of every ``adaptive`` group, in order (for each N the
        orbitsim cases, one per thread count, then REBOUND)."""
        return [case for group in self.groups if group.kind == "adaptive" for case in expand_adaptive(group)]

    def trace_cases(self) -> list[TraceCase]:
        """Every (N, engine) case of every ``trace`` group, in order (orbitsim, then REBOUND)."""
        return [case for group in self.groups if group.kind == "trace" for case in expand_trace(group)]

    def select(self, names: tuple[str, ...]) -> BenchMatrix:
        """The same matrix with only the groups named (in the matrix's order); raises
        :class:`BenchMatrixError` naming an unknown group and listing the valid ones."""
        known = [g.name for g in self.groups]
        for name in names:
            if name not in known:
                raise BenchMatrixError(self.source, "groups", f"no group named {name!r}; groups: {', '.join(known)}")
        return dataclasses.replace(self, groups=tuple(g for g in self.groups if g.name in names))


def load_matrix(path: str | Path) -> BenchMatrix:
    """Read and validate a matrix file, or the bundled matrix of that name (``"full"``, ``"quick"``).

    Raises :class:`BenchMatrixError` (one line) on any problem.
    """
    import yaml  # noqa: PLC0415 -- lazy: loads yaml

    try:
        found = locate(MATRICES, path)
    except LookupError as err:
        raise BenchMatrixError(str(path), "", str(err)) from None
    source = str(path) if found == Path(path) else str(found)
    try:
        text = found.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as err:
        raise BenchMatrixError(source, "", f"cannot read the file ({err.__class__.__name__}: {err})") from None
    try:
        doc = yaml.safe_load(text)
    except yaml.YAMLError as err:
        mark = getattr(err, "problem_mark", None)
        where = f" (line {mark.line + 1})" if mark is not None else ""
        raise BenchMatrixError(source, "", f"not valid YAML{where}") from None
    return matrix_from_dict(doc, source=source, default_name=found.stem)


def matrix_from_dict(doc: Any, *, source: str = "<inline>", default_name: str = "bench") -> BenchMatrix:
    """Validate a matrix given as a mapping (the parsed YAML document)."""
    r = Reader(source)
    top = r.mapping(doc, "", _TOP_KEYS)
    repeats = r.integer(top, "repeats", "", 5, minimum=1)
    warmup = r.integer(top, "warmup", "", 1, minimum=0)
    threads = r.optional_integer(top, "threads", "", minimum=1)
    name = top.get("name", default_name)
    if not isinstance(name, str) or not name.strip():
        raise r.error("name", f"expected a non-empty string, got {name!r}")
    groups_doc = top.get("groups")
    if not isinstance(groups_doc, list) or not groups_doc:
        raise r.error("groups", "expected a non-empty list of groups")
    groups = tuple(_read_group(r, item, f"groups[{k}]", repeats, warmup) for k, item in enumerate(groups_doc))
    seen: set[str] = set()
    for k, group in enumerate(groups):
        if group.name in seen:
            raise r.error(f"groups[{k}].name", f"duplicate group name {group.name!r}")
        seen.add(group.name)
    return BenchMatrix(name=name, source=source, repeats=repeats, warmup=warmup, threads=threads, groups=groups)


def _read_group(r: Reader, item: Any, path: str, repeats: int, warmup: int) -> Group:
    if not isinstance(item, Mapping):
        raise r.error(path, f"expected a mapping, got {type(item).__name__}")
    kind = item.get("kind", "steps")
    if kind not in KINDS:
        raise r.error(f"{path}.kind", f"unknown kind {kind!r}; valid: {', '.join(KINDS)}")
    g = r.mapping(item, path, _COMMON_GROUP_KEYS + _GROUP_KEYS[kind])
    name = g.get("name", f"{kind}_{path[len('groups['):-1]}")
    if not isinstance(name, str) or not name.replace("_", "").replace("-", "").isalnum():
        raise r.error(f"{path}.name", f"expected a plain name (letters, digits, _ -), got {name!r}")
    params = _READERS[kind](r, g, path)
    return Group(name=name, kind=kind, repeats=r.integer(g, "repeats", path, repeats, minimum=1),
                 warmup=r.integer(g, "warmup", path, warmup, minimum=0), params=params)


def _read_steps(r: Reader, g: Mapping[str, Any], path: str) -> dict[str, Any]:
    engines = tuple(r.strings(g, "engines", path, ["orbitsim", "rebound"], choices=_ENGINES))
    system, fixed = r.system(g, path, "plummer")
    p: dict[str, Any] = {
        "system": system,
        "engines": engines,
        "integrators": _fixed_step_names(r, g, path),
        "rebound_integrators": tuple(r.strings(g, "rebound_integrators", path, ["leapfrog"],
                                               choices=tuple(REBOUND_INTEGRATORS))),
        "n": tuple(r.sizes(g, "n", path, fixed)),
        "threads": tuple(r.integers(g, "threads", path, [0], minimum=0)),
        "dt": r.number(g, "dt", path, 1e-3),
        "softening": r.number(g, "softening", path, 0.01, allow_zero=True),
        "seed": r.integer(g, "seed", path, 1, minimum=0),
        "min_steps": r.integer(g, "min_steps", path, 2, minimum=1),
        "max_steps": r.integer(g, "max_steps", path, 10_000_000, minimum=1),
    }
    p["rebound_n"] = tuple(r.integers(g, "rebound_n", path, list(p["n"]), minimum=2))
    if "steps" in g and ("work" in g or "rebound_work" in g):
        raise r.error(f"{path}.steps", "give either steps or work/rebound_work, not both")
    p["steps"] = tuple(r.integers(g, "steps", path, [], minimum=1)) if "steps" in g else ()
    p["work"] = r.number(g, "work", path, 2e9)
    p["steps_by_n"] = r.steps_by_n(g, path)
    p["rebound_work"] = r.number(g, "rebound_work", path, p["work"] / 10.0)
    if p["max_steps"] < p["min_steps"]:
        raise r.error(f"{path}.max_steps", f"must be >= min_steps ({p['min_steps']})")
    return p


def _fixed_step_names(r: Reader, g: Mapping[str, Any], path: str) -> tuple[str, ...]:
    """The ``integrators`` of a steps group; an adaptive scheme is refused (see :func:`_orbitsim_names`)."""
    from orbitsim.integrators.registry import get_spec  # noqa: PLC0415 -- lazy: loads numba

    names = r.integrator_names(g, "integrators", path, ["verlet"])
    for k, name in enumerate(names):
        if name != "all" and get_spec(name).adaptive:
            raise r.error(f"{path}.integrators[{k}]", f"{name} is adaptive: a grid interval is not its step; "
                          "measure it in a group of kind: adaptive")
    return tuple(names)


def _read_kernels(r: Reader, g: Mapping[str, Any], path: str) -> dict[str, Any]:
    return {"n": tuple(r.integers(g, "n", path, None, minimum=2)),
            "threads": r.integer(g, "threads", path, 0, minimum=0),
            "work": r.number(g, "work", path, 5e7)}


def _read_startup(r: Reader, g: Mapping[str, Any], path: str) -> dict[str, Any]:
    return {"integrator": r.integrator_names(g, "integrator", path, ["verlet"], single=True)[0],
            "n": r.integer(g, "n", path, 2, minimum=2),
            "steps": r.integer(g, "steps", path, 1000, minimum=1),
            "cold": r.flag(g, "cold", path, True)}


def _read_sampling(r: Reader, g: Mapping[str, Any], path: str) -> dict[str, Any]:
    system, fixed = r.system(g, path, "planets")
    return {"system": system,
            "integrator": r.integrator_names(g, "integrator", path, ["verlet"], single=True)[0],
            "n": fixed or r.integer(g, "n", path, 9, minimum=2),
            "steps": r.integer(g, "steps", path, 200_000, minimum=1),
            "every": r.integer(g, "every", path, 100, minimum=1),
            "dt": r.number(g, "dt", path, 1e-3),
            "seed": r.integer(g, "seed", path, 1, minimum=0)}


def _read_memory(r: Reader, g: Mapping[str, Any], path: str) -> dict[str, Any]:
    return {"n": r.integer(g, "n", path, 16384, minimum=2),
            "steps": r.integer(g, "steps", path, 3, minimum=1),
            "trace_n": r.integer(g, "trace_n", path, 2, minimum=2),
            "trace_samples": r.integer(g, "trace_samples", path, 0, minimum=0),
            "trace_every": r.integer(g, "trace_every", path, 1, minimum=1),
            "limit_mb": r.number(g, "limit_mb", path, 300.0)}


def _read_ensemble(r: Reader, g: Mapping[str, Any], path: str) -> dict[str, Any]:
    return {"map_n": r.integer(g, "map_n", path, 20, minimum=2),
            "years": r.number(g, "years", path, 1e4),
            "indicator": g.get("indicator", "megno"),
            "k": r.integer(g, "k", path, 4096, minimum=1),
            "steps": r.integer(g, "steps", path, 2000, minimum=1),
            "large_map_n": r.integer(g, "large_map_n", path, 0, minimum=0)}


_READERS: dict[str, Callable[[Reader, Mapping[str, Any], str], dict[str, Any]]] = {
    "steps": _read_steps, "kernels": _read_kernels, "startup": _read_startup, "sampling": _read_sampling,
    "memory": _read_memory, "adaptive": read_adaptive, "trace": read_trace, "ensemble": _read_ensemble,
}


def _registry_lookup(name: str) -> tuple[str, int]:
    from orbitsim.integrators.registry import get_spec  # noqa: PLC0415 -- lazy: loads numba

    spec = get_spec(name)
    return spec.name, spec.force_evals


def _orbitsim_names(group: Group, lookup: Callable[[str], tuple[str, int]]) -> list[tuple[str, int]]:
    names = group.params["integrators"]
    if tuple(names) == ("all",):
        from orbitsim.integrators.registry import INTEGRATORS  # noqa: PLC0415 -- lazy: loads numba

        # An adaptive scheme (IAS15) takes as many steps of its own as each grid interval needs:
        # timing "dt steps" of it would report a grid interval as a step. The adaptive kind
        # counts its accepted steps instead.
        names = tuple(spec.name for spec in INTEGRATORS if not spec.adaptive)
    return [lookup(name) for name in names]


def steps_for(work: float, n: int, evals: int, min_steps: int, max_steps: int) -> int:
    """Steps that do about ``work`` pair interactions (N(N-1) per force evaluation), clamped."""
    pairs_per_step = max(1, evals * n * (n - 1))
    return int(min(max_steps, max(min_steps, math.ceil(work / pairs_per_step))))


def _expand_steps(group: Group, lookup: Callable[[str], tuple[str, int]]) -> list[StepsCase]:
    p = group.params
    cases: list[StepsCase] = []
    schemes: list[tuple[str, str, int, tuple[int, ...], tuple[int | None, ...], float]] = []
    if "orbitsim" in p["engines"]:
        threads = tuple(t or None for t in p["threads"])
        schemes += [("orbitsim", name, evals, p["n"], threads, p["work"])
                    for name, evals in _orbitsim_names(group, lookup)]
    if "rebound" in p["engines"]:
        schemes += [("rebound", name, REBOUND_INTEGRATORS[name], p["rebound_n"], (1,), p["rebound_work"])
                    for name in p["rebound_integrators"]]
    for n in sorted(set(p["n"]) | set(p["rebound_n"])):
        for engine, name, evals, ns, threads, work in schemes:
            if n not in ns:
                continue
            fixed = p["steps_by_n"].get(n) if engine == "orbitsim" else None
            counts = p["steps"] or (fixed or steps_for(work, n, evals, p["min_steps"], p["max_steps"]),)
            for t in threads:
                for steps in counts:
                    cases.append(StepsCase(
                        group=group.name, engine=engine, integrator=name, system=p["system"], n=n,
                        steps=steps, threads=t, force_evals=evals, dt=p["dt"], softening=p["softening"],
                        seed=p["seed"], repeats=group.repeats, warmup=group.warmup))
    return cases
