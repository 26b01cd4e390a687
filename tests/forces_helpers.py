"""Shared set-ups of the forces tests: ForceSets built by hand, Mercury's orbit, and the perihelion
precession rate measured the way the acceptance criterion states it."""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from typing import Any

import numpy as np

from orbitsim.forces.table import N_PARAMS, ForceSet

#: REBOUNDx's constants.C: the speed of light in au per (yr / 2 pi).
C_REBOUND = 10065.32012038219
#: Mercury in REBOUNDx's GeneralRelativity example (the issue's acceptance case).
MERCURY = {"m": 1.66013e-7, "a": 0.387098, "e": 0.205630}
#: A Julian century in yr / 2 pi and an arcsecond in radians, as REBOUNDx's example converts them.
CENTURY = 628.33195
ARCSEC = 4.8481368e-06


#: A star and two inclined, eccentric planets with strong GR (c = 100) about SOURCE (replace it with a
#: body name): the compare and convergence tests with forces.
GR_PLANETS_YAML = """\
name: gr_planets
units: nbody
G: 1.0
integrator: leapfrog4
dt: 0.01
steps: 1000
output:
  every: 10
frame: barycentric
bodies:
  - {name: star, m: 1.0, x: [0, 0, 0], v: [0, 0, 0]}
  - {name: b, m: 1.0e-3, primary: star, a: 0.5, e: 0.2, inc: 5.7, M: 30}
  - {name: c, m: 3.0e-4, primary: star, a: 1.3, e: 0.05, inc: 17, Omega: 57, M: 200}
forces:
  - {force: gr, c: 100.0, source: SOURCE}
"""


def make_forces(n: int, rows: Iterable[tuple[int, int, Mapping[int, float], Any]]) -> ForceSet:
    """A ForceSet of ``(id, source, {param column: value}, per_body (3, n) or None)`` rows."""
    rows = list(rows)
    params = np.zeros((len(rows), N_PARAMS))
    per_body = np.zeros((len(rows), 3, n))
    for k, (_, _, values, taus) in enumerate(rows):
        for col, value in values.items():
            params[k, col] = value
        if taus is not None:
            per_body[k] = taus
    return ForceSet(np.array([r[0] for r in rows], dtype=np.int64), np.array([r[1] for r in rows], dtype=np.int64),
                    params, per_body)


def rebound_state(sim: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(m, x, v) of a REBOUND simulation as (N,), (N, 3), (N, 3) arrays."""
    m = np.array([p.m for p in sim.particles])
    x = np.array([p.xyz for p in sim.particles])
    v = np.array([p.vxyz for p in sim.particles])
    return m, x, v


def mercury_simulation() -> Any:
    """REBOUNDx's example: the Sun (m = 1) and Mercury at perihelion, moved to the centre of mass, G = 1."""
    import rebound

    sim = rebound.Simulation()
    sim.add(m=1.0)
    sim.add(**MERCURY)
    sim.move_to_com()
    return sim


def precession_arcsec_per_century(time: np.ndarray, pomega_rad: np.ndarray) -> float:
    """Slope of a straight-line fit to the unwrapped longitude of perihelion, in arcsec per century."""
    slope = np.polyfit(np.asarray(time, dtype=np.float64), np.unwrap(pomega_rad), 1)[0]
    return float(slope * CENTURY / ARCSEC)


def rebx_mercury_rate(force: str, integrator: str, dt: float | None, times: np.ndarray) -> float:
    """REBOUNDx's precession rate of Mercury under ``force``, sampled at ``times``: exactly with
    IAS15, after whole steps of ``dt`` otherwise (``times`` must then be multiples of dt)."""
    from orbitsim.forces.table import FORCE_IDS, P_C
    from orbitsim.reference.rebx import attach_forces

    sim = mercury_simulation()
    sim.integrator = integrator
    if dt is not None:
        sim.dt = dt
    attached = attach_forces(sim, make_forces(2, [(FORCE_IDS[force], 0, {P_C: C_REBOUND}, None)]))
    pomega = []
    for t in times:
        if dt is None:
            sim.integrate(t, exact_finish_time=1)
        else:
            sim.steps(round((t - sim.t) / dt))
        assert math.isclose(sim.t, t, rel_tol=1e-9)
        pomega.append(sim.particles[1].orbit(primary=sim.particles[0]).pomega)
    del attached
    return precession_arcsec_per_century(times, np.array(pomega))
