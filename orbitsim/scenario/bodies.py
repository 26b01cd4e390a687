"""Bodies of a scenario from its three sources: an explicit list, the DE421 ephemeris, generators.

Sources are read in a fixed order (``ephemeris``, then ``generator``, then ``bodies``), so a body
given by orbital elements may orbit any body from the ephemeris or a generator, or one listed
before it. Each body remembers the key path it came from, so a later whole-system check (two
bodies at one point) can still name the key to fix.
"""

from __future__ import annotations

import math
import os
from typing import Any, NamedTuple

import numpy as np

from orbitsim.initial_conditions.ephemeris import EPHEMERIS_BODIES, de421_states, epoch_to_jd
from orbitsim.initial_conditions.generators import disc, plummer, sphere_radii
from orbitsim.scenario.body_set import BodySet
from orbitsim.scenario.element_input import ELEMENT_ONLY_KEYS, elements_state
from orbitsim.scenario.errors import ScenarioError
from orbitsim.scenario.fields import Fields, describe, join_path
from orbitsim.scenario.frames import AXES, rotate
from orbitsim.scenario.quantities import ANGLE_UNITS, QuantityReader
from orbitsim.units import AU_M, DAY_S, GAUSSIAN_YEAR_DAYS, UNIT_SYSTEMS

__all__ = ["BodyPrefix", "BodySet", "available_memory", "check_coincident", "read_bodies", "read_body_prefix",
           "shift_to_barycentre"]

CARTESIAN_KEYS = ("name", "m", "x", "v", "r")
ELEMENT_KEYS = ("name", "m", *ELEMENT_ONLY_KEYS, "r")
EPHEMERIS_KEYS = ("source", "epoch", "jd", "bodies", "frame")
PLUMMER_KEYS = ("kind", "n", "seed", "total_mass", "scale_radius", "prefix")
DISC_KEYS = ("kind", "n", "seed", "central_mass", "r_min", "r_max", "e_max", "inc_max", "star", "prefix", "m_min",
             "m_max", "mass_index", "density", "star_r")
GENERATOR_KINDS = {"plummer": PLUMMER_KEYS, "disc": DISC_KEYS}

#: Bytes of memory a run needs per body, generously: generator temporaries (~40 doubles), the
#: scenario's and the simulation's state, force scratch (16 slabs of 3 doubles: gravity.MAX_BLOCKS)
#: and the resolved-YAML text that is stored in the trace (~250 bytes, held twice).
BYTES_PER_BODY = 2048
#: Bytes a run needs whatever N: Python, numba, HDF5 and the bounded sample and write buffers.
BYTES_FIXED = 512 * 2**20

#: How many bodies a note of ``orbitsim validate`` names before it counts the rest.
_NOTE_BODIES = 5

#: Ephemeris states come in au and days: length and time factors (au -> unit, day -> unit).
_EPHEMERIS_SCALE = {"au-day-msun": ("au", "day"), "au-yr-msun": ("au", "gyr"), "si": ("m", "s")}


