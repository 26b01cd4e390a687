"""``bodies: {rebound: sim.bin, snapshot: -1}``: a scenario's bodies from a REBOUND file.

The file's particles become explicit Cartesian bodies (their floats unchanged, so the run starts
from the file's exact bits), and the file also supplies ``G``, ``dt``, ``softening`` and the
integrator wherever the scenario gives none: positions and velocities mean something only in the
file's units, whose ``G`` is the file's. The file's time ``t`` becomes ``t_start`` (the run's clock
continues the file's; ``t_end`` is then an absolute time after it) unless the scenario gives one.
:func:`~orbitsim.scenario.loader.rebound_scenario` is ``orbitsim run sim.bin``: the same, with only the run length
from the command line.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from orbitsim.scenario.errors import ScenarioError
from orbitsim.scenario.fields import describe

__all__ = ["REBOUND_KEYS", "expand_rebound_bodies", "uses_rebound_file"]

REBOUND_KEYS = ("rebound", "snapshot", "names")


def uses_rebound_file(doc: Any) -> bool:
    """Whether ``doc`` takes its bodies from a REBOUND file (``bodies`` is a mapping with ``rebound``)."""
    return isinstance(doc, Mapping) and isinstance(doc.get("bodies"), Mapping) and "rebound" in doc["bodies"]


def expand_rebound_bodies(doc: Mapping[str, Any], source: str) -> dict[str, Any]:
    """``doc`` with ``bodies: {rebound: FILE, ...}`` replaced by the file's bodies.

    ``FILE`` is relative to the scenario file's directory. ``snapshot`` (default -1, the last)
    picks a snapshot of a Simulationarchive; ``names`` (default ``p0``, ``p1``, ...) names the
    particles. ``G``, ``dt``, ``softening``, ``t_start`` (the file's ``t``) and ``integrator`` come
    from the file unless ``doc`` gives them.

    Raises
    ------
    ScenarioError
        At ``bodies.rebound`` (missing file, not a REBOUND file, an integrator without an orbitsim
        counterpart and no ``integrator:``), ``bodies.snapshot`` or ``bodies.names``.
    """
    from orbitsim.io.rebound_file import ReboundFileError, read_rebound_file  # noqa: PLC0415 -- lazy: off `orbitsim validate`

    spec = doc["bodies"]
    unknown = [key for key in spec if key not in REBOUND_KEYS]
    if unknown:
        raise ScenarioError(f"unknown key {unknown[0]!r} with rebound; valid: {', '.join(REBOUND_KEYS)}",
                            key=f"bodies.{unknown[0]}")
    file = spec["rebound"]
    if not isinstance(file, str) or not file.strip():
        raise ScenarioError(f"expected the path of a REBOUND file, got {describe(file)}", key="bodies.rebound")
    snapshot = spec.get("snapshot", -1)
    if isinstance(snapshot, bool) or not isinstance(snapshot, int):
        raise ScenarioError(f"expected a whole snapshot index (-1 for the last), got {describe(snapshot)}",
                            key="bodies.snapshot")
    base = Path(source).parent if Path(source).is_file() else Path()
    try:
        state = read_rebound_file(base / file, snapshot)
    except ReboundFileError as err:
        raise ScenarioError(str(err), key=f"bodies.{'snapshot' if err.field == 'snapshot' else 'rebound'}") from None
    names = _names(spec.get("names"), state.masses.shape[0])
    out = dict(doc)
    out["bodies"] = _bodies(state, names)
    for key, value in (("G", state.G), ("dt", state.dt), ("softening", state.softening), ("t_start", state.t)):
        out.setdefault(key, value)
    if "integrator" not in out:
        if state.integrator is None:
            raise ScenarioError(f"{state.path}: {state.unmapped}", key="bodies.rebound")
        name, settings = state.integrator
        out["integrator"] = {"name": name, **settings} if settings else name
    out.setdefault("description", f"from the REBOUND file {state.path}, snapshot {state.index} of {state.count} "
                                  f"(REBOUND t = {state.t!r})")
    return out


def _names(given: Any, n: int) -> list[str]:
    if given is None:
        return [f"p{i}" for i in range(n)]
    if not isinstance(given, list) or len(given) != n or not all(isinstance(s, str) for s in given):
        raise ScenarioError(f"expected a list of {n} names, one per particle of the file, got {describe(given)}",
                            key="bodies.names")
    return given


def _bodies(state: Any, names: list[str]) -> list[dict[str, Any]]:
    """Explicit bodies; ``tolist()`` gives Python floats with the arrays' exact bits."""
    m, x, v = state.masses.tolist(), state.positions.tolist(), state.velocities.tolist()
    r = state.radii.tolist() if state.radii is not None else None
    bodies = []
    for i, name in enumerate(names):
        body: dict[str, Any] = {"name": name, "m": m[i], "x": x[i], "v": v[i]}
        if r is not None:
            body["r"] = r[i]
        bodies.append(body)
    return bodies
