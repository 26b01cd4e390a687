"""How a trace lays its datasets out in HDF5: chunk shapes, write-buffer bounds, the metadata cache.

Numbers measured for the write path of :mod:`orbitsim.io.trace_writer`; none of them changes what
a trace holds, only how fast and in how much memory it is written.
"""

from __future__ import annotations

import h5py
import numpy as np

__all__ = ["FLUSH_BYTES", "FLUSH_ROWS", "bound_metadata_cache", "chunk_shape"]

SERIES_CHUNK_ROWS = 1024  # 8-24 KiB chunks for the small series
BODY_CHUNK_BYTES = 512 * 1024  # keeps positions chunks under 1 MiB for any N
FLUSH_ROWS = 1024
FLUSH_BYTES = 8 * 1024 * 1024  # bounds the write buffer when N is large
#: Ceiling of HDF5's metadata cache while a trace is written. The writer only appends, so it needs
#: the newest nodes of each chunk index; under the adaptive default (up to 32 MiB) the cache grew
#: by ~13 MB over a 10^7-sample run (the memory probe of ``orbitsim bench``), under this one ~4 MB.
METADATA_CACHE_BYTES = 4 * 2**20


def bound_metadata_cache(f: h5py.File) -> None:
    """Hold the file's metadata cache between 1 MiB and :data:`METADATA_CACHE_BYTES`."""
    config = f.id.get_mdc_config()
    config.set_initial_size = True
    config.initial_size = config.min_size = 2**20
    config.max_size = METADATA_CACHE_BYTES
    f.id.set_mdc_config(config)


def _body_chunks(n_bodies: int) -> tuple[int, int, int]:
    """Chunk shape for (S, N, 3) datasets: as many samples as fit in ~512 KiB."""
    per_sample = max(n_bodies, 1) * 3 * 8
    if per_sample <= BODY_CHUNK_BYTES:
        return (min(SERIES_CHUNK_ROWS, BODY_CHUNK_BYTES // per_sample), max(n_bodies, 1), 3)
    # One sample alone exceeds the budget: split along the body axis too.
    return (1, BODY_CHUNK_BYTES // 24, 3)


def _series_chunks(tail: tuple[int, ...]) -> tuple[int, ...]:
    """Chunk shape for (S, *tail) series: 1024 samples, fewer when a sample is wide (``(S, N)``)."""
    width = max(1, int(np.prod(tail))) * 8
    return (max(1, min(SERIES_CHUNK_ROWS, BODY_CHUNK_BYTES // width)), *tail)


def chunk_shape(tail: tuple[int, ...], n_bodies: int) -> tuple[int, ...]:
    """Chunk shape of a per-sample dataset whose samples have shape ``tail``."""
    return _body_chunks(n_bodies) if len(tail) == 2 else _series_chunks(tail)
