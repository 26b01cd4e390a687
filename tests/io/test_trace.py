"""Tests for the HDF5 energy-trace format (orbitsim.io.trace) and run provenance."""

from __future__ import annotations

import os
import re
from pathlib import Path
from types import SimpleNamespace

import h5py
import numpy as np
import pytest

from orbitsim.io.trace import (
    TRACE_FORMAT,
    TRACE_VERSION,
    TraceError,
    TraceWriter,
    open_trace_summary,
    read_trace,
)
from orbitsim.provenance import provenance

NAMES = ("Sun", "Ætna", "Jörmungandr")
MASSES = np.array([1.0, 3.0e-6, 1.0e-3])
ATTRS = {"scenario": "bodies: [Sun, Ætna]\n", "integrator": "leapfrog", "dt": 0.01,
         "steps_requested": 100, "G": 1.0, "softening": 0.0, "units": "nbody"}


def make_chunk(rng: np.random.Generator, start: int, k: int, n: int = 3, *, positions: bool = True,
               energy: np.ndarray | None = None) -> SimpleNamespace:
    """k random samples starting at step index `start`."""
    kinetic, potential = rng.random(k), -1.0 - rng.random(k)
    return SimpleNamespace(
        time=0.01 * np.arange(start, start + k), step=np.arange(start, start + k),
        kinetic=kinetic, potential=potential,
        energy=kinetic + potential if energy is None else energy,
        momentum=rng.standard_normal((k, 3)), angular_momentum=rng.standard_normal((k, 3)),
        positions=rng.standard_normal((k, n, 3)) if positions else None,
        velocities=rng.standard_normal((k, n, 3)) if positions else None,
    )


def writer(path: Path, *, positions: bool = True, **kw) -> TraceWriter:
    return TraceWriter(path, attrs=ATTRS, names=NAMES, masses=MASSES, n_bodies=3,
                       record_positions=positions, **kw)


def test_round_trip_is_bit_exact(tmp_path: Path) -> None:
    path = tmp_path / "run.h5"
    rng = np.random.default_rng(1)
    chunks = [make_chunk(rng, s, k) for s, k in ((0, 5), (5, 1), (6, 17))]
    with writer(path) as w:
        for c in chunks:
            w.append(c)
        w.set_attrs(note="mid-run")
        assert w.samples_written == 23
        w.close("diverged", steps_done=23, wall_time_s=1.5, message="energy blew up")
    tr = read_trace(path)
    for name in ("time", "step", "kinetic", "potential", "energy", "momentum", "angular_momentum",
                 "positions", "velocities"):
        expected = np.concatenate([getattr(c, name) for c in chunks])
        got = getattr(tr, name)
        assert got.dtype == expected.dtype and np.array_equal(got, expected), name
    assert tr.step.dtype == np.int64
    assert tr.names == NAMES
    assert np.array_equal(tr.masses, MASSES)
    assert tr.n_samples == 23
    a = tr.attrs
    assert (a["format"], a["format_version"]) == (TRACE_FORMAT, TRACE_VERSION)
    assert (a["status"], a["steps_done"], a["wall_time_s"]) == ("diverged", 23, 1.5)
    assert a["message"] == "energy blew up" and a["note"] == "mid-run"
    for key, value in ATTRS.items():
        assert a[key] == value
    assert len(a["scenario_sha256"]) == 64
    assert all(f"provenance_{k}" in a for k in provenance())


def test_energy_error(tmp_path: Path) -> None:
    path = tmp_path / "e.h5"
    rng = np.random.default_rng(2)
    e = np.array([-2.0, -2.5, -1.0, -2.0])
    with writer(path, positions=False) as w:
        w.append(make_chunk(rng, 0, 2, positions=False, energy=e[:2]))
        w.append(make_chunk(rng, 2, 2, positions=False, energy=e[2:]))
    tr = read_trace(path)
    assert tr.positions is None and tr.velocities is None
    assert tr.attrs["E0"] == -2.0 and tr.attrs["status"] == "complete"
    np.testing.assert_array_equal(tr.energy_error, (e + 2.0) / 2.0)


def test_energy_error_relative_to_t_plus_u_when_e0_is_zero(tmp_path: Path) -> None:
    """E0 = 0 cannot be divided by: the error is relative to T0 + |U0| (orbitsim.io.schema.energy_scale)."""
    path = tmp_path / "e0.h5"
    e = np.array([0.0, 1e-3, -2e-3])
    chunk = make_chunk(np.random.default_rng(3), 0, 3, positions=False, energy=e)
    with writer(path, positions=False) as w:
        w.append(chunk)
    size = chunk.kinetic[0] + abs(chunk.potential[0])
    tr = read_trace(path)
    np.testing.assert_array_equal(tr.energy_error, e / size)
    assert tr.attrs["energy_scale"] == size


def test_target_appears_only_at_close(tmp_path: Path) -> None:
    path = tmp_path / "run.h5"
    w = writer(path)
    w.append(make_chunk(np.random.default_rng(4), 0, 4))
    w.flush()
    assert not path.exists()
    assert w.tmp_path == tmp_path / "run.h5.tmp" and w.tmp_path.exists()
    assert w.close() == path
    assert path.exists() and not w.tmp_path.exists()
    assert read_trace(path).attrs["steps_done"] == 3  # default: last sample's step index


def test_existing_file_refused_then_overwritten(tmp_path: Path) -> None:
    path = tmp_path / "run.h5"
    path.write_bytes(b"precious")
    with pytest.raises(FileExistsError, match=r"run\.h5"):
        writer(path)
    assert path.read_bytes() == b"precious"
    assert not (tmp_path / "run.h5.tmp").exists()
    with writer(path, overwrite=True) as w:
        w.append(make_chunk(np.random.default_rng(5), 0, 2))
    assert read_trace(path).n_samples == 2


