"""The scenario's ``forces:`` list: reading, checking and resolving it, and its arrays.

Each entry is one force, ``{force: <name>, <parameters>}``; the schema, the equations and the
REBOUNDx names are in ``docs/scenarios.md`` (section "Forces"). Reading resolves every default, so
the entries a :class:`~orbitsim.scenario.Scenario` keeps (and writes into its resolved YAML, which
every trace stores) say exactly what was run: the speed of light ``c`` as a number, the ``source``
of ``gr`` as a body name, a unit ``spin_axis``. Reading a resolved entry again gives it back bit
for bit, which the stored scenario's SHA-256 relies on.

Every problem is a one-line :class:`~orbitsim.scenario.ScenarioError` naming the key path
(``forces[1].J2``); the scenario adds the file and the line. This is the reader of one section of a
scenario, beside the others in this package; the force kernels it feeds are in :mod:`orbitsim.forces`.
"""

from __future__ import annotations

import difflib
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from orbitsim.forces.table import FORCE_IDS, MIGRATION, N_PARAMS, P_C, P_J2, P_J4, P_R_EQ, P_SPIN, ForceSet
from orbitsim.scenario.data import ScenarioData
from orbitsim.scenario.errors import ScenarioError
from orbitsim.scenario.fields import Fields, describe, join_path, unknown_key_error
from orbitsim.units import AU_M, DAY_S, GAUSSIAN_YEAR_DAYS, UNIT_SYSTEMS

__all__ = ["C_M_PER_S", "FORCE_KEYS", "GR_FORCES", "SPEED_OF_LIGHT", "TAU_KEYS", "default_c", "describe_forces",
           "force_set", "read_forces"]

#: The speed of light in m/s, exact by the SI definition of the metre (CGPM 1983).
C_M_PER_S = 299_792_458.0
#: ``c`` in each unit system's length and time, from the IAU definitions of the au (exactly
#: 149 597 870 700 m, IAU 2012 B2) and the day (86400 s). orbitsim's ``au-yr-msun`` year is the
#: Gaussian year 2 pi / k days (:data:`orbitsim.units.GAUSSIAN_YEAR_DAYS`, the year in which
#: G = 4 pi^2 is exact), so c = 63242.27 au/yr there, not the Julian year's 63241.08. REBOUND's
#: "au, yr/2pi" units (G = 1) have c = 10065.32012038219 = this value / (2 pi). ``nbody`` has no
#: physical scale, hence no default.
SPEED_OF_LIGHT: dict[str, float] = {
    "si": C_M_PER_S,
    "au-day-msun": C_M_PER_S * DAY_S / AU_M,
    "au-yr-msun": C_M_PER_S * DAY_S * GAUSSIAN_YEAR_DAYS / AU_M,
}
#: The keys each force takes (``force`` names it).
FORCE_KEYS: dict[str, tuple[str, ...]] = {
    "gr_potential": ("force", "c", "source"),
    "gr": ("force", "c", "source"),
    "gr_full": ("force", "c"),
    "harmonics": ("force", "body", "J2", "J4", "R_eq", "spin_axis"),
    "migration": ("force", "bodies"),
}
#: The three forms of general relativity: each is all of first post-Newtonian order, so two of them
#: together would count it twice.
GR_FORCES = ("gr_potential", "gr", "gr_full")
#: ``migration``'s timescales per body: a, e and inclination (REBOUNDx ``modify_orbits_forces``).
TAU_KEYS = ("tau_a", "tau_e", "tau_inc")
#: A spin axis this close to unit length is kept as given: normalising it again could move its
#: last bit, and a resolved scenario must read back to the same bits (its SHA-256 is checked).
_UNIT_TOLERANCE = 4.0 * np.finfo(np.float64).eps


