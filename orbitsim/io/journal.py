"""The sample journal of a checkpointed run: ``<OUT>.journal``, fixed-size records, append only.

:mod:`orbitsim.io.checkpoint` explains why a checkpointed run keeps its samples here rather than
in HDF5. Bytes made durable before a checkpoint names them are never touched again; on resume the
file is checked against the checkpoint's length and CRC-32 and cut back to that prefix.
"""

from __future__ import annotations

import contextlib
import os
import zlib
from collections.abc import Iterator, Mapping
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np

from orbitsim.io.durable import datasync
from orbitsim.io.h5safe import io_failure
from orbitsim.io.schema import CheckpointError

try:
    import fcntl
except ImportError:  # Windows: no advisory locks (each use says what happens then)
    fcntl = None

__all__ = ["Journal", "as_chunk", "check_journal", "journal_dtype", "journal_is_locked", "journal_path"]

_JOURNAL_BLOCK_BYTES = 8 * 2**20  # read-back block: flat memory for any N


def journal_path(output: str | os.PathLike) -> Path:
    """``<OUT>.journal``: the append-only samples of the run writing ``OUT``."""
    return Path(f"{os.fspath(output)}.journal")


def journal_dtype(n_bodies: int, record_positions: bool, extra: Mapping[str, tuple[int, ...]] | None = None,
                  ) -> np.dtype:
    """One journal record: a sample's time, step, energies, momenta and, optionally, its state and
    the ``extra`` series of the trace (their names and per-sample shapes: ``energy_offset``, ...)."""
    fields: list[tuple[Any, ...]] = [("time", "<f8"), ("step", "<i8"), ("kinetic", "<f8"), ("potential", "<f8"),
                                     ("momentum", "<f8", (3,)), ("angular_momentum", "<f8", (3,))]
    if record_positions:
        fields += [("positions", "<f8", (n_bodies, 3)), ("velocities", "<f8", (n_bodies, 3))]
    fields += [(name, "<f8", tuple(shape)) for name, shape in (extra or {}).items()]
    return np.dtype(fields)


