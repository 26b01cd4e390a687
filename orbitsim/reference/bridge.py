"""Scenario -> :class:`rebound.Simulation` with settings matched to an orbitsim run.

What "matched" means (checked against REBOUND 5.2.2 by experiment):

* ``sim.G``, ``sim.softening`` (REBOUND's Plummer softening enters as ``r^2 + eps^2``, exactly as
  in :mod:`orbitsim.physics.gravity`) and ``sim.dt`` are copied; gravity stays ``basic`` (direct
  summation), collisions and boundaries ``none``.
* Particles are added with ``m, x, y, z, vx, vy, vz`` in the scenario's order and frame. There is
  no ``move_to_com``: the scenario already chose its frame, and moving one code's frame would make
  the two runs different problems. Zero-mass bodies need nothing special: with REBOUND's default
  ``N_active`` every particle is active and a massless one simply exerts no force, as in orbitsim.
* The scheme is set through the integrator-configuration object of REBOUND 5
  (``sim.integrator = "leapfrog"; sim.integrator.order = 4``); WHFast goes through
  :func:`orbitsim.reference.wh_pairing.configure_rebound_whfast` when that module exists, so it
  uses the same coordinates and corrector as orbitsim's ``wisdom_holman``.

REBOUND is imported inside the functions: importing this module costs nothing.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from typing import Any

import numpy as np

#: REBOUND integrators this bridge configures: name -> (declared order in dt, fixed step?,
#: default option, what the option sets). WHFast and SABA are second order in dt once the
#: planet-planet term dominates (their error is O(eps dt^n + eps^2 dt^2), eps the mass ratio);
#: SABA's ``type`` picks the generalised order. IAS15 is adaptive: it is the reference.
REBOUND_SCHEMES: dict[str, tuple[int | None, bool, str | None, str]] = {
    "leapfrog": (2, True, "2", "order (2, 4, 6 or 8)"),
    "whfast": (2, True, None, "none (coordinates and corrector follow the orbitsim settings)"),
    "saba": (2, True, "1", "type, e.g. 1, 2, 3, 4, 10_6_4"),
    "ias15": (None, False, None, "none (adaptive; epsilon = 1e-9, REBOUND's default)"),
    "trace": (2, True, None, "none (r_crit_hill, peri_crit_eta and peri_mode follow the orbitsim settings)"),
}

#: Accepted values of ``leapfrog``'s option: the composition orders REBOUND implements.
LEAPFROG_ORDERS = (2, 4, 6, 8)


class ReboundSchemeError(ValueError):
    """An unknown REBOUND scheme or option; the message lists the valid ones."""


@dataclass(frozen=True)
class ReboundScheme:
    """A REBOUND integrator with its defining option, e.g. ``leapfrog`` of order 4.

    Parameters
    ----------
    name : str
        One of :data:`REBOUND_SCHEMES`.
    option : str or None
        ``leapfrog``: the order; ``saba``: the type; others: None.
    """

    name: str
    option: str | None = None

    @property
    def key(self) -> str:
        """Identifier used in group names and file names, e.g. ``leapfrog_order4``."""
        if self.name == "leapfrog":
            return f"leapfrog_order{self.option}"
        return f"{self.name}_{self.option}" if self.option else self.name

    @property
    def display(self) -> str:
        """Name for tables and legends, e.g. ``REBOUND leapfrog (order 4)``."""
        if self.name == "leapfrog":
            return f"REBOUND leapfrog (order {self.option})"
        suffix = f" ({self.option})" if self.option else ""
        return f"REBOUND {self.name}{suffix}"

    @property
    def order(self) -> int | None:
        """Declared order of accuracy in dt (None for the adaptive IAS15)."""
        if self.name == "leapfrog":
            return int(str(self.option))
        return REBOUND_SCHEMES[self.name][0]

    @property
    def fixed_step(self) -> bool:
        """True for schemes that take whole steps of ``dt``."""
        return REBOUND_SCHEMES[self.name][1]

    @property
    def options(self) -> dict[str, Any]:
        """The option as a dict, for HDF5 attributes and summaries."""
        if self.name == "leapfrog":
            return {"order": int(str(self.option))}
        if self.name == "saba":
            return {"type": str(self.option)}
        return {}


def parse_rebound_scheme(text: str) -> ReboundScheme:
    """Parse ``name[:option]`` (``leapfrog:4``, ``whfast``, ``saba:10_6_4``, ``ias15``).

    ``leapfrog4`` is accepted for ``leapfrog:4``. A bare ``leapfrog`` is order 2 and a bare
    ``saba`` is SABA1, REBOUND's defaults.
    """
    raw = text.strip().lower()
    name, _, option = raw.partition(":")
    if name.startswith("leapfrog") and name[len("leapfrog"):].isdigit() and not option:
        name, option = "leapfrog", name[len("leapfrog"):]
    if name not in REBOUND_SCHEMES:
        valid = ", ".join(f"{n}[:{REBOUND_SCHEMES[n][3]}]" if REBOUND_SCHEMES[n][2] else n
                          for n in REBOUND_SCHEMES)
        raise ReboundSchemeError(f"unknown REBOUND integrator {text!r}; valid: {valid}")
    default = REBOUND_SCHEMES[name][2]
    if option and default is None:
        raise ReboundSchemeError(f"REBOUND integrator {name!r} takes no option (got {text!r})")
    option = option or default
    if name == "leapfrog" and (not option.isdigit() or int(option) not in LEAPFROG_ORDERS):
        raise ReboundSchemeError(f"REBOUND leapfrog order must be one of {LEAPFROG_ORDERS}, got {option!r}")
    return ReboundScheme(name, option)


def whfast_configurator() -> Any | None:
    """``configure_rebound_whfast(sim, settings)`` if the pairing module exists, else None."""
    try:
        module = importlib.import_module("orbitsim.reference.wh_pairing")
    except ImportError:
        return None
    return getattr(module, "configure_rebound_whfast", None)


def configure_scheme(sim: Any, scheme: ReboundScheme, settings: dict[str, Any] | None = None) -> None:
    """Select ``scheme`` on ``sim`` and set its options.

    ``settings`` are the orbitsim integrator settings of the partner run; WHFast and TRACE read them.
    """
    if scheme.name == "whfast":
        configure = whfast_configurator()
        if configure is not None:
            configure(sim, dict(settings or {}))
            return
        # Without the pairing module: REBOUND's defaults, stated explicitly so a change of
        # REBOUND's defaults cannot silently change the comparison.
        sim.integrator = "whfast"
        sim.integrator.coordinates = "jacobi"
        sim.integrator.corrector = 0
        sim.integrator.safe_mode = 1
        return
    sim.integrator = scheme.name
    if scheme.name == "trace":
        from orbitsim.integrators.trace import SETTINGS, validate_settings  # noqa: PLC0415 -- lazy: loads numba

        # The orbitsim partner's settings; REBOUND's defaults for what they do not give.
        config = validate_settings({k: v for k, v in (settings or {}).items() if k in SETTINGS})
        sim.integrator.r_crit_hill = config["r_crit_hill"]
        sim.integrator.peri_crit_eta = config["peri_crit_eta"]
        sim.integrator.peri_mode = config["peri_mode"].upper()
    if scheme.name == "leapfrog":
        sim.integrator.order = int(str(scheme.option))
    elif scheme.name == "saba":
        sim.integrator.type = str(scheme.option).upper()
        sim.integrator.safe_mode = 1


def rebound_simulation(masses: np.ndarray, positions: np.ndarray, velocities: np.ndarray, *,
                       G: float, softening: float, dt: float, scheme: ReboundScheme | str,
                       settings: dict[str, Any] | None = None) -> Any:
    """A :class:`rebound.Simulation` of the system, matched to an orbitsim run.

    Parameters
    ----------
    masses : (N,) array
    positions, velocities : (N, 3) arrays
        Initial state in the scenario's frame (not moved to the centre of mass).
    G, softening, dt : float
        Gravitational constant, Plummer softening length and timestep of the orbitsim run.
    scheme : ReboundScheme or str
        The REBOUND integrator, e.g. ``"leapfrog:4"``.
    settings : dict, optional
        orbitsim integrator settings of the partner run (used by WHFast).

    Returns
    -------
    rebound.Simulation
        Ready to step; ``sim.t == 0``.
    """
    import rebound  # noqa: PLC0415 -- lazy: loads rebound

    if isinstance(scheme, str):
        scheme = parse_rebound_scheme(scheme)
    m = np.asarray(masses, dtype=np.float64).reshape(-1)
    x = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    v = np.asarray(velocities, dtype=np.float64).reshape(-1, 3)
    sim = rebound.Simulation()
    sim.G = float(G)
    sim.softening = float(softening)
    for i in range(m.shape[0]):
        sim.add(m=float(m[i]), x=float(x[i, 0]), y=float(x[i, 1]), z=float(x[i, 2]),
                vx=float(v[i, 0]), vy=float(v[i, 1]), vz=float(v[i, 2]))
    sim.dt = float(dt)  # before the scheme: configure_rebound_whfast expects dt already set
    configure_scheme(sim, scheme, settings)
    return sim


def read_state(sim: Any) -> tuple[np.ndarray, np.ndarray]:
    """Positions and velocities of every particle as (N, 3) arrays (one C call, no Python loop)."""
    pos = np.zeros((sim.N, 3))
    vel = np.zeros((sim.N, 3))
    sim.serialize_particle_data(xyz=pos, vxvyvz=vel)
    return pos, vel
