"""The scenario a trace or checkpoint stores: its resolved YAML text, and a large one's bodies as datasets.

A trace (and a ``.ckpt`` file) holds the scenario it ran so that ``resume``, ``run --from`` and
``export`` continue it bit for bit (:func:`orbitsim.scenario.serialize.stored_form`):

* up to :data:`~orbitsim.scenario.serialize.STORED_TEXT_MAX` bytes (about 1,000 bodies), the
  whole resolved text in the ``scenario`` attribute, as always;
* beyond that, the ``scenario`` attribute holds the text without its per-body rows, and the group
  :data:`SCENARIO_BODIES` holds the rows as datasets: ``names`` (N,) UTF-8, ``m`` (N,), ``x``,
  ``v`` (N, 3), ``r`` (N,) when the bodies have radii, and ``mapping_positions``,
  ``mapping_velocities`` (N, 3) when the scenario carries an integrator state.

Either way ``scenario_sha256`` is the SHA-256 of the whole text, so a trace's identity (what batch
resumes match on) does not depend on how it was stored. Metadata stays small at any N: a 10^6-body
Plummer run used to keep 176 MB of YAML in one attribute.
"""

from __future__ import annotations

from collections.abc import Mapping

import h5py
import numpy as np

__all__ = ["SCENARIO_BODIES", "read_scenario_bodies", "write_scenario_bodies"]

#: The group of a large scenario's per-body rows, beside the ``scenario`` attribute (the text's comment
#: names it too: :data:`orbitsim.scenario.serialize.BODIES_GROUP`).
SCENARIO_BODIES = "scenario_bodies"


def write_scenario_bodies(group: h5py.Group, arrays: Mapping[str, np.ndarray]) -> None:
    """Write a stored scenario's arrays into the new group :data:`SCENARIO_BODIES` of ``group``.

    Compressed (gzip level 1 with shuffle, as a trace's series are): a generator's names and equal
    masses shrink to almost nothing, and 10^6 bodies take about a second. The names are fixed-length
    UTF-8 (11 MB for 10^6 generated names, where variable-length strings took 48 MB), unless one
    holds a NUL, which fixed-length strings would drop.
    """
    target = group.create_group(SCENARIO_BODIES)
    for name, arr in arrays.items():
        if name == "names":
            encoded = [str(n).encode("utf-8") for n in arr]
            width = max((len(b) for b in encoded), default=1)
            if any(b"\0" in b for b in encoded):
                data = np.array([str(n) for n in arr], dtype=object)
                dtype = h5py.string_dtype("utf-8")
            else:
                dtype = h5py.string_dtype("utf-8", width)
                data = np.array(encoded, dtype=f"S{width}").astype(dtype)
        else:
            data, dtype = np.asarray(arr, dtype=np.float64), np.float64
        target.create_dataset(name, data=data, dtype=dtype, compression="gzip", compression_opts=1, shuffle=True)


def read_scenario_bodies(group: h5py.Group) -> dict[str, np.ndarray] | None:
    """The arrays of ``group``'s :data:`SCENARIO_BODIES`, or None when the scenario's text is whole.

    Raises
    ------
    KeyError, OSError
        For a damaged group (the callers say which file).
    """
    found = group.get(SCENARIO_BODIES)
    if found is None:
        return None
    arrays: dict[str, np.ndarray] = {}
    for name, dataset in found.items():
        arrays[name] = dataset.asstr()[()] if name == "names" else dataset[()]
    return arrays
