"""The sweep summary: one row per run, written as ``summary.csv``, ``summary.h5`` and a terminal table.

Columns, in order (``params`` are the sweep's dotted key paths, one column each):

========================  =====  ===========================================================
``case``                  int    position of the case in the sweep (0-based)
``run_id``                str    16 hex digits of the SHA-256 of the fully resolved scenario
                                 (empty for an invalid case: it has no resolved scenario)
*params*                  any    the value of each swept key path in this case
``status``                str    ``complete``, ``diverged``, ``halted``, ``failed``, ``not run`` or
                                 ``invalid``
``steps_done``            int    steps integrated (0 when the run failed before stepping)
``max_abs_energy_error``  float  max over samples of abs(energy_error), the trace's
                                 (E + energy_offset - E0) / energy_scale
``final_energy_error``    float  the trace's energy_error at the last sample
``megno``                 float  MEGNO <Y> at the last sample, for a run with ``output.chaos``
                                 (empty otherwise)
``mlce``                  float  the mLCE (Lyapunov exponent) at the last sample, likewise; its
                                 inverse, where positive, is the Lyapunov time
``wall_time_s``           float  wall-clock seconds of the run, as recorded in its trace
``steps_per_second``      float  ``steps_done / wall_time_s``
``encounters``            count  close encounters in the trace's ``events`` table (0 for a run
                                 without ``events:``; missing for a run with no trace)
``collisions``            count  collisions, likewise
``escapes``               count  escapes, likewise
``unresolved``            count  unresolved-step events, likewise
``worker``                str    address of the Dask worker that ran it (empty when unknown: a run
                                 that finished while an interrupted sweep shut down)
``resumed``               bool   true when an existing complete trace was reused
``trace``                 str    trace path relative to the output directory (empty when none)
``error``                 str    why a run failed, diverged or halted, or a case is invalid (empty
                                 otherwise)
========================  =====  ===========================================================

Missing numbers (a failed run has no energy error) are empty in the CSV and NaN in the HDF5 file.
A count is a whole number in the CSV and float64 in the HDF5 file, so that it can be NaN there.
Both files are written next to their final name and renamed onto it, so a summary on disk is
always whole.
"""

from __future__ import annotations

import csv
import json
import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

__all__ = ["RESULT_COLUMNS", "Count", "column_names", "events_cell", "format_table", "write_csv", "write_h5"]

class Count(int):
    """The type of a count column: a whole number that may be missing (a run with no trace)."""


#: Result columns and their types; the parameter columns go between ``run_id`` and ``status``.
RESULT_COLUMNS: tuple[tuple[str, type], ...] = (
    ("status", str),
    ("steps_done", int),
    ("max_abs_energy_error", float),
    ("final_energy_error", float),
    ("megno", float),
    ("mlce", float),
    ("wall_time_s", float),
    ("steps_per_second", float),
    ("encounters", Count),
    ("collisions", Count),
    ("escapes", Count),
    ("unresolved", Count),
    ("worker", str),
    ("resumed", bool),
    ("trace", str),
    ("error", str),
)
_LEAD_COLUMNS: tuple[tuple[str, type], ...] = (("case", int), ("run_id", str))
_RESERVED = frozenset(name for name, _ in _LEAD_COLUMNS + RESULT_COLUMNS)


def param_column(path: str) -> str:
    """CSV header of a swept key path: the path itself, unless it clashes with a result column."""
    return f"param:{path}" if path in _RESERVED else path


def column_names(params: Sequence[str]) -> list[str]:
    """Every CSV header, in order."""
    return [n for n, _ in _LEAD_COLUMNS] + [param_column(p) for p in params] + [n for n, _ in RESULT_COLUMNS]


def _cell(value: Any) -> str:
    """A CSV cell: floats in shortest round-trip form (so equal bits give equal text), NaN empty."""
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return repr(value)
    if isinstance(value, dict | list):
        return json.dumps(value, sort_keys=True)
    return str(value)


def write_csv(path: str | os.PathLike, rows: Sequence[Mapping[str, Any]], params: Sequence[str]) -> Path:
    """Write ``rows`` (dicts with ``case``, ``run_id``, ``params`` and the result columns) as CSV."""
    from orbitsim.io.h5safe import io_failure  # noqa: PLC0415 -- lazy: loads h5py

    final = Path(path)
    tmp = final.with_name(final.name + ".tmp")
    try:
        with open(tmp, "w", newline="", encoding="utf-8") as fh:
            writer = csv.writer(fh)
            writer.writerow(column_names(params))
            for row in rows:
                values = [row["case"], row["run_id"]]
                values += [row["params"].get(p) for p in params]
                values += [row.get(name) for name, _ in RESULT_COLUMNS]
                writer.writerow([_cell(v) for v in values])
        os.replace(tmp, final)
    except OSError as err:
        tmp.unlink(missing_ok=True)
        raise io_failure(err, f"{final}: {{reason}} (the previous summary, if any, is unchanged)", tmp) from None
    return final


def _param_array(values: list[Any]) -> Any:
    """A numpy column for one parameter: bool, int64 or float64 when every value allows, else text."""
    import numpy as np  # noqa: PLC0415 -- lazy: loads numpy

    present = [v for v in values if v is not None]
    if present and all(isinstance(v, bool) for v in present) and len(present) == len(values):
        return np.array(values, dtype=np.bool_)
    numeric = all(isinstance(v, int | float) and not isinstance(v, bool) for v in present)
    if numeric and present:
        if all(isinstance(v, int) for v in present) and len(present) == len(values):
            return np.array(values, dtype=np.int64)
        return np.array([math.nan if v is None else float(v) for v in values], dtype=np.float64)
    return np.array([_cell(v) for v in values], dtype=object)


