"""The resolved scenario as plain Python and as YAML text: what a trace stores and hashes.

Bodies are explicit and Cartesian, the frame is ``as_given`` (any shift is already applied),
``steps`` replaces ``t_end`` (except for an adaptive integrator, whose grid ends on ``t_end``
exactly) and the sampling is explicit, so loading the text reproduces the same bits. Keys a
scenario does not use (``t_start`` when 0, radii, ``events``, ``forces``, ``output.elements``,
``output.checkpoint``) are left out rather than written as defaults, so the text and SHA-256 of
every scenario written before they existed stay the same.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from orbitsim.scenario.yamlio import dump_value, format_float

if TYPE_CHECKING:
    from orbitsim.scenario.model import Scenario

__all__ = ["scenario_to_dict", "scenario_to_yaml"]


def scenario_to_dict(s: Scenario) -> dict[str, Any]:
    """The fully resolved scenario as plain Python (what :func:`scenario_to_yaml` writes)."""
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
    if s.checkpoints:
        output["checkpoint"] = {k: v for k, v in (("every", s.checkpoint_every), ("seconds", s.checkpoint_seconds))
                                if v is not None}
    bodies = []
    for k, (name, m, x, v) in enumerate(zip(s.names, s.masses, s.positions, s.velocities, strict=True)):
        body = {"name": name, "m": float(m), "x": [float(c) for c in x], "v": [float(c) for c in v]}
        if s.radii is not None:
            body["r"] = float(s.radii[k])
        bodies.append(body)
    # t_start only when set, so a scenario without it keeps its text and SHA-256 from before t_start existed.
    start = {"t_start": s.t_start} if s.t_start else {}
    doc = {"name": s.name, "description": s.description, "units": s.units, "G": s.G, "integrator": integrator,
           "dt": s.dt, **start, "steps": s.steps, "output": output, "softening": s.softening, "frame": "as_given"}
    if s.adaptive:  # its grid is the output intervals up to t_end exactly, and `steps` is refused
        doc = {("t_end" if k == "steps" else k): (s.t_end if k == "steps" else v) for k, v in doc.items()}
    if s.events is not None:
        doc["events"] = s.events.to_dict()
    if s.forces:  # resolved: c, source and spin axis explicit, so the text says what ran
        doc["forces"] = [dict(entry) for entry in s.forces]
    if s.integrator_state is not None:  # after the bodies it belongs to (orbitsim.scenario.integrator_state)
        from orbitsim.scenario.integrator_state import state_to_dict

        doc["bodies"] = bodies
        doc["integrator_state"] = state_to_dict(s.integrator_state)
        return doc
    doc["bodies"] = bodies
    return doc


def scenario_to_yaml(s: Scenario) -> str:
    """The fully resolved scenario as YAML text; loading it reproduces the same bits."""
    doc = scenario_to_dict(s)
    del doc["bodies"]  # written row by row below: far faster than the generic writer
    state = doc.pop("integrator_state", None)
    lines = ["# orbitsim scenario, fully resolved: explicit Cartesian bodies, whole steps."]
    for key, value in doc.items():
        if key in ("output", "events"):
            lines.append(f"{key}:")
            lines.extend(f"  {k}: {dump_value(v)}" for k, v in value.items())
        elif key == "forces":
            lines.append(f"{key}:")
            lines.extend(f"  - {dump_value(entry)}" for entry in value)
        else:
            lines.append(f"{key}: {dump_value(value)}")
    lines.append("bodies:")
    f = format_float
    radii = s.radii.tolist() if s.radii is not None else None
    for k, (name, m, x, v) in enumerate(zip(s.names, s.masses.tolist(), s.positions.tolist(), s.velocities.tolist(),
                                            strict=True)):
        r = f", r: {f(radii[k])}" if radii is not None else ""
        lines.append(f"  - {{name: {dump_value(name)}, m: {f(m)}, x: [{f(x[0])}, {f(x[1])}, {f(x[2])}], "
                     f"v: [{f(v[0])}, {f(v[1])}, {f(v[2])}]{r}}}")
    if state is not None:
        lines.append("# wisdom_holman's own coordinates at this state, so the run continues bit for bit; used")
        lines.append("# only while every bit above that they belong to (`of`) is unchanged")
        lines.append("integrator_state:")
        lines.extend(f"  {k}: {dump_value(v)}" for k, v in state.items() if k not in ("mapping_positions",
                                                                                   "mapping_velocities"))
        for k in ("mapping_positions", "mapping_velocities"):
            lines.append(f"  {k}:")
            lines.extend(f"    - [{', '.join(f(c) for c in row)}]" for row in state[k])
    return "\n".join(lines) + "\n"
