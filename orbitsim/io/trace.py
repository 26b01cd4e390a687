"""HDF5 energy-trace format (``orbitsim.trace``, version 1): writer and reader.

Schema
------
S is the number of samples, N the number of bodies. All floats are float64.

Root attributes written by the writer itself

=====================  ==================================================================
``format``             ``"orbitsim.trace"`` (identifies the file; checked by the reader)
``format_version``     ``1`` (checked by the reader)
``orbitsim_version``   version of the writing orbitsim
``status``             ``"running"`` while written, then ``"complete"``,
                       ``"interrupted"`` or ``"diverged"``
``steps_done``         steps integrated (set at close; default: last sample's step)
``wall_time_s``        wall-clock seconds of the run (set at close)
``message``            free text, e.g. the divergence message (``""`` by default)
``E0``                 energy of the first sample (present once a sample was written)
``scenario_sha256``    hex SHA-256 of the UTF-8 ``scenario`` text, unless supplied
``provenance_<key>``   one attribute per key of :func:`orbitsim.provenance.provenance`,
                       flattened into the root so ``h5dump -A`` shows them directly
=====================  ==================================================================

Root attributes supplied by the caller (documented, not enforced): ``scenario``
(YAML text), ``integrator``, ``dt``, ``steps_requested``, ``G``, ``softening``,
``units``; any other str/int/float/bool/array attribute may be added.

Datasets (per-sample ones are resizable along S, chunked, gzip+shuffle compressed)

* ``time`` (S,), ``step`` (S,) int64 step index of each sample
* ``kinetic``, ``potential``, ``energy`` (S,)
* ``energy_error`` (S,): ``(E - E0) / |E0|``; when ``E0 == 0`` the relative error
  is undefined and the absolute error ``E - E0`` is stored instead
* ``momentum``, ``angular_momentum`` (S, 3)
* ``positions``, ``velocities`` (S, N, 3): only when positions are recorded
* group ``bodies``: ``names`` (N,) variable-length UTF-8 strings, ``masses`` (N,)
* group ``checkpoint`` (optional): the state the run stopped in, so that it can be resumed or
  extended bit for bit; its layout is documented in :mod:`orbitsim.io.checkpoint`

Writing protocol: data go to ``<path>.tmp`` in the target's directory and are renamed
onto ``<path>`` only in :meth:`TraceWriter.close`, so a file at ``<path>`` is always
complete. Samples are buffered up to a bounded size and written block-wise, because
resizing HDF5 datasets once per sample is slow; memory use therefore stays flat.
"""

from __future__ import annotations

import dataclasses
import hashlib
import os
import time as _time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from orbitsim._version import __version__
from orbitsim.provenance import provenance

__all__ = ["TRACE_FORMAT", "TRACE_VERSION", "Trace", "TraceError", "TraceWriter",
           "open_trace", "open_trace_summary", "read_trace"]

TRACE_FORMAT = "orbitsim.trace"
TRACE_VERSION = 1
FINAL_STATUSES = ("complete", "interrupted", "diverged")
_RESERVED = frozenset({"format", "format_version", "E0"})

# Per-sample datasets, grouped by trailing shape: (), (3,), (N, 3).
_SCALARS = ("time", "step", "kinetic", "potential", "energy", "energy_error")
_VECTORS = ("momentum", "angular_momentum")
_BODY_ARRAYS = ("positions", "velocities")

_SERIES_CHUNK_ROWS = 1024  # 8-24 KiB chunks for the small series
_BODY_CHUNK_BYTES = 512 * 1024  # keeps positions chunks under 1 MiB for any N
_FLUSH_ROWS = 1024
_FLUSH_BYTES = 8 * 1024 * 1024  # bounds the write buffer when N is large


class TraceError(ValueError):
    """A file is missing, unreadable, or not a supported orbitsim trace."""


