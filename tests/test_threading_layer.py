"""A cached kernel that embeds a prange kernel loads safely in a fresh process, whatever called it first.

Numba #8578: a plain @jit caller (``gravity.accelerations``) compiled in a process that loaded its
``prange`` callee (``gravity.accelerations_parallel``) from the on-disk cache is cached with the threading
layer's symbols in it; a later process that loads it before the layer has started dies of SIGSEGV. A
helper's suite hit it (a GPU-simulator test script calls ``accelerations`` directly). ``orbitsim._jit``
starts the layer on import, so no Python caller can reach such a kernel first.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

SCRIPT = """
import sys
import numpy as np
from orbitsim.physics import gravity
n = 64
pos = np.random.default_rng(1).normal(size=(3, n))
m, acc = np.ones(n) / n, np.zeros((3, n))
slabs, bounds = gravity.force_scratch(n)
getattr(gravity, sys.argv[1])(pos, m, 1.0, 0.0, acc, slabs, bounds)
print(repr(float(acc[0, 0])))
"""


def test_a_caller_compiled_against_a_cached_parallel_kernel_loads_in_a_fresh_process(tmp_path: Path) -> None:
    env = {**os.environ, "ORBITSIM_CACHE_DIR": str(tmp_path / "cache")}
    env.pop("NUMBA_CACHE_DIR", None)
    results = []
    # 1: the parallel kernel alone (compiled and cached); 2: its caller compiled against the cached kernel;
    # 3: the caller loaded from the cache by a process that has run nothing parallel before
    for name in ("accelerations_parallel", "accelerations", "accelerations"):
        done = subprocess.run([sys.executable, "-c", SCRIPT, name], env=env, capture_output=True, text=True,
                              timeout=600)
        assert done.returncode == 0, f"{name}: exit {done.returncode}: {done.stderr[-400:]}"
        results.append(done.stdout.strip())
    assert results[0] == results[1] == results[2]  # the serial path at one block: the same bits from each
