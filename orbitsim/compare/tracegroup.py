"""Runs stored as HDF5 groups in the ``orbitsim.trace`` layout, several to one file.

:class:`orbitsim.io.trace.TraceWriter` streams one run into one whole file. A comparison holds
many finished runs in one file (``compare.h5``), so this module writes each
:class:`~orbitsim.record.RunRecord` into a *group* with the same attributes, dataset
names, shapes and dtypes as a trace file's root (the schema, names and version constants are
imported from :mod:`orbitsim.io.trace`, so the two cannot drift apart). :func:`read_trace_group`
reads a group back as a :class:`~orbitsim.io.trace.Trace`.

File layout of ``compare.h5``::

    /                       attrs: format = "orbitsim.compare", format_version, scenario (YAML),
                            scenario_sha256, command, provenance_<key>
    /orbitsim/<integrator>  one trace-layout group per orbitsim run
    /rebound/<scheme key>   one per REBOUND run (e.g. leapfrog_order4, whfast)
    /rebound_twin/<key>     the perturbed REBOUND twins behind the pair tolerances
    /reference/ias15        the IAS15 reference
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from typing import Any

import h5py
import numpy as np

from orbitsim._version import __version__
from orbitsim.io.schema import py_value
from orbitsim.io.trace import TRACE_FORMAT, TRACE_VERSION, Trace
from orbitsim.provenance import provenance
from orbitsim.record import RunRecord

#: Identifies a comparison file (its groups are traces, the file itself is not one).
COMPARE_FORMAT = "orbitsim.compare"
COMPARE_VERSION = 1

_SERIES = ("time", "step", "kinetic", "potential", "energy", "energy_error", "momentum",
           "angular_momentum", "positions", "velocities")


def write_file_attrs(f: h5py.File, attrs: Mapping[str, Any]) -> None:
    """Root attributes of a comparison file: format, versions, provenance and ``attrs``."""
    root: dict[str, Any] = {f"provenance_{k}": v for k, v in provenance().items()}
    root.update(attrs)
    root.update(format=COMPARE_FORMAT, format_version=COMPARE_VERSION, orbitsim_version=__version__)
    for key, value in root.items():
        f.attrs[key] = value


def write_trace_group(parent: h5py.Group, path: str, record: RunRecord, *, names: Sequence[str],
                      masses: np.ndarray, attrs: Mapping[str, Any] | None = None) -> h5py.Group:
    """Write ``record`` as a trace-layout group at ``parent[path]``.

    Parameters
    ----------
    parent : h5py.Group
        An open file or group.
    path : str
        Group path relative to ``parent`` (intermediate groups are created).
    record : RunRecord
    names : sequence of str
        Body names (N,).
    masses : (N,) array
    attrs : mapping, optional
        Extra attributes (``scenario``, ``scenario_sha256``, ``units`` ...).

    Returns
    -------
    h5py.Group
    """
    group = parent.create_group(path)
    energy = record.energy
    base: dict[str, Any] = {
        "format": TRACE_FORMAT, "format_version": TRACE_VERSION, "orbitsim_version": __version__,
        "engine": record.engine, "integrator": record.integrator, "display": record.display,
        "options": json.dumps(record.options, sort_keys=True), "dt": record.dt,
        "steps_requested": int(record.step[-1]) if record.n_samples else 0,
        "order": -1 if record.order is None else int(record.order),
        "status": record.status, "steps_done": int(record.steps_done),
        "wall_time_s": float(record.wall_time_s), "message": record.message,
    }
    if energy.size:
        base["E0"] = float(energy[0])
    base.update(attrs or {})
    for key, value in base.items():
        group.attrs[key] = value
    bodies = group.create_group("bodies")
    bodies.create_dataset("names", data=list(names), dtype=h5py.string_dtype("utf-8"))
    bodies.create_dataset("masses", data=np.asarray(masses, dtype=np.float64))
    for name in _SERIES:
        data = getattr(record, name)
        dtype = np.int64 if name == "step" else np.float64
        group.create_dataset(name, data=np.asarray(data, dtype=dtype), compression="gzip",
                             compression_opts=4, shuffle=True)
    return group


def read_trace_group(group: h5py.Group) -> Trace:
    """Read a trace-layout group (as written by :func:`write_trace_group`) into a Trace."""
    if py_value(group.attrs.get("format")) != TRACE_FORMAT:
        raise ValueError(f"{group.name}: not a trace-layout group")
    arrays = {name: group[name][()] for name in _SERIES if name in group}
    return Trace(attrs={k: py_value(v) for k, v in group.attrs.items()},
                 names=tuple(group["bodies/names"].asstr()[()]), masses=group["bodies/masses"][()],
                 **arrays)


def list_trace_groups(f: h5py.File) -> list[str]:
    """Paths of every trace-layout group in an open comparison file, in file order."""
    found: list[str] = []

    def visit(name: str, obj: Any) -> None:
        if isinstance(obj, h5py.Group) and py_value(obj.attrs.get("format")) == TRACE_FORMAT:
            found.append(name)

    f.visititems(visit)
    return found
