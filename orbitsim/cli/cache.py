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
    """Print the cache directory of this orbitsim build and its size.

    Example: orbitsim cache info
    """
    from orbitsim._jit import CACHE_DIR, cache_root

    root = cache_root()
    generations = sorted(p for p in root.iterdir() if p.is_dir()) if root.exists() else []
    size = sum(f.stat().st_size for f in CACHE_DIR.rglob("*") if f.is_file()) if CACHE_DIR.exists() else 0
    click.echo(f"current: {CACHE_DIR} ({size / 2**20:.1f} MiB)")
    click.echo(f"root:    {root} ({len(generations)} generation(s))")


@command.command("clear")
@click.option("--all", "clear_all", is_flag=True, help="Also remove the current build's cache.")
def clear(clear_all: bool) -> None:
    """Remove stale cache generations (and, with --all, the current one).

    Example: orbitsim cache clear --all
    """
    from orbitsim._jit import CACHE_DIR, cache_root

    root = cache_root()
    removed = 0
    if root.exists():
        for path in root.iterdir():
            if path.is_dir() and (clear_all or path != CACHE_DIR):
                shutil.rmtree(path, ignore_errors=True)
                removed += 1
    click.echo(f"removed {removed} cache generation(s) under {root}")
