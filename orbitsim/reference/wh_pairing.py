"""REBOUND WHFast settings that reproduce orbitsim's ``wisdom_holman`` step for step.

orbitsim's Wisdom-Holman map keeps its (corrected) Jacobi or democratic heliocentric state between
steps, merges neighbouring half drifts, and applies the inverse corrector only to a *copy* of that
state at output times. In REBOUND that is WHFast with

* ``sim.integrator = "whfast"``;
* ``sim.integrator.coordinates = "jacobi"`` or ``"democraticheliocentric"`` (orbitsim's
  ``democratic_heliocentric``);
* ``sim.integrator.corrector = 0, 3, 5, 7, 11 or 17`` (the same order; Jacobi only);
* ``sim.integrator.safe_mode = 0``: no round trip to inertial coordinates between steps, drifts
  merged (with ``safe_mode = 1`` and a corrector REBOUND applies C and C^-1 every step: a
  different map, agreeing only to ~1e-10 after 1000 steps);
* ``sim.integrator.keep_unsynchronized = 1``: ``sim.synchronize()`` works on a copy, so outputs do
  not change the trajectory (without it REBOUND restarts from the synchronised state after each
  output, and the bits depend on the output cadence);
* ``sim.exact_finish_time = 0``: ``sim.integrate(t)`` never shortens a step (orbitsim never does).

The caller must also: give REBOUND the same G, masses and inertial state as orbitsim, in the same
order, body 0 the central body; **not** call ``sim.move_to_com()`` unless orbitsim's input is
shifted the same way (orbitsim uses the state as given); advance with ``sim.steps(n)`` (or
``integrate`` with the flag above); and call ``sim.synchronize()`` before reading particles.
With these settings the two codes agree to ~1e-13 (outer Solar System) and ~1e-12 (Sun and eight
planets, dt = 5 d) relative in position after 1000 steps.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from orbitsim.integrators.wisdom_holman.settings import validate_settings

#: orbitsim's ``coordinates`` setting -> REBOUND's WHFast ``coordinates`` value.
REBOUND_COORDINATES = {"jacobi": "jacobi", "democratic_heliocentric": "democraticheliocentric"}


def configure_rebound_whfast(sim: Any, settings: Mapping[str, Any] | None) -> None:
    """Select and configure REBOUND WHFast on ``sim`` to match orbitsim ``wisdom_holman``.

    Parameters
    ----------
    sim : rebound.Simulation
        A simulation with its particles, G and dt already set (dt is not touched).
    settings : mapping or None
        orbitsim's integrator settings (``coordinates``, ``corrector``); validated and
        defaulted by :func:`orbitsim.integrators.wisdom_holman.settings.validate_settings`.

    Raises
    ------
    ValueError
        For invalid settings (the message names the key).
    """
    config = validate_settings(settings)
    sim.integrator = "whfast"
    sim.integrator.coordinates = REBOUND_COORDINATES[config["coordinates"]]
    sim.integrator.corrector = config["corrector"]
    sim.integrator.safe_mode = 0
    sim.integrator.keep_unsynchronized = 1
    sim.exact_finish_time = 0
