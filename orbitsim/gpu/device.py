"""Is there a CUDA device to run on? One answer, one line when there is not.

``require_cuda()`` is the one gate for ``--device gpu`` and ``device: gpu``: it imports numba-cuda (never at
module level: the CPU paths must not load it), and raises :class:`GPUUnavailableError` with a line the CLI
prints as it is (exit 2, nothing written) when the extra is missing or ``numba.cuda.is_available()`` is False.
Under Numba's CUDA simulator (``NUMBA_ENABLE_CUDASIM=1``) ``is_available()`` is True and the kernels run on
the CPU, which is how the suite tests them.
"""

from __future__ import annotations

import os
from types import ModuleType

import numpy as np

NO_EXTRA = "no CUDA support installed: numba-cuda is missing; pip install -e '.[gpu]', or run without --device gpu"
NO_DEVICE = "no CUDA device: numba.cuda.is_available() is False; run without --device gpu"


class GPUUnavailableError(RuntimeError):
    """No usable CUDA device (or no numba-cuda): the message is the one line to print."""


def simulated() -> bool:
    """True when Numba's CUDA simulator stands in for a GPU (``NUMBA_ENABLE_CUDASIM=1``)."""
    return os.environ.get("NUMBA_ENABLE_CUDASIM", "0") not in ("", "0")


def _patch_numpy_for_numba_cuda() -> None:
    # numba-cuda 0.30 still calls np.row_stack at the first kernel launch; numpy 2.5 removed the alias
    # (seen on a CUDA 13 image: "module 'numpy' has no attribute 'row_stack'"). vstack is the same function.
    if not hasattr(np, "row_stack"):
        np.row_stack = np.vstack  # type: ignore[attr-defined]


def require_cuda() -> ModuleType:
    """Return ``numba.cuda`` when a device (or the simulator) can run kernels, else raise one line."""
    _patch_numpy_for_numba_cuda()
    try:
        from numba import cuda  # noqa: PLC0415 - lazy: loads numba-cuda, only for --device gpu
    except ImportError as err:
        raise GPUUnavailableError(NO_EXTRA) from err
    try:
        available = bool(cuda.is_available())
    except Exception:  # a broken driver reads as "no device", said in one line
        available = False
    if not available:
        raise GPUUnavailableError(NO_DEVICE)
    return cuda


def device_name() -> str:
    """The GPU's name for provenance and benchmark records ("CUDA simulator" under the simulator)."""
    cuda = require_cuda()
    if simulated():
        return "CUDA simulator"
    name = cuda.get_current_device().name
    return name.decode() if isinstance(name, bytes) else str(name)
