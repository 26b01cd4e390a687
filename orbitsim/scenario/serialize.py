"""The resolved scenario as plain Python and as YAML text: what a trace stores and hashes.

Bodies are explicit and Cartesian, the frame is ``as_given`` (any shift is already applied),
``steps`` replaces ``t_end`` (except for an adaptive integrator, whose grid ends on ``t_end``
exactly) and the sampling is explicit, so loading the text reproduces the same bits. Keys a
scenario does not use (``t_start`` when 0, radii, ``events``, ``forces``, ``output.elements``,
``output.checkpoint``, ``output.chaos``) are left out rather than written as defaults, so the text
and SHA-256 of every scenario written before they existed stay the same.
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np

from orbitsim.scenario.data import ScenarioData
from orbitsim.scenario.integrator_state import state_to_dict
from orbitsim.scenario.yamlio import dump_value, format_float

__all__ = ["BODIES_GROUP", "BODY_ARRAYS", "STORED_TEXT_MAX", "scenario_text_sha256", "scenario_to_dict",
           "scenario_to_yaml", "scenario_yaml_lines", "stored_form"]

_STATE_ARRAYS = ("mapping_positions", "mapping_velocities")


def scenario_to_dict(s: ScenarioData, bodies: bool = True) -> dict[str, Any]:
    """The fully resolved scenario as plain Python (what :func:`scenario_to_yaml` writes); without
    the ``bodies`` list when ``bodies`` is false (a large scenario's rows are written one by one)."""
    integrator: Any = s.integrator
    if s.integrator_settings:
        integrator = {"name": s.integrator, **s.integrator_settings}
    # An adaptive scheme samples by time only (``every`` is refused), so its default grid is written as the interval.
    interval = s.interval if s.interval is not None or not s.adaptive else s.grid_dt
    output: dict[str, Any] = {"interval": interval} if interval is not None else {"every": s.sample_every}
    output["positions"] = bool(s.record_positions)
    if s.record_elements:
        output["elements"] = True
        output["primary"] = s.elements_primary
    if s.chaos is not None:
        from orbitsim.scenario.chaos import chaos_to_dict  # noqa: PLC0415 -- lazy: only a run that asks for it

        output["chaos"] = chaos_to_dict(s.chaos, s.names)
    if s.checkpoints:
        output["checkpoint"] = {k: v for k, v in (("every", s.checkpoint_every), ("seconds", s.checkpoint_seconds))
                                if v is not None}
    # t_start only when set, so a scenario without it keeps its text and SHA-256 from before t_start existed.
    start = {"t_start": s.t_start} if s.t_start else {}
    doc = {"name": s.name, "description": s.description, "units": s.units, "G": s.G, "integrator": integrator,
           "dt": s.dt, **start, "steps": s.steps, "output": output, "softening": s.softening, "frame": "as_given"}
    if s.adaptive:  # its grid is the output intervals up to t_end exactly, and `steps` is refused
        doc = {("t_end" if k == "steps" else k): (s.t_end if k == "steps" else v) for k, v in doc.items()}
    if s.device != "cpu":  # only when asked for, so every CPU scenario keeps its text and SHA-256
        doc["device"] = s.device
    if s.events is not None:
        doc["events"] = s.events.to_dict()
    if s.forces:  # resolved: c, source and spin axis explicit, so the text says what ran
        doc["forces"] = [dict(entry) for entry in s.forces]
    if bodies:
        doc["bodies"] = _body_dicts(s)
    if s.integrator_state is not None:  # after the bodies it belongs to (orbitsim.scenario.integrator_state)

        doc["integrator_state"] = state_to_dict(s.integrator_state)
    return doc


def _body_dicts(s: ScenarioData) -> list[dict[str, Any]]:
    bodies = []
    for k, (name, m, x, v) in enumerate(zip(s.names, s.masses, s.positions, s.velocities, strict=True)):
        body = {"name": name, "m": float(m), "x": [float(c) for c in x], "v": [float(c) for c in v]}
        if s.radii is not None:
            body["r"] = float(s.radii[k])
        bodies.append(body)
    return bodies


def scenario_to_yaml(s: ScenarioData) -> str:
    """The fully resolved scenario as YAML text; loading it reproduces the same bits."""
    return "\n".join(scenario_yaml_lines(s)) + "\n"


def scenario_text_sha256(s: ScenarioData) -> str:
    """Hex SHA-256 of :func:`scenario_to_yaml`'s UTF-8 text, hashed line by line: a large
    scenario's text (176 MB for 10^6 bodies) is never held in memory at once."""
    digest = hashlib.sha256()
    for line in scenario_yaml_lines(s):
        digest.update(line.encode("utf-8"))
        digest.update(b"\n")
    return digest.hexdigest()


def scenario_yaml_lines(s: ScenarioData) -> Iterator[str]:
    """The lines of :func:`scenario_to_yaml` (without their newlines), one body per line."""
    doc = scenario_to_dict(s, bodies=False)
    state = doc.pop("integrator_state", None)
    yield from _head_lines(doc)
    yield "bodies:"
    yield from _body_lines(s)
    if state is not None:
        yield from _state_head_lines(state)
        for k in _STATE_ARRAYS:
            yield f"  {k}:"
            yield from (f"    - [{', '.join(format_float(c) for c in row)}]" for row in state[k])


def _head_lines(doc: dict[str, Any]) -> Iterator[str]:
    """Everything before ``bodies:``, one top-level key (or section entry) per line."""
    yield "# orbitsim scenario, fully resolved: explicit Cartesian bodies, whole steps."
    for key, value in doc.items():
        if key in ("output", "events"):
            yield f"{key}:"
            yield from (f"  {k}: {dump_value(v)}" for k, v in value.items())
        elif key == "forces":
            yield f"{key}:"
            yield from (f"  - {dump_value(entry)}" for entry in value)
        else:
            yield f"{key}: {dump_value(value)}"


def _body_lines(s: ScenarioData) -> Iterator[str]:
    """One flow mapping per body, written row by row: far faster than the generic writer."""
    f = format_float
    radii = s.radii.tolist() if s.radii is not None else None
    for k, (name, m, x, v) in enumerate(zip(s.names, s.masses.tolist(), s.positions.tolist(), s.velocities.tolist(),
                                            strict=True)):
        r = f", r: {f(radii[k])}" if radii is not None else ""
        yield (f"  - {{name: {dump_value(name)}, m: {f(m)}, x: [{f(x[0])}, {f(x[1])}, {f(x[2])}], "
               f"v: [{f(v[0])}, {f(v[1])}, {f(v[2])}]{r}}}")


def _state_head_lines(state: dict[str, Any]) -> Iterator[str]:
    yield "# wisdom_holman's own coordinates at this state, so the run continues bit for bit; used"
    yield "# only while every bit above that they belong to (`of`) is unchanged"
    yield "integrator_state:"
    yield from (f"  {k}: {dump_value(v)}" for k, v in state.items() if k not in _STATE_ARRAYS)


# -- the stored form: what a trace or a checkpoint keeps ---------------------------------------

#: A trace or checkpoint keeps the resolved text whole (its ``scenario`` attribute) up to this many
#: bytes, which every scenario of up to ~1,000 bodies fits (the bundled plummer_1k's is 176 kB).
#: Beyond it the per-body rows are datasets (:data:`BODY_ARRAYS`) and the attribute holds the rest:
#: a 10^6-body scenario's text is 176 MB, which HDF5 metadata is not made for, and which took
#: minutes to parse back on every resume.
STORED_TEXT_MAX = 256 * 1024
#: The shortest a body's row can be (``  - {name: "a", m: 0.0, x: [0.0, 0.0, 0.0], v: [...]}``):
#: a scenario with more bodies than ``STORED_TEXT_MAX`` over this is stored as datasets unwritten.
_MIN_ROW_BYTES = 60
#: The datasets of the stored form, by name: what each holds, as the text's rows would.
BODY_ARRAYS = ("names", "m", "x", "v", "r", "mapping_positions", "mapping_velocities")
#: The HDF5 group beside the stored text that holds the rows (:data:`orbitsim.io.stored_scenario.SCENARIO_BODIES`).
BODIES_GROUP = "scenario_bodies"
#: The line that stands for the bodies in the stored form's text.
BODIES_IN_DATASETS = "# bodies: {n} rows, in the datasets {group}/{{{names}}} beside this text (one row per body)"


def stored_form(s: ScenarioData, whole_text: Callable[[], str]) -> tuple[str, dict[str, np.ndarray] | None]:
    """The scenario as a trace or checkpoint stores it: ``(text, None)`` with the whole resolved
    text when it is at most :data:`STORED_TEXT_MAX` bytes, else ``(text, arrays)``: the text without
    the per-body rows (a comment in their place) and the rows as arrays by :data:`BODY_ARRAYS` name
    (``r`` only with radii, the ``mapping_*`` only with an integrator state). ``whole_text()`` gives the
    whole text (:meth:`Scenario.to_yaml <orbitsim.scenario.model.Scenario.to_yaml>`, which keeps it).

    Either form loads back to the same bits (:func:`orbitsim.scenario.loader.scenario_from_stored`),
    and the scenario's SHA-256 is the whole text's in both.
    """
    if s.n_bodies * _MIN_ROW_BYTES <= STORED_TEXT_MAX:
        text = whole_text()
        if len(text.encode("utf-8")) <= STORED_TEXT_MAX:
            return text, None
    arrays: dict[str, np.ndarray] = {"names": np.array(s.names, dtype=object), "m": s.masses, "x": s.positions,
                                     "v": s.velocities}
    if s.radii is not None:
        arrays["r"] = s.radii
    doc = scenario_to_dict(s, bodies=False)
    state = doc.pop("integrator_state", None)
    lines = [*_head_lines(doc), BODIES_IN_DATASETS.format(n=s.n_bodies, group=BODIES_GROUP, names=", ".join(arrays))]
    if state is not None:
        lines += [*_state_head_lines(state), f"  # {', '.join(_STATE_ARRAYS)}: in the datasets {BODIES_GROUP}/<name>"]
        arrays.update({k: np.asarray(s.integrator_state[k], dtype=np.float64) for k in _STATE_ARRAYS})
    return "\n".join(lines) + "\n", arrays
