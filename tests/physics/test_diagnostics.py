"""The potential energy: its three paths give the same bits, on any thread count, and agree with the
slow reference in ``tests/naive.py``.

The potential has a fixed order of addition (four round-robin partial sums per row), computed by an
allocation-free loop for small N, by buffered vector rows from BUFFERED_POTENTIAL_MIN_N, and by
the same rows in parallel from PARALLEL_POTENTIAL_MIN_N. A sample must not change its bits when N
crosses a threshold or the thread count changes, or the same run would report different energies.
"""

from __future__ import annotations

import naive
import numba
import numpy as np
import pytest

from orbitsim.physics import diagnostics as d

G = 1.3
EPS = 0.01


def cloud(n: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(n)
    pos = np.ascontiguousarray(rng.normal(size=(3, n)))
    m = rng.uniform(0.1, 1.0, size=n) / n
    return pos, m


@pytest.mark.parametrize("n", [2, 5, 9, 63, 64, 130])
def test_small_and_buffered_paths_give_the_same_bits(n: int) -> None:
    pos, m = cloud(n)
    small = -G * d._potential_small(pos, m, EPS * EPS)
    buf = np.empty(d.TERM_BLOCK)
    buffered = -G * sum(d._potential_row_buffered(pos, m, EPS * EPS, i, buf) for i in range(n))
    assert small == buffered


@pytest.mark.parametrize("n", [400, 700])
def test_serial_and_parallel_give_the_same_bits_on_any_thread_count(n: int) -> None:
    pos, m = cloud(n)
    serial = d.potential_energy(pos, m, G, EPS * EPS, np.zeros(0))
    before = numba.get_num_threads()
    try:
        for threads in range(1, numba.config.NUMBA_NUM_THREADS + 1):
            numba.set_num_threads(threads)
            assert d.potential_energy(pos, m, G, EPS * EPS, d.potential_rows_scratch(n)) == serial
    finally:
        numba.set_num_threads(before)


@pytest.mark.parametrize("n", [3, 64, 400])
def test_potential_matches_the_reference(n: int) -> None:
    pos, m = cloud(n)
    got = d.potential_energy(pos, m, G, EPS * EPS, d.potential_rows_scratch(n))
    want = naive.potential_energy(pos.T, m, G, EPS)
    # Both sum the same N(N-1)/2 positive terms in different orders: a few ulp per term at most.
    assert abs(got - want) <= 1e-13 * abs(want)


@pytest.mark.parametrize("n", [5, 200, 400])
def test_each_force_context_compiles_one_path_with_the_serial_bits(n: int) -> None:
    """A sample's potential goes by the force context's kind (all pairs, serial rows, parallel rows:
    one path compiled per kind) and gives the serial kernel's bits; the parallel rows allocate their
    own scratch where a caller passes none."""
    from orbitsim.physics.force_context import kernel_class, make_force

    pos, m = cloud(n)
    serial = d.potential_energy(pos, m, G, EPS * EPS, np.zeros(0))
    force = make_force(G, EPS, n)
    assert kernel_class(numba.typeof(force)).__name__ == {5: "AllPairs", 200: "Rows", 400: "Blocks"}[n]
    assert d.potential_energy_at(force, pos, m, d.potential_rows_scratch(n)) == serial
    assert d._potential_parallel(pos, m, G, EPS * EPS, np.zeros(0)) == serial
