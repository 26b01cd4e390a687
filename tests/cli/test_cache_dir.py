"""``orbitsim cache`` and the cache directory a user's ``NUMBA_CACHE_DIR`` chooses (issue 27, item 8).

``cache info`` used to print ``~/.cache/orbitsim/numba/...`` while Numba wrote to the user's
``NUMBA_CACHE_DIR``, flat, where a callee's old machine code outlives an upgrade. Now that
variable is where orbitsim's generations go (``NUMBA_CACHE_DIR/orbitsim/<version>-<hash>``), and
``cache info`` says so. Each case runs in a fresh process: the directory is fixed at import.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from test_cli import TINY


def orbitsim(*args: str, cwd: Path, **env: str) -> subprocess.CompletedProcess[str]:
    clean = {k: v for k, v in os.environ.items() if k not in ("ORBITSIM_CACHE_DIR", "NUMBA_CACHE_DIR")}
    return subprocess.run([sys.executable, "-m", "orbitsim", *args], cwd=cwd, capture_output=True, text=True,
                          timeout=600, env={**clean, **env})


def test_cache_info_reports_the_numba_cache_dir_that_is_used(tmp_path: Path) -> None:
    numba_dir = tmp_path / "nb"
    (tmp_path / "tiny.yaml").write_text(TINY, encoding="utf-8")
    ran = orbitsim("run", "tiny.yaml", "-q", cwd=tmp_path, NUMBA_CACHE_DIR=str(numba_dir))
    assert ran.returncode == 0, ran.stderr
    (generation,) = (numba_dir / "orbitsim").iterdir()  # the kernels went there, keyed by the build
    assert any(generation.rglob("*.nbi")) and not any(p.suffix == ".nbi" for p in numba_dir.iterdir())
    info = orbitsim("cache", "info", cwd=tmp_path, NUMBA_CACHE_DIR=str(numba_dir))
    assert info.returncode == 0, info.stderr
    current, root = info.stdout.splitlines()
    assert current.startswith(f"current: {generation} (") and not current.endswith("(0.0 MiB)"), current
    assert root == f"root:    {numba_dir / 'orbitsim'} (1 generation(s); from NUMBA_CACHE_DIR)", root


def test_orbitsim_cache_dir_still_comes_first_and_children_share_it(tmp_path: Path) -> None:
    ours = tmp_path / "ours"
    info = orbitsim("cache", "info", cwd=tmp_path, ORBITSIM_CACHE_DIR=str(ours), NUMBA_CACHE_DIR=str(tmp_path / "nb"))
    assert info.returncode == 0 and info.stdout.splitlines()[1].startswith(f"root:    {ours} ("), info.stdout
    assert info.stdout.splitlines()[1].endswith("from ORBITSIM_CACHE_DIR)")
    # A child (a Dask worker) inherits NUMBA_CACHE_DIR = this generation: it must use the same one,
    # not read it as a user's setting and nest another generation inside it.
    probe = ("import os, subprocess, sys\nfrom orbitsim._jit import CACHE_DIR\n"
             "child = subprocess.run([sys.executable, '-c', 'from orbitsim._jit import CACHE_DIR; print(CACHE_DIR)'],"
             " capture_output=True, text=True, env=dict(os.environ)).stdout.strip()\nprint(CACHE_DIR, child)")
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=300,
                         env={**{k: v for k, v in os.environ.items() if k not in ("ORBITSIM_CACHE_DIR",)},
                              "NUMBA_CACHE_DIR": str(tmp_path / "nb")})
    parent, child = out.stdout.split()
    assert parent == child and Path(parent).parent == tmp_path / "nb" / "orbitsim", out