def read_bodies(doc: Fields, G: float, units: str, *, start: BodyPrefix | None = None,
                stop: int | None = None) -> BodySet:
    """All bodies of a document, in source order ``ephemeris``, ``generator``, ``bodies``.

    ``stop``: read ``bodies[:stop]`` only (and skip the checks of a whole document), for a
    :class:`BodyPrefix`. ``start``: continue from such a prefix of this same document (a copy of it is
    filled): its ephemeris, generators and first ``start.count`` bodies are not read again, so a caller
    that edits only later bodies (a stability map's pixels) reads only those, with the bits a whole read
    gives them.
    """
    if start is None:
        angles = doc.string("angles", "deg", choices=ANGLE_UNITS, fold_case=True)
        bodies = BodySet(reader=QuantityReader(units, angles, own_G=G != UNIT_SYSTEMS[units].G))
        first = 0
        if doc.has("ephemeris"):
            _read_ephemeris(Fields(doc.raw("ephemeris"), "ephemeris", EPHEMERIS_KEYS), G, units, bodies)
        if doc.has("generator"):
            specs = doc.raw("generator")
            if isinstance(specs, list):
                for i, spec in enumerate(specs):
                    _read_generator(spec, join_path("generator", i), G, bodies)
            else:
                _read_generator(specs, "generator", G, bodies)
    else:
        bodies, first = start.bodies.copy(), start.count
    if doc.has("bodies"):
        items = doc.raw("bodies")
        if not isinstance(items, list):
            raise ScenarioError(f"expected a list of bodies, got {describe(items)}", key="bodies")
        for i in range(first, len(items) if stop is None else min(stop, len(items))):
            _read_body(items[i], join_path("bodies", i), G, bodies)
    if stop is not None:
        return bodies
    if not bodies.names:
        raise ScenarioError("the scenario has no bodies: give a bodies list, an ephemeris or a generator")
    if bodies.no_anomaly:
        shown = ", ".join(bodies.no_anomaly[:_NOTE_BODIES])
        more = f" and {len(bodies.no_anomaly) - _NOTE_BODIES} more" if len(bodies.no_anomaly) > _NOTE_BODIES else ""
        bodies.notes.append(f"no anomaly (M, f, l or theta) for {shown}{more}: f = 0, at pericentre (REBOUND's "
                            "default)")
    return bodies


class BodyPrefix(NamedTuple):
    """The bodies of a document read up to ``bodies[count]`` (:func:`read_body_prefix`)."""

    bodies: BodySet
    count: int


def read_body_prefix(doc: Fields, G: float, units: str, count: int) -> BodyPrefix:
    """The ephemeris, generators and ``bodies[:count]`` of ``doc``, for :func:`read_bodies`'s ``start``."""
    return BodyPrefix(read_bodies(doc, G, units, stop=count), count)


def _body_name(body: Fields) -> str:
    name = body.string("name")
    if not name.strip():
        raise body.error("name", "a body name must not be empty")
    return name


def _read_body(item: Any, path: str, G: float, bodies: BodySet) -> None:
    """One entry of ``bodies``: cartesian ``{name, m, x, v}`` or orbital elements."""
    keys = set(item) if isinstance(item, dict) else set()
    cartesian = bool(keys & {"x", "v"})
    elements = bool(keys & set(ELEMENT_ONLY_KEYS))
    if cartesian and elements:
        raise ScenarioError("give either x and v (cartesian) or primary and orbital elements, not both",
                            key=path)
    body = Fields(item, path, ELEMENT_KEYS if elements else CARTESIAN_KEYS, "body")
    name = _body_name(body)
    m = bodies.reader.number(body.raw("m"), body.key("m"), "mass")
    if m < 0.0:
        raise body.error("m", f"mass must be >= 0, got {body.raw('m')}")
    if elements:
        x, v = elements_state(body, m, G, bodies)
    elif not cartesian:
        raise ScenarioError("a body needs x and v (cartesian) or primary and a (orbital elements)", key=path)
    else:
        x, v = _vector(body, "x", "length", bodies.reader), _vector(body, "v", "speed", bodies.reader)
    radius = bodies.reader.number(body.raw("r"), body.key("r"), "length", minimum=0.0) if body.has("r") else None
    if radius is not None:
        bodies.radii[len(bodies.names)] = radius
    bodies.add([name], [m], x, v, [path], [body.key("name")])


def _vector(body: Fields, name: str, kind: str, reader: QuantityReader) -> list[float]:
    """A list of three numbers, each of which may carry a unit (``["1 au", 0, 0]``)."""
    value = body.raw(name)
    if not isinstance(value, list | tuple) or len(value) != 3:
        raise body.error(name, f"expected a list of 3 numbers [x, y, z], got {describe(value)}")
    return [reader.number(item, join_path(body.key(name), i), kind) for i, item in enumerate(value)]


def _ephemeris_factors(units: str, key: str) -> tuple[float, float]:
    """Length and time factors from (au, day) to the scenario's unit system."""
    if units not in _EPHEMERIS_SCALE:
        raise ScenarioError(f"ephemeris states are in au and days: set units to one of "
                            f"{', '.join(_EPHEMERIS_SCALE)} (got {units!r})", key=key)
    length, time = _EPHEMERIS_SCALE[units]
    return (AU_M if length == "m" else 1.0), {"day": 1.0, "gyr": 1.0 / GAUSSIAN_YEAR_DAYS, "s": DAY_S}[time]


