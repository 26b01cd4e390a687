"""``rsqrt(x) = 1 / sqrt(x)`` on the device, for the direct sum's and the ensemble's gravity.

On a GPU it is ``numba.cuda.libdevice.rsqrt`` (1.4x over ``1 / sqrt`` on an H100, issue 30; it rounds
differently from the CPU's division, so GPU results are not the CPU's bits: docs/gpu.md). Under Numba's
CUDA simulator the libdevice functions are stubs that return None, so it is the same quantity by division,
in numpy's float64 so that ``1 / 0`` is inf as on the device (Python's floats would raise).
"""

from __future__ import annotations

import math

import numpy as np

from orbitsim._jit import cuda_device
from orbitsim.gpu.device import simulated

__all__ = ["rsqrt"]

if simulated():
    @cuda_device
    def rsqrt(x):
        """1 / sqrt(x) (the simulator's stand-in for libdevice.rsqrt)."""
        return np.float64(1.0) / np.float64(math.sqrt(x))
else:  # pragma: no cover - hardware only (benchmarks/gpu_check.py)
    from numba.cuda.libdevice import rsqrt
