"""What a Dask worker runs for one case, and how a finished trace becomes a summary row.

:func:`run_case` is the only function shipped to workers. It runs the scenario through
:func:`orbitsim.runner.run_scenario` (the same code path as ``orbitsim run``), which writes the trace
atomically, and returns a small dict; the traces themselves never travel through Dask. Every
failure of the run itself (bad settings found late, a crash in the kernels, a full disk) is caught
and returned as a ``failed`` row: one bad case must not take the sweep down, and re-raising would
only make Dask retry a deterministic error.

The numbers of a row are read back from the trace by :func:`trace_result`, for a fresh run and for a
run reused by ``--resume`` alike, so both give the same bits.
"""

from __future__ import annotations

import errno
import math
import os
import socket
from typing import Any

from orbitsim._version import __version__

__all__ = ["EVENT_COLUMNS", "failed_result", "run_case", "run_error", "trace_result", "warm_up", "worker_label"]


def worker_label() -> str:
    """Address of the Dask worker running the caller, or ``host:pid`` outside a worker."""
    try:
        from distributed import get_worker  # noqa: PLC0415 -- lazy: loads yaml, numpy, distributed

        return str(get_worker().address)
    except (ImportError, ValueError):
        return f"{socket.gethostname()}:{os.getpid()}"


def _one_line(err: BaseException) -> str:
    text = " ".join(str(err).split())
    return f"{type(err).__name__}: {text}" if text else type(err).__name__


def run_error(err: BaseException, trace_path: str = "") -> str:
    """A failed run's ``error``: one line, and for an I/O error the OS's reason first.

    The terminal table shows the first 40 characters, which must say ``No space left on device``
    rather than an exception's name and a long path; the row already names its trace, so a message
    that starts with that path loses it.
    """
    code = getattr(err, "errno", None)
    if not (isinstance(err, OSError) and code in errno.errorcode and err.strerror):
        return _one_line(err)
    text = " ".join(str(err.strerror).split()).removeprefix(f"{trace_path}: ")
    reason = os.strerror(code)
    if not text.startswith(reason):
        text = f"{reason}: {text}"
    if err.filename and str(err.filename) not in text:
        text += f" ({err.filename})"
    return text


#: Summary columns of event counts, and the kind of the trace's ``events`` table each counts.
EVENT_COLUMNS = (("encounters", "encounter"), ("collisions", "collision"), ("escapes", "escape"),
                 ("unresolved", "unresolved"))


def failed_result(err: BaseException | str, worker: str = "") -> dict[str, Any]:
    """The result of a run that produced no usable trace (its event counts are unknown: None)."""
    return {
        "status": "failed",
        "steps_done": 0,
        "max_abs_energy_error": math.nan,
        "final_energy_error": math.nan,
        "megno": math.nan,
        "mlce": math.nan,
        "wall_time_s": math.nan,
        "steps_per_second": math.nan,
        **{column: None for column, _ in EVENT_COLUMNS},
        "worker": worker,
        "error": err if isinstance(err, str) else _one_line(err),
    }


def _event_counts(f: Any) -> dict[str, int]:
    """The trace's events by summary column; 0 each for a run without ``events:``."""
    from orbitsim.io.trace_events import event_counts  # noqa: PLC0415 -- lazy: loads numpy

    counts = event_counts(f) or {}
    return {column: int(counts.get(kind, 0)) for column, kind in EVENT_COLUMNS}


def _last(dataset: Any) -> float:
    """The last sample of a (S,) series, NaN for an empty one (a run stopped before its first sample)."""
    return float(dataset[-1]) if dataset.shape[0] else math.nan


