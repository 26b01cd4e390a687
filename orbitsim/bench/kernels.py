"""The force kernels on their own, to place the thresholds in :mod:`orbitsim.physics.gravity`.

For each N this times, interleaved, one force evaluation by

* ``all_pairs``: the small-N loop over all ordered pairs (up to :data:`ALL_PAIRS_MAX_N`);
* ``rows``: the third-law rows in one block, on one thread (what N < ``PARALLEL_MIN_N`` uses);
* ``blocked``: the third-law rows in ``MAX_BLOCKS`` blocks on all threads (what larger N use),

and reports pair interactions per second (N(N-1) per evaluation). The crossovers it finds are
the measured justification of ``SMALL_N_MAX`` and ``PARALLEL_MIN_N``.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numba
import numpy as np

from orbitsim._jit import jit, set_num_threads
from orbitsim.bench.matrix import Group
from orbitsim.bench.stats import summarise
from orbitsim.bench.systems import build_system
from orbitsim.physics import gravity

__all__ = ["ALL_PAIRS_MAX_N", "run_kernels"]

#: The all-pairs loop costs twice the arithmetic; beyond this N it is not worth timing.
ALL_PAIRS_MAX_N = 256


def _bounds(n: int, blocks: int) -> np.ndarray:
    """Row boundaries splitting the pairs into ``blocks`` nearly equal shares (as block_bounds)."""
    total = n * (n - 1) / 2.0
    rows = np.arange(n + 1, dtype=np.float64)
    cumulative = rows * n - rows * (rows + 1) / 2.0  # pairs in rows [0, i)
    bounds = np.searchsorted(cumulative, total * np.arange(blocks + 1) / blocks).astype(np.int64)
    bounds[0], bounds[-1] = 0, n
    return np.maximum.accumulate(bounds)


@jit
def _repeat_serial(kernel, reps, pos, m, eps2, acc):
    """``reps`` evaluations of a serial kernel in one jitted loop: at small N a Python-level call
    costs more than the evaluation. ``kernel`` 0 is the all-pairs loop, 1 the third-law rows."""
    n = pos.shape[1]
    for _ in range(reps):
        if kernel == 0:
            gravity.all_pairs_accelerations(pos, m, 1.0, eps2, acc)
        else:
            acc[:, :] = 0.0
            gravity._accumulate_rows(pos[0], pos[1], pos[2], m, eps2, np.int64(0), n, acc[0], acc[1], acc[2])


def _evaluators(n: int, threads: int) -> dict[str, Callable[[int], None]]:
    s = build_system("plummer", n)
    pos = np.ascontiguousarray(s.positions.T)
    m, acc, eps2 = s.masses, np.zeros((3, n)), 1e-4
    bounds = _bounds(n, gravity.MAX_BLOCKS)
    slabs = np.zeros((gravity.MAX_BLOCKS, 3, n))

    def blocked(reps: int) -> None:
        set_num_threads(threads)
        for _ in range(reps):
            gravity.accelerations_parallel(pos, m, 1.0, eps2, acc, slabs, bounds)

    out: dict[str, Callable[[int], None]] = {"rows": lambda reps: _repeat_serial(1, reps, pos, m, eps2, acc),
                                             "blocked": blocked}
    if n <= ALL_PAIRS_MAX_N:
        out["all_pairs"] = lambda reps: _repeat_serial(0, reps, pos, m, eps2, acc)
    return out


def _time(fn: Callable[[int], None], reps: int) -> float:
    start = time.perf_counter()
    fn(reps)
    return (time.perf_counter() - start) / reps


def run_kernels(group: Group) -> dict[str, Any]:
    """Pairs/s of each kernel at each N (interleaved repeats) and the crossovers found."""
    p = group.params
    threads = int(p["threads"] or numba.get_num_threads())
    rows: list[dict[str, Any]] = []
    for n in p["n"]:
        fns = _evaluators(n, threads)
        reps = max(1, int(p["work"] // (n * (n - 1))))
        for fn in fns.values():
            fn(1)
        times: dict[str, list[float]] = {k: [] for k in fns}
        for _ in range(group.repeats):
            for key, fn in fns.items():
                times[key].append(_time(fn, reps))
        rates = {k: n * (n - 1) / summarise(v)["median"] for k, v in times.items()}
        rows.append({"n": n, "evaluations": reps, "pairs_per_s": rates,
                     "time_s": {k: summarise(v) for k, v in times.items()}})
    numba.set_num_threads(threads)
    return {"threads": threads, "rows": rows, "small_n_max": gravity.SMALL_N_MAX,
            "parallel_min_n": gravity.PARALLEL_MIN_N,
            "all_pairs_until": _last_win(rows, "all_pairs", "rows"),
            "blocked_from": _first_win(rows, "blocked", "rows")}


def _last_win(rows: list[dict[str, Any]], a: str, b: str) -> int | None:
    """Largest N at which kernel ``a`` is still faster than ``b``."""
    won = [r["n"] for r in rows if a in r["pairs_per_s"] and r["pairs_per_s"][a] > r["pairs_per_s"][b]]
    return max(won) if won else None


def _first_win(rows: list[dict[str, Any]], a: str, b: str) -> int | None:
    """Smallest N from which kernel ``a`` is faster than ``b`` at every larger N measured."""
    first = None
    for r in sorted(rows, key=lambda r: -r["n"]):
        if r["pairs_per_s"][a] > r["pairs_per_s"][b]:
            first = r["n"]
        else:
            break
    return first
