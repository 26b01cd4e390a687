"""Time reversibility: n steps forward, then n steps with -dt from the final state, return to the start.

For a symmetric scheme the map with -dt is the exact inverse of the map with dt, so only round-off
separates the return from the start: a few ulps per step. Explicit and semi-implicit Euler are
not symmetric; they miss the start by the scheme's local error, 10^10-10^12 ulps per step here.

The schemes tested are those whose record says ``reversible`` (:func:`test_reversible_is_what_the_records_say`
holds the list to the registry, so a new reversible scheme cannot go untested); for the others the
property is not claimed.
"""

from __future__ import annotations

import numpy as np
import pytest

from orbitsim.integrators.registry import INTEGRATORS
from orbitsim.simulation import Simulation

#: Every scheme whose record says ``spec.reversible``: the symmetric compositions of kicks and drifts
#: (Wisdom-Holman's drifts are exact Kepler flows, composed symmetrically with its kicks).
REVERSIBLE = ("verlet", "leapfrog", "leapfrog4", "leapfrog6", "leapfrog8", "wisdom_holman")
#: Negative controls: not symmetric, and their records say so.
IRREVERSIBLE = ("euler", "semi_implicit_euler")

DT = 0.01
STEPS = 1000
SOFTENING = 0.01
ULP = np.finfo(np.float64).eps

#: Allowed return error, relative to the state's scale: a few ulps per step (measured 0.005-0.29
#: ulps per step at n = 1000, wisdom_holman 0.025 and 0.5-1.2 at n = 10^4: round-off in the phase grows like n^2).
ULPS_PER_STEP = 4.0


def star_and_three_planets() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A mildly eccentric, slightly inclined, non-chaotic planetary system in the CoM frame."""
    m = np.array([1.0, 1e-3, 3e-4, 5e-5])
    x = np.zeros((4, 3))
    v = np.zeros((4, 3))
    for i, (a, phase) in enumerate(((1.0, 0.3), (1.6, 2.1), (2.5, 4.0)), start=1):
        x[i] = [a * np.cos(phase), a * np.sin(phase), 0.01 * i]
        speed = 1.05 * np.sqrt(1.0 / a)  # 5% above circular: e ~ 0.1
        v[i] = [-speed * np.sin(phase), speed * np.cos(phase), 0.001]
    v -= (m[:, None] * v).sum(axis=0) / m.sum()
    return m, x, v


def advance(m, x, v, name: str, dt: float, steps: int) -> tuple[np.ndarray, np.ndarray]:
    sim = Simulation(m, x, v, name, dt, 1.0, SOFTENING)
    for _ in sim.chunks(np.array([steps]), record_positions=False):
        pass
    assert sim.steps_done == steps
    return sim.state()


def round_trip_error(name: str) -> tuple[float, float, float]:
    """(position error, velocity error, distance travelled), errors relative to the state's scale."""
    m, x0, v0 = star_and_three_planets()
    x1, v1 = advance(m, x0, v0, name, DT, STEPS)
    x2, v2 = advance(m, x1, v1, name, -DT, STEPS)
    x_err = np.max(np.abs(x2 - x0)) / np.max(np.abs(x0))
    v_err = np.max(np.abs(v2 - v0)) / np.max(np.abs(v0))
    return float(x_err), float(v_err), float(np.max(np.abs(x1 - x0)))


@pytest.mark.parametrize("name", REVERSIBLE)
def test_symmetric_schemes_return_to_the_start(name: str) -> None:
    x_err, v_err, travelled = round_trip_error(name)
    assert travelled > 1.0  # the planets really went somewhere and came back
    bound = ULPS_PER_STEP * STEPS * ULP
    assert x_err < bound, f"{name}: positions return within {x_err / ULP / STEPS:.2f} ulps per step"
    assert v_err < bound, f"{name}: velocities return within {v_err / ULP / STEPS:.2f} ulps per step"


@pytest.mark.parametrize("name", IRREVERSIBLE)
def test_euler_schemes_are_not_reversible(name: str) -> None:
    """Negative control: the round trip misses the start by the local error, not by round-off."""
    x_err, v_err, _ = round_trip_error(name)
    # Measured 0.7 (euler) and 1.4e-2 (semi-implicit): >= 4e10 ulps per step; the bound below is 1e-6.
    assert x_err > 1e6 * ULPS_PER_STEP * STEPS * ULP
    assert v_err > 1e6 * ULPS_PER_STEP * STEPS * ULP


def test_reversible_is_what_the_records_say() -> None:
    """REVERSIBLE is exactly the registry's reversible schemes (a scheme registered as reversible
    fails here until it is added above), and the negative controls are not reversible."""
    by_name = {spec.name: spec for spec in INTEGRATORS}
    assert set(REVERSIBLE) == {name for name, spec in by_name.items() if spec.reversible}
    for name in IRREVERSIBLE:
        assert not by_name[name].reversible, name