def default_c(units: str, G: float) -> float | None:
    """The speed of light in ``units``, or None when there is none to give.

    None for ``nbody`` (no physical scale) and whenever ``G`` is not the unit system's own: a
    scenario that sets ``G: 1`` with au and Msun (REBOUND's "yr/2pi" time unit) has another time
    unit than the one its ``units`` name, so no default would be right.
    """
    system = UNIT_SYSTEMS.get(units)
    if system is None or G != system.G:
        return None
    return SPEED_OF_LIGHT.get(units)


@dataclass(frozen=True)
class _Bodies:
    """What reading the forces needs to know about the scenario."""

    names: tuple[str, ...]
    masses: np.ndarray | None
    units: str
    G: float | None

    def index(self, name: str) -> int:
        return self.names.index(name)

    def heaviest(self) -> str:
        """The most massive body (the first of equals); REBOUNDx's source is particle 0, which is the
        heaviest in every usual setup."""
        if self.masses is None or len(self.masses) == 0:
            return self.names[0]
        return self.names[int(np.argmax(self.masses))]

    def mass(self, name: str) -> float | None:
        return None if self.masses is None else float(self.masses[self.index(name)])


def read_forces(raw: Any, body_keys: Sequence[str], units: str, path: str = "forces", *,
                masses: Any = None, G: float | None = None) -> tuple[dict[str, Any], ...]:
    """Check a ``forces:`` list and resolve its defaults.

    Parameters
    ----------
    raw : Any
        The list as parsed from YAML (or the resolved entries of a Scenario); None means no forces.
    body_keys : Sequence[str]
        The scenario's body names, in its body order.
    units : str
        The scenario's unit system (for the default ``c``).
    path : str
        Key path of the list, for messages.
    masses : array_like, optional
        (N,) masses: the default ``source`` of ``gr`` is the heaviest body (else the first), and a
        massless source is refused.
    G : float, optional
        The scenario's G; without it, or when it is not the unit system's, ``c`` has no default.

    Returns
    -------
    tuple of dict
        One resolved mapping per force, keys in the order of :data:`FORCE_KEYS`.

    Raises
    ------
    ScenarioError
        Naming the key path, e.g. ``forces[1].J2``.
    """
    if raw is None:
        return ()
    if isinstance(raw, str | bytes | Mapping) or not isinstance(raw, Sequence):
        raise ScenarioError(f"expected a list of forces, each {{force: <name>, ...}}, got {describe(raw)}", key=path)
    ctx = _Bodies(tuple(body_keys), None if masses is None else np.asarray(masses, dtype=np.float64), units, G)
    entries = tuple(_read_entry(item, join_path(path, i), ctx) for i, item in enumerate(raw))
    _check_combination(entries, path)
    return entries


def _read_entry(item: Any, path: str, ctx: _Bodies) -> dict[str, Any]:
    if not isinstance(item, Mapping):
        raise ScenarioError(f"expected a force {{force: <name>, ...}}, got {describe(item)}", key=path)
    name = Fields(item, path, item.keys()).string("force", choices=FORCE_KEYS)
    allowed = FORCE_KEYS[name]
    for key in item:
        if key not in allowed:
            if any(key in keys for keys in FORCE_KEYS.values()):
                raise ScenarioError(f"{name} takes no {key!r}; its keys: {', '.join(allowed)}",
                                    key=join_path(path, str(key)))
            raise unknown_key_error(str(key), path, allowed)
    fields = Fields(item, path, allowed, f"{name} force")
    if name in GR_FORCES:
        entry: dict[str, Any] = {"force": name, "c": _speed_of_light(fields, ctx)}
        if name != "gr_full":
            entry["source"] = _massive_body(fields, "source", ctx, ctx.heaviest(), name)
        return entry
    if name == "harmonics":
        return _read_harmonics(fields, ctx)
    return {"force": name, "bodies": _read_migration(fields, ctx)}


