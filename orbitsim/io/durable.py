"""Durable files: make written bytes survive a crash, and publish a finished file atomically.

A rename is atomic, but without fsync a crash may still leave the new name pointing at a file
whose data never reached the disk; hence fsync the file, rename, then fsync the directory
(:func:`replace_durably`). A text file (an exported scenario, a CSV) is written under a temporary
name beside its target and published that way once complete (:func:`pending_text`,
:func:`write_atomically`), so a failure leaves nothing half-written.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import IO, Any

__all__ = ["PendingText", "datasync", "fsync_path", "pending_text", "replace_durably", "write_atomically"]


def fsync_path(path: Path, *, best_effort: bool = False) -> None:
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


def datasync(fd: int) -> None:
    """Make a file's data (and the size needed to read it back) durable: ``fdatasync`` where the OS
    has it, which skips the timestamps ``fsync`` would also write."""
    getattr(os, "fdatasync", os.fsync)(fd)


def replace_durably(tmp: Path, path: Path) -> None:
    """Move the finished file ``tmp`` onto ``path``: fsync it, rename (atomic), fsync the directory.

    A kill at any instant leaves either the previous file or the new one at ``path``.
    """
    fsync_path(tmp)
    os.replace(tmp, path)
    fsync_path(path.parent, best_effort=True)


class PendingText:
    """A text file being written under a temporary name; :meth:`done` marks it complete."""

    def __init__(self, target: Path) -> None:
        self.target = target
        self.tmp = target.with_name(f".{target.name}.tmp{os.getpid()}")
        self.file: IO[str] = open(self.tmp, "w", encoding="utf-8", newline="")  # closed by pending_text
        self.complete = False

    def done(self) -> None:
        self.complete = True


@contextlib.contextmanager
def pending_text(target: str | os.PathLike[str]) -> Iterator[PendingText]:
    """Write to a temporary file; rename it onto ``target`` only if :meth:`PendingText.done` was called
    and no error occurred, else remove it. Write errors become one :class:`OutputWriteError` line."""
    from orbitsim.io.h5safe import io_failure  # noqa: PLC0415 -- lazy: loads h5py, which a plain durable rename does not need

    path = Path(target)
    try:
        pending = PendingText(path)
    except OSError as err:
        raise io_failure(err, f"{path}: {{reason}} (nothing was written)", path) from None
    try:
        yield pending
        pending.file.close()
        if pending.complete:
            replace_durably(pending.tmp, path)
    except OSError as err:
        raise io_failure(err, f"{path}: {{reason}} (nothing was written)", path) from None
    finally:
        pending.file.close()
        pending.tmp.unlink(missing_ok=True)


def write_atomically(target: str | os.PathLike[str], write: Callable[[IO[str]], Any]) -> None:
    """Write a text file with ``write(file)`` under a temporary name, then rename it onto ``target``."""
    with pending_text(target) as pending:
        write(pending.file)
        pending.done()
