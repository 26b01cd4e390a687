"""Run a sweep on Dask: skip what is done, submit the rest, collect results, write the summary.

Reliability comes from Dask and from content addressing, not from bookkeeping of our own:

* Each run writes ``OUTDIR/runs/<run-id>.h5`` atomically (``.tmp`` then rename), and the run id
  hashes the fully resolved scenario. A trace that exists, says ``status = complete`` and carries
  the case's ``scenario_sha256`` *is* that case's result, so a rerun skips it (resume).
* A worker that dies mid-run loses only its running tasks; the scheduler resubmits them to other
  workers (``distributed.scheduler.allowed-failures`` times) and the stale ``.tmp`` is overwritten.
* A run that fails is a ``failed`` row (see :mod:`orbitsim.batch.task`); the sweep goes on.
* Rows are placed by case index, never by completion order, and every number in a row is read
  from the trace, so the summary does not depend on how many workers ran it or in which order.
* Ctrl-C, or SIGTERM (what ``timeout`` and Slurm send), stops the sweep: what is queued is cancelled,
  the cluster is shut down (a second signal does not break that: :mod:`orbitsim.batch.signals`), and
  only then is the summary written, reading back from disk every case that has no row yet, so a run
  that completed during the shutdown is ``complete``, not ``not run``. The lock and ``.tmp`` files of
  the runs the shutdown killed are removed (their holders are gone), and so are any a killed sweep
  left for a rerun to find (:func:`clear_abandoned`).
* With ``skip_invalid`` a sweep's invalid cases are ``invalid`` rows (no run id, no trace) and the
  valid ones run.
"""

from __future__ import annotations

import csv
import signal
import time
from collections import Counter
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from orbitsim._version import __version__
from orbitsim.batch.cluster import ClusterError, open_client, plan_local
from orbitsim.batch.signals import interrupt_once
from orbitsim.batch.summary import write_csv, write_h5
from orbitsim.batch.sweep import Case, InvalidCase, Sweep
from orbitsim.batch.task import failed_result, run_case, trace_result, warm_up

__all__ = ["TASK_RETRIES", "SweepInterrupted", "SweepOutcome", "clear_abandoned", "completed_result", "run_sweep",
           "trace_path_for"]

#: Extra attempts Dask makes when the task function itself raises (e.g. a worker that cannot
#: import orbitsim). Run failures never raise (they are returned as rows), and a *killed* worker's
#: tasks are rescheduled by the scheduler independently of this number.
TASK_RETRIES = 1

#: How often the driver looks for finished runs (a run takes seconds to hours), and how long one
#: result fetch may take before the run is treated as still pending (its holder died mid-fetch).
POLL_S = 0.1
RESULT_WAIT_S = 60.0

#: Called after each finished run with (runs finished so far, runs submitted, the new row).
Progress = Callable[[int, int, dict[str, Any]], None]


@dataclass
class SweepOutcome:
    """What a sweep produced: the rows in case order and where the summaries are."""

    sweep: Sweep
    outdir: Path
    rows: list[dict[str, Any]]
    resumed: int = 0
    interrupted: bool = False
    files: list[Path] = field(default_factory=list)
    signum: int = signal.SIGINT  # the signal that interrupted it

    @property
    def counts(self) -> Counter[str]:
        """Number of rows per status."""
        return Counter(row["status"] for row in self.rows)


class SweepInterrupted(KeyboardInterrupt):
    """Ctrl-C or SIGTERM stopped the sweep; ``outcome`` is what was written (its rows say what finished)."""

    def __init__(self, outcome: SweepOutcome) -> None:
        super().__init__("the sweep was interrupted")
        self.outcome = outcome


