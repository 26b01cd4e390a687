"""Run a map: chunks of pixels through the ensemble kernel, here or on Dask, each written as it finishes.

:func:`run_map` takes a checked :class:`~orbitsim.stability.plan.MapPlan`, skips the chunks a
killed run already finished (:class:`~orbitsim.stability.store.MapParts`), runs the rest (in this
process, or as one Dask task per chunk with ``scheduler``: a killed worker's task is rerun by Dask,
and only finished results are ever written), reports progress, and assembles ``map.h5`` and
``map.png``. A pixel's bits depend only on the plan, never on the chunk it ran in, the thread count
or the worker, so a resumed map is bit-identical to one run straight through.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import Any

import numpy as np

from orbitsim.stability.plan import (
    INDICATORS,
    ChunkResult,
    MapPlan,
    chunk_states,
    fingerprint,
    ready_kernels,
    run_chunk,
    without_states,
)
from orbitsim.stability.store import MAP_FORMAT, MapParts, write_map

__all__ = ["read_map", "run_map"]


def _local(plan: MapPlan, todo: list[int]) -> Iterator[ChunkResult]:
    for index in todo:
        yield run_chunk(plan, index)


def _on_dask(plan: MapPlan, todo: list[int], scheduler: str) -> Iterator[ChunkResult]:
    from distributed import as_completed  # noqa: PLC0415 - lazy: loads distributed

    from orbitsim.batch.cluster import open_client  # noqa: PLC0415 - lazy: as above

    with open_client(scheduler) as client:
        light = without_states(plan)  # each task carries its own chunk's start states, not the map's
        futures = [client.submit(run_chunk, light, index, chunk_states(plan, index), pure=False) for index in todo]
        for future in as_completed(futures):
            yield future.result()


def run_map(plan: MapPlan, directory: Path, *, max_energy_error: float, indicator: str, attrs: dict[str, Any],
            scheduler: str | None = None, progress: Callable[[str], None] | None = None,
            on_compile: Callable[[str], None] | None = None) -> dict[str, Any]:
    """Finish the map of ``plan`` in ``directory`` (``map.h5``, ``map.png``); returns the map's data.

    Here (no ``scheduler``) the kernels are made ready first (:func:`~orbitsim.stability.plan.ready_kernels`:
    Numba's set-up and the kernels' load from its cache, or their compilation on a first run, announced once
    through ``on_compile``), and only then does the clock of the pixels' computation start, so that the
    progress line's pixels/s and ETA, and map.h5's ``wall_time_s``, are the pixels' own; the set-up's time is
    ``setup_time_s``. A compilation later in the map (a kernel only some chunk needs) is kept out of
    ``wall_time_s`` too (``compile_time_s`` counts every compilation). On Dask each worker readies its own
    kernels within its first chunk."""
    parts = MapParts(directory, fingerprint(plan), plan.n_chunks, plan.chunk)
    parts.start()
    done = parts.done()
    todo = [i for i in range(plan.n_chunks) if i not in done]
    results: dict[str, ChunkResult] = {}
    # lazy: loads numba, which read_map's callers (orbitsim info, orbitsim plot) do not need
    from orbitsim._jit import CompileWatch, watch_compiles  # noqa: PLC0415

    note = f"compiling the map's kernels for {plan.integrator} (first run only)"
    compiles = CompileWatch(None if on_compile is None else lambda: on_compile(note))
    with watch_compiles(compiles):
        setup_started = time.perf_counter()
        if todo and scheduler is None:
            ready_kernels(plan)
        setup = time.perf_counter() - setup_started
        compiled_in_setup = compiles.seconds
        started = time.perf_counter()
        finished_pixels = 0
        pending = sum(min(plan.chunk, plan.n_pixels - i * plan.chunk) for i in todo)
        source: Iterable[ChunkResult] = (_local(plan, todo) if scheduler is None
                                         else _on_dask(plan, todo, scheduler))
        for result in source:
            parts.write(result)
            finished_pixels += len(result.status)
            if progress is not None:
                elapsed = time.perf_counter() - started - (compiles.seconds - compiled_in_setup)
                rate = finished_pixels / elapsed if elapsed > 0 else math.inf
                eta = (pending - finished_pixels) / rate if rate > 0 else math.inf
                progress(f"map: {plan.n_pixels - pending + finished_pixels}/{plan.n_pixels} pixels, "
                         f"{rate:.0f} pixels/s, ETA {eta:.1f} s")
        wall = time.perf_counter() - started - (compiles.seconds - compiled_in_setup)
    for index in range(plan.n_chunks):
        results[str(index)] = parts.read(index)
    ordered = [results[str(i)] for i in range(plan.n_chunks)]
    shape = plan.shape
    status = np.concatenate([r.status for r in ordered]).reshape(shape)
    stop_time = np.concatenate([r.stop_time for r in ordered]).reshape(shape)
    table = np.concatenate([r.indicators for r in ordered])
    grids: dict[str, np.ndarray] = {"status": status, "stop_time": stop_time}
    for column, name in enumerate(INDICATORS):
        grids[name] = table[:, column].reshape(shape)
    energy = grids["energy_error"]
    grids["unreliable"] = np.isfinite(energy) & (energy > max_energy_error)
    kernel_seconds = float(sum(r.seconds for r in ordered))
    axes = [{"name": name, "values": a.values, "body": a.body, "key": a.key, "unit": a.unit, "log": a.log}
            for name, a in zip(("x", "y"), plan.axes, strict=False)]
    from orbitsim.ensemble.status import STATUS_NAMES  # noqa: PLC0415 - lazy: small, but beside its use

    full_attrs = dict(attrs)
    full_attrs.update({
        "status_names": json.dumps(list(STATUS_NAMES)), "integrator": plan.integrator, "dt": plan.dt,
        "t_start": plan.t_start,
        "steps": plan.n_steps, "t_end": plan.t_start + plan.n_steps * plan.dt,
        "escape_distance": plan.escape_distance, "max_energy_error": max_energy_error,
        "watch_body": plan.names[plan.watch], "fingerprint": parts.fingerprint, "pixels": plan.n_pixels,
        "chunk": plan.chunk, "wall_time_s": wall, "pixels_computed": pending, "kernel_time_s": kernel_seconds,
        "setup_time_s": setup, "compile_time_s": compiles.seconds,
        "pixels_per_s": plan.n_pixels / kernel_seconds if kernel_seconds > 0 else 0.0,
    })
    write_map(directory / "map.h5", grids, axes, full_attrs)
    data = read_map(directory / "map.h5")
    from orbitsim.stability.figure import draw_map  # noqa: PLC0415 - lazy: loads matplotlib

    draw_map(directory / "map.png", data, indicator)
    parts.remove()
    return data


def read_map(path: str | Path) -> dict[str, Any]:
    """A map file's grids, axes and attributes as plain numpy arrays and Python values.

    Raises :class:`orbitsim.io.schema.TraceError` if ``path`` is not a readable map file.
    """
    import h5py  # noqa: PLC0415 - lazy: loads h5py

    from orbitsim.io.schema import TraceError  # noqa: PLC0415 - lazy: as above

    try:
        with h5py.File(path, "r") as f:
            if f.attrs.get("format") != MAP_FORMAT:
                raise TraceError(f"{path}: not a map file (format {f.attrs.get('format')!r})")
            data: dict[str, Any] = {key: (value.item() if hasattr(value, "item") else value)
                                    for key, value in f.attrs.items()}
            data["status_names"] = json.loads(str(f.attrs["status_names"]))
            for name in ("x", "y"):
                if name in f:
                    ds = f[name]
                    data[name] = {"values": ds[()], **{k: (v.item() if hasattr(v, "item") else v)
                                                       for k, v in ds.attrs.items()}}
            data["status"] = f["status"][()]
            data["stop_time"] = f["stop_time"][()]
            data["unreliable"] = f["unreliable"][()]
            data["indicators"] = {name: f["indicators"][name][()] for name in f["indicators"]}
    except OSError as err:
        raise TraceError(f"{path}: cannot read map file: {' '.join(str(err).split())}") from None
    except KeyError as err:
        raise TraceError(f"{path}: map file lacks {err}") from None
    return data
