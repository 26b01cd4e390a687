"""Identifiers, dataset names and errors of the ``orbitsim.trace`` format (documented in
:mod:`orbitsim.io.trace`), shared by the writer, the reader and the checkpoint files."""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["BODY_ARRAYS", "ELEMENTS", "FINAL_STATUSES", "NEAR_ZERO_ENERGY", "RESERVED_ATTRS", "SCALARS", "TRACE_FORMAT",
           "TRACE_VERSION", "VECTORS", "CheckpointError", "OutputBusyError", "OutputError", "OutputWriteError",
           "TraceError", "energy_scale", "py_value"]

TRACE_FORMAT = "orbitsim.trace"
TRACE_VERSION = 1
FINAL_STATUSES = ("complete", "interrupted", "diverged", "halted")
#: Root attributes only the writer sets.
RESERVED_ATTRS = frozenset({"format", "format_version", "E0", "energy_scale"})

# Per-sample datasets, grouped by trailing shape: (), (3,), (N, 3).
SCALARS = ("time", "step", "kinetic", "potential", "energy", "energy_error")
VECTORS = ("momentum", "angular_momentum")
BODY_ARRAYS = ("positions", "velocities")
#: Osculating elements a run records with ``output.elements``: datasets ``elements/<name>`` (S, N).
ELEMENTS = ("a", "e", "inc", "Omega", "omega", "f", "M")


#: |E0| below this fraction of T0 + |U0| counts as zero: the energy error is then measured against
#: T0 + |U0| instead, which cannot vanish. A bound system in virial equilibrium has |E0| = (T0 +
#: |U0|) / 3, and every bundled scenario is far above this, so their errors are unchanged; a
#: nearly parabolic pair would otherwise divide by a number that makes any error look huge, or
#: (E0 -> 0 by round-off) any error look like anything at all.
NEAR_ZERO_ENERGY = 1e-3


def energy_scale(kinetic0: float, potential0: float, e0: float | None = None) -> float:
    """The energy ``energy_error`` is relative to: |E0|, or T0 + |U0| when |E0| is tiny next to
    them (:data:`NEAR_ZERO_ENERGY`); 1 (an absolute error) when every energy is zero. ``e0``
    defaults to T0 + U0 (a caller that has the stored E0 passes it, so the two agree to the bit)."""
    e0 = kinetic0 + potential0 if e0 is None else e0
    size = kinetic0 + abs(potential0)
    if abs(e0) >= NEAR_ZERO_ENERGY * size and e0 != 0.0:
        return abs(e0)
    return size if size > 0.0 else 1.0


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
