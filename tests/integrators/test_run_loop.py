"""The fixed-dt loop gives the same bits whatever the sampling.

Sampling only reads the state: taking 84 steps with a sample after every step, after every 7th or
only at the end must leave the same final state, bit for bit, and the samples that the plans share
must agree bit for bit. This also pins the loops that fuse work across step boundaries (verlet
fuses each closing kick with the next opening kick and drift while no sample falls between them):
with a sample after every step nothing is fused, so any change of arithmetic would show here.
"""

from __future__ import annotations

import numpy as np
import pytest

from orbitsim.integrators.registry import INTEGRATORS
from orbitsim.simulation import simulate

STEPS = 84


def planets_and_a_test_body() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(7)
    m = np.array([1.0, 1e-3, 3e-4, 5e-5, 0.0])
    a = np.array([0.0, 1.0, 1.7, 2.6, 3.5])
    phase = rng.uniform(0.0, 2.0 * np.pi, size=5)
    x = np.stack([a * np.cos(phase), a * np.sin(phase), rng.uniform(-0.01, 0.01, 5)], axis=1)
    speed = np.where(a > 0, 1.0 / np.sqrt(np.where(a > 0, a, 1.0)), 0.0)
    v = np.stack([-speed * np.sin(phase), speed * np.cos(phase), np.zeros(5)], axis=1)
    return m, x, v


@pytest.mark.parametrize("name", [spec.name for spec in INTEGRATORS])
def test_sampling_does_not_change_the_bits(name: str) -> None:
    m, x0, v0 = planets_and_a_test_body()
    runs = {
        every: simulate(m, x0, v0, integrator=name, dt=0.01, steps=STEPS, every=every, G=1.0,
                        softening=0.0, record_positions=True)
        for every in (1, 7, STEPS)
    }
    dense = runs[1]
    for every, result in runs.items():
        assert np.array_equal(result.final_positions, dense.final_positions), f"{name}, every {every}"
        assert np.array_equal(result.final_velocities, dense.final_velocities), f"{name}, every {every}"
        shared = np.isin(dense.step, result.step)
        assert np.array_equal(dense.step[shared], result.step)
        assert np.array_equal(dense.positions[shared], result.positions), f"{name}, every {every}"
        assert np.array_equal(dense.velocities[shared], result.velocities), f"{name}, every {every}"
        assert np.array_equal(dense.energy[shared], result.energy), f"{name}, every {every}"
    # The system really moved, so equal bits are not equal starting points.
    assert np.max(np.abs(dense.final_positions - x0)) > 1e-2
