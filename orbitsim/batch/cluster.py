"""Where a sweep runs: an embedded ``dask.distributed.LocalCluster`` or an existing Dask cluster.

The local cluster uses worker *processes* with one Dask thread each: a run holds the GIL only
between jitted calls, but several runs in one process would share one Numba thread pool, and
processes also isolate a crashing run. Each worker gets ``NUMBA_NUM_THREADS`` through the nanny's
``env`` (applied in the worker process before it imports anything), chosen so that
workers x Numba threads <= cores: oversubscribing the cores would only slow every run down.

The local cluster's processes ignore SIGINT and SIGTERM. A terminal's Ctrl-C goes to every
process of its foreground group, workers included, as Slurm's SIGTERM goes to every process of a
job, and a worker that took it died (with a traceback of its own: 68 lines for two workers) and
took its run down, leaving that run's lock file, while answering the signal is the driver's job:
stop, keep what finished, say so in one line (:mod:`orbitsim.batch.driver`). The driver closes the
workers instead (Dask asks each to stop, and kills one that does not within seconds).

For an existing cluster (``--scheduler tcp://HOST:PORT``) the workers' own settings apply; see
docs/batch.md for how to start ``dask worker`` with a matching ``NUMBA_NUM_THREADS``.
"""

from __future__ import annotations

import contextlib
import logging
import os
import signal
import threading
import warnings
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

__all__ = ["CONNECT_TIMEOUT_S", "WORKER_WAIT_S", "ClusterPlan", "available_cores", "open_client", "plan_local"]

#: Seconds to reach an existing scheduler before giving up with a clear error.
CONNECT_TIMEOUT_S = 20.0
#: Seconds to wait for the first worker: without one, the sweep would wait forever.
WORKER_WAIT_S = 120.0


class ClusterError(RuntimeError):
    """The Dask cluster could not be started or reached."""


@dataclass(frozen=True)
class ClusterPlan:
    """Shape of an embedded local cluster: ``workers`` processes with ``threads`` Numba threads each."""

    workers: int
    threads: int


