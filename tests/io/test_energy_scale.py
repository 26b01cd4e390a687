"""What ``energy_error`` is relative to: |E0|, or T0 + |U0| when E0 is nearly zero (orbitsim.io.schema).

Dividing by an E0 that is zero by accident (a nearly parabolic pair) makes any error look enormous,
or, with E0 at round-off level, like anything at all; T0 + |U0| cannot vanish while anything moves
or attracts. Every bundled scenario is far from that threshold, so its errors keep their old bits.
"""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np
import pytest

from orbitsim.io.schema import NEAR_ZERO_ENERGY, energy_scale
from orbitsim.physics.diagnostics import kinetic_energy, potential_energy, potential_rows_scratch
from orbitsim.runner import run_scenario
from orbitsim.scenario import bundled_scenarios, load_scenario, scenario_from_dict


def test_the_scale_is_abs_e0_for_a_bound_system_and_t_plus_u_near_zero() -> None:
    assert energy_scale(0.5, -1.0) == 0.5  # |E0| = (T + |U|) / 3: the virial ratio, nowhere near zero
    tiny = 0.5 * NEAR_ZERO_ENERGY * 2.0  # |E0| = 0.5e-3 of T + |U| = 2: below the threshold
    assert energy_scale(1.0 + tiny / 2, -1.0 + tiny / 2) == pytest.approx(2.0, rel=1e-12)  # reason: one rounding
    assert energy_scale(1.0, -1.0) == 2.0  # exactly parabolic: E0 = 0
    assert energy_scale(0.0, 0.0) == 1.0  # nothing moves or attracts: the absolute error


@pytest.mark.parametrize("name", sorted(bundled_scenarios()))
def test_every_bundled_scenario_keeps_dividing_by_abs_e0(name: str) -> None:
    """So the energy_error bits of every run made before the change are unchanged."""
    sc = load_scenario(name)
    pos, vel = np.ascontiguousarray(sc.positions.T), np.ascontiguousarray(sc.velocities.T)
    t0 = float(kinetic_energy(vel, sc.masses))
    u0 = float(potential_energy(pos, sc.masses, sc.G, sc.softening**2, potential_rows_scratch(sc.n_bodies)))
    e0 = t0 + u0
    assert energy_scale(t0, u0) == (abs(e0) if e0 != 0.0 else 1.0)  # the old rule: |E0|, or absolute at 0


def test_a_nearly_parabolic_pair_is_measured_against_t_plus_u(tmp_path: Path) -> None:
    """Two unit masses at distance 2 with the speed of escape: E0 is zero up to round-off."""
    v = np.sqrt(0.5)  # T0 = 2 * (1/2) * 0.5 = 0.5 = |U0| = G m m / 2
    doc = {"name": "flyby", "integrator": "verlet", "dt": 0.001, "steps": 500, "output": {"every": 50},
           "bodies": [{"name": "a", "m": 1.0, "x": [-1.0, 0.0, 0.0], "v": [0.0, -float(v), 0.0]},
                      {"name": "b", "m": 1.0, "x": [1.0, 0.0, 0.0], "v": [0.0, float(v), 0.0]}]}
    sc = scenario_from_dict(doc)
    run_scenario(sc, tmp_path / "f.h5", handle_signals=False)
    with h5py.File(tmp_path / "f.h5", "r") as f:
        kinetic, potential = f["kinetic"][()], f["potential"][()]
        t0, u0 = float(kinetic[0]), float(potential[0])
        assert abs(t0 + u0) < NEAR_ZERO_ENERGY * (t0 + abs(u0))  # the case this is about
        assert f.attrs["energy_scale"] == t0 + abs(u0)
        expected = (kinetic + potential - f.attrs["E0"]) / (t0 + abs(u0))
        assert np.array_equal(f["energy_error"][()], expected)