def _read_ephemeris(eph: Fields, G: float, units: str, bodies: BodySet) -> None:
    """DE421 states and GM values, converted to the scenario's units (masses are GM / G)."""
    eph.string("source", "de421", choices=["de421"])
    # DE421 is equatorial (ICRF); frame: ecliptic turns it, and so the whole scenario, to the J2000 ecliptic.
    frame = eph.string("frame", "equatorial", choices=AXES, fold_case=True)
    bodies.axes = frame
    bodies.notes.append(f"axes: the {'J2000 mean ecliptic' if frame == 'ecliptic' else 'ICRF equator'} "
                        f"(ephemeris.frame: {frame}); elements without a frame refer to it")
    length, time = _ephemeris_factors(units, "units")
    when = eph.one_of("epoch", "jd")
    if when == "epoch":
        try:
            jd = epoch_to_jd(eph.string("epoch"))
        except ValueError as err:
            raise eph.error("epoch", str(err)) from None
    else:
        jd = eph.number("jd")
    names = eph.raw("bodies")
    if not isinstance(names, list) or not names:
        raise eph.error("bodies", f"expected a list of body names, got {describe(names)}")
    for i, name in enumerate(names):
        if name not in EPHEMERIS_BODIES:
            raise ScenarioError(f"unknown ephemeris body {name!r}; valid: {', '.join(EPHEMERIS_BODIES)}",
                                key=join_path(eph.key("bodies"), i))
    if "earthmoon" in names and {"earth", "moon"} & set(names):
        raise eph.error("bodies", "earthmoon is the Earth-Moon barycentre: do not combine it with earth or moon")
    try:
        states = de421_states(names, jd)
    except ValueError as err:
        raise eph.error(when, str(err)) from None
    gm = states.gm * length**3 / time**2
    keys = [join_path(eph.key("bodies"), i) for i in range(len(names))]
    x, v = rotate(states.positions, "equatorial", frame), rotate(states.velocities, "equatorial", frame)
    bodies.add(list(names), gm / G, x * length, v * (length / time), keys, keys)


