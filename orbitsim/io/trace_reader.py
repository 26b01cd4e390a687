"""Reading ``orbitsim.trace`` files (the format is documented in :mod:`orbitsim.io.trace`)."""

from __future__ import annotations

import dataclasses
import os
from typing import Any

import h5py
import numpy as np

from orbitsim.io.schema import BODY_ARRAYS, SCALARS, TRACE_FORMAT, TRACE_VERSION, VECTORS, TraceError, py_value

#: Per-body datasets of the ``bodies`` group, each of length N.
BODY_DATASETS = ("bodies/names", "bodies/masses")

__all__ = ["Trace", "open_trace", "open_trace_summary", "read_trace"]


@dataclasses.dataclass(frozen=True, eq=False)
class Trace:
    """Contents of an ``orbitsim.trace`` file (see :mod:`orbitsim.io.trace` for the fields)."""

    attrs: dict[str, Any]
    time: np.ndarray
    step: np.ndarray
    kinetic: np.ndarray
    potential: np.ndarray
    energy: np.ndarray
    energy_error: np.ndarray
    momentum: np.ndarray
    angular_momentum: np.ndarray
    names: tuple[str, ...]
    masses: np.ndarray
    positions: np.ndarray | None = None
    velocities: np.ndarray | None = None

    @property
    def n_samples(self) -> int:
        """Number of samples S."""
        return int(self.time.shape[0])


def _open_checked(path: str | os.PathLike) -> h5py.File:
    """Open `path` read-only after checking it is a supported trace; raise TraceError."""
    p = os.fspath(path)
    if not os.path.isfile(p):
        raise TraceError(f"{p}: no such trace file")
    try:
        if not h5py.is_hdf5(p):
            raise TraceError(f"{p}: not an HDF5 file")
        f = h5py.File(p, "r")
    except OSError as err:
        raise TraceError(f"{p}: cannot open HDF5 file ({err})") from None
    fmt = py_value(f.attrs.get("format"))
    version = py_value(f.attrs.get("format_version"))
    if fmt == TRACE_FORMAT and version == TRACE_VERSION:
        try:
            _check_datasets(f, p)
        except BaseException:
            f.close()
            raise
        return f
    f.close()
    if fmt is None:
        raise TraceError(f"{p}: not an orbitsim trace (no 'format' attribute)")
    if fmt != TRACE_FORMAT:
        raise TraceError(f"{p}: not an orbitsim trace (format is {fmt!r}, expected {TRACE_FORMAT!r})")
    raise TraceError(f"{p}: unsupported trace format_version {version!r} (supported: {TRACE_VERSION})")


def _check_datasets(f: h5py.File, path: str) -> None:
    """Raise TraceError unless every dataset the writer creates is there with matching lengths.

    The writer creates all of them when it opens the file, so one missing, or of another length
    than ``time``, means the file was damaged or edited after the fact; saying which here spares
    every reader a ``KeyError`` or ``IndexError``. Only shapes are read (metadata, no data).
    """
    shapes: dict[str, tuple[int, ...]] = {}
    for name in (*SCALARS, *VECTORS, *BODY_ARRAYS, *BODY_DATASETS):
        obj = f.get(name)
        if obj is None:
            if name in BODY_ARRAYS:
                continue  # positions were not recorded
            raise TraceError(f"{path}: damaged trace: dataset '{name}' is missing")
        if not isinstance(obj, h5py.Dataset):
            raise TraceError(f"{path}: damaged trace: '{name}' is not a dataset")
        shapes[name] = obj.shape
    recorded = [name for name in BODY_ARRAYS if name in shapes]
    if recorded and len(recorded) < len(BODY_ARRAYS):
        missing = next(name for name in BODY_ARRAYS if name not in shapes)
        raise TraceError(f"{path}: damaged trace: dataset '{missing}' is missing (it is written with '{recorded[0]}')")
    n_samples, n_bodies = _first_dim(shapes["time"]), _first_dim(shapes["bodies/masses"])
    for name, shape in shapes.items():
        if name in BODY_DATASETS:
            if _first_dim(shape) != n_bodies:
                raise TraceError(f"{path}: damaged trace: dataset '{name}' has {_first_dim(shape)} bodies, "
                                 f"'bodies/masses' has {n_bodies}")
        elif _first_dim(shape) != n_samples:
            raise TraceError(f"{path}: damaged trace: dataset '{name}' has {_first_dim(shape)} samples, "
                             f"'time' has {n_samples}")
        elif name in BODY_ARRAYS and shape[1:2] != (n_bodies,):
            raise TraceError(f"{path}: damaged trace: dataset '{name}' has shape {shape}, expected "
                             f"({n_samples}, {n_bodies}, 3)")


def _first_dim(shape: tuple[int, ...] | None) -> int:
    """Length along the first axis (a scalar dataset, shape ``()``, has none: -1)."""
    return int(shape[0]) if shape else -1


def open_trace(path: str | os.PathLike) -> h5py.File:
    """Open a trace read-only after checking its format and version (the caller closes it).

    Raises
    ------
    TraceError
        As for `read_trace`.
    """
    return _open_checked(path)


def read_trace(path: str | os.PathLike) -> Trace:
    """Load a whole trace file into a :class:`Trace`.

    Raises
    ------
    TraceError
        If the file is missing, not HDF5, not an orbitsim trace, of an unsupported
        version, or damaged: a required dataset missing, or one of another length than
        ``time`` (the message names it).
    """
    with _open_checked(path) as f:
        try:
            arrays = {name: f[name][()] for name in (*SCALARS, *VECTORS)}
            for name in BODY_ARRAYS:
                arrays[name] = f[name][()] if name in f else None
            names = tuple(f["bodies/names"].asstr()[()])
            masses = f["bodies/masses"][()]
        except (KeyError, OSError) as err:
            raise TraceError(f"{os.fspath(path)}: damaged trace ({err})") from None
        attrs = {k: py_value(v) for k, v in f.attrs.items()}
    return Trace(attrs=attrs, names=names, masses=masses, **arrays)


def open_trace_summary(path: str | os.PathLike) -> dict[str, Any]:
    """Describe a trace without loading its arrays.

    Returns
    -------
    dict
        ``path`` (str), ``attrs`` (dict of root attributes), ``shapes`` (dataset
        path -> shape tuple), ``n_samples`` and ``n_bodies``.

    Raises
    ------
    TraceError
        As for `read_trace`.
    """
    with _open_checked(path) as f:
        shapes: dict[str, tuple[int, ...]] = {}
        f.visititems(lambda name, obj: shapes.__setitem__(name, obj.shape)
                     if isinstance(obj, h5py.Dataset) else None)
        attrs = {k: py_value(v) for k, v in f.attrs.items()}
    return {"path": os.fspath(path), "attrs": attrs, "shapes": shapes,
            "n_samples": shapes.get("time", (0,))[0], "n_bodies": shapes.get("bodies/masses", (0,))[0]}
