"""A map's files: finished chunks as they finish, then ``map.h5`` in one piece.

While a map runs, ``DIR/map.parts/`` holds ``plan.json`` (the map's fingerprint and shape) and one
``chunk-NNNNNN.npz`` per finished chunk, each written to a temporary name, flushed to the disk and
renamed, so a chunk file exists whole or not at all: a map killed at any instant (SIGKILL included)
keeps every chunk that finished, and the same command finds them and runs only the rest. When every
chunk is there, ``map.h5`` is built in memory and written to ``map.h5.tmp``, flushed and renamed
(:mod:`orbitsim.io.durable`), and only then is ``map.parts/`` removed.

``map.h5`` layout (``format = "orbitsim-map"``): datasets ``x`` (nx,) and ``y`` (ny,) (absent for a
one-axis map) with attributes ``body``, ``key``, ``unit``, ``log``; ``status`` int8 (ny, nx) with the
codes of :mod:`orbitsim.ensemble.status` (``status_names`` attribute), ``stop_time`` (ny, nx),
``unreliable`` bool (ny, nx) (``energy_error`` above ``max_energy_error``); group ``indicators`` with
one (ny, nx) grid per indicator; attributes: the scenario (YAML text and its SHA-256), the scheme
(``integrator``, a registry name: wisdom_holman, verlet, leapfrog, leapfrog4, ...), t_end, dt,
steps, escape distance, the command, wall time, pixels/s and provenance.
"""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path
from typing import Any

import numpy as np

from orbitsim.io.durable import fsync_path, replace_durably
from orbitsim.stability.plan import INDICATORS, ChunkResult

__all__ = ["MAP_FORMAT", "MapParts", "is_map_file", "write_map"]

MAP_FORMAT = "orbitsim-map"
MAP_FORMAT_VERSION = 1


def is_map_file(path: str | os.PathLike) -> bool:
    """True if ``path`` is an HDF5 file written by ``orbitsim map``."""
    import h5py  # noqa: PLC0415 - lazy: loads h5py

    try:
        with h5py.File(path, "r") as f:
            return f.attrs.get("format") == MAP_FORMAT
    except OSError:
        return False


class MapParts:
    """The finished chunks of a map in progress (``DIR/map.parts``)."""

    def __init__(self, directory: Path, fingerprint: str, n_chunks: int, chunk: int) -> None:
        self.dir = directory / "map.parts"
        self.fingerprint = fingerprint
        self.n_chunks = n_chunks
        self.chunk = chunk

    def plan_matches(self) -> bool | None:
        """None: no parts yet; True: the parts are this map's; False: another map's."""
        plan = self.dir / "plan.json"
        if not plan.exists():
            return None
        try:
            saved = json.loads(plan.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            return False
        return saved.get("fingerprint") == self.fingerprint and saved.get("chunk") == self.chunk

    def start(self) -> None:
        """Create ``map.parts/plan.json`` (durably) if it is not there."""
        self.dir.mkdir(parents=True, exist_ok=True)
        plan = self.dir / "plan.json"
        if not plan.exists():
            tmp = plan.with_suffix(".tmp")
            tmp.write_text(json.dumps({"fingerprint": self.fingerprint, "chunk": self.chunk,
                                       "n_chunks": self.n_chunks}), encoding="utf-8")
            replace_durably(tmp, plan)

    def _path(self, index: int) -> Path:
        return self.dir / f"chunk-{index:06d}.npz"

    def done(self) -> set[int]:
        """Indices of the chunks already written."""
        return {i for i in range(self.n_chunks) if self._path(i).exists()}

    def write(self, result: ChunkResult) -> None:
        """Write one finished chunk whole (temporary file, flush, rename)."""
        path = self._path(result.index)
        tmp = path.with_name(path.name + ".tmp")
        try:
            with open(tmp, "wb") as f:
                np.savez(f, status=result.status, stop_time=result.stop_time, indicators=result.indicators,
                         seconds=np.float64(result.seconds))
                f.flush()
                os.fsync(f.fileno())
            replace_durably(tmp, path)
        except BaseException:
            tmp.unlink(missing_ok=True)
            raise

    def read(self, index: int) -> ChunkResult:
        with np.load(self._path(index)) as data:
            return ChunkResult(index, data["status"], data["stop_time"], data["indicators"], float(data["seconds"]))

    def remove(self) -> None:
        shutil.rmtree(self.dir, ignore_errors=True)
        fsync_path(self.dir.parent, best_effort=True)


def write_map(path: Path, grids: dict[str, np.ndarray], axes: list[dict[str, Any]], attrs: dict[str, Any]) -> None:
    """Write ``map.h5`` in one piece (built in memory, written to ``.tmp``, flushed, renamed).

    ``grids``: ``status``, ``stop_time``, ``unreliable`` and one entry per indicator, each (ny, nx);
    ``axes``: ``{"name": "x"|"y", "values", "body", "key", "unit", "log"}``.
    """
    from orbitsim.io import h5safe  # noqa: PLC0415 - lazy: loads h5py

    tmp = path.with_name(path.name + ".tmp")
    with h5safe.in_memory() as f:
        f.attrs["format"] = MAP_FORMAT
        f.attrs["format_version"] = MAP_FORMAT_VERSION
        for key, value in attrs.items():
            f.attrs[key] = value
        f.attrs["indicator_names"] = json.dumps(list(INDICATORS))
        for axis in axes:
            ds = f.create_dataset(axis["name"], data=np.asarray(axis["values"], dtype=np.float64))
            for key in ("body", "key", "unit", "log"):
                ds.attrs[key] = axis[key]
        f.create_dataset("status", data=grids["status"].astype(np.int8))
        f.create_dataset("stop_time", data=grids["stop_time"])
        f.create_dataset("unreliable", data=grids["unreliable"])
        group = f.create_group("indicators")
        for name in INDICATORS:
            group.create_dataset(name, data=grids[name])
        try:
            h5safe.write_image(f, tmp)
            replace_durably(tmp, path)
        except OSError:
            tmp.unlink(missing_ok=True)
            raise
