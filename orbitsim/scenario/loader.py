"""From a YAML file, a bundled name or a Python mapping to a validated :class:`Scenario`."""

from __future__ import annotations

import difflib
import os
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from orbitsim.data import SCENARIOS, bundled_dir, bundled_files
from orbitsim.gpu.support import DEVICES
from orbitsim.integrators.rebound_names import rebound_note
from orbitsim.scenario.bodies import BodySet, check_coincident, read_bodies, shift_to_barycentre
from orbitsim.scenario.direction import check_adaptive_t_end, check_dt, check_t_end
from orbitsim.scenario.errors import ScenarioError
from orbitsim.scenario.events import read_events
from orbitsim.scenario.fields import MISSING, Fields, check_count, check_number, describe
from orbitsim.scenario.model import DEFAULT_SAMPLES, FRAMES, Scenario, resolve_steps
from orbitsim.scenario.quantities import scenario_time, wall_seconds
from orbitsim.scenario.rebound_bodies import expand_rebound_bodies, uses_rebound_file
from orbitsim.scenario.timing import adaptive_integrator, check_t_start, resolve_grid, run_span, whole_count
from orbitsim.scenario.yamlio import parse_yaml
from orbitsim.units import UNIT_SYSTEMS

__all__ = ["TOP_KEYS", "bundled_scenarios", "config_dir", "load_scenario", "rebound_scenario", "scenario_from_dict",
           "scenario_from_stored"]

TOP_KEYS = ("name", "description", "units", "G", "integrator", "dt", "t_start", "steps", "t_end", "output", "softening",
            "frame", "bodies", "ephemeris", "generator", "events", "forces", "integrator_state",
            "angles", "device")  # angles: read with the bodies (orbitsim.scenario.bodies)
OUTPUT_KEYS = ("every", "interval", "positions", "checkpoint", "elements", "primary", "chaos")
CHECKPOINT_KEYS = ("every", "seconds")
#: Characters a REBOUND file's stem may not bring into a scenario name (which becomes a file name).
_UNSAFE_NAME_CHARS = re.compile(r"[^A-Za-z0-9_.+-]")


def config_dir() -> Path:
    """Directory of the bundled scenarios: ``orbitsim/data/scenarios`` (see :mod:`orbitsim.data`)."""
    return bundled_dir(SCENARIOS)


def bundled_scenarios() -> dict[str, Path]:
    """Bundled scenarios by name (the file stem), sorted by name.

    Returns
    -------
    dict[str, pathlib.Path]
        Every ``*.yaml`` file of :func:`config_dir`.
    """
    return bundled_files(SCENARIOS)


def _locate(spec: str | os.PathLike[str]) -> tuple[Path, str]:
    """The file behind a path or a bundled name, and the label error messages use for it."""
    path = Path(spec)
    if path.is_file():
        return path, os.fspath(spec)
    text = os.fspath(spec)
    bundled = bundled_scenarios()
    if text in bundled:
        found = bundled[text]
        try:
            label = os.path.relpath(found)
        except ValueError:  # another drive (Windows)
            label = os.fspath(found)
        return found, label if not label.startswith("..") else os.fspath(found)
    if path.is_dir():
        raise ScenarioError("is a directory, not a scenario file", file=text)
    if path.suffix or os.sep in text or "/" in text:
        raise ScenarioError("no such file", file=text)
    close = difflib.get_close_matches(text, list(bundled), n=1, cutoff=0.6)
    hint = f"did you mean {close[0]!r}?" if close else f"bundled: {', '.join(bundled) or 'none found'}"
    raise ScenarioError(f"no such file or bundled scenario; {hint}", file=text)


def load_scenario(spec: str | os.PathLike[str]) -> Scenario:
    """Load and validate a scenario file or a bundled scenario by name.

    Parameters
    ----------
    spec : str or os.PathLike
        A YAML file path, or the name of a bundled scenario (``orbitsim list scenarios``).

    Returns
    -------
    Scenario
        With ``source`` set to the path as given (or the bundled file's path).

    Raises
    ------
    ScenarioError
        With ``file``, ``key`` (e.g. ``"bodies[1].m"``) and ``line`` where known.
    """
    path, label = _locate(spec)
    try:
        text = path.read_bytes().decode("utf-8")
    except UnicodeDecodeError as err:
        raise ScenarioError(f"not UTF-8 text (byte {err.start})", file=label) from None
    except OSError as err:
        raise ScenarioError(f"cannot read file: {err.strerror}", file=label) from None
    doc, lines = parse_yaml(text, label)
    default_name = _UNSAFE_NAME_CHARS.sub("_", path.stem) or "scenario"
    try:
        return _build(doc, label, default_name)
    except ScenarioError as err:
        raise err.located(label, lines) from None