class Journal:
    """The append-only sample file of one run, locked against a second writer.

    Parameters
    ----------
    path : path
        ``<OUT>.journal``.
    dtype : numpy.dtype
        Record type (:func:`journal_dtype`).
    keep_bytes, crc32 : int
        0 to start a new journal (truncating any file there); otherwise the valid prefix named
        by a checkpoint and its CRC-32: the file must hold that prefix intact, and is cut back
        to it.

    Raises
    ------
    CheckpointError
        If another live process holds the journal, or its prefix is short or damaged.
    """

    def __init__(self, path: str | os.PathLike, dtype: np.dtype, *, keep_bytes: int = 0, crc32: int = 0) -> None:
        self.path = Path(path)
        self.dtype = dtype
        if keep_bytes % dtype.itemsize:
            raise CheckpointError(f"{self.path}: checkpoint names {keep_bytes} bytes, not a whole number of "
                                  f"{dtype.itemsize}-byte records")
        exists = self.path.exists()
        if keep_bytes and not exists:
            raise CheckpointError(f"{self.path}: the sample journal the checkpoint needs is missing")
        # Unbuffered, held open (and locked) for the run: a chunk is one write call, and a failed write
        # (a full disk) raises in append, never later from a buffer's flush at close.
        self._fh = open(self.path, "r+b" if exists else "w+b", buffering=0)
        try:
            _lock(self._fh, self.path)
            _check_prefix(self._fh, self.path, keep_bytes, crc32)
            self._fh.truncate(keep_bytes)
            self._fh.seek(keep_bytes)
        except BaseException:
            self._fh.close()
            raise
        self.bytes = keep_bytes
        self.crc32 = crc32

    @property
    def records(self) -> int:
        """Samples in the journal."""
        return self.bytes // self.dtype.itemsize

    def append(self, chunk: Any) -> None:
        """Append the samples of a chunk (``time``, ``step``, ... attributes, as a SampleChunk)."""
        rec = np.empty(len(chunk.time), dtype=self.dtype)
        extra = getattr(chunk, "extra", None) or {}
        for name in self.dtype.names:
            rec[name] = extra[name] if name in extra else getattr(chunk, name)
        data = memoryview(rec.tobytes())
        try:
            written = 0
            while written < len(data):  # a raw write may write less than asked
                written += self._fh.write(data[written:])
        except OSError as err:
            raise io_failure(err, f"{self.path}: {{reason}}", self.path) from None
        self.bytes += len(data)
        self.crc32 = zlib.crc32(data, self.crc32)

    def sync(self) -> None:
        """Make every appended byte durable (before a checkpoint names it)."""
        try:
            datasync(self._fh.fileno())
        except OSError as err:
            raise io_failure(err, f"{self.path}: {{reason}}", self.path) from None

    def chunks(self, stop: int | None = None) -> Iterator[SimpleNamespace]:
        """Read the first ``stop`` records (default all) back, block by block, as chunk-like objects."""
        total = self.records if stop is None else stop
        per_block = max(1, _JOURNAL_BLOCK_BYTES // self.dtype.itemsize)
        with open(self.path, "rb") as fh:
            for start in range(0, total, per_block):
                rec = np.fromfile(fh, dtype=self.dtype, count=min(per_block, total - start))
                yield as_chunk({name: rec[name] for name in self.dtype.names})

    def close(self, *, delete: bool = False) -> None:
        """Close (releasing the lock); ``delete`` removes the file first, while still locked."""
        if self._fh.closed:
            return
        if delete:
            self.path.unlink(missing_ok=True)
        self._fh.close()


def check_journal(path: str | os.PathLike, keep_bytes: int, crc32: int) -> None:
    """Check, read-only, that the journal at ``path`` holds the prefix a checkpoint names.

    Raises
    ------
    CheckpointError
        If the journal is missing, shorter than ``keep_bytes`` or does not match ``crc32``.
    """
    try:
        with open(path, "rb") as fh:
            _check_prefix(fh, Path(path), keep_bytes, crc32)
    except FileNotFoundError:
        raise CheckpointError(f"{path}: the sample journal the checkpoint needs is missing") from None


def _check_prefix(fh: Any, path: Path, keep_bytes: int, crc32: int) -> None:
    size = os.fstat(fh.fileno()).st_size
    if size < keep_bytes:
        raise CheckpointError(f"{path}: damaged journal ({size} bytes, the checkpoint needs {keep_bytes})")
    crc = 0
    fh.seek(0)
    left = keep_bytes
    while left:
        block = fh.read(min(left, _JOURNAL_BLOCK_BYTES))
        if not block:
            raise CheckpointError(f"{path}: damaged journal (short read)")
        crc = zlib.crc32(block, crc)
        left -= len(block)
    if crc != crc32:
        raise CheckpointError(f"{path}: damaged journal (its samples do not match the checkpoint's CRC-32)")


#: Fields of a chunk itself; anything else in a record is one of its ``extra`` series.
_CHUNK_FIELDS = ("time", "step", "kinetic", "potential", "momentum", "angular_momentum", "positions", "velocities")


def as_chunk(arrays: dict[str, np.ndarray]) -> SimpleNamespace:
    """A chunk-like object for :meth:`orbitsim.io.trace.TraceWriter.append` (energy = T + U)."""
    fields = {name: arrays.get(name) for name in _CHUNK_FIELDS}
    extra = {name: arr for name, arr in arrays.items() if name not in _CHUNK_FIELDS}
    return SimpleNamespace(energy=arrays["kinetic"] + arrays["potential"], extra=extra, **fields)


def _lock(fh: Any, path: Path) -> None:
    """An exclusive advisory lock, dropped by the OS when the holder dies (SIGKILL included)."""
    if fcntl is None:  # Windows: no advisory locks; a concurrent resume is then the user's lookout
        return
    try:
        fcntl.flock(fh.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        raise CheckpointError(f"{path}: another orbitsim process is writing this run; stop it first") from None


def journal_is_locked(path: str | os.PathLike) -> bool:
    """Whether a live process holds the journal at ``path`` (False if there is none)."""
    if fcntl is None:
        return False
    try:
        fh = open(path, "rb")
    except OSError:
        return False
    with fh:
        try:
            fcntl.flock(fh.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            return True
        with contextlib.suppress(OSError):
            fcntl.flock(fh.fileno(), fcntl.LOCK_UN)
    return False