def clear_abandoned(outdir: Path, cases: list[Case]) -> int:
    """Remove the lock files, and the ``.tmp`` beside them, that runs of ``cases`` left when they
    were killed; returns how many. A lock whose holder is alive (its ``flock`` is held, as by a run
    still going on another worker) is left alone (:func:`orbitsim.io.lock.clear_abandoned_lock`).

    Without this, a case whose run completed but was killed before it removed its lock, or whose
    trace a rerun reuses, kept the stale lock for good.
    """
    from orbitsim.io.lock import clear_abandoned_lock  # noqa: PLC0415 -- lazy: loads numpy

    return sum(clear_abandoned_lock(trace_path_for(outdir, case)) for case in cases)


def trace_path_for(outdir: Path, case: Case) -> Path:
    """``OUTDIR/runs/<run-id>.h5``."""
    return outdir / "runs" / f"{case.run_id}.h5"


def completed_result(path: Path, case: Case) -> dict[str, Any] | None:
    """The result of ``case`` read from its trace, if the trace is complete and matches its scenario."""
    from orbitsim.io.trace import TraceError  # noqa: PLC0415 -- lazy: loads h5py

    if not path.is_file():
        return None
    try:
        return trace_result(path, require_sha256=case.sha256)
    except TraceError:
        return None  # unreadable or foreign: run it again, replacing the file


def _previous_workers(outdir: Path) -> dict[str, str]:
    """run id -> worker from an earlier summary, so resumed rows still say who ran them."""
    try:
        with open(outdir / "summary.csv", newline="", encoding="utf-8") as fh:
            return {row["run_id"]: row.get("worker", "") for row in csv.DictReader(fh)}
    except (OSError, KeyError, csv.Error):
        return {}


def _row(case: Case, outdir: Path, result: dict[str, Any], resumed: bool) -> dict[str, Any]:
    row = {"case": case.index, "run_id": case.run_id, "params": case.params}
    row.update(result)
    row["resumed"] = resumed
    row["trace"] = trace_path_for(outdir, case).relative_to(outdir).as_posix()
    if row["status"] in ("failed", "not run") and not (outdir / row["trace"]).is_file():
        row["trace"] = ""
    return row


def _invalid_row(case: InvalidCase) -> dict[str, Any]:
    """An invalid case's row: it has no resolved scenario, hence no run id and no trace."""
    result = failed_result(case.message)
    result["status"] = "invalid"
    return {"case": case.index, "run_id": "", "params": case.params, **result, "resumed": False, "trace": ""}


