"""``orbitsim._jit.wide_vectors``: 512-bit vectors in the function that calls it, with the same bits.

The ensemble's lane kernels call it first thing (benchmarks/README.md, "Eighth pass"): LLVM's attribute
``"prefer-vector-width"="512"`` on their LLVM function, so that on an AVX-512 CPU their lane loops use zmm
registers where LLVM would otherwise stop at 256 bits. The lane kernels' own tests (tests/ensemble/) check
their bits against the scalar kernels; here a small lane loop, written as the kernels write theirs (one
flat array, rows at constant offsets), checks the mechanism itself: compiled with and without the call in
a process of its own with an empty cache (a function loaded from the cache has no LLVM IR to look at).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

from orbitsim._jit import wide_vectors

ATTRIBUTE = '"prefer-vector-width"="512"'

#: One lane loop, written as the kernels write theirs: one flat array, rows at constant offsets. A loop of 16
#: this short is unrolled first and then left scalar (benchmarks/README.md, fifth pass), hence 64 lanes.
LOOP = """
    for lane in range(64):
        x, y, z = g[lane], g[64 + lane], g[128 + lane]
        r2 = x * x + y * y + z * z
        k = a / (r2 * math.sqrt(r2))
        g[192 + lane] = k * x
        g[256 + lane] = k * y
        g[320 + lane] = k * z
"""

PROBE = f'''
import json
import math

import llvmlite.binding as llvm
import numpy as np
from orbitsim._jit import jit, wide_vectors


@jit
def lanes(g, a):
    wide_vectors()
{LOOP}

@jit
def lanes_default(g, a):
{LOOP}

g = np.random.default_rng(5).uniform(0.5, 2.0, 384)
h = g.copy()
lanes(g, 1.0 / 3.0)
lanes_default(h, 1.0 / 3.0)
print(json.dumps({{
    "same_bits": g.tobytes() == h.tobytes(),
    "attribute": [{ATTRIBUTE!r} in f.inspect_llvm(f.signatures[0]) for f in (lanes, lanes_default)],
    "zmm": "zmm" in lanes.inspect_asm(lanes.signatures[0]),
    "avx512f": "+avx512f" in llvm.get_host_cpu_features().flatten(),
}}))
'''


def test_the_caller_gets_the_attribute_and_keeps_its_bits(tmp_path: Path) -> None:
    probe = tmp_path / "probe.py"
    probe.write_text(PROBE, encoding="utf-8")
    env = {**os.environ, "ORBITSIM_CACHE_DIR": str(tmp_path / "cache")}
    env.pop("NUMBA_CACHE_DIR", None)
    done = subprocess.run([sys.executable, str(probe)], capture_output=True, text=True, env=env, timeout=300)
    assert done.returncode == 0, done.stderr
    found = json.loads(done.stdout.strip().splitlines()[-1])
    assert found["same_bits"]  # no fastmath: the register width moves no bit
    assert found["attribute"] == [True, False]
    if found["avx512f"]:
        assert found["zmm"]  # what the attribute is for


def test_called_from_python_it_does_nothing() -> None:
    assert wide_vectors() is None
