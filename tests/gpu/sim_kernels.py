"""The GPU kernels against the CPU kernels, under Numba's CUDA simulator (run by test_gpu_simulator.py).

Collected only by that test, in a subprocess with ``NUMBA_ENABLE_CUDASIM=1`` (its name is not
``test_*.py``): importing numba.cuda under the simulator fixes it for the whole process.

Tolerance, everywhere here: 1e-13 relative, because both sides are FP64 but not bitwise: the GPU sums
j in index order per body where the CPU uses the third law (another order of the same terms), the
device compiler may fuse multiply-adds, and hardware uses rsqrt (the simulator 1/sqrt). Each is an
error of a few ulps per term, ~1e-15 relative for these sums; 1e-13 leaves room and still fails for
any wrong term (a missing pair moves a sum by ~1/N).
"""

from __future__ import annotations

import os

import numpy as np
import pytest

if os.environ.get("NUMBA_ENABLE_CUDASIM") != "1":  # pragma: no cover - a guard, not a path
    raise RuntimeError("run under Numba's CUDA simulator: tests/gpu/test_gpu_simulator.py does")

from orbitsim.gpu.direct import SIM_TILE, direct_kernels
from orbitsim.gpu.stepping import DeviceSystem
from orbitsim.gpu.support import GPU_SCHEMES
from orbitsim.physics.diagnostics import kinetic_energy, potential_energy
from orbitsim.physics.gravity import accelerations, force_scratch
from orbitsim.simulation import Simulation

RTOL = 1e-13  # FP64 on both sides, not bitwise (order of the sum, FMA, rsqrt): see the module docstring


def system(n: int, seed: int = 7) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    return rng.uniform(0.5, 1.5, n) / n, rng.normal(size=(3, n)), 0.3 * rng.normal(size=(3, n))


def cpu_accelerations(m: np.ndarray, x: np.ndarray, G: float, eps2: float) -> np.ndarray:
    acc = np.zeros_like(x)
    slabs, bounds = force_scratch(m.shape[0])
    accelerations(x, m, G, eps2, acc, slabs, bounds)
    return acc


def rel(a: np.ndarray, b: np.ndarray) -> float:
    """Largest per-body |a - b| / |b| (norm-wise: a component can vanish by cancellation)."""
    return float(np.max(np.linalg.norm(a - b, axis=0) / np.linalg.norm(b, axis=0)))


# N = 8: one partial tile; 40: a full tile and a partial one; 64: two full tiles (SIM_TILE = 32).
@pytest.mark.parametrize("n", [8, 40, 64])
@pytest.mark.parametrize("softening", [0.0, 0.05])
def test_accelerations_match_the_cpu(n: int, softening: float) -> None:
    assert SIM_TILE == 32
    m, x, v = system(n)
    gpu = DeviceSystem(m, x, v, "verlet", 1.7, softening ** 2)
    assert rel(gpu.download()[2], cpu_accelerations(m, x, 1.7, softening ** 2)) < RTOL


def test_the_tile_size_does_not_change_a_bit() -> None:
    """Each thread sums its j in index order whatever the tile, so tiles of 16 (two full tiles and a partial
    one at N = 40) and 32 give the same bits; the sample's sums are a tree over the tile, so only close."""
    m, x, v = system(40)
    s16, s32 = (DeviceSystem(m, x, v, "verlet", 1.0, 1e-4, tile=tile) for tile in (16, 32))
    assert np.array_equal(s16.download()[2], s32.download()[2])
    assert abs(s16.sample().potential / s32.sample().potential - 1.0) < RTOL


def test_a_tile_must_be_a_power_of_two() -> None:
    for tile in (24, 8):
        with pytest.raises(ValueError, match="power of two >= 16"):
            direct_kernels(tile)


@pytest.mark.parametrize("n", [8, 40])
def test_sample_sums_match_the_cpu(n: int) -> None:
    m, x, v = system(n, seed=3)
    G, eps2 = 2.0, 1e-3
    sums = DeviceSystem(m, x, v, "verlet", G, eps2).sample()
    assert abs(sums.kinetic / kinetic_energy(v, m) - 1.0) < RTOL
    assert abs(sums.potential / potential_energy(x, m, G, eps2, np.zeros(0)) - 1.0) < RTOL
    p_scale = np.sum(m * np.linalg.norm(v, axis=0))  # |P| itself can be near 0: compare with its terms' size
    l_scale = np.sum(m * np.linalg.norm(np.cross(x.T, v.T), axis=1))
    assert np.max(np.abs(sums.momentum - (m * v).sum(axis=1))) < RTOL * p_scale
    assert np.max(np.abs(sums.angular_momentum - (m * np.cross(x.T, v.T).T).sum(axis=1))) < RTOL * l_scale
    assert sums.non_finite == 0


# The simulator's threads compute with numpy scalars, which warn (inf - inf) where hardware is silent.
@pytest.mark.filterwarnings("ignore:invalid value encountered:RuntimeWarning")
@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_a_non_finite_body_is_counted(bad: float) -> None:
    m, x, v = system(8)
    x[1, 5] = bad
    v[0, 2] = bad
    assert DeviceSystem(m, x, v, "verlet", 1.0, 1e-2).sample().non_finite == 2


#: Steps per scheme: the 9- and 17-stage compositions take one (each stage is a force launch, slow here).
STEPS = {"leapfrog6": 1, "leapfrog8": 1}


@pytest.mark.parametrize("scheme", GPU_SCHEMES)
def test_whole_steps_of_every_scheme_match_the_cpu(scheme: str) -> None:
    from orbitsim.gpu.simulation import GPUSimulation

    n, dt, G, eps = 12, 0.01, 1.0, 0.05
    m, x, v = system(n, seed=11)
    steps = STEPS.get(scheme, 2)
    plan = np.array([0, steps], dtype=np.int64)
    cpu = Simulation(m, x.T, v.T, scheme, dt, G, eps, threads=1)
    gpu = GPUSimulation(m, x.T, v.T, scheme, dt, G, eps)
    cpu_chunks = list(cpu.chunks(plan))
    gpu_chunks = list(gpu.chunks(plan))
    assert gpu.steps_done == cpu.steps_done == steps
    c, g = cpu_chunks[0], gpu_chunks[0]
    assert np.array_equal(c.step, g.step) and np.array_equal(c.time, g.time)
    assert rel(gpu.pos, cpu.pos) < RTOL and rel(gpu.vel, cpu.vel) < RTOL and rel(gpu.acc, cpu.acc) < RTOL
    assert np.max(np.abs(g.energy / c.energy - 1.0)) < RTOL
    assert np.max(np.abs(g.positions - c.positions)) < RTOL * np.max(np.abs(c.positions))
    # the steps moved the bodies, far beyond the tolerance: a scheme that did nothing would fail above
    assert np.max(np.abs(gpu.pos - x)) > 1e3 * RTOL