def scenario_from_dict(doc: Mapping[str, Any], source: str = "<inline>") -> Scenario:
    """Validate a scenario given as a Python mapping (the parsed YAML document).

    Parameters
    ----------
    doc : Mapping
        Same schema as a scenario file (see ``docs/scenarios.md``).
    source : str
        Label for error messages; ``name`` defaults to ``"scenario"``.

    Returns
    -------
    Scenario

    Raises
    ------
    ScenarioError
    """
    try:
        return _build(doc, source, "scenario")
    except ScenarioError as err:
        raise err.located(source) from None


def scenario_from_stored(text: str, arrays: Mapping[str, Any] | None, source: str = "<inline>") -> Scenario:
    """The scenario a trace or checkpoint stores (:func:`orbitsim.scenario.serialize.stored_form`):
    its resolved text, and for a large scenario the per-body rows as arrays beside it.

    Raises
    ------
    ScenarioError
        For text or arrays that do not make a valid scenario (a missing or misshapen array names
        its dataset).
    """
    doc, _ = parse_yaml(text, source)
    if arrays is None:
        return scenario_from_dict(doc, source)
    if not isinstance(doc, Mapping) or "bodies" in doc:
        raise ScenarioError("the text beside the stored bodies must be a mapping without bodies", file=source)
    doc = dict(doc)
    try:
        given = _stored_bodies(arrays)
        if isinstance(doc.get("integrator_state"), Mapping):
            doc["integrator_state"] = {**doc["integrator_state"],
                                       **{k: arrays[k] for k in ("mapping_positions", "mapping_velocities")}}
        return _build(doc, source, "scenario", given)
    except KeyError as err:
        raise ScenarioError(f"the stored bodies lack the dataset {err}", file=source) from None
    except ScenarioError as err:
        raise err.located(source) from None


def rebound_scenario(path: str | os.PathLike[str], *, steps: int | None = None, t_end: float | None = None) -> Scenario:
    """The scenario of ``orbitsim run sim.bin``: the file's last snapshot, run for ``steps`` or to ``t_end``
    (an absolute time, after the file's ``t``).

    Raises
    ------
    ScenarioError
        When neither run length is given, or as :func:`~orbitsim.scenario.rebound_bodies.expand_rebound_bodies`.
    """
    label = os.fspath(path)
    if steps is None and t_end is None:
        raise ScenarioError("a REBOUND file holds no run length: give --steps N or --t-end T", file=label)
    doc: dict[str, Any] = {"name": _UNSAFE_NAME_CHARS.sub("_", Path(label).stem) or "rebound",
                           "bodies": {"rebound": Path(label).name}}
    doc.update({"steps": steps} if steps is not None else {"t_end": t_end})
    return scenario_from_dict(doc, source=label)


def _stored_bodies(arrays: Mapping[str, Any]) -> BodySet:
    """The bodies of a stored scenario's arrays (names, m, x, v and maybe r), as the reader makes them."""
    names = [n.decode() if isinstance(n, bytes) else str(n) for n in np.asarray(arrays["names"]).tolist()]
    n = len(names)
    m, x, v = (np.asarray(arrays[k], dtype=np.float64) for k in ("m", "x", "v"))
    if m.shape != (n,) or x.shape != (n, 3) or v.shape != (n, 3):
        raise ScenarioError(f"the stored bodies' arrays do not fit {n} names (m {m.shape}, x {x.shape}, v {v.shape})")
    bodies = BodySet()
    keys = [f"bodies[{i}]" for i in range(n)]
    bodies.add(names, m, x, v, keys, keys)
    if "r" in arrays:
        r = np.asarray(arrays["r"], dtype=np.float64)
        if r.shape != (n,):
            raise ScenarioError(f"the stored radii have shape {r.shape}, expected ({n},)")
        bodies.radii = dict(enumerate(r.tolist()))
    return bodies