def test_exception_in_with_keeps_interrupted_trace(tmp_path: Path) -> None:
    path = tmp_path / "run.h5"
    rng = np.random.default_rng(6)
    with pytest.raises(RuntimeError, match="boom"), writer(path) as w:
        w.append(make_chunk(rng, 0, 3))
        w.append(make_chunk(rng, 3, 2))
        raise RuntimeError("boom")
    tr = read_trace(path)
    assert tr.attrs["status"] == "interrupted" and "boom" in tr.attrs["message"]
    assert tr.n_samples == 5 and list(tr.step) == [0, 1, 2, 3, 4]
    assert not (tmp_path / "run.h5.tmp").exists()


def test_exception_before_any_sample_and_abort_leave_nothing(tmp_path: Path) -> None:
    path = tmp_path / "run.h5"
    with pytest.raises(RuntimeError), writer(path):
        raise RuntimeError("setup failed")
    assert list(tmp_path.iterdir()) == []
    w = writer(path)
    w.append(make_chunk(np.random.default_rng(7), 0, 1))
    w.abort()
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(RuntimeError, match="closed"):
        w.append(make_chunk(np.random.default_rng(7), 1, 1))


def test_bad_chunk_shapes_rejected(tmp_path: Path) -> None:
    rng = np.random.default_rng(8)
    with writer(tmp_path / "run.h5") as w:
        bad = make_chunk(rng, 0, 2)
        bad.momentum = bad.momentum[:, :2]
        with pytest.raises(ValueError, match="momentum"):
            w.append(bad)
        with pytest.raises(ValueError, match="positions"):
            w.append(make_chunk(rng, 0, 2, positions=False))
        w.append(make_chunk(rng, 0, 1))
    assert read_trace(tmp_path / "run.h5").n_samples == 1


@pytest.mark.parametrize("kind", ["missing", "text", "foreign", "version"])
def test_reader_errors_name_the_file(tmp_path: Path, kind: str) -> None:
    path = tmp_path / f"{kind}.h5"
    if kind == "text":
        path.write_text("not hdf5 at all\n")
    elif kind == "foreign":
        with h5py.File(path, "w") as f:
            f["x"] = np.arange(3)
    elif kind == "version":
        with writer(path) as w:
            w.append(make_chunk(np.random.default_rng(9), 0, 1))
        with h5py.File(path, "r+") as f:
            f.attrs["format_version"] = TRACE_VERSION + 1
    for reader in (read_trace, open_trace_summary):
        with pytest.raises(TraceError, match=re.escape(f"{kind}.h5")) as info:
            reader(path)
        assert "\n" not in str(info.value)


def test_many_single_appends_and_chunk_shapes(tmp_path: Path) -> None:
    path = tmp_path / "long.h5"
    n, samples = 3, 10_000
    one = make_chunk(np.random.default_rng(10), 0, 1, n)
    with writer(path) as w:
        for i in range(samples):
            one.step, one.time = np.array([i]), np.array([0.01 * i])
            w.append(one)
        # memory stays flat: only a bounded number of samples are buffered, and HDF5's metadata
        # cache (the chunk indexes) is held to 4 MiB instead of its adaptive 32 MiB ceiling
        assert w._buffer_rows < 1024
        cache = w._require_open().id.get_mdc_config()
        assert cache.max_size == 4 * 2**20 and cache.initial_size <= cache.max_size
    with h5py.File(path, "r") as f:
        chunks = f["positions"].chunks
        assert chunks[1:] == (n, 3) and 1 < chunks[0] <= 1024
        assert np.prod(chunks) * 8 < 1 << 20
        assert f["time"].maxshape == (None,) and f["positions"].maxshape == (None, n, 3)
        assert f["energy"].compression == "gzip"
    tr = read_trace(path)
    assert tr.n_samples == samples and np.array_equal(tr.step, np.arange(samples))


def test_large_n_positions_chunks_stay_small(tmp_path: Path) -> None:
    n = 100_000
    names = [f"b{i}" for i in range(n)]
    w = TraceWriter(tmp_path / "big.h5", attrs={}, names=names, masses=np.ones(n), n_bodies=n,
                    record_positions=True)
    try:
        chunks = w._require_open()["positions"].chunks
        assert chunks[0] == 1 and np.prod(chunks) * 8 <= 1 << 20
    finally:
        w.abort()


def test_summary_does_not_need_arrays(tmp_path: Path) -> None:
    path = tmp_path / "run.h5"
    with writer(path) as w:
        w.append(make_chunk(np.random.default_rng(11), 0, 6))
    info = open_trace_summary(path)
    assert info["n_samples"] == 6 and info["n_bodies"] == 3
    assert info["shapes"]["positions"] == (6, 3, 3) and info["shapes"]["bodies/names"] == (3,)
    assert info["attrs"]["status"] == "complete" and info["path"] == os.fspath(path)


def test_provenance_keys(monkeypatch: pytest.MonkeyPatch) -> None:
    expected = {"orbitsim_version", "python_version", "platform", "numpy_version", "numba_version",
                "llvmlite_version", "h5py_version", "rebound_version", "cpu_model", "cpu_count",
                "numba_threads", "hostname"}
    monkeypatch.delenv("NUMBA_NUM_THREADS", raising=False)
    info = provenance()
    assert expected <= info.keys()
    assert info["numba_threads"] == info["cpu_count"] == (os.cpu_count() or 1)
    assert all(isinstance(v, str | int) for v in info.values())
    monkeypatch.setenv("NUMBA_NUM_THREADS", "3")
    assert provenance()["numba_threads"] == 3
    info["hostname"] = "mutated"
    assert provenance()["hostname"] != "mutated"  # the cache is not exposed
