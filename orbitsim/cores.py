"""How many threads a run uses when none is asked for: the cores that other processes leave free.

A parallel force evaluation waits for its slowest thread (it is one fork-join region). With one
of two cores taken by another process, the thread that shares that core runs about half the time
and every evaluation waits for it: the default two threads made an N = 2,000 cluster 2.4x slower
than one thread. So a run given no thread count (``--threads`` absent, ``threads=None``) measures
how much of the cores it may run on (``os.sched_getaffinity``) other processes keep busy *now*,
over :data:`WINDOW_S` (``/proc/stat``, less this process's own CPU time), and takes one thread per
core left free, at least one and at most ``NUMBA_NUM_THREADS``. The load average is no use for
this: a minute's average, it still reads 0.15 ten seconds after a busy process started, and it
counts this process's own past work. Where ``/proc/stat`` cannot be read (not Linux) the
1-minute load average, less this process, stands in.

A thread count that is asked for always rules, and results never depend on the count (the
kernels are bit-identical on any number of threads): only the speed does. The choice and its
reason are kept with the run (the trace's ``threads`` and ``threads_choice``; ``orbitsim info``).
This module imports nothing heavy: it is plain arithmetic on ``/proc``.
"""

from __future__ import annotations

import math
import os
import time

__all__ = ["FREE_SHARE", "WINDOW_S", "busy_cores", "choose_threads", "usable_cores"]

#: Seconds over which the other processes' CPU use is measured: /proc/stat counts in ticks of
#: 10 ms, so each core gets 10 ticks, enough to tell a busy core (10) from an idle one (0-1).
WINDOW_S = 0.1
#: A core counts as free when other processes leave at least this share of it: with a core half
#: taken, the thread there would run half the time, and a fork-join kernel that waits for it at
#: every evaluation is no faster than one thread.
FREE_SHARE = 2.0 / 3.0
#: A measurement is reused for this long (seconds): a program that builds many simulations in a
#: row pays the window once, not per simulation.
REUSE_S = 10.0

_last: tuple[float, float] | None = None  # (monotonic time, busy cores) of the last measurement


def usable_cores() -> list[int]:
    """The CPUs this process may run on."""
    try:
        return sorted(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return list(range(os.cpu_count() or 1))


def _cpu_ticks(cpus: list[int]) -> tuple[int, int] | None:
    """(busy, total) ticks summed over ``cpus`` from /proc/stat, or None where it cannot be read."""
    wanted = {f"cpu{k}" for k in cpus}
    busy = total = 0
    try:
        with open("/proc/stat", encoding="ascii") as stat:
            for line in stat:
                fields = line.split()
                if fields and fields[0] in wanted:
                    # user nice system idle iowait irq softirq steal (guest time is inside user)
                    ticks = [int(v) for v in fields[1:9]]
                    total += sum(ticks)
                    busy += sum(ticks) - ticks[3] - ticks[4]
    except (OSError, ValueError, IndexError):
        return None
    return (busy, total) if total > 0 else None


def busy_cores(window_s: float = WINDOW_S) -> float:
    """How many of :func:`usable_cores` other processes keep busy now (0.0 on an idle machine).

    Measured over ``window_s`` while this thread sleeps; what this process itself used meanwhile
    (its other threads) is taken off. Reused for :data:`REUSE_S` seconds.
    """
    global _last
    now = time.monotonic()
    if _last is not None and now - _last[0] < REUSE_S:
        return _last[1]
    cpus = usable_cores()
    before, own_before, start = _cpu_ticks(cpus), time.process_time(), time.monotonic()
    if before is None:
        busy = _busy_from_load_average()
    else:
        time.sleep(window_s)
        after, own, wall = _cpu_ticks(cpus), time.process_time() - own_before, time.monotonic() - start
        if after is None or after[1] <= before[1]:
            busy = _busy_from_load_average()
        else:
            share = (after[0] - before[0]) / (after[1] - before[1])  # of all the usable cores' time
            busy = max(0.0, share * len(cpus) - own / wall)
    _last = (time.monotonic(), busy)
    return busy


def _busy_from_load_average() -> float:
    """Runnable processes beyond this one, averaged over a minute (lags; a stand-in only)."""
    try:
        return max(0.0, os.getloadavg()[0] - 1.0)
    except (AttributeError, OSError):
        return 0.0


def choose_threads(requested: int | None, limit: int, parallel: bool) -> tuple[int | None, str]:
    """The thread count for a run, and why (the text ``orbitsim info`` shows beside it).

    Parameters
    ----------
    requested : int or None
        The count asked for (``--threads``, ``threads=``): it rules.
    limit : int
        The most threads Numba can run (``NUMBA_NUM_THREADS``).
    parallel : bool
        Whether the run's kernels run in parallel at all (N >= 384); where they do not, nothing is
        measured and the count is left as it is (None).
    """
    if requested is not None:
        return requested, "as asked"
    if not parallel:
        return None, "default; below N = 384 the force kernel runs on one thread whatever the count"
    cores = len(usable_cores())
    busy = busy_cores()
    free = max(1, math.floor(cores - busy + (1.0 - FREE_SHARE)))
    threads = min(free, limit)
    cap = f", at most {limit} (NUMBA_NUM_THREADS)" if free > limit else ""
    return threads, f"default: {free} of {cores} cores free, {busy:.1f} busy with other processes{cap}"