def run_sweep(
    sweep: Sweep,
    outdir: str | Path,
    *,
    client: Any = None,
    scheduler: str | None = None,
    workers: int | None = None,
    threads: int | None = None,
    resume: bool = True,
    progress: Progress | None = None,
    on_start: Callable[[int, int, str], None] | None = None,
) -> SweepOutcome:
    """Run every case of ``sweep`` not already done and write ``summary.csv`` and ``summary.h5``.

    Parameters
    ----------
    sweep : Sweep
        A validated sweep (:func:`orbitsim.batch.sweep.load_sweep`).
    outdir : path
        Output directory; created if needed. Must be visible to the workers at the same path.
    client : distributed.Client, optional
        Use this client (and its cluster) as is; otherwise one is opened from ``scheduler``.
    scheduler : str, optional
        Address of an existing Dask scheduler; default: an embedded ``LocalCluster``.
    workers, threads : int, optional
        Local cluster size and Numba threads per worker (:func:`orbitsim.batch.cluster.plan_local`).
        With an existing cluster ``threads`` is passed to each run, ``workers`` is ignored.
    resume : bool
        Reuse every trace that is complete and matches its case's scenario hash (default).
    progress : callable, optional
        Called after each finished run.
    on_start : callable, optional
        Called once with (runs to submit, runs reused, description of the cluster).

    Returns
    -------
    SweepOutcome
        Rows in case order, the sweep's invalid cases (:attr:`Sweep.invalid`) included.

    Raises
    ------
    SweepInterrupted
        On Ctrl-C or SIGTERM (``outcome.signum`` says which), after the cluster is shut down and
        the summary is written: every run that finished (during the shutdown too) is in it, the
        others are ``not run``. A lost cluster writes the same summary and its error goes on.
    orbitsim.batch.cluster.ClusterError
        When the cluster cannot be started or reached, or a worker lacks this orbitsim; nothing
        has been written then.
    """
    outdir = Path(outdir).resolve()
    clear_abandoned(outdir, sweep.cases)  # what a killed sweep left: its runs' processes are gone
    rows: dict[int, dict[str, Any]] = {case.index: _invalid_row(case) for case in sweep.invalid}
    pending: list[Case] = []
    earlier = _previous_workers(outdir) if resume else {}
    for case in sweep.cases:
        done = completed_result(trace_path_for(outdir, case), case) if resume else None
        if done is None:
            pending.append(case)
        else:
            rows[case.index] = _row(case, outdir, {**done, "worker": earlier.get(case.run_id, "")}, True)
    outcome = SweepOutcome(sweep, outdir, [], resumed=len(sweep.cases) - len(pending))
    before = {case.index: _identity(trace_path_for(outdir, case)) for case in pending}
    with interrupt_once():
        try:
            if pending:
                _run_pending(pending, outdir, rows, client, scheduler, workers, threads, progress, on_start)
            elif on_start is not None:
                on_start(0, outcome.resumed, "nothing to run")
        except ClusterError:
            raise  # raised before anything was submitted: there is nothing to summarise
        except BaseException as exc:  # a signal, or the cluster went away: keep a summary of what finished
            outcome.interrupted = isinstance(exc, KeyboardInterrupt)
            outcome.signum = getattr(exc, "signum", signal.SIGINT)
            clear_abandoned(outdir, pending)  # the cluster is closed: the runs it killed left their locks
            _finish(outcome, rows, [c for c in pending if _identity(trace_path_for(outdir, c)) != before[c.index]])
            if outcome.interrupted:
                raise SweepInterrupted(outcome) from None
            raise
        _finish(outcome, rows)
    return outcome


def _identity(path: Path) -> tuple[int, int] | None:
    """Inode and mtime of a file: a trace renamed into place by a run gets a new one."""
    try:
        stat = path.stat()
    except OSError:
        return None
    return stat.st_ino, stat.st_mtime_ns


def _finish(outcome: SweepOutcome, rows: dict[int, dict[str, Any]], unsure: list[Case] | None = None) -> None:
    """Order the rows by case and write the summaries.

    ``unsure`` are the submitted cases whose trace file changed while the sweep ran, when it stopped
    early: the cluster is shut down by now, so each of those traces is final, and a run that
    completed after the last result came back (during the shutdown) is read from its trace rather
    than called ``not run``. (A trace that did not change is an earlier sweep's, which
    ``--no-resume`` was asked to redo.)
    """
    outdir = outcome.outdir
    for case in unsure or ():
        done = None if case.index in rows else completed_result(trace_path_for(outdir, case), case)
        if done is not None:
            rows[case.index] = _row(case, outdir, {**done, "worker": ""}, False)
    not_run = {c.index: _row(c, outdir, _not_run(), False) for c in outcome.sweep.cases if c.index not in rows}
    outcome.rows = [row for _, row in sorted({**rows, **not_run}.items())]
    outdir.mkdir(parents=True, exist_ok=True)
    outcome.files = _write_summaries(outcome)


def _not_run() -> dict[str, Any]:
    result = failed_result("the sweep stopped before this run finished")
    result["status"] = "not run"
    return result


def _run_pending(
    pending: list[Case],
    outdir: Path,
    rows: dict[int, dict[str, Any]],
    client: Any,
    scheduler: str | None,
    workers: int | None,
    threads: int | None,
    progress: Progress | None,
    on_start: Callable[[int, int, str], None] | None,
) -> None:
    if client is not None:
        _collect(client, pending, outdir, rows, threads, progress, on_start, "the given Dask client")
        return
    if scheduler is None:
        plan = plan_local(workers, threads, n_runs=len(pending))
        label = f"local Dask cluster: {plan.workers} worker(s) x {plan.threads} Numba thread(s)"
        task_threads = None  # the workers' NUMBA_NUM_THREADS already says it
    else:
        plan, label, task_threads = None, f"Dask scheduler {scheduler}", threads
    with open_client(scheduler, plan) as opened:
        _collect(opened, pending, outdir, rows, task_threads, progress, on_start, label)