def _speed_of_light(fields: Fields, ctx: _Bodies) -> float:
    if fields.has("c"):
        return fields.number("c", positive=True)
    c = default_c(ctx.units, ctx.G) if ctx.G is not None else None
    if c is not None:
        return c
    if ctx.units == "nbody":
        why = "units nbody have no physical scale, so there is no default"
    else:
        why = f"G = {ctx.G:g} is not the {ctx.units} value, so the time unit is not the one {ctx.units} names"
    raise fields.error("c", f"give c, the speed of light in the scenario's units: {why} (REBOUND's au, yr/2pi "
                            "units with G = 1 have c = 10065.32012038219)")


def _body_name(fields: Fields, key: str, ctx: _Bodies, default: str | None = None) -> str:
    name = fields.string(key) if default is None else fields.string(key, default)
    return _known_body(name, fields.key(key), ctx)


def _known_body(name: Any, key: str, ctx: _Bodies) -> str:
    if not isinstance(name, str):
        raise ScenarioError(f"expected a body name, got {describe(name)}", key=key)
    if name not in ctx.names:
        close = difflib.get_close_matches(name, ctx.names, n=1, cutoff=0.6)
        hint = f"did you mean {close[0]!r}?" if close else f"bodies: {_list(ctx.names)}"
        raise ScenarioError(f"no body named {name!r}; {hint}", key=key)
    return name


def _massive_body(fields: Fields, key: str, ctx: _Bodies, default: str | None, force: str) -> str:
    """A body that must have mass: a massless one would make the force zero, which is never meant."""
    name = _body_name(fields, key, ctx, default)
    if ctx.mass(name) == 0.0:
        raise ScenarioError(f"body {name!r} has no mass, so {force} about it would do nothing; name a massive body",
                            key=fields.key(key) if fields.has(key) else fields.path)
    return name


def _read_harmonics(fields: Fields, ctx: _Bodies) -> dict[str, Any]:
    body = _massive_body(fields, "body", ctx, None, "harmonics")
    return {"force": "harmonics", "body": body,
            "J2": fields.number("J2", minimum=0.0),  # J4 < 0 is usual (Earth, Jupiter); J2 < 0 a prolate body
            "J4": fields.number("J4", 0.0),
            "R_eq": fields.number("R_eq", positive=True),
            "spin_axis": _unit_vector(fields, "spin_axis")}


def _unit_vector(fields: Fields, key: str) -> list[float]:
    if not fields.has(key):
        return [0.0, 0.0, 1.0]
    v = np.array(fields.vector3(key))
    norm = math.sqrt(float(v @ v))  # vector3 checked each part finite; the square may still overflow
    if norm == 0.0 or not math.isfinite(norm):
        raise fields.error(key, f"must be a non-zero, finite direction [x, y, z], got {fields.raw(key)}")
    if abs(norm - 1.0) > _UNIT_TOLERANCE:
        v = v / norm
    return [float(x) for x in v]


def _read_migration(fields: Fields, ctx: _Bodies) -> dict[str, dict[str, float]]:
    raw = fields.raw("bodies")
    where = fields.key("bodies")
    if not isinstance(raw, Mapping) or not raw:
        raise ScenarioError("expected the bodies to migrate or damp, {<name>: {tau_a: ..., tau_e: ..., tau_inc: "
                            f"...}}, got {describe(raw)}", key=where)
    out: dict[str, dict[str, float]] = {}
    for name, taus in raw.items():
        key = join_path(where, str(name))
        if _known_body(name, key, ctx) == ctx.names[0]:  # the kernels' Jacobi chain starts at body 0
            raise ScenarioError(f"{name!r} is the first body, the root of the Jacobi coordinates in which orbits "
                                "migrate: it has no orbit of its own to change (as in REBOUNDx)", key=key)
        body = Fields(taus, key, TAU_KEYS, "mapping of timescales")
        if not any(body.has(k) for k in TAU_KEYS):
            raise ScenarioError(f"give at least one of {', '.join(TAU_KEYS)}", key=key)
        out[name] = {k: _timescale(body, k) for k in TAU_KEYS if body.has(k)}
    return out


