"""A run's ``forces:`` on the REBOUND side of ``compare`` and ``convergence``: the same problem in both codes.

orbitsim applies a force according to what it depends on (:mod:`orbitsim.forces.hooks`); the
REBOUND run gets the REBOUNDx effect of every force (:mod:`orbitsim.reference.rebx`) arranged the
same way, so that a matched pair takes the same steps and agrees to round-off:

=================== ============================================ ============================================
REBOUND scheme      position-only (gr_potential, harmonics)      velocity-dependent (gr, migration)
=================== ============================================ ============================================
leapfrog, SABA      ``add_force``: with gravity in every kick    ``integrate_force`` operators, implicit
                                                                 midpoint, over dt/2 before and after each step
WHFast              ``add_force``: in the interaction kick       the same operators, with ``safe_mode = 1``
                                                                 (synchronised around them, as orbitsim's
                                                                 Wisdom-Holman restarts from the inertial
                                                                 state after each operator)
IAS15               ``add_force``: in the equations of motion    ``add_force``: in the equations of motion
=================== ============================================ ============================================

Measured (REBOUND 5.2.2, REBOUNDx 5.1.0; star and two planets, dt = 0.01, 1000 steps, c = 100,
J2 = 1e-2): leapfrog of order 2, 4 and 8 and WHFast (Jacobi and democratic heliocentric) agree
with orbitsim's partners to 5e-15 .. 3e-13 relative with ``gr``, ``gr_potential``, ``migration``
and ``gr`` + ``harmonics``; kicking ``gr`` with gravity instead gives 6e-3, and WHFast's operators
without safe mode (orbitsim's ``configure_rebound_whfast`` sets ``safe_mode = 0``,
``keep_unsynchronized = 1``) 2e-2.

Where no arrangement makes the two codes integrate the same problem the pair is *not comparable*
(:func:`rebound_refusal`, :func:`orbitsim_refusal`): the reason is one line, and ``compare`` says
it instead of judging the pair.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from orbitsim.forces.compat import DERIVATIVE, check_run
from orbitsim.forces.table import GR, GR_FULL, GR_POTENTIAL, POSITION_ONLY, ForceSet
from orbitsim.reference.bridge import ReboundScheme
from orbitsim.reference.rebx import REBX_NAMES, AttachedForces, attach_forces

__all__ = ["attach_rebound_forces", "forces_summary", "orbitsim_force_lines", "orbitsim_refusal",
           "rebound_force_lines", "rebound_refusal"]


def _entry_text(forces: ForceSet, row: int) -> str:
    """``gr about sun (c = 173.1446327)``: the force as the scenario resolved it (its id's name
    and body indices when the set was built without entries)."""
    from orbitsim.scenario.forces import describe_forces  # noqa: PLC0415 -- lazy: loads yaml

    if row < len(forces.entries):
        return describe_forces([forces.entries[row]])
    source = int(forces.source[row])
    return forces.names[row] + (f" about body {source}" if source >= 0 else "")


def _source_name(forces: ForceSet, row: int) -> str:
    if row < len(forces.entries) and "source" in forces.entries[row]:
        return f"{forces.entries[row]['source']} (body {int(forces.source[row])})"
    return f"body {int(forces.source[row])}"


def rebound_refusal(forces: ForceSet | None, scheme: ReboundScheme,
                    settings: dict[str, Any] | None = None) -> str | None:
    """Why REBOUND + REBOUNDx 5.1 cannot run ``scheme`` with ``forces`` as orbitsim's partner does,
    or None when it can (always None without forces).

    Parameters
    ----------
    forces : ForceSet or None
        The run's forces.
    scheme : ReboundScheme
        The REBOUND integrator.
    settings : dict, optional
        orbitsim integrator settings of the partner (WHFast's corrector).

    Returns
    -------
    str or None
        One clause: what cannot be expressed and why.
    """
    if forces is None or forces.ids.shape[0] == 0:
        return None
    for row, fid in enumerate(int(i) for i in forces.ids):
        if fid in (GR, GR_POTENTIAL) and int(forces.source[row]) != 0:
            return (f"REBOUNDx 5.1 {REBX_NAMES[fid]} takes particle 0 as the dominant mass (its gr_source flag is "
                    f"not read), and this {forces.names[row]} is about {_source_name(forces, row)}")
    if scheme.name == "trace":
        return ("orbitsim's trace applies no forces (splitting a force between its Wisdom-Holman and "
                "Bulirsch-Stoer parts is not ported), so REBOUND TRACE with REBOUNDx has no partner to match")
    if scheme.fixed_step and any(int(i) == GR_FULL for i in forces.ids):
        return ("gr_full depends on every body's velocity and acceleration (found by iteration), so it is applied "
                "only in the equations of motion of rk4 and ias15; a REBOUND fixed-step scheme could only kick it "
                "or split it off as an operator, another problem")
    if scheme.name == "whfast" and int((settings or {}).get("corrector", 0) or 0):
        return "wisdom_holman's symplectic correctors do not include the forces yet: use corrector 0"
    return None


def orbitsim_refusal(forces: ForceSet | None, integrator: str, settings: dict[str, Any] | None = None) -> str | None:
    """Why orbitsim's ``integrator`` cannot apply ``forces`` (:func:`orbitsim.forces.compat.check_run`),
    or None."""
    if forces is None or forces.ids.shape[0] == 0:
        return None

    return check_run(forces.names, integrator, dict(settings or {}), False)


def _split(scheme: ReboundScheme) -> bool:
    """True where velocity-dependent forces are their own operator (every fixed-step scheme)."""
    return scheme.fixed_step


def attach_rebound_forces(sim: Any, forces: ForceSet | None, scheme: ReboundScheme) -> AttachedForces | None:
    """Give ``sim`` (built for ``scheme`` by :func:`orbitsim.reference.bridge.rebound_simulation`) the
    REBOUNDx forces arranged as the module docstring's table says; None without forces.

    The caller checks :func:`rebound_refusal` first, and keeps the returned object alive while
    ``sim`` runs (it owns the REBOUNDx forces).
    """
    if forces is None or forces.ids.shape[0] == 0:
        return None

    attached = attach_forces(sim, forces, split=_split(scheme))
    if scheme.name == "whfast" and forces.velocity_dependent:
        # The operators act on the synchronised inertial state; WHFast must restart from it after
        # each (orbitsim's Wisdom-Holman does): safe mode, which keep_unsynchronized excludes.
        sim.integrator.keep_unsynchronized = 0
        sim.integrator.safe_mode = 1
    return attached


def rebound_force_lines(forces: ForceSet | None, scheme: ReboundScheme) -> tuple[str, ...]:
    """How the REBOUND run of ``scheme`` carries each force, one phrase per force (empty without)."""
    if forces is None or forces.ids.shape[0] == 0:
        return ()
    lines = []
    for row, fid in enumerate(int(i) for i in forces.ids):
        what = f"{_entry_text(forces, row)} as REBOUNDx {REBX_NAMES[fid]}"
        if not scheme.fixed_step:
            lines.append(f"{what}: an additional force in IAS15's equations of motion")
        elif fid in POSITION_ONLY:
            lines.append(f"{what}: an additional force, kicked with gravity")
        else:
            safe = ", WHFast in safe mode" if scheme.name == "whfast" else ""
            lines.append(f"{what}: integrate_force operators (implicit midpoint) over dt/2 before and after each "
                         f"step{safe}")
    return tuple(lines)


def orbitsim_force_lines(forces: ForceSet | None, integrator: str) -> tuple[str, ...]:
    """How orbitsim's ``integrator`` applies each force, one phrase per force (empty without)."""
    if forces is None or forces.ids.shape[0] == 0:
        return ()

    lines = []
    for row, fid in enumerate(int(i) for i in forces.ids):
        what = _entry_text(forces, row)
        if integrator in DERIVATIVE:
            lines.append(f"{what}: in the equations of motion")
        elif fid in POSITION_ONLY:
            lines.append(f"{what}: added to gravity in every kick")
        else:
            lines.append(f"{what}: its own operator (implicit midpoint) over dt/2 before and after each step")
    return tuple(lines)


def forces_summary(lines: Sequence[str]) -> str:
    """The lines of :func:`rebound_force_lines` / :func:`orbitsim_force_lines` as one cell ("none" if empty)."""
    return "; ".join(lines) if lines else "none"
