"""Durable files: make written bytes survive a crash, and publish a finished file atomically.

A rename is atomic, but without fsync a crash may still leave the new name pointing at a file
whose data never reached the disk; hence fsync the file, rename, then fsync the directory.
"""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ["datasync", "fsync_path", "replace_durably"]


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
