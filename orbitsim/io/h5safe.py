"""HDF5 files that fail cleanly: an I/O error (a full disk) ends in one exception, never a crash.

What happens without this, measured on a 2 MB tmpfs: once a write has failed, HDF5 keeps its dirty
chunks and metadata and retries them at every later call, at ``close`` and in its own shutdown at
interpreter exit. h5py reports the failures raised in object destructors as "Exception ignored"
tracebacks (37 of them in one run), and the flush at exit crashed the interpreter (SIGSEGV, exit
code 139), leaving a 2 MB ``.tmp`` behind.

The cures, each measured against a write layer that fails every call from the Nth on
(``tests/fault_shim.c``):

* :func:`discard`: a file being abandoned has its descriptor pointed at ``/dev/null`` (``dup2``), so
  every write HDF5 still has pending succeeds into nothing, ``close`` completes, and the file can be
  unlinked. It also makes an ordinary abort cheaper: nothing is flushed to a file about to be
  deleted. The descriptor is read (:func:`vfd_handle`) while the file is healthy: asked for it
  after a failed close, HDF5 crashed.
* :func:`surfaced`: a write that fails in an h5py object's destructor (a dataset released while its
  data are still cached) is only printed by Python; inside this block it is caught and raised at
  the block's end, where the caller can discard the file.
* Small files are built in memory (:func:`in_memory`) and reach the disk as one plain write of their
  image (:func:`write_image`), or are copied into a trace in one HDF5 call, so no HDF5 object that
  could fail on release ever points at the disk.

:func:`io_failure` turns the error (HDF5's long text, or the OS's) into a
:class:`~orbitsim.io.schema.OutputWriteError` whose message is one line naming the path and the cause.
"""

from __future__ import annotations

import contextlib
import errno as errno_codes
import itertools
import os
import re
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import h5py

from orbitsim.io.schema import OutputWriteError

__all__ = ["H5_WRITE_ERRORS", "create", "discard", "in_memory", "io_failure", "new_file", "reason", "surfaced",
           "vfd_handle", "write_image"]

#: What h5py raises when HDF5 fails to write: OSError mostly, but RuntimeError for some layers
#: ("Can't flush entry", "Can't decrement id ref count"), both seen under injected ENOSPC.
H5_WRITE_ERRORS = (OSError, RuntimeError)
#: HDF5 puts the OS's error in its message as ``errno = 28, error message = '...'``.
_HDF5_REASON = re.compile(r"error message = '([^']*)'")
_HDF5_ERRNO = re.compile(r"errno = (\d+)")


def reason(err: BaseException) -> str:
    """The OS's words for an I/O error (``No space left on device``), whatever layer raised it."""
    if isinstance(err, OutputWriteError):
        return err.cause
    code = getattr(err, "errno", None)
    if isinstance(code, int) and code in errno_codes.errorcode:
        return os.strerror(code)
    found = _HDF5_REASON.search(str(err))
    if found:
        return found.group(1)
    return getattr(err, "strerror", None) or " ".join(str(err).split()) or type(err).__name__


def io_failure(err: BaseException, message: str, filename: str | os.PathLike = "") -> OutputWriteError:
    """A :class:`OutputWriteError` for ``err`` whose text is ``message`` with ``{reason}`` filled in."""
    code = getattr(err, "errno", None)
    if not isinstance(code, int):
        found = _HDF5_ERRNO.search(str(err))
        code = int(found.group(1)) if found else None
    cause = reason(err)
    return OutputWriteError(code, message.format(reason=cause), os.fspath(filename), cause)


@contextlib.contextmanager
def surfaced() -> Iterator[None]:
    """Raise, at the end of the block, the first HDF5 write error an h5py destructor reported inside it."""
    captured: list[BaseException] = []
    previous = sys.unraisablehook

    def hook(report: Any) -> None:
        if isinstance(report.exc_value, H5_WRITE_ERRORS):
            captured.append(report.exc_value)
        else:
            previous(report)

    sys.unraisablehook = hook
    try:
        yield
    finally:
        sys.unraisablehook = previous
    if captured:
        raise captured[0]


@contextlib.contextmanager
def _quiet_destructors() -> Iterator[None]:
    """Swallow the "Exception ignored" reports of h5py destructors while a file is abandoned."""
    previous = sys.unraisablehook
    sys.unraisablehook = lambda _: None
    try:
        yield
    finally:
        sys.unraisablehook = previous


def vfd_handle(f: Any) -> int | None:
    """The file descriptor under an open HDF5 file (the default ``sec2`` driver), read while the
    file is healthy: after a failed ``close`` HDF5 can crash when asked for it."""
    try:
        handle = f.id.get_vfd_handle()
    except Exception:  # a driver without a descriptor
        return None
    return handle if isinstance(handle, int) and handle >= 0 else None


def discard(f: Any, handle: int | None) -> None:
    """Close an HDF5 file whose contents are not wanted, without writing them (see the module
    docstring); ``handle`` is its :func:`vfd_handle`. Errors are ignored: the file is about to be
    deleted."""
    with _quiet_destructors():
        if handle is not None:
            null = os.open(os.devnull, os.O_RDWR)
            try:
                os.dup2(null, handle)
            finally:
                os.close(null)
        with contextlib.suppress(Exception):
            f.close()


def create(path: Path) -> h5py.File:
    """``h5py.File(path, "w")``; a file left half-created by a failure (a full disk) is removed, but
    not one that another process has locked (HDF5's ``EAGAIN``)."""
    try:
        return h5py.File(path, "w")
    except OSError as err:
        if getattr(err, "errno", None) != errno_codes.EAGAIN:
            path.unlink(missing_ok=True)
        raise


_memory_files = itertools.count()


@contextlib.contextmanager
def in_memory() -> Iterator[h5py.File]:
    """A new HDF5 file that exists in memory only (the ``core`` driver, no backing store)."""
    f = h5py.File(f"orbitsim-memory-{os.getpid()}-{next(_memory_files)}.h5", "w", driver="core",
                  backing_store=False)
    try:
        yield f
    finally:
        f.close()


@contextlib.contextmanager
def new_file(path: str | os.PathLike) -> Iterator[h5py.File]:
    """Create the HDF5 file ``path`` for the ``with`` block and close it at the end.

    The block should set attributes and copy in groups built :func:`in_memory` (``f.copy(group,
    name)``), so that no object of the file outlives a call with data still to write. Any I/O
    error in the block or at the close discards the file, removes it, and raises one
    :class:`~orbitsim.io.schema.OutputWriteError` naming ``path`` and the cause.
    """
    path = Path(path)
    try:
        f = create(path)
    except H5_WRITE_ERRORS as err:
        raise io_failure(err, f"{path}: {{reason}}", path) from None
    handle = vfd_handle(f)
    try:
        with surfaced():
            yield f
            f.close()
    except H5_WRITE_ERRORS as err:
        discard(f, handle)
        path.unlink(missing_ok=True)
        raise io_failure(err, f"{path}: {{reason}} (the file was removed)", path) from None
    except BaseException:
        discard(f, handle)
        path.unlink(missing_ok=True)
        raise


def write_image(f: h5py.File, path: Path) -> None:
    """Write the in-memory file ``f`` to ``path`` as plain bytes: a failure is an ordinary OSError,
    and ``path`` is then removed."""
    f.flush()
    data = memoryview(f.id.get_file_image())
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
    try:
        written = 0
        while written < len(data):  # a write may write less than asked
            written += os.write(fd, data[written:])
    except OSError:
        os.close(fd)
        path.unlink(missing_ok=True)
        raise
    os.close(fd)
