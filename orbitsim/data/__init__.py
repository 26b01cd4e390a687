"""The files that ship inside the package: bundled scenarios, parameter sweeps and benchmark matrices.

Each kind has its folder here, and each file is named by its stem, wherever a file path is accepted:

=====================  ========================================================================
``scenarios/*.yaml``   ``orbitsim run two_body_eccentric`` (also validate, compare, animate, ...)
``sweeps/*.yaml``      ``orbitsim batch integrators_dt``
``bench/*.yaml``       ``orbitsim bench full`` (the default), ``orbitsim bench quick`` (``--quick``)
=====================  ========================================================================

``orbitsim list`` names them all, with the file behind each (copy one to start your own). They are
package data (``pyproject.toml``, ``[tool.setuptools.package-data]``) found through
:mod:`importlib.resources`, so a wheel installed anywhere has them; ``$ORBITSIM_CONFIG_DIR`` points
orbitsim at another folder laid out the same way (``scenarios/``, ``sweeps/``, ``bench/``).

This module is a leaf: it imports nothing of orbitsim, so every reader of bundled files can use it.
"""

from __future__ import annotations

import difflib
import os
from importlib import resources
from pathlib import Path

__all__ = ["KINDS", "MATRICES", "SCENARIOS", "SWEEPS", "bundled_dir", "bundled_files", "data_dir", "locate"]

#: Folder of the bundled scenarios.
SCENARIOS = "scenarios"
#: Folder of the bundled parameter sweeps (``orbitsim batch``).
SWEEPS = "sweeps"
#: Folder of the bundled benchmark matrices (``orbitsim bench``).
MATRICES = "bench"
#: Every kind, and the word error messages use for one file of it.
KINDS = {SCENARIOS: "scenario", SWEEPS: "sweep", MATRICES: "benchmark matrix"}


def data_dir() -> Path:
    """The folder of bundled files: ``$ORBITSIM_CONFIG_DIR`` when set, else this package's own.

    Raises
    ------
    RuntimeError
        If orbitsim is imported from somewhere that is not a folder (a zip file): its bundled files
        must be files on disk, as pip installs every wheel.
    """
    override = os.environ.get("ORBITSIM_CONFIG_DIR")
    if override:
        return Path(override)
    root = resources.files(__name__)
    if not isinstance(root, Path):
        raise RuntimeError(f"orbitsim's bundled files are not in a folder ({root!r}): install orbitsim with pip")
    return root


def bundled_dir(kind: str) -> Path:
    """The folder of one kind of bundled file (:data:`SCENARIOS`, :data:`SWEEPS` or :data:`MATRICES`)."""
    if kind not in KINDS:
        raise ValueError(f"unknown kind of bundled file {kind!r}; one of {', '.join(KINDS)}")
    return data_dir() / kind


def bundled_files(kind: str) -> dict[str, Path]:
    """Every ``*.yaml`` file of one kind, by name (the file's stem), sorted by name.

    Returns an empty mapping when the folder does not exist (an ``$ORBITSIM_CONFIG_DIR`` without it).
    """
    folder = bundled_dir(kind)
    if not folder.is_dir():
        return {}
    return {path.stem: path for path in sorted(folder.glob("*.yaml"))}


def locate(kind: str, spec: str | os.PathLike[str]) -> Path:
    """The file a user named: a path to an existing file, else the bundled file of that name.

    Parameters
    ----------
    kind : str
        :data:`SCENARIOS`, :data:`SWEEPS` or :data:`MATRICES`.
    spec : str or os.PathLike
        A file path, or a bundled name such as ``"integrators_dt"``.

    Returns
    -------
    pathlib.Path
        The existing file; the bundled file of that name; or ``spec`` unchanged when it looks like
        a path (it has a suffix or a separator), so that the caller's reader reports the missing
        file in its own words.

    Raises
    ------
    LookupError
        When ``spec`` is a bare name that is neither a file nor bundled; the message (one line)
        names the closest bundled file, or lists them all.
    """
    path = Path(spec)
    if path.is_file():
        return path
    text = os.fspath(spec)
    found = bundled_files(kind)
    if text in found:
        return found[text]
    if path.suffix or os.sep in text or "/" in text or path.is_dir():
        return path
    close = difflib.get_close_matches(text, list(found), n=1, cutoff=0.6)
    hint = f"did you mean {close[0]!r}?" if close else f"bundled: {', '.join(found) or 'none found'}"
    raise LookupError(f"no such file or bundled {KINDS[kind]}; {hint}")