def _column_array(name: str, kind: type, rows: Sequence[Mapping[str, Any]]) -> Any:
    import numpy as np  # noqa: PLC0415 -- lazy: loads numpy

    values = [row.get(name) for row in rows]
    if kind is float or kind is Count:  # a count is float64 here, so that a missing one can be NaN
        return np.array([math.nan if v is None else float(v) for v in values], dtype=np.float64)
    if kind is int:
        return np.array([0 if v is None else int(v) for v in values], dtype=np.int64)
    if kind is bool:
        return np.array([bool(v) for v in values], dtype=np.bool_)
    return np.array(["" if v is None else str(v) for v in values], dtype=object)


def write_h5(
    path: str | os.PathLike,
    rows: Sequence[Mapping[str, Any]],
    params: Sequence[str],
    attrs: Mapping[str, Any] | None = None,
) -> Path:
    """Write the summary as HDF5: one dataset per result column, parameters under ``params/``.

    The root attribute ``columns`` lists the CSV headers in order and ``params`` the swept key
    paths; text columns are variable-length UTF-8.
    """
    import h5py  # noqa: PLC0415 -- lazy: loads h5py

    from orbitsim.io.h5safe import in_memory, io_failure, write_image  # noqa: PLC0415 -- lazy: loads h5py

    final = Path(path)
    tmp = final.with_name(final.name + ".tmp")
    text = h5py.string_dtype("utf-8")
    with in_memory() as f:  # a small file: built in memory, so that a full disk is one plain write error
        for key, value in (attrs or {}).items():
            f.attrs[key] = value
        f.attrs["columns"] = column_names(params)
        f.attrs["params"] = list(params)
        for name, kind in _LEAD_COLUMNS + RESULT_COLUMNS:
            data = _column_array(name, kind, rows)
            f.create_dataset(name, data=data, dtype=text if data.dtype == object else data.dtype)
        group = f.create_group("params")
        for p in params:
            data = _param_array([row["params"].get(p) for row in rows])
            group.create_dataset(p, data=data, dtype=text if data.dtype == object else data.dtype)
        try:
            write_image(f, tmp)
            os.replace(tmp, final)
        except OSError as err:
            tmp.unlink(missing_ok=True)
            raise io_failure(err, f"{final}: {{reason}} (the previous summary, if any, is unchanged)", tmp) from None
    return final


def _short(value: Any, width: int) -> str:
    if isinstance(value, float):
        text = "" if math.isnan(value) else f"{value:.3g}"
    else:
        text = _cell(value)
    return text if len(text) <= width else text[: width - 1] + "…"


#: Columns of the terminal table: (header, row key, width before truncation).
_TABLE: tuple[tuple[str, str, int], ...] = (
    ("status", "status", 9),
    ("max|dE/E|", "max_abs_energy_error", 9),
    ("final dE/E", "final_energy_error", 10),
    ("steps/s", "steps_per_second", 9),
    ("wall s", "wall_time_s", 8),
    ("worker", "worker", 22),
    ("error", "error", 40),
)


#: How the terminal table abbreviates each count column, in its ``events logged`` column.
_EVENT_ABBREVIATIONS = (("encounters", "enc"), ("collisions", "col"), ("escapes", "esc"), ("unresolved", "unres"))
#: Width of the ``events logged`` column before truncation: "12 enc, 3 col, 1 esc, 40 unres" fits.
_EVENTS_WIDTH = 30


def events_cell(row: Mapping[str, Any]) -> str:
    """The terminal's compact ``events logged`` cell: ``3 enc, 1 esc``; "" for none, or for a run with no trace."""
    parts = []
    for column, short in _EVENT_ABBREVIATIONS:
        value = row.get(column)
        if isinstance(value, int | float) and not (isinstance(value, float) and math.isnan(value)) and value > 0:
            parts.append(f"{int(value)} {short}")
    return ", ".join(parts)


def format_table(rows: Sequence[Mapping[str, Any]], params: Sequence[str], max_rows: int = 40) -> str:
    """A fixed-width text table of the summary (the first ``max_rows`` rows) for the terminal.

    The ``events logged`` column (before ``error``) is there only when a run logged an event, and the
    ``MEGNO`` and ``mLCE`` columns only when a run recorded them (``output.chaos``): a sweep without
    either gets the table it always got.
    """
    table = list(_TABLE)
    if any(isinstance(row.get("megno"), float) and not math.isnan(row["megno"]) for row in rows):
        table[3:3] = [("MEGNO", "megno", 8), ("mLCE", "mlce", 9)]  # after the energy errors, for chaos runs only
    if any(events_cell(row) for row in rows):
        # Not plain "events": a sweep of the scenario key `events` has a parameter column of that name.
        table.insert(len(table) - 1, ("events logged", "", _EVENTS_WIDTH))
    headers = ["case", "run_id", *params, *(h for h, _, _ in table)]
    lines = []
    for row in rows[:max_rows]:
        cells = [_short(row["case"], 6), _short(row["run_id"], 16)]
        cells += [_short(row["params"].get(p), 20) for p in params]
        cells += [_short(row.get(key) if key else events_cell(row), width) for _, key, width in table]
        lines.append(cells)
    widths = [max([len(h)] + [len(c[i]) for c in lines]) for i, h in enumerate(headers)]
    out = ["  ".join(h.ljust(w) for h, w in zip(headers, widths, strict=True)).rstrip()]
    out += ["  ".join(c.ljust(w) for c, w in zip(cells, widths, strict=True)).rstrip() for cells in lines]
    if len(rows) > max_rows:
        out.append(f"... {len(rows) - max_rows} more rows in summary.csv")
    return "\n".join(out)