def _read_integrator(top: Fields) -> tuple[str, dict[str, Any]]:
    """``integrator: name`` or ``integrator: {name: ..., <settings>}``."""
    value = top.raw("integrator")
    if isinstance(value, str):
        return value, {}
    if isinstance(value, Mapping):
        if not isinstance(value.get("name"), str):
            raise ScenarioError(f"an integrator mapping needs a name, got {describe(value.get('name'))}",
                                key="integrator.name")
        return value["name"], {k: v for k, v in value.items() if k != "name"}
    raise ScenarioError(f"expected an integrator name or a mapping {{name: ..., <settings>}}, got "
                        f"{describe(value)}", key="integrator")


def _build(doc: Any, source: str, default_name: str, given: BodySet | None = None) -> Scenario:
    if doc is None:
        raise ScenarioError("the scenario is empty: it needs at least integrator, dt, steps or t_end, and bodies")
    if uses_rebound_file(doc):  # bodies: {rebound: FILE}: explicit bodies, and G, dt, integrator from the file
        doc = expand_rebound_bodies(doc, source)
    top = Fields(doc, "", TOP_KEYS, "scenario")
    units = top.string("units", "nbody", choices=list(UNIT_SYSTEMS), fold_case=True)
    G = top.number("G", UNIT_SYSTEMS[units].G, positive=True)
    integrator, settings = _read_integrator(top)
    times = _Times(units, G)  # dt, t_start, t_end and output.interval: numbers, or "1 day", "10 yr"
    dt = check_dt(times.read(top, "dt"))  # < 0 runs backwards (orbitsim.scenario.direction)
    output = Fields(top.raw("output", {}), "output", OUTPUT_KEYS, "output section")
    output.one_of("every", "interval", required=False)
    t_start = check_t_start(times.read(top, "t_start", 0.0))  # the run's clock starts here; t_end stays absolute
    t_end = None
    adaptive = adaptive_integrator(integrator, settings)
    if adaptive:
        steps, t_end = _adaptive_grid(top, output, integrator, t_start, times)
    elif top.one_of("steps", "t_end") == "steps":
        steps = top.integer("steps", minimum=1, steps=True)
    else:
        t_end = check_t_end(times.read(top, "t_end"), dt, t_start)  # before t_start with a negative dt
        steps = resolve_steps(t_end, dt, t_start)[0]
    softening = top.number("softening", 0.0, minimum=0.0)
    frame = top.string("frame", "as_given", choices=FRAMES)
    device = top.string("device", "cpu", choices=list(DEVICES))
    name = top.string("name", default_name)
    description = top.string("description", "")
    every = output.integer("every", None, minimum=1, steps=True)
    interval = times.read(output, "interval", None, positive=True)
    positions = output.boolean("positions", None)
    elements = output.boolean("elements", False)
    primary = output.string("primary", "heaviest")
    if output.has("primary") and not elements:
        raise output.error("primary", "output.primary chooses the primary of the recorded orbital elements: it "
                                      "needs output.elements: true")
    grid_step = _grid_step(dt, t_end, t_start, interval, adaptive)
    checkpoint_every, checkpoint_seconds = _read_checkpoint(output, times, grid_step)
    bodies = read_bodies(top, G, units) if given is None else given  # given: a stored scenario's arrays
    m, x, v = bodies.arrays()
    radii = bodies.radii_array()
    events = read_events(top, radii)
    if frame == "barycentric":
        x, v = shift_to_barycentre(m, x, v)
    check_coincident(x, bodies.names, bodies.origins, softening)
    scenario = Scenario(name=name, description=description, units=units, G=G, integrator=integrator,
                        integrator_settings=settings, dt=dt, steps=steps, t_end=t_end, every=every,
                        interval=interval, record_positions=positions, softening=softening, frame=frame,
                        names=tuple(bodies.names), masses=m, positions=x, velocities=v, source=source,
                        checkpoint_every=checkpoint_every, checkpoint_seconds=checkpoint_seconds, radii=radii,
                        events=events, record_elements=elements, elements_primary=primary,
                        forces=top.raw("forces", ()), t_start=t_start,
                        integrator_state=top.raw("integrator_state", None), chaos=output.raw("chaos", None),
                        device=device)
    scenario.remember_origins(bodies.origins)
    renamed = rebound_note(integrator, settings)  # REBOUND's whfast, leapfrog with order: what they became
    scenario.remember_input([renamed, *bodies.notes] if renamed else bodies.notes)  # for `orbitsim validate`
    return scenario


