"""``orbitsim cache``: where compiled kernels live, and how to clear them."""

from __future__ import annotations

import shutil

import click


@click.group("cache")
def command() -> None:
    """Inspect or clear the on-disk cache of compiled Numba kernels.

    \b
    Example:
      orbitsim cache info
      orbitsim cache clear
    """


@command.command("info")
def info() -> None:
    """Print the cache directory of this orbitsim build and its size, and the root of every build's
    (set by ORBITSIM_CACHE_DIR, else NUMBA_CACHE_DIR/orbitsim, else ~/.cache/orbitsim/numba).

    Example: orbitsim cache info
    """
    import numba

    from orbitsim._jit import CACHE_DIR, CACHE_ROOT, CACHE_ROOT_FROM

    root = CACHE_ROOT
    generations = sorted(p for p in root.iterdir() if p.is_dir()) if root.exists() else []
    size = sum(f.stat().st_size for f in CACHE_DIR.rglob("*") if f.is_file()) if CACHE_DIR.exists() else 0
    used = numba.config.CACHE_DIR  # what Numba writes to: the current generation, checked here
    current = CACHE_DIR if str(CACHE_DIR) == used else f"{used} (Numba's; orbitsim's would be {CACHE_DIR})"
    chosen = {"ORBITSIM_CACHE_DIR": "from ORBITSIM_CACHE_DIR", "NUMBA_CACHE_DIR": "from NUMBA_CACHE_DIR",
              "XDG_CACHE_HOME": "from XDG_CACHE_HOME", "default": "the default"}[CACHE_ROOT_FROM]
    click.echo(f"current: {current} ({size / 2**20:.1f} MiB)")
    click.echo(f"root:    {root} ({len(generations)} generation(s); {chosen})")


@command.command("clear")
@click.option("--all", "clear_all", is_flag=True, help="Also remove the current build's cache.")
def clear(clear_all: bool) -> None:
    """Remove stale cache generations (and, with --all, the current one).

    Example: orbitsim cache clear --all
    """
    from orbitsim._jit import CACHE_DIR, CACHE_ROOT

    root = CACHE_ROOT
    removed = 0
    if root.exists():
        for path in root.iterdir():
            if path.is_dir() and (clear_all or path != CACHE_DIR):
                shutil.rmtree(path, ignore_errors=True)
                removed += 1
    click.echo(f"removed {removed} cache generation(s) under {root}")
