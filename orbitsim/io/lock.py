"""One writer per output path: an exclusive lock on ``<OUT>.lock``, taken before anything is touched.

Every command that writes a run's output (``run``, ``resume``, ``run --from``, a batch worker's run)
holds :func:`hold_output` on that path from before its first check until its last rename. A second
process asking for the same path is refused at once with :class:`OutputBusyError` (one line, exit
code 2), before it has truncated, deleted or renamed anything.

Why a lock file of our own:

* HDF5's file lock covers the file HDF5 has open, ``<OUT>.tmp``, and only once ``h5py.File(tmp, "w")``
  has already truncated it: a second run used to wipe the first run's samples and then fail.
  The lock must cover the *output path* and every file beside it, and be taken first.
* ``flock`` is advisory and dropped by the kernel when its holder dies, SIGKILL included, so a
  killed run never blocks the next one: its lock file is left behind, unlocked.

The lock file holds one JSON line about its holder (pid, host, start time, the command line and
working directory). A holder removes it when it finishes; one found unlocked belongs to a run
that was killed, which ``orbitsim resume`` reads (:attr:`OutputLock.previous`) to say what
happened and how to rerun it.

Removal is safe against a waiter: the holder unlinks the path while still holding the lock, and
an acquirer checks, once locked, that the path still names the inode it locked (else it retries),
so two processes can never each hold a lock on a different file of the same name.

Holding is re-entrant within one thread (``run_scenario`` inside ``orbitsim resume``, which
holds the lock across its preparation and the run), and exclusive between threads.
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import shlex
import socket
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from orbitsim.io.schema import OutputBusyError, OutputError, OutputWriteError

try:
    import fcntl
except ImportError:  # Windows: no advisory locks (each use says what happens then)
    fcntl = None

__all__ = ["OutputLock", "clear_abandoned_lock", "current_holder", "describe_holder", "hold_output", "lock_path",
           "rerun_command"]

_ATTEMPTS = 20  # a lock file replaced under us this many times in a row means something is wrong


def lock_path(output: str | os.PathLike) -> Path:
    """``<OUT>.lock``: the lock of the process writing ``OUT``."""
    return Path(f"{os.fspath(output)}.lock")


class OutputLock:
    """The lock on one output path, held by this process (see the module docstring).

    Attributes
    ----------
    output : Path
        The output path it guards.
    previous : dict or None
        What the lock file said before this process took it: the holder of an earlier run that
        ended without removing it (killed), or None when there was no such file.
    """

    def __init__(self, output: Path, fd: int, previous: dict[str, Any] | None) -> None:
        self.output, self._fd, self.previous = output, fd, previous
        self.owner = threading.get_ident()
        self.depth = 1
        self._restore = False

    def keep_previous(self) -> None:
        """On release, put back the earlier holder's record instead of removing the file: this
        holder changed nothing (``resume`` found nothing to resume), and the next one should read
        the same story."""
        self._restore = self.previous is not None

    def release(self) -> None:
        """Remove the lock file (while still holding it), then drop the lock."""
        with contextlib.suppress(OSError):
            if self._restore:
                os.ftruncate(self._fd, 0)
                os.pwrite(self._fd, (json.dumps(self.previous) + "\n").encode(), 0)
            else:
                lock_path(self.output).unlink()
        os.close(self._fd)


_HELD: dict[str, OutputLock] = {}
_HELD_GUARD = threading.Lock()


def _holder_info() -> dict[str, Any]:
    return {"pid": os.getpid(), "host": socket.gethostname(), "started": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
            "argv": list(sys.argv), "cwd": os.getcwd()}


def _read_info(fd: int) -> dict[str, Any] | None:
    try:
        text = os.pread(fd, 65536, 0).decode("utf-8", errors="replace").strip()
        info = json.loads(text) if text else None
    except (OSError, ValueError):
        return None
    return info if isinstance(info, dict) else None


def describe_holder(info: dict[str, Any] | None) -> str:
    """``pid 123 on host, since 2026-11-24T03:41:02, `orbitsim run long.yaml -o same.h5```."""
    if not info:
        return "an unknown process"
    text = f"pid {info.get('pid', '?')} on {info.get('host', '?')}, since {info.get('started', '?')}"
    command = rerun_command(info)
    return f"{text}: `{command}`" if command else text


def rerun_command(info: dict[str, Any] | None) -> str:
    """The ``orbitsim ...`` command line a holder was started with, or "" when it was not the CLI
    (the Python API, a batch worker)."""
    argv = (info or {}).get("argv") or []
    if not argv or not isinstance(argv, list):
        return ""
    program = str(argv[0]).replace("\\", "/")
    if not (program.endswith("/orbitsim") or program == "orbitsim" or program.endswith("orbitsim/__main__.py")):
        return ""
    return shlex.join(["orbitsim", *map(str, argv[1:])])


#: Errors that say the directory is not ours to write (exit code 2), rather than a failing device.
_NOT_WRITABLE = (errno.EROFS, errno.EACCES, errno.EPERM, errno.ENOENT, errno.ENOTDIR)


def _cannot_write(output: Path, err: OSError) -> OSError | OutputError:
    where = output.parent if str(output.parent) else Path(".")
    if err.errno in _NOT_WRITABLE:
        return OutputError(f"{output}: cannot write in {where}: {err.strerror or err}")
    return OutputWriteError(err.errno, f"{output}: {err.strerror or err} while writing its lock file in {where}; "
                            "nothing was written", os.fspath(lock_path(output)), err.strerror or "")


def _acquire(output: Path) -> OutputLock:
    path = lock_path(output)
    for _ in range(_ATTEMPTS):
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        except OSError as err:
            raise _cannot_write(output, err) from None
        if fcntl is None:  # Windows: no advisory locks; a second writer is then the user's lookout
            return OutputLock(output, fd, None)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            holder = describe_holder(_read_info(fd))
            os.close(fd)
            raise OutputBusyError(f"{output}: another orbitsim process is writing this output ({holder}); wait for "
                                  "it to finish, or write elsewhere with -o") from None
        try:
            same = os.fstat(fd).st_ino == os.stat(path).st_ino
        except FileNotFoundError:
            same = False
        if not same:  # its holder removed it between our open and our lock: take the new one
            os.close(fd)
            continue
        previous = _read_info(fd)
        try:
            os.ftruncate(fd, 0)
            os.pwrite(fd, (json.dumps(_holder_info()) + "\n").encode(), 0)
        except OSError as err:
            with contextlib.suppress(OSError):
                path.unlink()
            os.close(fd)
            raise _cannot_write(output, err) from None
        return OutputLock(output, fd, previous)
    raise OutputBusyError(f"{output}: its lock file {path} keeps being replaced; is another program removing it?")


def current_holder(output: str | os.PathLike) -> dict[str, Any] | None:
    """The record of the live process writing ``output`` now, or None when none is (read-only:
    the lock is only tested, never taken)."""
    if fcntl is None:
        return None
    try:
        fd = os.open(lock_path(output), os.O_RDONLY)
    except OSError:
        return None
    try:
        fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
    except OSError:
        return _read_info(fd) or {}
    finally:
        os.close(fd)  # also drops the shared lock, if it was granted
    return None


@contextlib.contextmanager
def hold_output(output: str | os.PathLike) -> Iterator[OutputLock]:
    """Hold the lock on ``output`` for the ``with`` block (re-entrant in one thread).

    Raises
    ------
    OutputBusyError
        If another process (or another thread of this one) holds it.
    OutputError
        If ``output`` is a directory, or the lock file cannot be created beside it: the directory
        is missing, read-only or not ours.
    """
    output = Path(output)
    if output.is_dir():  # checked before a lock file is made beside it
        raise OutputError(f"{output}: is a directory; give a file name inside it")
    if not output.parent.is_dir():
        raise OutputError(f"{output}: directory {output.parent} does not exist")
    key = os.path.abspath(output)
    with _HELD_GUARD:
        held = _HELD.get(key)
        if held is not None and held.owner != threading.get_ident():
            raise OutputBusyError(f"{output}: another run in this process is writing this output")
        if held is None:
            held = _HELD[key] = _acquire(output)
        else:
            held.depth += 1
    try:
        yield held
    finally:
        with _HELD_GUARD:
            held.depth -= 1
            if held.depth == 0:
                del _HELD[key]
                held.release()


def clear_abandoned_lock(output: str | os.PathLike) -> bool:
    """Remove ``<OUT>.lock`` and ``<OUT>.tmp`` when the run that left them is gone; True if it was.

    The holder is gone when its lock can be taken: ``flock`` is dropped by the kernel when its
    holder dies, SIGKILL included, and the record in the file (pid, host) is only what it was. The
    lock is taken as a run takes it (:func:`hold_output`), so this never races a run starting on
    the same output; the ``.tmp`` is then nobody's (a run truncates it under the same lock), and
    releasing the lock removes its file. A live holder's files are left alone (False).

    ``orbitsim batch`` calls it for each run of a sweep, so the files of runs killed with it (a
    shutdown, SIGTERM, SIGKILL) do not outlive a rerun that reuses their finished traces.
    """
    output = Path(output)
    if not lock_path(output).exists():
        return False
    try:
        with hold_output(output):
            Path(f"{os.fspath(output)}.tmp").unlink(missing_ok=True)
    except OutputError:  # a live holder (OutputBusyError), or the directory is not ours to change
        return False
    return True
