"""A trace's per-sample series, and every body's state per sample, as CSV (``orbitsim export --format csv``).

* :func:`export_csv`: one row per sample (step, time, energies, momentum, angular momentum, MEGNO and
  the mLCE where the run recorded them (``output.chaos``), and the orbital elements the run
  recorded), and with ``positions`` every body's x, y, z, vx, vy, vz in long
  format (one row per sample and body) beside it (:func:`positions_csv_path`).

Floats are written with ``%.17g``, so each reads back to the same bits; a body name holding a comma,
quote or line break is quoted (RFC 4180). The trace is read in blocks, so memory stays bounded for
any trace length. Each file is written under a temporary name and renamed once complete
(:func:`orbitsim.io.durable.pending_text`): a failure leaves nothing half-written.
"""

from __future__ import annotations

import contextlib
import os
from pathlib import Path
from typing import IO, Any

import numpy as np

from orbitsim.io.durable import pending_text
from orbitsim.io.schema import ELEMENTS, TraceError
from orbitsim.io.trace_reader import open_trace

__all__ = ["export_csv", "positions_csv_path"]

#: A chaos run's per-sample series (orbitsim.chaos.state.CHAOS_SERIES), columns after the momenta where present.
CHAOS_COLUMNS = ("megno", "mlce")
#: Samples per block when streaming a CSV: bounded memory for any trace length.
CSV_BLOCK = 4096
#: ``%.17g`` prints every float64 so that it reads back to the same bits.
_EXACT = "%.17g"


def positions_csv_path(output: str | os.PathLike[str]) -> Path:
    """Where ``--positions`` writes the long-format body states: ``OUT.csv`` -> ``OUT.positions.csv``."""
    out = Path(output)
    return out.with_name(f"{out.stem}.positions{out.suffix or '.csv'}")


def export_csv(trace: str | os.PathLike[str], output: str | os.PathLike[str], *, positions: bool = False) -> None:
    """The series (one row per sample) to ``output``; with ``positions`` also every body's state
    (one row per sample and body) to :func:`positions_csv_path`. Each file is complete or absent."""
    name = os.fspath(trace)
    with open_trace(name) as f:
        if positions and "positions" not in f:
            raise TraceError(f"{name}: the run did not record positions (output.positions: false); drop --positions")
        names = tuple(f["bodies/names"].asstr()[()])
        elements = [e for e in ELEMENTS if f"elements/{e}" in f]
        chaos = [c for c in CHAOS_COLUMNS if c in f]
        with contextlib.ExitStack() as stack:
            series = stack.enter_context(pending_text(output))
            _write_series(f, series.file, names, elements, chaos)
            if positions:
                bodies = stack.enter_context(pending_text(positions_csv_path(output)))
                _write_positions(f, bodies.file, names)
                bodies.done()
            series.done()


def _write_series(f: Any, out: IO[str], names: tuple[str, ...], elements: list[str], chaos: list[str]) -> None:
    columns = ["sample", "step", "time", "kinetic", "potential", "energy", "energy_error", "px", "py", "pz",
               "Lx", "Ly", "Lz", *chaos, *(_text(f"{e}[{n}]") for e in elements for n in names)]
    out.write(",".join(columns) + "\n")
    count = int(f["time"].shape[0])
    for start in range(0, count, CSV_BLOCK):
        stop = min(count, start + CSV_BLOCK)
        parts = [np.arange(start, stop)[:, None], f["step"][start:stop][:, None],
                 *(f[s][start:stop][:, None] for s in ("time", "kinetic", "potential", "energy", "energy_error")),
                 f["momentum"][start:stop], f["angular_momentum"][start:stop],
                 *(f[c][start:stop][:, None] for c in chaos),
                 *(f[f"elements/{e}"][start:stop] for e in elements)]
        _rows(out, np.hstack([np.asarray(p, dtype=np.float64) for p in parts]), ints=2)


def _write_positions(f: Any, out: IO[str], names: tuple[str, ...]) -> None:
    out.write("sample,step,time,body,x,y,z,vx,vy,vz\n")
    count, n = int(f["time"].shape[0]), len(names)
    block = max(1, CSV_BLOCK // max(n, 1))
    for start in range(0, count, block):
        stop = min(count, start + block)
        x, v = f["positions"][start:stop], f["velocities"][start:stop]
        step, time = f["step"][start:stop], f["time"][start:stop]
        for s in range(stop - start):
            head = f"{start + s},{int(step[s])},{_EXACT % time[s]},"
            for i, body in enumerate(map(_text, names)):
                out.write(head + body + "," + ",".join(_EXACT % c for c in (*x[s, i], *v[s, i])) + "\n")


def _text(value: str) -> str:
    """A CSV field: quoted (RFC 4180) when a body name holds a comma, quote or line break."""
    return f'"{value.replace(chr(34), chr(34) * 2)}"' if any(c in value for c in ',"\r\n') else value


def _rows(out: IO[str], table: np.ndarray, ints: int) -> None:
    """Rows of ``table``; the first ``ints`` columns (sample, step) as whole numbers."""
    for row in table:
        out.write(",".join([*(str(int(c)) for c in row[:ints]), *(_EXACT % c for c in row[ints:])]) + "\n")
