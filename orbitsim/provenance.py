"""Run provenance: software versions and host description stored with every result.

numba is deliberately *not* imported here: importing it costs about a second and
this module is used by light commands (``info``) as well; versions are read from
package metadata instead, and the thread count from ``NUMBA_NUM_THREADS``, which
is what numba itself consults at start-up.
"""

from __future__ import annotations

import functools
import os
import platform
import socket
from importlib import metadata

from orbitsim._version import __version__

__all__ = ["provenance"]

NOT_INSTALLED = "not installed"
_PACKAGES = ("numpy", "numba", "llvmlite", "h5py", "rebound")


def _package_version(name: str) -> str:
    """Return the installed version of distribution `name`, or ``"not installed"``."""
    try:
        return metadata.version(name)
    except metadata.PackageNotFoundError:
        return NOT_INSTALLED


def _cpu_model() -> str:
    """Return the CPU model name from /proc/cpuinfo, else ``platform.processor()``."""
    try:
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as fh:
            for line in fh:
                key, sep, value = line.partition(":")
                if sep and key.strip() == "model name":
                    return value.strip()
    except OSError:
        pass  # not Linux, or /proc unavailable: fall through to the portable guess
    return platform.processor() or "unknown"


def _numba_threads(cpu_count: int) -> int:
    """Thread count numba will use, without importing numba."""
    raw = os.environ.get("NUMBA_NUM_THREADS", "").strip()
    try:
        return int(raw) if raw else cpu_count
    except ValueError:
        # numba would refuse to start with a malformed value; record the default
        # rather than failing a provenance call over it.
        return cpu_count


@functools.lru_cache(maxsize=1)
def _static_provenance() -> tuple[tuple[str, str | int], ...]:
    """Facts that cannot change during a process's lifetime (cached; a tuple so it is immutable)."""
    items: list[tuple[str, str | int]] = [
        ("orbitsim_version", __version__),
        ("python_version", platform.python_version()),
        ("python_implementation", platform.python_implementation()),
        ("platform", platform.platform()),
    ]
    items += [(f"{pkg}_version", _package_version(pkg)) for pkg in _PACKAGES]
    items += [
        ("cpu_model", _cpu_model()),
        ("cpu_count", os.cpu_count() or 1),
        ("hostname", socket.gethostname()),
    ]
    return tuple(items)


def provenance() -> dict[str, str | int]:
    """Describe the software and host producing a result.

    Returns
    -------
    dict[str, str | int]
        Keys ``orbitsim_version``, ``python_version``, ``python_implementation``,
        ``platform``, ``numpy_version``, ``numba_version``, ``llvmlite_version``,
        ``h5py_version``, ``rebound_version`` (``"not installed"`` when missing),
        ``cpu_model``, ``cpu_count``, ``numba_threads`` and ``hostname``.
        A fresh dict is returned on each call, so callers may modify it.

    Notes
    -----
    Everything except ``numba_threads`` is computed once per process;
    ``numba_threads`` re-reads ``NUMBA_NUM_THREADS`` on every call because
    a driver may set it before spawning workers.
    """
    info = dict(_static_provenance())
    info["numba_threads"] = _numba_threads(int(info["cpu_count"]))
    return info
