"""Identifiers, dataset names and errors of the ``orbitsim.trace`` format (documented in
:mod:`orbitsim.io.trace`), shared by the writer, the reader and the checkpoint files."""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["BODY_ARRAYS", "FINAL_STATUSES", "RESERVED_ATTRS", "SCALARS", "TRACE_FORMAT", "TRACE_VERSION", "VECTORS",
           "CheckpointError", "OutputBusyError", "OutputError", "OutputWriteError", "TraceError", "py_value"]

TRACE_FORMAT = "orbitsim.trace"
TRACE_VERSION = 1
FINAL_STATUSES = ("complete", "interrupted", "diverged")
#: Root attributes only the writer sets.
RESERVED_ATTRS = frozenset({"format", "format_version", "E0"})

# Per-sample datasets, grouped by trailing shape: (), (3,), (N, 3).
SCALARS = ("time", "step", "kinetic", "potential", "energy", "energy_error")
VECTORS = ("momentum", "angular_momentum")
BODY_ARRAYS = ("positions", "velocities")


class TraceError(ValueError):
    """A file is missing, unreadable, or not a supported orbitsim trace."""


class CheckpointError(TraceError):
    """A checkpoint or journal is missing, damaged, foreign, or does not fit the run."""


class OutputError(ValueError):
    """The output path cannot be used: it exists (and ``force`` is off), its directory is missing or
    cannot be written, or it is another file of the run. Nothing has been written."""


class OutputBusyError(OutputError):
    """Another process is writing the same output (:mod:`orbitsim.io.lock`)."""


class OutputWriteError(OSError):
    """Writing an output failed (disk full, quota, a device error) and was cleaned up.

    ``str()`` is the whole one-line message: what failed, why (the OS's words, such as
    ``No space left on device``) and what is kept on disk. ``errno`` is the OS error number and
    ``cause`` the OS's words alone.
    """

    def __init__(self, errno: int | None, message: str, filename: str = "", cause: str = "") -> None:
        super().__init__(errno, message, filename)
        self.message = " ".join(message.split())
        self.cause = cause or self.message

    def __str__(self) -> str:
        return self.message


def py_value(value: Any) -> Any:
    """Turn attribute values read by h5py into plain Python objects where possible."""
    if isinstance(value, bytes):
        return value.decode("utf-8", errors="replace")
    if isinstance(value, np.generic):
        return value.item()
    return value
