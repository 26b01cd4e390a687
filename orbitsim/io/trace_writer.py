"""Writing an ``orbitsim.trace`` file (the format is documented in :mod:`orbitsim.io.trace`).

Data go to ``<path>.tmp`` and are renamed onto ``<path>`` only in :meth:`TraceWriter.close`, so a
file at ``<path>`` is always complete. Samples are buffered up to a bounded size and written
block-wise, because resizing HDF5 datasets once per sample is slow; memory use stays flat.

An I/O error at any write (a full disk, a quota, a device error; the rename included) discards the
``.tmp`` (:func:`orbitsim.io.h5safe.discard`, which keeps HDF5 from crashing on it) and raises one
:class:`~orbitsim.io.schema.OutputWriteError` naming the path and the cause: ``<path>`` keeps whatever
it held before. No HDF5 object of the file is ever released while it may still have data to write:
the sample datasets stay open for the writer's life, and the small groups (``bodies``,
``checkpoint``) are built in memory and copied in by one call. So HDF5 writes only inside the
writer's own calls, where a failure is caught, never from an object's destructor, where h5py can
only print it (and where a failure left HDF5 in a state that crashed at the next close).
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import time as _time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from orbitsim._version import __version__
from orbitsim.io.durable import replace_durably
from orbitsim.io.h5layout import FLUSH_BYTES, FLUSH_ROWS, bound_metadata_cache, chunk_shape
from orbitsim.io.h5safe import H5_WRITE_ERRORS, create, discard, in_memory, io_failure, surfaced, vfd_handle
from orbitsim.io.schema import (
    BODY_ARRAYS,
    FINAL_STATUSES,
    RESERVED_ATTRS,
    SCALARS,
    TRACE_FORMAT,
    TRACE_VERSION,
    VECTORS,
    energy_scale,
)
from orbitsim.io.stored_scenario import SCENARIO_BODIES, write_scenario_bodies
from orbitsim.provenance import provenance

__all__ = ["TraceWriter"]

def _attr_value(key: str, value: Any) -> Any:
    """Convert `value` into something h5py stores as an attribute, or raise TypeError."""
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    if isinstance(value, str | bool | int | float | np.generic | np.ndarray):
        return value
    raise TypeError(f"trace attribute {key!r}: unsupported type {type(value).__name__}")


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
    extra_series : Mapping[str, tuple[int, ...]], optional
        Further per-sample datasets by name and per-sample shape (``energy_offset``: ``()``,
        ``elements/a``: ``(N,)``, ...), read from each chunk's ``extra`` mapping. An
        ``energy_offset`` series is added to the energy before ``energy_error`` is computed.
    group_attrs : Mapping[str, Mapping[str, Any]], optional
        Attributes of the groups those series make (``{"elements": {"primary": "jacobi"}}``).
    scenario_bodies : Mapping[str, numpy.ndarray], optional
        A large scenario's per-body rows, stored beside its ``scenario`` text attribute
        (:mod:`orbitsim.io.stored_scenario`).

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
                 overwrite: bool = False, extra_series: Mapping[str, tuple[int, ...]] | None = None,
                 group_attrs: Mapping[str, Mapping[str, Any]] | None = None,
                 scenario_bodies: Mapping[str, np.ndarray] | None = None) -> None:
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
        bad = RESERVED_ATTRS.intersection(attrs)
        if bad:
            raise ValueError(f"{self.path}: reserved trace attributes {sorted(bad)}")
        self.n_bodies = n_bodies
        self.record_positions = record_positions
        # Per-sample shape of every per-sample dataset, in file order.
        self._trailing: dict[str, tuple[int, ...]] = {name: () for name in SCALARS}
        self._trailing.update({name: (3,) for name in VECTORS})
        if record_positions:
            self._trailing.update({name: (n_bodies, 3) for name in BODY_ARRAYS})
        self._extra = dict(extra_series or {})
        self._trailing.update(self._extra)
        self.names = list(names)
        self._t_start = _time.perf_counter()
        self._E0: float | None = None
        self._scale = 1.0
        self._last_step: int | None = None
        self._written = 0
        self._buffer: list[dict[str, np.ndarray]] = []
        self._buffer_rows = 0
        self._buffer_bytes = 0
        self._datasets: dict[str, h5py.Dataset] = {}
        # Truncating a stale .tmp from a crashed run is intended: the caller holds the output's
        # lock (orbitsim.io.lock), so no live writer can own it.
        self._file: h5py.File | None = None
        self._handle: int | None = None
        with self._writing():
            self._file = create(self.tmp_path)
            self._handle = vfd_handle(self._file)
            bound_metadata_cache(self._file)
            self._init_file(self._file, attrs, names, masses, scenario_bodies)
            for group, values in (group_attrs or {}).items():
                for key, value in values.items():
                    self._file[group].attrs[key] = _attr_value(key, value)

    def _init_file(self, f: h5py.File, attrs: Mapping[str, Any], names: Sequence[str],
                   masses: np.ndarray, scenario_bodies: Mapping[str, np.ndarray] | None) -> None:
        root: dict[str, Any] = {"steps_done": 0, "wall_time_s": 0.0, "message": ""}
        root.update({f"provenance_{k}": v for k, v in provenance().items()})
        root.update(attrs)
        if "scenario" in root and "scenario_sha256" not in root:
            root["scenario_sha256"] = hashlib.sha256(str(root["scenario"]).encode()).hexdigest()
        root.update(format=TRACE_FORMAT, format_version=TRACE_VERSION,
                    orbitsim_version=__version__, status="running")
        for key, value in root.items():
            f.attrs[key] = _attr_value(key, value)
        with in_memory() as memory:  # copied in whole: see the module docstring
            bodies = memory.create_group("bodies")
            bodies.create_dataset("names", data=list(names), dtype=h5py.string_dtype("utf-8"))
            bodies.create_dataset("masses", data=masses)
            f.copy(bodies, "bodies")
            if scenario_bodies is not None:  # a large scenario's rows (orbitsim.io.stored_scenario)

                write_scenario_bodies(memory, scenario_bodies)
                f.copy(memory[SCENARIO_BODIES], SCENARIO_BODIES)
        for name, tail in self._trailing.items():
            chunks = chunk_shape(tail, self.n_bodies)
            self._datasets[name] = f.create_dataset(
                name, shape=(0, *tail), maxshape=(None, *tail), chunks=chunks,
                dtype=np.int64 if name == "step" else np.float64, compression="gzip", compression_opts=4, shuffle=True)

    @contextlib.contextmanager
    def _writing(self) -> Any:
        """Around every call that may write: an I/O error discards the file and becomes one
        :class:`OutputWriteError`."""
        try:
            with surfaced():
                yield
        except H5_WRITE_ERRORS as err:
            self.abort()
            raise io_failure(err, f"{self.path}: {{reason}} while writing the trace ({self.tmp_path}, now removed)",
                             self.tmp_path) from None

    @property
    def series(self) -> dict[str, tuple[int, ...]]:
        """The ``extra_series`` this trace holds, with their per-sample shapes."""
        return dict(self._extra)

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
            if name in self._extra:
                value = (getattr(chunk, "extra", None) or {}).get(name)
            else:
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
            and ``positions``, ``velocities`` (k, N, 3) or None, and ``extra`` holding the
            ``extra_series``. The arrays are copied.
        """
        f = self._require_open()
        data = self._normalise(chunk)
        energy = data["energy"]
        if self._E0 is None:
            self._E0 = float(energy[0])
            self._scale = energy_scale(float(data["kinetic"][0]), float(data["potential"][0]), self._E0)
            with self._writing():
                f.attrs["E0"] = self._E0
                f.attrs["energy_scale"] = self._scale
        conserved = energy + data["energy_offset"] if "energy_offset" in data else energy
        data["energy_error"] = (conserved - self._E0) / self._scale
        self._buffer.append(data)
        self._buffer_rows += energy.shape[0]
        self._buffer_bytes += sum(a.nbytes for a in data.values())
        self._written += energy.shape[0]
        self._last_step = int(data["step"][-1])
        if self._buffer_rows >= FLUSH_ROWS or self._buffer_bytes >= FLUSH_BYTES:
            self._write_buffer()

    def _write_buffer(self) -> None:
        if not self._buffer:
            return
        self._require_open()
        with self._writing():
            for name in self._buffer[0]:
                block = np.concatenate([d[name] for d in self._buffer])
                ds = self._datasets[name]
                start = ds.shape[0]
                ds.resize(start + block.shape[0], axis=0)
                ds[start:] = block
        self._buffer.clear()
        self._buffer_rows = self._buffer_bytes = 0

    def set_attrs(self, **kw: Any) -> None:
        """Update root attributes mid-run (``format``, ``format_version``, ``E0`` are reserved)."""
        f = self._require_open()
        bad = RESERVED_ATTRS.intersection(kw)
        if bad:
            raise ValueError(f"{self.path}: reserved trace attributes {sorted(bad)}")
        values = {key: _attr_value(key, value) for key, value in kw.items()}
        with self._writing():
            for key, value in values.items():
                f.attrs[key] = value

    def add_arrays(self, group: str, arrays: Mapping[str, np.ndarray]) -> None:
        """Add datasets to the group ``group`` (made if missing; an existing dataset of the same
        name is replaced), each copied in from memory in one call (see the module docstring).
        Object arrays are stored as UTF-8 text."""
        f = self._require_open()
        if group in self._trailing:
            raise ValueError(f"{self.path}: {group!r} is a dataset of the trace format")
        with in_memory() as memory, self._writing():
            target = f.require_group(group)
            for name, arr in arrays.items():
                arr = np.asarray(arr)
                text = arr.dtype == object or arr.dtype.kind == "U"
                memory.create_dataset(name, data=arr.astype(object) if text else arr,
                                      dtype=h5py.string_dtype("utf-8") if text else arr.dtype)
                if name in target:
                    del target[name]
                target.copy(memory[name], name)

    def copy_group(self, name: str, source: h5py.Group) -> None:
        """Copy ``source`` (e.g. a group built in memory) into the trace as the group ``name``,
        replacing one of that name, in one HDF5 call: no object of the trace file is left to
        write, and maybe fail, when it is released."""
        f = self._require_open()
        if name in self._trailing or name == "bodies":
            raise ValueError(f"{self.path}: {name!r} is a dataset of the trace format")
        with self._writing():
            if name in f:
                del f[name]
            f.copy(source, name)

    def flush(self) -> None:
        """Write buffered samples and flush HDF5 buffers to the temporary file."""
        self._write_buffer()
        f = self._require_open()
        with self._writing():
            f.flush()

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
        self._write_buffer()
        final = {"status": status, "wall_time_s": float(wall_time_s), "message": message}
        if steps_done is not None:
            final["steps_done"] = int(steps_done)
        with self._writing():
            for key, value in final.items():
                f.attrs[key] = value
            f.flush()  # every pending write happens here, where its failure is caught
            self._datasets.clear()
            f.close()
        self._file = None
        if self.path.exists() and not self._overwrite:
            # Someone created the target during the run: keep our data in .tmp instead of clobbering.
            raise FileExistsError(f"{self.path}: appeared during the run; trace left at {self.tmp_path}")
        try:
            replace_durably(self.tmp_path, self.path)
        except OSError as err:  # the fsync of the file or the rename: the output path is untouched
            self.tmp_path.unlink(missing_ok=True)
            raise io_failure(err, f"{self.path}: {{reason}} while moving the finished trace into place "
                                  f"({self.tmp_path}, now removed)", self.tmp_path) from None
        return self.path

    def abort(self) -> None:
        """Close and delete the temporary file, leaving nothing behind (no-op once closed)."""
        if self._file is None:
            return
        try:
            discard(self._file, self._handle)  # before the datasets are released, whose destructors would write
            self._datasets.clear()
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
