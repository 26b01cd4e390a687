"""Which integrators apply which force correctly, and the one-line refusal for the others.

A force is only as good as the way a scheme applies it (Tamayo, Rein, Shi & Hernandez 2020,
MNRAS 491, 2885):

* position-only forces (``gr_potential``, ``harmonics``) are a potential, so they are kicked with
  gravity and every symplectic scheme stays symplectic (Wisdom-Holman included: they go into its
  interaction kick); ``euler``, ``rk4`` and ``ias15`` add them to the derivative;
* velocity-dependent forces (``gr``, ``migration``) must not go into a kick: in a symplectic
  scheme they are their own operator, integrated over half a step before and after the step (as
  REBOUNDx ``integrate_force`` does); ``euler``, ``rk4`` and ``ias15`` add them to the derivative;
* ``gr_full`` depends on every body's velocity and acceleration, solved by iteration; orbitsim
  applies it only in the derivative of ``rk4`` and ``ias15``, the way REBOUNDx's tests use it;
* ``trace`` takes no forces: its switching splits every force between its Wisdom-Holman and
  Bulirsch-Stoer parts, and that split is not ported.

A variational run (chaos indicators) also needs each force's derivative in the tangent equations
(:mod:`orbitsim.forces.tangent`): :func:`check_chaos_forces` refuses, in one line, a force whose
derivative is not built and a scheme whose variational kernel does not take forces, so a run never
silently integrates Newtonian variations beside forced bodies (REBOUND's MEGNO does, its #800).
"""

from __future__ import annotations

from collections.abc import Iterable

__all__ = ["CHAOS_FORCE_SCHEMES", "DERIVATIVE", "FORCE_INTEGRATORS", "SYMPLECTIC", "TANGENT_BUILT",
           "check_chaos_forces", "check_integrator", "check_run"]

#: Schemes that evaluate every force in the equations of motion they integrate.
DERIVATIVE = ("euler", "rk4", "ias15")
#: Kick-drift schemes: position-only forces join the kick, velocity-dependent ones are an operator.
SYMPLECTIC = ("semi_implicit_euler", "verlet", "leapfrog", "leapfrog4", "leapfrog6", "leapfrog8", "wisdom_holman")
_EVERY = ("euler", "semi_implicit_euler", "verlet", "leapfrog", "leapfrog4", "leapfrog6", "leapfrog8",
          "wisdom_holman", "rk4", "ias15")

#: The integrators that apply each force correctly (registry names, in the registry's order).
FORCE_INTEGRATORS: dict[str, tuple[str, ...]] = {
    "gr_potential": _EVERY,
    "harmonics": _EVERY,
    "gr": _EVERY,
    "migration": _EVERY,
    "gr_full": ("rk4", "ias15"),
}

#: Forces whose derivative enters the variational equations (:mod:`orbitsim.forces.tangent`).
TANGENT_BUILT = ("gr_potential", "harmonics")
#: Schemes whose variational kernel passes the run's forces to the bodies' kicks and to the tangent
#: kicks (:func:`orbitsim.forces.tangent.add_tangent_kick_forces`).
CHAOS_FORCE_SCHEMES = ("verlet", "leapfrog", "leapfrog4", "leapfrog6", "leapfrog8", "wisdom_holman", "ias15")

_WHY_NOT = {
    "trace": "trace switches between Wisdom-Holman and Bulirsch-Stoer, and splitting a force between them is not "
             "ported",
    "gr_full": "gr_full depends on every body's velocity and acceleration (found by iteration), so it is applied "
               "only in the equations of motion of a high-order scheme, never as a kick or a split operator",
}


def check_integrator(force_names: Iterable[str], integrator: str) -> str | None:
    """Why ``integrator`` cannot apply one of ``force_names``, or None if it can apply them all.

    Parameters
    ----------
    force_names : Iterable[str]
        Scenario names of the forces (keys of :data:`FORCE_INTEGRATORS`).
    integrator : str
        The integrator's registry (canonical) name.

    Returns
    -------
    str or None
        One line: the first force it cannot apply, why, and the integrators that can.
    """
    for name in force_names:
        can = FORCE_INTEGRATORS[name]
        if integrator in can:
            continue
        why = _WHY_NOT["trace"] if integrator == "trace" else _WHY_NOT.get(name, f"{integrator} has no way to apply it")
        return f"{integrator} cannot apply {name}: {why}; integrators that can: {', '.join(can)}"
    return None


def check_run(force_names: Iterable[str], integrator: str, settings: dict, has_events: bool) -> str | None:
    """:func:`check_integrator`, then what the schemes do not combine with forces yet: events
    (collisions, encounters, escapes) and Wisdom-Holman's symplectic correctors. One line, or None.

    Shared by the scenario's validation (``validate`` and ``run`` refuse before anything is
    written) and :class:`~orbitsim.simulation.Simulation` (for callers of the Python API).
    """
    why = check_integrator(force_names, integrator)
    if why is None and has_events:
        why = ("events (collisions, encounters, escapes) are not watched in runs with forces yet: remove "
               "`events` or the forces")
    if why is None and integrator == "wisdom_holman" and settings.get("corrector", 0):
        why = "wisdom_holman's symplectic correctors do not include the forces yet: use corrector 0"
    return why


def check_chaos_forces(force_names: Iterable[str], integrator: str) -> str | None:
    """Why a variational (chaos) run of ``integrator`` cannot take one of ``force_names``, or None.

    Parameters
    ----------
    force_names : Iterable[str]
        Scenario names of the forces (keys of :data:`FORCE_INTEGRATORS`).
    integrator : str
        The integrator's registry (canonical) name; a scheme with variational equations.

    Returns
    -------
    str or None
        One line naming the first force refused and why: its derivative is not built
        (velocity-dependent forces), the scheme's variational kernel takes no forces, or the
        scheme cannot apply the force at all (:func:`check_integrator`).
    """
    names = tuple(force_names)
    for name in names:
        if name not in TANGENT_BUILT:
            return (f"force {name}: its derivative in the variational equations is not built (it depends on "
                    f"velocities), so no chaos indicators with it rather than Newtonian variations; forces whose "
                    f"derivatives are built: {', '.join(TANGENT_BUILT)}")
    if names and integrator not in CHAOS_FORCE_SCHEMES:
        return (f"force {names[0]}: {integrator}'s variational equations do not take forces yet, so no chaos "
                f"indicators with it rather than Newtonian variations; schemes whose do: "
                f"{', '.join(CHAOS_FORCE_SCHEMES)}")
    return check_integrator(names, integrator)