def _collect(
    client: Any,
    pending: list[Case],
    outdir: Path,
    rows: dict[int, dict[str, Any]],
    threads: int | None,
    progress: Progress | None,
    on_start: Callable[[int, int, str], None] | None,
    label: str,
) -> None:
    """Submit ``pending`` in case order and file each result under its case as it arrives."""
    _check_workers(client)
    (outdir / "runs").mkdir(parents=True, exist_ok=True)
    if on_start is not None:
        on_start(len(pending), len(rows), label)
    futures = {}
    for case in pending:
        future = client.submit(
            run_case, case.scenario, str(trace_path_for(outdir, case)), threads,
            key=f"orbitsim-run-{case.run_id}", pure=False, retries=TASK_RETRIES,
        )
        futures[future] = case
    finished = 0
    try:
        for future, result in _results(futures):
            case = futures[future]
            rows[case.index] = _row(case, outdir, result, False)
            finished += 1
            if progress is not None:
                progress(finished, len(pending), rows[case.index])
    finally:
        if finished < len(futures):  # Ctrl-C or an error in here: stop what is still queued
            client.cancel(list(futures))


def _results(futures: dict[Any, Case]) -> Iterator[tuple[Any, dict[str, Any]]]:
    """Each future with its result (or its failure as a row), in the order they finish.

    Polls ``Future.done()`` rather than using ``distributed.as_completed``: when a worker dies
    holding a result that was already computed, the scheduler recomputes it elsewhere, but
    ``as_completed`` (distributed 2026.8) keeps waiting on the lost attempt and never yields it,
    so a sweep hung forever after a worker was killed (reproduced under load). A fetch that
    finds the result gone again within ``RESULT_WAIT_S`` goes back to the pending set.
    """
    from distributed import TimeoutError as DaskTimeout  # noqa: PLC0415 -- lazy: loads yaml, numpy, distributed

    pending = dict.fromkeys(futures)
    while pending:
        done = [future for future in pending if future.done()]
        if not done:
            time.sleep(POLL_S)
            continue
        for future in done:
            try:
                result = future.result(timeout=RESULT_WAIT_S)
            except (DaskTimeout, TimeoutError):
                continue  # lost again while fetching: wait for the recomputation
            except Exception as err:  # e.g. KilledWorker after too many worker deaths: a failed row
                result = failed_result(err)
            del pending[future]
            yield future, result


def _check_workers(client: Any) -> None:
    """Warm every worker up and refuse workers whose orbitsim is missing or of another version.

    A mismatch would make some runs differ from others, or fail every run on one worker.
    """
    answers = client.run(warm_up, on_error="return")
    for worker, answer in sorted(answers.items()):
        if isinstance(answer, BaseException):
            raise ClusterError(f"worker {worker} cannot import orbitsim: {type(answer).__name__}: {answer}")
        if answer != __version__:
            raise ClusterError(f"worker {worker} runs orbitsim {answer}, this is {__version__}; "
                               "install the same version on every worker")


def _write_summaries(outcome: SweepOutcome) -> list[Path]:
    attrs = {"sweep_name": outcome.sweep.name, "sweep_file": outcome.sweep.file,
             "sweep_yaml": outcome.sweep.text, "orbitsim_version": __version__,
             "runs": len(outcome.rows), "interrupted": outcome.interrupted}
    params = outcome.sweep.params
    return [write_csv(outcome.outdir / "summary.csv", outcome.rows, params),
            write_h5(outcome.outdir / "summary.h5", outcome.rows, params, attrs)]

