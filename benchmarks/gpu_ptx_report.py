"""Compile the GPU ensemble's kernels for an H100 (sm_90) on a machine without a GPU, and report what they cost.

For each kernel of :mod:`orbitsim.gpu.ensemble_kernels` at a body count N, prints one JSON line: the
seconds numba-cuda and NVVM took, the PTX's local-memory bytes (arrays indexed at run time live there,
not in registers), its ``rsqrt`` and FP64 ``fma`` counts, and, where ``ptxas`` is found, the registers,
stack frame and spill bytes of the machine code. No kernel runs: this is the check that the kernels
compile for the device at all (the CUDA simulator runs them as Python and cannot tell), and the
compiler's resource report, worth reading before any device time is spent.

Needs libnvvm, libdevice and NVRTC (and ptxas for the second half), e.g. from PyPI::

    pip install --target /tmp/cu nvidia-nvvm nvidia-cuda-nvrtc nvidia-cuda-nvcc
    LD_LIBRARY_PATH=/tmp/cu/nvidia/cu13/lib python benchmarks/gpu_ptx_report.py --site /tmp/cu --n 4 5

numba-cuda asks the current device for its compute capability when it compiles a device function;
without a device this script answers (9, 0) for it and reports ``is_available()`` as True, for this
process only.
"""

from __future__ import annotations

import argparse
import json
import re
import shutil
import subprocess
import sys
import tempfile
import time
import types
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the project, where it is not installed


def _pretend_sm90(site: str | None) -> None:
    if site:
        sys.path.insert(0, site)
    import numba.cuda
    import numba.cuda.dispatcher as dispatcher

    numba.cuda.is_available = lambda: True
    dispatcher.get_current_device = lambda: types.SimpleNamespace(compute_capability=(9, 0))


def _ptxas(site: str | None) -> str | None:
    """The ``--site`` folder's ptxas (the version of its NVVM), else the one on PATH."""
    candidates = sorted(Path(site).glob("nvidia/*/bin/ptxas")) if site else []
    return str(candidates[0]) if candidates else shutil.which("ptxas")


def report(n: int, site: str | None) -> list[dict[str, object]]:
    from numba import cuda
    from numba.cuda import boolean, float64, int64

    from orbitsim.gpu import ensemble_kernels

    a3, a2, i1 = float64[:, :, ::1], float64[:, ::1], int64[::1]
    scalars = (float64, float64, float64, int64, float64, boolean)
    signatures = {
        "leapfrog": (lambda n, w: ensemble_kernels.fixed_step_kernel(n, w, "leapfrog"),
                     (a3, a3, a2, a2, a2, a2, *scalars, i1, i1, a2)),
        "verlet": (lambda n, w: ensemble_kernels.fixed_step_kernel(n, w, "verlet"),
                   (a3, a3, a2, a2, a2, a2, *scalars, i1, i1, a2)),
        "wisdom_holman_megno": (ensemble_kernels.wh_variational_kernel,
                                (a3, a3, a3, a3, a2, a2, a2, a2, *scalars, i1, i1, a2)),
    }
    ptxas = _ptxas(site)
    out = []
    for name, (factory, signature) in signatures.items():
        started = time.perf_counter()
        ptx, _ = cuda.compile_ptx(factory(n, n - 1).py_func, signature, cc=(9, 0))
        record: dict[str, object] = {
            "kernel": name, "n": n, "compile_s": round(time.perf_counter() - started, 2),
            "local_bytes": sum(int(b) for b in re.findall(r"\.local\s+\.align\s+\d+\s+\.b8\s+\S+\[(\d+)\]", ptx)),
            "rsqrt": ptx.count("rsqrt"), "fma_f64": ptx.count("fma.rn.f64"), "calls": ptx.count("call.uni"),
        }
        if ptxas is not None:
            with tempfile.TemporaryDirectory() as tmp:
                source = Path(tmp) / "kernel.ptx"
                source.write_text(ptx, encoding="utf-8")
                done = subprocess.run([ptxas, "-arch=sm_90", "-v", str(source), "-o", str(Path(tmp) / "k.cubin")],
                                      capture_output=True, text=True, check=True)
            text = done.stderr + done.stdout
            for key, pattern in (("registers", r"Used (\d+) registers"), ("stack_bytes", r"(\d+) bytes stack frame"),
                                 ("spill_store_bytes", r"(\d+) bytes spill stores"),
                                 ("spill_load_bytes", r"(\d+) bytes spill loads")):
                match = re.search(pattern, text)
                record[key] = int(match.group(1)) if match else None
        out.append(record)
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--n", type=int, nargs="+", default=[4, 5], help="body counts (default: 4 5)")
    parser.add_argument("--site", default=None, help="a --target folder holding nvidia-nvvm etc. (added to sys.path)")
    args = parser.parse_args(argv)
    _pretend_sm90(args.site)
    for n in args.n:
        for record in report(n, args.site):
            print(json.dumps(record, sort_keys=True), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