def trace_result(path: str | os.PathLike, *, require_sha256: str | None = None) -> dict[str, Any] | None:
    """Summary numbers of a finished trace: status, steps, energy errors, MEGNO and the mLCE at the last
    sample (a run with ``output.chaos``), wall time, steps/s and the counts of events by kind.

    With ``require_sha256`` (the resume check) the answer is None unless the trace is complete and
    was made from the scenario with that hash.

    One open of the file, reading the root attributes, ``energy_error``, the last ``megno`` and ``mlce``
    and ``events/kind`` only:
    this runs once per run and per resumed run, and :func:`orbitsim.io.trace.open_trace_summary`
    (which also walks every dataset) would double the cost of a small run's bookkeeping.

    Raises
    ------
    orbitsim.io.trace.TraceError
        If ``path`` is not a readable orbitsim trace.
    """
    import h5py  # noqa: PLC0415 -- lazy: loads h5py
    import numpy as np  # noqa: PLC0415 -- lazy: loads numpy

    from orbitsim.io.trace import TRACE_FORMAT, TRACE_VERSION, TraceError  # noqa: PLC0415 -- lazy: loads h5py

    try:
        with h5py.File(path, "r") as f:
            attrs = {key: f.attrs.get(key) for key in ("format", "format_version", "status", "steps_done",
                                                       "wall_time_s", "message", "scenario_sha256")}
            if attrs["format"] != TRACE_FORMAT or attrs["format_version"] != TRACE_VERSION:
                raise TraceError(f"{os.fspath(path)}: not an {TRACE_FORMAT} v{TRACE_VERSION} file")
            if require_sha256 is not None and (attrs["status"], attrs["scenario_sha256"]) != (
                    "complete", require_sha256):
                return None
            energy_error = f["energy_error"][()]
            events = _event_counts(f)
            chaos = {name: _last(f[name]) if name in f else math.nan for name in ("megno", "mlce")}
    except (OSError, KeyError) as err:
        raise TraceError(f"{os.fspath(path)}: unreadable trace ({err})") from None
    steps = int(attrs["steps_done"] or 0)
    wall = float(attrs["wall_time_s"]) if attrs["wall_time_s"] is not None else math.nan
    status = str(attrs["status"])
    return {
        "status": status,
        "steps_done": steps,
        "max_abs_energy_error": float(np.max(np.abs(energy_error))) if energy_error.size else math.nan,
        "final_energy_error": float(energy_error[-1]) if energy_error.size else math.nan,
        **chaos,
        "wall_time_s": wall,
        "steps_per_second": steps / wall if wall > 0.0 else math.nan,
        **events,
        "error": "" if status == "complete" else str(attrs["message"] or ""),
    }


def warm_up() -> str:
    """Import what a run needs (numba, the kernels) once per worker; return the orbitsim version.

    Run on every worker before the first task, so that the first run on each worker does not carry
    the ~1 s import in its wall time and steps per second, and so that a worker with a missing or
    different orbitsim is reported before any run is submitted.
    """
    import orbitsim.integrators.registry  # noqa: PLC0415 -- lazy: loads numba
    import orbitsim.runner  # noqa: F401, PLC0415 -- lazy: loads yaml, numpy

    return __version__


def run_case(scenario: Any, trace_path: str, threads: int | None = None) -> dict[str, Any]:
    """Run one case on a worker and describe the outcome.

    Parameters
    ----------
    scenario : orbitsim.scenario.Scenario
        The fully resolved case.
    trace_path : str
        Where the trace goes; an existing file there is replaced (the driver only submits runs
        whose trace is missing, stale or unfinished).
    threads : int, optional
        Numba threads for this run (default: the worker's ``NUMBA_NUM_THREADS``).

    Returns
    -------
    dict
        The result columns of :mod:`orbitsim.batch.summary` except the case's own identifiers.
    """
    worker = worker_label()
    try:
        from orbitsim.runner import run_scenario  # noqa: PLC0415 -- lazy: loads yaml, numpy

        run_scenario(scenario, trace_path, force=True, threads=threads, handle_signals=False)
        result = trace_result(trace_path)
    except Exception as err:  # the run's failure is its result; see the module docstring
        return failed_result(run_error(err, trace_path), worker)
    result["worker"] = worker
    return result