def _timescale(body: Fields, key: str) -> float:
    tau = body.number(key)
    if tau == 0.0:
        raise body.error(key, "must be a non-zero time (negative: damping or inward migration, positive: growth), "
                              "got 0")
    return tau


def _check_combination(entries: tuple[dict[str, Any], ...], path: str) -> None:
    """Refuse forces that would count one effect twice: two forms of GR, two sets of harmonics of
    one body, two migrations."""
    seen: dict[tuple[str, str], int] = {}
    for k, entry in enumerate(entries):
        name = entry["force"]
        kind = ("gr", "") if name in GR_FORCES else (name, entry.get("body", ""))
        first = seen.setdefault(kind, k)
        if first == k:
            continue
        if kind[0] == "gr":
            reason = (f"{name} repeats the general relativity of {path}[{first}] ({entries[first]['force']}): "
                      f"give one of {', '.join(GR_FORCES)}")
        elif kind[0] == "harmonics":
            reason = f"body {kind[1]!r} already has harmonics in {path}[{first}]: give its J2 and J4 in one entry"
        else:
            reason = f"there is already a migration in {path}[{first}]: give every body's timescales in one entry"
        raise ScenarioError(reason, key=join_path(path, k))


def _list(names: Sequence[str], limit: int = 8) -> str:
    shown = ", ".join(names[:limit])
    return shown + (f" and {len(names) - limit} more" if len(names) > limit else "")


def describe_forces(entries: Sequence[Mapping[str, Any]]) -> str:
    """The resolved forces in a few words each, for ``orbitsim validate``:
    ``gr about sun (c = 63242.27), harmonics of earth (J2 = 0.0010826, J4 = 0)``."""
    words = []
    for e in entries:
        name = e["force"]
        if name == "harmonics":
            words.append(f"harmonics of {e['body']} (J2 = {e['J2']:.6g}, J4 = {e['J4']:.6g}, R_eq = {e['R_eq']:.6g})")
        elif name == "migration":
            words.append(f"migration of {', '.join(e['bodies'])}")
        else:
            about = f" about {e['source']}" if "source" in e else ""
            words.append(f"{name}{about} (c = {e['c']:.10g})")
    return ", ".join(words)


def force_set(scenario: ScenarioData) -> ForceSet | None:
    """The arrays of a scenario's forces, or None when it has none.

    Body names become indices in the scenario's body order; ``params`` columns are those of
    :mod:`orbitsim.forces.table` (unused ones 0); ``per_body`` holds ``migration``'s tau_a, tau_e,
    tau_inc, inf where a body has none.
    """
    entries = tuple(scenario.forces)
    if not entries:
        return None
    n, f = scenario.n_bodies, len(entries)
    index = {name: i for i, name in enumerate(scenario.names)}
    ids = np.array([FORCE_IDS[e["force"]] for e in entries], dtype=np.int64)
    source = np.full(f, -1, dtype=np.int64)
    params = np.zeros((f, N_PARAMS))
    per_body = np.zeros((f, 3, n))
    for k, e in enumerate(entries):
        if "c" in e:
            params[k, P_C] = e["c"]
        if "source" in e:
            source[k] = index[e["source"]]
        if e["force"] == "harmonics":
            source[k] = index[e["body"]]
            params[k, P_J2], params[k, P_J4], params[k, P_R_EQ] = e["J2"], e["J4"], e["R_eq"]
            params[k, P_SPIN:P_SPIN + 3] = e["spin_axis"]
        if ids[k] == MIGRATION:
            per_body[k] = np.inf
            for name, taus in e["bodies"].items():
                for row, key in enumerate(TAU_KEYS):
                    per_body[k, row, index[name]] = taus.get(key, np.inf)
    return ForceSet(ids, source, params, per_body, entries)