def available_memory() -> int:
    """Bytes of memory this process can expect to get (MemAvailable, else physical memory)."""
    try:
        with open("/proc/meminfo", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass  # not Linux: physical memory is the best portable bound
    try:
        return int(os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):
        return 2**62  # unknown: do not refuse


def _check_memory(n: int, key: str) -> None:
    """Refuse a generator whose system would not fit in memory, before allocating anything."""
    need = BYTES_FIXED + BYTES_PER_BODY * n
    have = available_memory()
    if need > have:
        raise ScenarioError(f"{n} bodies need about {_gib(need)} of memory but this machine has {_gib(have)} "
                            "available: lower n", key=key)


def _gib(nbytes: float) -> str:
    return f"{nbytes / 2**30:.3g} GiB"


@np.errstate(all="ignore")  # an overflow is reported as an error naming the key, not as a RuntimeWarning
def _read_generator(spec: Any, path: str, G: float, bodies: BodySet) -> None:
    """A Plummer sphere or a disc of test bodies, reproducible from its seed."""
    kind = spec.get("kind") if isinstance(spec, dict) else None
    if kind not in GENERATOR_KINDS:  # a known kind's own keys make the better "unknown key" message
        every_key = dict.fromkeys(k for keys in GENERATOR_KINDS.values() for k in keys)  # each once
        kind = Fields(spec, path, every_key, "generator").string("kind", choices=list(GENERATOR_KINDS))
    gen = Fields(spec, path, GENERATOR_KINDS[kind], f"{kind} generator")
    n = gen.integer("n", minimum=1)
    _check_memory(n, gen.key("n"))
    seed = gen.integer("seed", minimum=0)
    prefix = gen.string("prefix", kind)
    width = len(str(n - 1))
    names = [f"{prefix}{i:0{width}d}" for i in range(n)]
    if kind == "plummer":
        m, x, v = plummer(n, seed=seed, G=G, total_mass=gen.number("total_mass", 1.0, positive=True),
                          scale_radius=gen.number("scale_radius", 1.0, positive=True))
    else:
        e_max = gen.number("e_max", 0.0, minimum=0.0)
        if e_max >= 1.0:
            raise gen.error("e_max", f"must be < 1 (bound orbits), got {e_max:g}")
        inc_max = bodies.reader.angle(gen.raw("inc_max"), gen.key("inc_max")) if gen.has("inc_max") else 0.0
        if inc_max < 0.0:
            raise gen.error("inc_max", f"must be >= 0, got {gen.raw('inc_max')} ({bodies.reader.angle_words})")
        if inc_max > 180.0:
            raise gen.error("inc_max", f"must be <= 180 degrees, got {inc_max:g}")
        r_min, r_max = gen.number("r_min", positive=True), gen.number("r_max", positive=True)
        if r_min > r_max:
            raise gen.error("r_max", f"must be >= r_min, got r_min = {r_min:g} > r_max = {r_max:g}")
        masses = _disc_masses(gen, bodies.reader)
        m, x, v = disc(n, seed=seed, G=G, central_mass=gen.number("central_mass", 1.0, positive=True),
                       r_min=r_min, r_max=r_max, e_max=e_max, inc_max_deg=inc_max, **masses)
        names = [gen.string("star", "star"), *names]
    if not all(np.isfinite(arr).all() for arr in (m, x, v)):
        raise ScenarioError("the generated masses, positions or velocities overflow float64: use units in which "
                            "the masses and radii are closer to 1", key=path)
    radii = _disc_radii(gen, bodies.reader, m) if kind == "disc" else None
    if radii is not None:
        first = len(bodies.names)
        bodies.radii.update(zip(range(first, first + len(radii)), radii.tolist(), strict=True))
    bodies.add(names, m, x, v, [path] * len(names), [gen.key("prefix")] * len(names))


def _disc_masses(gen: Fields, reader: QuantityReader) -> dict[str, float | None]:
    """A disc's ``m_min``, ``m_max`` and ``mass_index`` (dN/dm ∝ m^mass_index); none of them: test bodies."""
    if not (gen.has("m_min") or gen.has("m_max")):
        for key in ("mass_index", "density"):
            if gen.has(key):
                raise gen.error(key, f"{key} describes the bodies' masses: give m_min and m_max too (without them "
                                     "the disc's bodies are massless test bodies)")
        return {}
    if gen.has("m_min") != gen.has("m_max"):
        given, missing = ("m_min", "m_max") if gen.has("m_min") else ("m_max", "m_min")
        raise gen.error(missing, f"give both m_min and m_max (the range of the bodies' masses), got only {given}")
    m_min = reader.number(gen.raw("m_min"), gen.key("m_min"), "mass", positive=True)
    m_max = reader.number(gen.raw("m_max"), gen.key("m_max"), "mass", positive=True)
    if m_min > m_max:
        raise gen.error("m_max", f"must be >= m_min, got m_min = {m_min:g} > m_max = {m_max:g}")
    index = gen.number("mass_index", None)
    if index is None and m_min < m_max:
        raise gen.error("mass_index", "m_min < m_max needs the power-law index of dN/dm ∝ m^mass_index (e.g. -1.8333 "
                                      "for a collisional cascade, -1 for equal mass per decade)")
    return {"m_min": m_min, "m_max": m_max, "mass_index": index}


def _disc_radii(gen: Fields, reader: QuantityReader, m: np.ndarray) -> np.ndarray | None:
    """Radii of a disc's star (``star_r``) and bodies (spheres of bulk ``density``); None when neither is given."""
    if not (gen.has("density") or gen.has("star_r")):
        return None
    r = np.zeros(m.shape[0])
    if gen.has("star_r"):
        r[0] = reader.number(gen.raw("star_r"), gen.key("star_r"), "length", minimum=0.0)
    if gen.has("density"):
        density = reader.number(gen.raw("density"), gen.key("density"), "density", positive=True)
        r[1:] = sphere_radii(m[1:], density)
        if not np.isfinite(r[1:]).all() or not (r[1:] > 0.0).all():
            raise gen.error("density", f"the radii (3 m / (4 pi density))^(1/3) from density = {density:g} are not "
                                       "finite and > 0 in these units: use units in which the masses and the density "
                                       "are closer to 1")
    return r


def shift_to_barycentre(m: np.ndarray, x: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Positions and velocities relative to the centre of mass (total mass must be > 0)."""
    total = float(np.sum(m))
    if not total > 0.0:
        raise ScenarioError("frame: barycentric needs a positive total mass", key="frame")
    with np.errstate(all="ignore"):  # an overflow is reported below, not as a RuntimeWarning
        shifted = x - (m @ x) / total, v - (m @ v) / total
    if not (np.isfinite(shifted[0]).all() and np.isfinite(shifted[1]).all() and math.isfinite(total)):
        raise ScenarioError("the centre of mass (sums of m x and m v) overflows float64: use units in which the "
                            "masses, positions and velocities are smaller", key="frame")
    return shifted


def check_coincident(x: np.ndarray, names: list[str] | tuple[str, ...], origins: list[str] | None,
                     softening: float) -> None:
    """Refuse two bodies at exactly one point without softening: their force would be infinite.

    Sorting the rows finds equal positions in O(N log N), so this stays cheap for large N.
    """
    if softening > 0.0 or x.shape[0] < 2:
        return
    order = np.lexsort((x[:, 2], x[:, 1], x[:, 0]))
    ordered = x[order]
    same = np.flatnonzero(np.all(ordered[1:] == ordered[:-1], axis=1))
    if same.size:
        i, j = sorted((int(order[same[0]]), int(order[same[0] + 1])))
        where = ", ".join(f"{c:g}" for c in x[i])
        key = origins[j] if origins else f"bodies[{j}]"
        if key.startswith("bodies["):  # an explicit body: point at its position
            key += ".x"
        raise ScenarioError(f"bodies {names[i]!r} and {names[j]!r} are both at ({where}) and softening is 0: "
                            "the force between them would be infinite; move one or set softening > 0", key=key)


def check_body_arrays(masses: Any, positions: Any, velocities: Any,
                      names: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, tuple[str, ...]]:
    """A scenario's bodies as float64 arrays, (N,) masses and (N, 3) states, and N unique names.

    Raises
    ------
    ScenarioError
        Naming ``bodies``, ``names`` or the array with a bad value.
    """
    try:
        m = np.array(masses, dtype=np.float64).reshape(-1)
        x = np.array(positions, dtype=np.float64)
        v = np.array(velocities, dtype=np.float64)
        names = tuple(names)
    except (TypeError, ValueError) as err:
        raise ScenarioError(f"bodies must be numeric arrays and a sequence of names ({err})", key="bodies") from None
    n = m.shape[0]
    if n < 1 or x.shape != (n, 3) or v.shape != (n, 3):
        raise ScenarioError(f"need N >= 1 bodies with positions and velocities of shape (N, 3); got masses "
                            f"{m.shape}, positions {x.shape}, velocities {v.shape}", key="bodies")
    check_finite_state(m, x, v)
    if len(names) != n or not all(isinstance(s, str) and s.strip() for s in names):
        raise ScenarioError(f"need {n} non-empty body names, got {len(names)}", key="names")
    if len(set(names)) != n:
        dup = next(s for i, s in enumerate(names) if s in names[:i])
        raise ScenarioError(f"duplicate body name {dup!r}; names must be unique", key="names")
    return m, x, v, names


def check_finite_state(m: np.ndarray, x: np.ndarray, v: np.ndarray) -> None:
    """Last line of defence for states built in code: finite values, masses >= 0."""
    for label, arr in (("masses", m), ("positions", x), ("velocities", v)):
        bad = np.flatnonzero(~np.isfinite(arr).reshape(arr.shape[0], -1).all(axis=1))
        if bad.size:
            raise ScenarioError(f"{label} of body {int(bad[0])} are not finite", key=label)
    negative = np.flatnonzero(m < 0.0)
    if negative.size:
        raise ScenarioError(f"mass must be >= 0, got {m[negative[0]]:g}", key=f"masses[{int(negative[0])}]")