class _Times:
    """Reads the keys that hold a time in the scenario's units: a number as it is (the same bits), or
    a number with a unit, ``"1 day"`` or ``"10 yr"`` (:func:`orbitsim.scenario.quantities.scenario_time`)."""

    def __init__(self, units: str, G: float) -> None:
        self.units, self.G = units, G

    def read(self, fields: Fields, name: str, default: Any = MISSING, *, positive: bool = False) -> Any:
        """The time at key ``name`` of ``fields`` as a float (``default`` when it is not given)."""
        value = fields.raw(name, default)
        if not isinstance(value, str):
            return fields.number(name, default, positive=positive)
        time = scenario_time(value, self.units, self.G, fields.key(name))
        return check_number(time, fields.key(name), positive=positive)


def _adaptive_grid(top: Fields, output: Fields, integrator: str, t_start: float, times: _Times) -> tuple[int, float]:
    """An adaptive scheme's output intervals from ``t_start`` and ``t_end``: it needs ``t_end``, and
    samples by ``output.interval``."""
    if top.has("steps") or not top.has("t_end"):
        raise top.error("steps" if top.has("steps") else "t_end",
                        f"{integrator} chooses its own steps: give t_end (the end time), not steps")
    if output.has("every"):
        raise output.error("every", f"{integrator} chooses its own steps, so samples are taken by time: give "
                                    "output.interval instead of output.every")
    t_end = check_adaptive_t_end(times.read(top, "t_end"), t_start)
    span = run_span(t_end, t_start)
    interval = times.read(output, "interval", None, positive=True)
    return resolve_grid(span, interval if interval is not None else span / DEFAULT_SAMPLES), t_end


def _grid_step(dt: float, t_end: float | None, t_start: float, interval: float | None, adaptive: bool) -> float:
    """How much time one step of the run's grid (what ``output.checkpoint.every`` counts) covers: |dt|, or
    an adaptive run's output interval."""
    if not adaptive:
        return abs(dt)
    return interval if interval is not None else run_span(float(t_end), t_start) / DEFAULT_SAMPLES


def _read_checkpoint(output: Fields, times: _Times, grid_step: float) -> tuple[int | None, float | None]:
    """``output.checkpoint: {every: K, seconds: S}`` (either or both); absent means no checkpoints.

    ``every`` may be a time with a unit (``"100 yr"``): the whole steps of the grid that fit in it.
    ``seconds`` may be a wall-clock duration with a unit (``"10 min"``)."""
    if not output.has("checkpoint"):
        return None, None
    section = Fields(output.raw("checkpoint"), "output.checkpoint", CHECKPOINT_KEYS, "checkpoint section")
    if isinstance(section.raw("every", None), str):
        every = _checkpoint_steps(times.read(section, "every", positive=True), grid_step, section.key("every"),
                                  section.raw("every"))
    else:
        every = section.integer("every", None, minimum=1, steps=True)
    if isinstance(section.raw("seconds", None), str):
        seconds = wall_seconds(section.raw("seconds"), section.key("seconds"))
    else:
        seconds = section.number("seconds", None, positive=True)
    if every is None and seconds is None:
        raise ScenarioError("give every (steps) and/or seconds (wall time) between checkpoints",
                            key="output.checkpoint")
    return every, seconds


def _checkpoint_steps(span: float, grid_step: float, key: str, given: str) -> int:
    """The whole grid steps in ``span`` (a ratio within 1e-9 of a whole number counts as whole, as for t_end)."""
    steps = whole_count(span / grid_step)
    if steps < 1:
        raise ScenarioError(f"{given!r} is shorter than one step ({grid_step:g} in the scenario's time unit): "
                            "checkpoint less often", key=key)
    return check_count(steps, key)
