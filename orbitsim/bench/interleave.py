"""Engines timed side by side: the cases of one N built and warmed up, then timed round by round.

Every kind that compares engines (``steps``, ``adaptive``, ``trace``) measures the same way. The
machine is shared and its load drifts, so the cases of one N are timed *interleaved*: repeat 1 of
each case, then repeat 2, and so on; each engine sees the same conditions, and a ratio taken
within a round is honest even when the absolute times are not. An engine here is any object with
``first_call() -> seconds`` (the first call, with JIT compilation or cache loading) and
``once() -> a timed repeat``.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterable
from typing import Any

__all__ = ["by_n", "prepare", "rounds", "select_cases"]

#: (case, engine, seconds of its first call), as :func:`prepare` hands them to :func:`rounds`.
Ready = tuple[Any, Any, float]


def select_cases(cases: list[Any], threads: tuple[int, int],
                 key: Callable[[Any], str] = lambda c: c.case_id) -> tuple[list[Any], list[dict]]:
    """The cases to time, orbitsim's with the default thread count filled in, and the skipped ones
    with their reason: more threads than Numba has, or the same case as another once filled in
    (threads [1, 0] when the default is 1 thread). ``threads`` is (default, Numba's maximum)."""
    usable: list[Any] = []
    skipped: list[dict] = []
    seen: set[str] = set()
    default, max_threads = threads
    for case in cases:
        if case.engine == "orbitsim" and case.threads is None:
            case = dataclasses.replace(case, threads=default)
        if case.threads is not None and case.threads > max_threads:
            skipped.append({"id": case.case_id, "reason": f"{case.threads} threads > NUMBA_NUM_THREADS={max_threads}"})
        elif key(case) in seen:
            skipped.append({"id": case.case_id, "reason": "same thread count as another case"})
        else:
            seen.add(key(case))
            usable.append(case)
    return usable, skipped


def prepare(cases: list[Any], threads: tuple[int, int], make: Callable[[Any, Any], Any], *,
            warmups: Callable[[Any], int] = lambda case: case.warmup,
            key: Callable[[Any], str] = lambda c: c.case_id) -> tuple[list[Ready], list[dict]]:
    """Build each usable case's engine on its system (built once per system), make its first call
    and its ``warmups(case)`` untimed repeats; returns (ready cases, skipped cases)."""
    from orbitsim.bench.systems import build_system  # noqa: PLC0415 -- lazy: loads numpy

    systems: dict[str, Any] = {}
    ready: list[Ready] = []
    usable, skipped = select_cases(cases, threads, key)
    for case in usable:
        if case.system not in systems:
            systems[case.system] = build_system(case.system, case.n, seed=case.seed)
        engine = make(case, systems[case.system])
        first = engine.first_call()
        for _ in range(warmups(case)):
            engine.once()
        ready.append((case, engine, first))
    return ready, skipped


def rounds(ready: list[Ready]) -> list[list[Any]]:
    """The timed repeats of every ready case, round by round: repeat r of each case, then r + 1."""
    times: list[list[Any]] = [[] for _ in ready]
    for r in range(max((case.repeats for case, _, _ in ready), default=0)):
        for k, (case, engine, _) in enumerate(ready):
            if r < case.repeats:
                times[k].append(engine.once())
    return times


def by_n(cases: list[Any], run_n: Callable[[list[Any]], tuple[list[dict], list[dict]]],
         ns: Iterable[int] | None = None) -> tuple[list[dict], list[dict]]:
    """``run_n`` on the cases of each N in turn (``ns``, else in the order the cases name them);
    the records and the skipped cases of all of them."""
    records: list[dict] = []
    skipped: list[dict] = []
    for n in dict.fromkeys(c.n for c in cases) if ns is None else ns:
        got, skip = run_n([c for c in cases if c.n == n])
        records += got
        skipped += skip
    return records, skipped
