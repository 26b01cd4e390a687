"""REBOUND's integrator names, as a user porting a REBOUND script writes them in a scenario.

REBOUND (``sim.integrator = "whfast"``; REBOUND 5.2.2's ``Simulation.__setattr__`` and
``reb_simulation_set_integrator``) and orbitsim name some schemes differently. Three kinds of name:

- :data:`SAME_SCHEME`: REBOUND's name for a scheme orbitsim has under another name (``whfast`` is
  orbitsim's ``wisdom_holman``, with REBOUND's defaults: Jacobi coordinates, no corrector). The
  registry accepts it (:func:`orbitsim.integrators.registry.get_integrator`), and ``orbitsim validate``
  says what it became (:func:`rebound_note`).
- REBOUND's ``leapfrog`` with its ``order`` setting (``sim.ri_leapfrog.order = 4``): orders 2, 4, 6
  and 8 are orbitsim's ``leapfrog``, ``leapfrog4``, ``leapfrog6``, ``leapfrog8``, which use
  REBOUND's coefficients (:func:`leapfrog_order`).
- :data:`CLOSEST`: REBOUND schemes orbitsim does not have. They are refused, as any unknown name is,
  and the refusal says which orbitsim scheme comes closest and how it differs, so a port never
  runs another scheme than the one asked for without the user choosing it.

``ias15`` and ``trace`` are the same names in both codes, with the same settings (``epsilon``,
``min_dt``; ``r_crit_hill``, ``peri_crit_eta``, ``peri_mode``).
"""

from __future__ import annotations

from typing import Any

__all__ = ["CLOSEST", "LEAPFROG_ORDERS", "SAME_SCHEME", "closest_scheme", "leapfrog_order", "rebound_note"]

#: REBOUND name -> orbitsim's name for the same scheme with the same defaults.
SAME_SCHEME: dict[str, str] = {
    "whfast": "wisdom_holman",
}

#: REBOUND's ``leapfrog`` order -> the orbitsim scheme with the same coefficients.
LEAPFROG_ORDERS: dict[int, str] = {2: "leapfrog", 4: "leapfrog4", 6: "leapfrog6", 8: "leapfrog8"}

#: REBOUND schemes with no orbitsim counterpart -> the closest orbitsim scheme and how it differs.
CLOSEST: dict[str, str] = {
    "mercurius": "the closest is trace, REBOUND's newer hybrid (a democratic heliocentric Wisdom-Holman map "
                 "that hands close encounters to Bulirsch-Stoer); MERCURIUS switches with a smooth changeover "
                 "function and IAS15, so steps differ",
    "saba": "the closest is wisdom_holman (SABA1 is a second-order Wisdom-Holman splitting in Jacobi "
            "coordinates; the higher SABA orders and their correctors have no counterpart: for more accuracy "
            "use {name: wisdom_holman, corrector: 17})",
    "whfast512": "the closest is wisdom_holman (REBOUND 5.2's WHFast512 is the AVX-512 WHFast in Jacobi "
                 "coordinates, 1e-10 from WHFast after 2e5 steps; REBOUND 4's was democratic heliocentric: "
                 "{name: wisdom_holman, coordinates: democratic_heliocentric}); orbitsim's kernel is not "
                 "vectorised across bodies, so the bits differ",
    "whc": "REBOUND's shortcut for whfast with corrector 17: write {name: wisdom_holman, corrector: 17}",
    "whckl": "the lazy implementer's kernel has no counterpart; the closest is {name: wisdom_holman, corrector: 17}",
    "whckm": "the modified-kick kernel has no counterpart; the closest is {name: wisdom_holman, corrector: 17}",
    "whckc": "the composition kernel has no counterpart; the closest is {name: wisdom_holman, corrector: 17}",
    "janus": "the closest is leapfrog (or leapfrog4/6/8 for JANUS's higher orders): drift-kick-drift "
             "compositions in floating point, not JANUS's integer arithmetic, so reversible to round-off "
             "rather than bit for bit",
    "eos": "the closest is one of leapfrog4/6/8 (or wisdom_holman for a dominant central mass): EOS nests one "
           "operator splitting inside another, which orbitsim does not",
    "bs": "the closest is ias15, the adaptive high-accuracy scheme (REBOUND's bs is Gragg-Bulirsch-Stoer)",
    "sei": "orbitsim has no shearing sheet, so the symplectic epicycle integrator has no counterpart",
    "none": "orbitsim always integrates; give a scheme from `orbitsim list integrators`",
}


def _key(name: str) -> str:
    """A name as the registry compares names: stripped, lower case, ``-`` as ``_``."""
    return name.strip().lower().replace("-", "_")


def closest_scheme(name: str) -> str | None:
    """What to say about a REBOUND scheme orbitsim lacks (``saba1``, ``saba(10,6,4)`` are ``saba``); None
    when ``name`` is not one of REBOUND's."""
    key = _key(name)
    if key.startswith("saba"):  # REBOUND's saba1 ... saba4, sabacm, sabacl, saba(10,6,4): one family
        key = "saba"
    return CLOSEST.get(key)


def leapfrog_order(name: str, settings: dict[str, Any]) -> tuple[str, dict[str, Any]]:
    """``leapfrog`` with REBOUND's ``order`` setting as orbitsim's scheme of that order; anything else as it is.

    Raises
    ------
    ValueError
        For an order REBOUND's leapfrog does not have (the message names ``'order'``).
    """
    if "order" not in settings or not isinstance(name, str) or _key(name) != "leapfrog":
        return name, settings
    order = settings["order"]
    if isinstance(order, bool) or order not in LEAPFROG_ORDERS:
        raise ValueError(f"leapfrog setting 'order' must be one of {', '.join(map(str, LEAPFROG_ORDERS))} "
                         f"(REBOUND's orders), got {order!r}")
    return LEAPFROG_ORDERS[order], {k: v for k, v in settings.items() if k != "order"}


def rebound_note(name: Any, settings: Any) -> str | None:
    """A line saying which orbitsim scheme a REBOUND name (or leapfrog ``order``) became; None otherwise."""
    if not isinstance(name, str):
        return None
    key = _key(name)
    if key in SAME_SCHEME:
        return (f"integrator: {name} is REBOUND's name for {SAME_SCHEME[key]}, which runs with REBOUND's defaults "
                "(Jacobi coordinates, no corrector) unless its settings say otherwise")
    if key == "leapfrog" and isinstance(settings, dict) and settings.get("order") in LEAPFROG_ORDERS:
        order = settings["order"]
        return (f"integrator: REBOUND's leapfrog of order {order} is orbitsim's {LEAPFROG_ORDERS[order]} "
                "(the same coefficients)")
    return None
