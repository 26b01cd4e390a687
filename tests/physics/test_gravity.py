"""The gravity kernels: serial == parallel bit for bit, thread-count independence, agreement with the
naive double loop, zero-mass bodies, softening, and the block partition of the pair loop."""

from __future__ import annotations

import naive
import numba
import numpy as np
import pytest

from orbitsim._jit import set_num_threads
from orbitsim.physics.gravity import (
    PARALLEL_MIN_N,
    accelerations,
    accelerations_parallel,
    accelerations_serial,
    block_bounds,
    force_scratch,
    n_blocks,
)
from orbitsim.simulation import simulate

#: The force sum is reassociated (vectorised) and pairs are computed once; against a plain double
#: loop that is a relative change of ~4e-15 (docs/design.md#fast-kernels), well inside 1e-12.
NAIVE_TOL = 1e-12


def random_system(n: int, seed: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Positions (3, N) in a unit ball-ish cloud, masses in [0.1, 1) with a few zero masses."""
    rng = np.random.default_rng(seed)
    pos = np.ascontiguousarray(rng.normal(size=(3, n)))
    m = rng.uniform(0.1, 1.0, size=n)
    m[:: max(1, n // 7)] = 0.0
    return pos, m


def serial(pos, m, G, eps, slabs, bounds) -> np.ndarray:
    acc = np.zeros_like(pos)
    accelerations_serial(pos, m, G, eps * eps, acc, slabs, bounds)
    return acc


def parallel(pos, m, G, eps, slabs, bounds) -> np.ndarray:
    acc = np.zeros_like(pos)
    accelerations_parallel(pos, m, G, eps * eps, acc, slabs, bounds)
    return acc


def dispatched(pos, m, G, eps) -> np.ndarray:
    slabs, bounds = force_scratch(pos.shape[1])
    acc = np.zeros_like(pos)
    accelerations(pos, m, G, eps * eps, acc, slabs, bounds)
    return acc


def vectorised_reference(pos: np.ndarray, m: np.ndarray, G: float, eps: float) -> np.ndarray:
    """All-pairs numpy broadcast (N x N): the naive loop's formula, fast enough for N ~ 1000."""
    d = pos[:, None, :] - pos[:, :, None]  # d[c, i, j] = x_j - x_i
    r2 = np.sum(d * d, axis=0) + eps * eps
    np.fill_diagonal(r2, np.inf)
    return G * np.sum(d * (m[None, None, :] / r2**1.5), axis=2)


def relative_error(acc: np.ndarray, ref: np.ndarray) -> float:
    return float(np.max(np.linalg.norm(acc - ref, axis=0)) / np.max(np.linalg.norm(ref, axis=0)))


@pytest.fixture
def restore_threads():
    before = numba.get_num_threads()
    yield
    numba.set_num_threads(before)


def two_threads_available() -> bool:
    return numba.config.NUMBA_NUM_THREADS >= 2


# --- serial == parallel -------------------------------------------------------------------


@pytest.mark.parametrize("n", [600, 1000])
def test_serial_and_parallel_identical_with_real_blocks(n: int) -> None:
    assert n >= PARALLEL_MIN_N and n_blocks(n) > 1
    pos, m = random_system(n)
    slabs, bounds = force_scratch(n)
    a_serial = serial(pos, m, 1.3, 0.01, slabs, bounds)
    a_parallel = parallel(pos, m, 1.3, 0.01, slabs, bounds)
    assert np.array_equal(a_serial, a_parallel)
    assert np.array_equal(dispatched(pos, m, 1.3, 0.01), a_serial)  # accelerations() takes the parallel path


@pytest.mark.parametrize("bounds", [[0, 10, 25, 50, 100], [0, 1, 2, 99, 100], [0, 100]])
def test_serial_and_parallel_identical_below_threshold(bounds: list[int]) -> None:
    """Below PARALLEL_MIN_N production uses one block; the kernels still agree on any partition."""
    n = 100
    assert n < PARALLEL_MIN_N and len(block_bounds(n)) == 2
    pos, m = random_system(n, seed=2)
    b = np.array(bounds, dtype=np.int64)
    slabs = np.zeros((len(bounds) - 1, 3, n))
    assert np.array_equal(serial(pos, m, 1.0, 0.0, slabs, b), parallel(pos, m, 1.0, 0.0, slabs, b))


def test_small_n_uses_the_single_block_serial_path() -> None:
    n = PARALLEL_MIN_N - 1
    slabs, bounds = force_scratch(n)
    assert bounds.tolist() == [0, n] and slabs.shape[0] == 0
    pos, m = random_system(n, seed=3)
    empty = np.zeros((0, 3, n))
    assert np.array_equal(dispatched(pos, m, 1.0, 0.02), serial(pos, m, 1.0, 0.02, empty, bounds))


# --- thread-count independence ---------------------------------------------------------------


@pytest.mark.skipif(not two_threads_available(), reason="needs NUMBA_NUM_THREADS >= 2")
def test_force_kernel_same_bits_on_one_and_two_threads(restore_threads) -> None:
    n = 1000
    pos, m = random_system(n, seed=4)
    slabs, bounds = force_scratch(n)
    set_num_threads(1)
    one = parallel(pos, m, 1.0, 0.01, slabs, bounds)
    set_num_threads(2)
    two = parallel(pos, m, 1.0, 0.01, slabs, bounds)
    assert numba.get_num_threads() == 2
    assert np.array_equal(one, two)


@pytest.mark.skipif(not two_threads_available(), reason="needs NUMBA_NUM_THREADS >= 2")
def test_simulation_same_bits_on_one_and_two_threads(restore_threads) -> None:
    n = 500
    assert n >= PARALLEL_MIN_N  # so the run really goes through the parallel kernels
    rng = np.random.default_rng(5)
    x = rng.normal(size=(n, 3))
    v = 0.1 * rng.normal(size=(n, 3))
    m = rng.uniform(0.5, 1.5, size=n) / n
    runs = [
        simulate(m, x, v, integrator="verlet", dt=1e-3, steps=50, every=10, softening=0.01, threads=t)
        for t in (1, 2)
    ]
    for field in ("positions", "velocities", "kinetic", "potential", "momentum", "angular_momentum"):
        assert np.array_equal(getattr(runs[0], field), getattr(runs[1], field)), field
    assert not np.array_equal(runs[0].final_positions, x)


# --- agreement with the naive double loop ---------------------------------------------------


@pytest.mark.parametrize("eps", [0.0, 0.1])
def test_matches_naive_double_loop(eps: float) -> None:
    n = 40
    pos, m = random_system(n, seed=6)
    ref = naive.accelerations(pos.T, m, 0.7, eps).T
    assert relative_error(dispatched(pos, m, 0.7, eps), ref) < NAIVE_TOL


def test_matches_naive_through_the_blocked_kernel() -> None:
    n = 700
    pos, m = random_system(n, seed=7)
    ref = vectorised_reference(pos, m, 1.0, 0.05)
    # The broadcast reference itself against the double loop on a few rows: same formula.
    sub = naive.accelerations(pos.T[:30], m[:30], 1.0, 0.05).T
    assert relative_error(vectorised_reference(pos[:, :30], m[:30], 1.0, 0.05), sub) < NAIVE_TOL
    assert relative_error(dispatched(pos, m, 1.0, 0.05), ref) < NAIVE_TOL


# --- zero-mass bodies and softening ------------------------------------------------------------


def test_zero_mass_bodies_feel_gravity_but_exert_none() -> None:
    pos, m = random_system(12, seed=8)
    m[:] = np.linspace(0.5, 1.5, 12)
    test_pos = np.ascontiguousarray(np.random.default_rng(9).normal(size=(3, 5)))
    all_pos = np.ascontiguousarray(np.concatenate([pos, test_pos], axis=1))
    all_m = np.concatenate([m, np.zeros(5)])
    with_tests = dispatched(all_pos, all_m, 1.0, 0.01)
    without = dispatched(pos, m, 1.0, 0.01)
    # Adding terms that are exactly 0.0 leaves each sum unchanged up to the reassociated order.
    assert relative_error(with_tests[:, :12], without) < 1e-15
    assert np.all(np.linalg.norm(with_tests[:, 12:], axis=0) > 1e-3)  # the test bodies are pulled
    ref = naive.accelerations(all_pos.T, all_m, 1.0, 0.01).T
    assert relative_error(with_tests[:, 12:], ref[:, 12:]) < NAIVE_TOL


@pytest.mark.parametrize("r", [1e-3, 0.05, 1.0, 30.0])
def test_plummer_softening_formula(r: float) -> None:
    G, eps, m2 = 2.0, 0.05, 3.0
    pos = np.array([[0.0, r], [0.0, 0.0], [0.0, 0.0]])
    m = np.array([0.0, m2])
    acc = dispatched(pos, m, G, eps)
    expected = G * m2 * r / (r * r + eps * eps) ** 1.5
    # One square root, one division and a few products: within a few ulps.
    assert acc[0, 0] == pytest.approx(expected, rel=1e-15)
    assert acc[1, 0] == 0.0 and acc[2, 0] == 0.0
    assert np.all(acc[:, 1] == 0.0)  # body 0 has no mass: body 1 feels nothing


def test_softening_keeps_coincident_bodies_finite() -> None:
    pos = np.zeros((3, 2))
    acc = dispatched(pos, np.array([1.0, 1.0]), 1.0, 0.1)
    assert np.all(acc == 0.0)


def test_unsoftened_force_is_inverse_square() -> None:
    pos = np.array([[0.0, 2.0], [0.0, 0.0], [0.0, 0.0]])
    acc = dispatched(pos, np.array([1.0, 1.0]), 1.0, 0.0)
    assert acc[0, 0] == 0.25 and acc[0, 1] == -0.25  # exact in binary


# --- the block partition ---------------------------------------------------------------------


@pytest.mark.parametrize("n", [1, 2, 10, PARALLEL_MIN_N - 1, PARALLEL_MIN_N, 500, 1000, 4096, 10007])
def test_block_bounds_cover_all_rows_and_balance_pairs(n: int) -> None:
    bounds = block_bounds(n)
    assert bounds[0] == 0 and bounds[-1] == n
    assert np.all(np.diff(bounds) >= 0)
    assert len(bounds) - 1 == n_blocks(n)
    if len(bounds) == 2:
        return
    pairs_per_row = n - 1 - np.arange(n)
    counts = np.array([pairs_per_row[bounds[b] : bounds[b + 1]].sum() for b in range(len(bounds) - 1)])
    assert counts.sum() == n * (n - 1) // 2
    mean = counts.mean()
    # Boundaries fall on whole rows, so each block can be off its share by at most one row's
    # pairs (< n) at each end.
    assert np.all(np.abs(counts - mean) <= 2 * (n - 1))
    if n >= 1000:
        # ... which for n >= 1000 is a few percent (measured 2.3% at n = 1000, 0.3% at 4096).
        assert np.all(np.abs(counts / mean - 1.0) < 0.03)


def test_block_bounds_do_not_depend_on_threads(restore_threads) -> None:
    first = block_bounds(1000)
    set_num_threads(1)
    assert np.array_equal(block_bounds(1000), first)