def available_cores() -> int:
    """Cores this process may use (the affinity mask where the OS has one)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # macOS and Windows have no affinity mask
        return max(1, os.cpu_count() or 1)


def plan_local(
    workers: int | None = None, threads: int | None = None, n_runs: int | None = None, cores: int | None = None
) -> ClusterPlan:
    """Size a local cluster: by default one worker per core, capped by the number of runs.

    Numba threads per worker default to ``cores // workers`` (at least 1), so that
    workers x threads <= cores; a worker per core with one thread each is what a sweep of many
    small runs wants, while a sweep of a few large runs may ask for fewer workers and more threads.
    """
    cores = cores or available_cores()
    if workers is not None and workers < 1:
        raise ValueError(f"--workers must be >= 1, got {workers}")
    if threads is not None and threads < 1:
        raise ValueError(f"--threads must be >= 1, got {threads}")
    n = workers or cores
    if workers is None and n_runs is not None:
        n = max(1, min(n, n_runs))  # no point starting a worker that would sit idle
    return ClusterPlan(workers=n, threads=threads or max(1, cores // n))


#: The signals the cluster's processes ignore: the driver answers them (see the module docstring).
IGNORED_SIGNALS = (signal.SIGINT, signal.SIGTERM)


def dask_setup(worker: Any = None) -> None:
    """Worker preload: ignore SIGINT and SIGTERM (see the module docstring).

    Workers started with the cluster inherit ignored signals already (:func:`_signals_ignored`);
    this covers a worker the nanny restarts later (after one died), which is spawned while the
    driver answers a signal again. Dask calls it on the worker's event-loop thread, the process's
    main thread, the only one that may set a signal handler.
    """
    if threading.current_thread() is threading.main_thread():
        for signum in IGNORED_SIGNALS:
            signal.signal(signum, signal.SIG_IGN)


@contextlib.contextmanager
def _signals_ignored() -> Iterator[None]:
    """Ignore SIGINT and SIGTERM in this process while the cluster's processes are spawned.

    A child inherits an ignored signal across ``exec`` (a handler, by contrast, is reset to the
    default), and CPython installs its KeyboardInterrupt handler only where SIGINT is at its
    default, so the workers spawned now ignore both for their whole life (checked in
    /proc/<pid>/status, SigIgn). The cost: a signal during the seconds the cluster takes to start
    is lost (nothing has been submitted yet; Slurm follows its SIGTERM with SIGKILL). Blocking
    them instead would keep them pending, but the kernel then hands them to another thread
    (OpenBLAS's), where the ignored disposition drops them all the same.
    """
    if threading.current_thread() is not threading.main_thread():
        yield  # only the main thread may change handlers; the workers then keep Dask's default
        return
    previous = {signum: signal.signal(signum, signal.SIG_IGN) for signum in IGNORED_SIGNALS}
    try:
        yield
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)


def _local_cluster(plan: ClusterPlan) -> Any:
    from distributed import LocalCluster  # noqa: PLC0415 -- lazy: loads yaml, numpy, distributed

    return LocalCluster(
        n_workers=plan.workers,
        threads_per_worker=1,
        processes=True,
        host="127.0.0.1",
        # No dashboard is wanted, but the scheduler serves HTTP anyway (health checks): a random
        # port keeps it from fighting over 8787 with other clusters on the machine.
        dashboard_address=":0",
        # Dask's own log lines would break the one-line error contract on stderr. A worker that
        # cannot reach a scheduler shutting down (after Ctrl-C, while it is busy compiling)
        # logs at ERROR a traceback that means nothing to the user; a failed run is reported
        # through its summary row, and a lost worker through the error the driver raises.
        silence_logs=logging.CRITICAL,
        env={"NUMBA_NUM_THREADS": str(plan.threads)},
        preload=[__name__],  # dask_setup: a restarted worker ignores Ctrl-C and SIGTERM too
    )


@contextlib.contextmanager
def open_client(scheduler: str | None, plan: ClusterPlan | None = None) -> Iterator[Any]:
    """A ``distributed.Client`` for the sweep, closed (with any cluster it started) on exit.

    Parameters
    ----------
    scheduler : str or None
        Address of an existing scheduler (``tcp://HOST:PORT``); None starts a local cluster.
    plan : ClusterPlan, optional
        Shape of the local cluster (ignored with ``scheduler``); default :func:`plan_local`.

    Raises
    ------
    ClusterError
        If the scheduler cannot be reached or no worker joins within :data:`WORKER_WAIT_S`.
    """
    from distributed import Client  # noqa: PLC0415 -- lazy: loads yaml, numpy, distributed

    # A client closed by a Ctrl-C drops its pending futures, and tornado's coroutines for them are never
    # awaited: Python then warns about each at exit ("coroutine 'Future._result' was never awaited", three
    # lines after the one-line message; seen once in a loaded suite). orbitsim awaits nothing itself.
    warnings.filterwarnings("ignore", message=r"coroutine '.*' was never awaited", category=RuntimeWarning)
    cluster = None
    try:
        if scheduler is None:
            with _signals_ignored():
                cluster = _local_cluster(plan or plan_local())
            client = Client(cluster)
        else:
            client = Client(scheduler, timeout=f"{CONNECT_TIMEOUT_S}s")
    except (OSError, TimeoutError) as err:
        if cluster is not None:
            cluster.close()
        target = scheduler or "a local Dask cluster"
        raise ClusterError(f"cannot reach {target}: {' '.join(str(err).split())}") from None
    try:
        try:
            client.wait_for_workers(1, timeout=WORKER_WAIT_S)
        except TimeoutError:
            raise ClusterError(f"no Dask worker joined {scheduler} within {WORKER_WAIT_S:.0f} s") from None
        yield client
    finally:
        try:
            client.close()
        finally:  # even when a Ctrl-C broke the line above: an open cluster would linger until exit
            if cluster is not None:
                cluster.close()