def _body_chunks(n_bodies: int) -> tuple[int, int, int]:
    """Chunk shape for (S, N, 3) datasets: as many samples as fit in ~512 KiB."""
    per_sample = max(n_bodies, 1) * 3 * 8
    if per_sample <= _BODY_CHUNK_BYTES:
        return (min(_SERIES_CHUNK_ROWS, _BODY_CHUNK_BYTES // per_sample), max(n_bodies, 1), 3)
    # One sample alone exceeds the budget: split along the body axis too.
    return (1, _BODY_CHUNK_BYTES // 24, 3)


def _attr_value(key: str, value: Any) -> Any:
    """Convert `value` into something h5py stores as an attribute, or raise TypeError."""
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    if isinstance(value, str | bool | int | float | np.generic | np.ndarray):
        return value
    raise TypeError(f"trace attribute {key!r}: unsupported type {type(value).__name__}")


def _py_value(value: Any) -> Any:
    """Turn attribute values read by h5py into plain Python objects where possible."""
    if isinstance(value, bytes):
        return value.decode("utf-8", errors="replace")
    if isinstance(value, np.generic):
        return value.item()
    return value


class TraceWriter:
    """Stream samples of a run into an ``orbitsim.trace`` HDF5 file.

    Parameters
    ----------
    path : str or os.PathLike
        Final location of the trace. Data are written to ``<path>.tmp`` until `close`.
    attrs : Mapping[str, Any]
        Run description stored as root attributes (``scenario``, ``integrator``,
        ``dt``, ``steps_requested``, ``G``, ``softening``, ``units``, ...).
        ``format``, ``format_version`` and ``E0`` are reserved.
    names : Sequence[str]
        Body names, length `n_bodies`.
    masses : numpy.ndarray
        Body masses, shape ``(n_bodies,)``.
    n_bodies : int
        Number of bodies N.
    record_positions : bool
        Whether ``positions`` and ``velocities`` are stored (then every appended
        chunk must carry both).
    overwrite : bool, default False
        Replace an existing file at `path` on `close`.

    Raises
    ------
    FileExistsError
        If `path` exists and `overwrite` is False (nothing is created).
    FileNotFoundError
        If the directory of `path` does not exist.
    ValueError
        If `names` or `masses` do not match `n_bodies`, or `attrs` uses a reserved key.
    """

    def __init__(self, path: str | os.PathLike, *, attrs: Mapping[str, Any], names: Sequence[str],
                 masses: np.ndarray, n_bodies: int, record_positions: bool,
                 overwrite: bool = False) -> None:
        self.path = Path(path)
        self.tmp_path = self.path.with_name(self.path.name + ".tmp")
        self._overwrite = overwrite
        if self.path.exists() and not overwrite:
            raise FileExistsError(f"{self.path}: trace file already exists (use overwrite to replace it)")
        if not self.path.parent.is_dir():
            raise FileNotFoundError(f"{self.path}: directory {self.path.parent} does not exist")
        masses = np.asarray(masses, dtype=np.float64)
        if len(names) != n_bodies or masses.shape != (n_bodies,):
            raise ValueError(f"{self.path}: expected {n_bodies} names and masses, "
                             f"got {len(names)} names and masses of shape {masses.shape}")
        bad = _RESERVED.intersection(attrs)
        if bad:
            raise ValueError(f"{self.path}: reserved trace attributes {sorted(bad)}")
        self.n_bodies = n_bodies
        self.record_positions = record_positions
        # Per-sample shape of every per-sample dataset, in file order.
        self._trailing: dict[str, tuple[int, ...]] = {name: () for name in _SCALARS}
        self._trailing.update({name: (3,) for name in _VECTORS})
        if record_positions:
            self._trailing.update({name: (n_bodies, 3) for name in _BODY_ARRAYS})
        self._t_start = _time.perf_counter()
        self._E0: float | None = None
        self._last_step: int | None = None
        self._written = 0
        self._buffer: list[dict[str, np.ndarray]] = []
        self._buffer_rows = 0
        self._buffer_bytes = 0
        # Truncating a stale .tmp from a crashed run is intended; HDF5 file locking
        # refuses if another live writer still holds it.
        self._file: h5py.File | None = h5py.File(self.tmp_path, "w")
        try:
            self._init_file(self._file, attrs, names, masses)
        except BaseException:
            self.abort()
            raise

    def _init_file(self, f: h5py.File, attrs: Mapping[str, Any], names: Sequence[str],
                   masses: np.ndarray) -> None:
        root: dict[str, Any] = {"steps_done": 0, "wall_time_s": 0.0, "message": ""}
        root.update({f"provenance_{k}": v for k, v in provenance().items()})
        root.update(attrs)
        if "scenario" in root and "scenario_sha256" not in root:
            root["scenario_sha256"] = hashlib.sha256(str(root["scenario"]).encode()).hexdigest()
        root.update(format=TRACE_FORMAT, format_version=TRACE_VERSION,
                    orbitsim_version=__version__, status="running")
        for key, value in root.items():
            f.attrs[key] = _attr_value(key, value)
        bodies = f.create_group("bodies")
        bodies.create_dataset("names", data=list(names), dtype=h5py.string_dtype("utf-8"))
        bodies.create_dataset("masses", data=masses)
        for name, tail in self._trailing.items():
            chunks = _body_chunks(self.n_bodies) if len(tail) == 2 else (_SERIES_CHUNK_ROWS, *tail)
            f.create_dataset(name, shape=(0, *tail), maxshape=(None, *tail), chunks=chunks,
                             dtype=np.int64 if name == "step" else np.float64,
                             compression="gzip", compression_opts=4, shuffle=True)

    @property
    def samples_written(self) -> int:
        """Number of samples appended so far (buffered ones included)."""
        return self._written

    @property
    def closed(self) -> bool:
        """Whether the writer has been closed or aborted."""
        return self._file is None

    def _require_open(self) -> h5py.File:
        if self._file is None:
            raise RuntimeError(f"{self.path}: trace writer is closed")
        return self._file

    def _normalise(self, chunk: Any) -> dict[str, np.ndarray]:
        """Copy one chunk into float64/int64 arrays of validated shapes."""
        out: dict[str, np.ndarray] = {}
        for name, tail in self._trailing.items():
            if name == "energy_error":
                continue  # derived by the writer
            value = getattr(chunk, name, None)
            if value is None:
                raise ValueError(f"{self.path}: chunk.{name} is required but is None")
            # Copy: callers typically reuse their sample buffers. A single sample may
            # come without its leading axis.
            arr = np.array(value, dtype=np.int64 if name == "step" else np.float64)
            out[name] = arr[None] if arr.shape == tail else arr
        k = out["time"].shape[0] if out["time"].ndim == 1 else 0
        wrong = {n: a.shape for n, a in out.items() if a.shape != (k, *self._trailing[n])}
        if k < 1 or wrong:
            raise ValueError(f"{self.path}: chunk has {k} samples; bad shapes {wrong}")
        return out

    def append(self, chunk: Any) -> None:
        """Append ``k >= 1`` samples.

        Parameters
        ----------
        chunk : object
            Any object with array attributes ``time``, ``step``, ``kinetic``,
            ``potential``, ``energy`` (k,), ``momentum``, ``angular_momentum`` (k, 3)
            and ``positions``, ``velocities`` (k, N, 3) or None. The arrays are copied.
        """
        f = self._require_open()
        data = self._normalise(chunk)
        energy = data["energy"]
        if self._E0 is None:
            self._E0 = float(energy[0])
            f.attrs["E0"] = self._E0
        delta = energy - self._E0
        data["energy_error"] = delta / abs(self._E0) if self._E0 != 0.0 else delta
        self._buffer.append(data)
        self._buffer_rows += energy.shape[0]
        self._buffer_bytes += sum(a.nbytes for a in data.values())
        self._written += energy.shape[0]
        self._last_step = int(data["step"][-1])
        if self._buffer_rows >= _FLUSH_ROWS or self._buffer_bytes >= _FLUSH_BYTES:
            self._write_buffer()

    def _write_buffer(self) -> None:
        if not self._buffer:
            return
        f = self._require_open()
        for name in self._buffer[0]:
            block = np.concatenate([d[name] for d in self._buffer])
            ds = f[name]
            start = ds.shape[0]
            ds.resize(start + block.shape[0], axis=0)
            ds[start:] = block
        self._buffer.clear()
        self._buffer_rows = self._buffer_bytes = 0

    def set_attrs(self, **kw: Any) -> None:
        """Update root attributes mid-run (``format``, ``format_version``, ``E0`` are reserved)."""
        f = self._require_open()
        bad = _RESERVED.intersection(kw)
        if bad:
            raise ValueError(f"{self.path}: reserved trace attributes {sorted(bad)}")
        for key, value in kw.items():
            f.attrs[key] = _attr_value(key, value)

    def new_group(self, name: str) -> h5py.Group:
        """An empty group ``name`` in the open file, replacing one of that name (e.g. ``checkpoint``)."""
        f = self._require_open()
        if name in self._trailing or name == "bodies":
            raise ValueError(f"{self.path}: {name!r} is a dataset of the trace format")
        if name in f:
            del f[name]
        return f.create_group(name)

    def flush(self) -> None:
        """Write buffered samples and flush HDF5 buffers to the temporary file."""
        self._write_buffer()
        self._require_open().flush()

    def close(self, status: str = "complete", *, steps_done: int | None = None,
              wall_time_s: float | None = None, message: str = "") -> Path:
        """Finalise the trace and atomically move it onto `path`.

        Parameters
        ----------
        status : {"complete", "interrupted", "diverged"}
            Final run status.
        steps_done : int, optional
            Steps integrated; default: the step index of the last sample, if any.
        wall_time_s : float, optional
            Run duration; default: seconds elapsed since the writer was created.
        message : str
            Free text for the ``message`` attribute.

        Returns
        -------
        pathlib.Path
            The final path of the trace.
        """
        if status not in FINAL_STATUSES:
            raise ValueError(f"{self.path}: status must be one of {FINAL_STATUSES}, got {status!r}")
        f = self._require_open()
        if steps_done is None:
            steps_done = self._last_step
        if wall_time_s is None:
            wall_time_s = _time.perf_counter() - self._t_start
        self.flush()
        final = {"status": status, "wall_time_s": float(wall_time_s), "message": message}
        if steps_done is not None:
            final["steps_done"] = int(steps_done)
        for key, value in final.items():
            f.attrs[key] = value
        f.close()
        self._file = None
        _fsync(self.tmp_path)
        if self.path.exists() and not self._overwrite:
            # Someone created the target during the run: keep our data in .tmp instead of clobbering.
            raise FileExistsError(f"{self.path}: appeared during the run; trace left at {self.tmp_path}")
        os.replace(self.tmp_path, self.path)
        _fsync(self.path.parent, best_effort=True)
        return self.path

    def abort(self) -> None:
        """Close and delete the temporary file, leaving nothing behind (no-op once closed)."""
        if self._file is None:
            return
        try:
            self._file.close()
        finally:
            self._file = None
            self.tmp_path.unlink(missing_ok=True)

    def __enter__(self) -> TraceWriter:
        return self

    def __exit__(self, exc_type: Any, exc: BaseException | None, tb: Any) -> None:
        """Close as ``complete``; on an exception, ``interrupted`` if samples exist, else abort."""
        if self._file is None:
            return
        if exc_type is None:
            self.close("complete")
        elif self._written > 0:
            self.close("interrupted", message=f"{exc_type.__name__}: {exc}")
        else:
            self.abort()


def _fsync(path: Path, *, best_effort: bool = False) -> None:
    """fsync a file or directory; directories cannot be fsynced on every OS/filesystem."""
    try:
        fd = os.open(path, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
    except OSError:
        if not best_effort:
            raise


@dataclasses.dataclass(frozen=True, eq=False)
class Trace:
    """Contents of an ``orbitsim.trace`` file (see the module docstring for fields)."""

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
    fmt = _py_value(f.attrs.get("format"))
    version = _py_value(f.attrs.get("format_version"))
    if fmt == TRACE_FORMAT and version == TRACE_VERSION:
        return f
    f.close()
    if fmt is None:
        raise TraceError(f"{p}: not an orbitsim trace (no 'format' attribute)")
    if fmt != TRACE_FORMAT:
        raise TraceError(f"{p}: not an orbitsim trace (format is {fmt!r}, expected {TRACE_FORMAT!r})")
    raise TraceError(f"{p}: unsupported trace format_version {version!r} (supported: {TRACE_VERSION})")


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
        version, or lacks a required dataset.
    """
    with _open_checked(path) as f:
        try:
            arrays = {name: f[name][()] for name in (*_SCALARS, *_VECTORS)}
            for name in _BODY_ARRAYS:
                arrays[name] = f[name][()] if name in f else None
            names = tuple(f["bodies/names"].asstr()[()])
            masses = f["bodies/masses"][()]
        except (KeyError, OSError) as err:
            raise TraceError(f"{os.fspath(path)}: damaged trace ({err})") from None
        attrs = {k: _py_value(v) for k, v in f.attrs.items()}
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
        attrs = {k: _py_value(v) for k, v in f.attrs.items()}
    return {"path": os.fspath(path), "attrs": attrs, "shapes": shapes,
            "n_samples": shapes.get("time", (0,))[0], "n_bodies": shapes.get("bodies/masses", (0,))[0]}
