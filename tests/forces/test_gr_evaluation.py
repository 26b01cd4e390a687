"""gr's two ways of evaluating at prepared positions, and the prepared work's cache (orbitsim/forces/gr.py).

The implicit midpoint's evaluation (:func:`gr_operator_accelerations`) solves v~ for every Jacobi
coordinate at once; IAS15's (:func:`gr_accelerations_prepared`, through ``gr_accelerations``) one
coordinate after another. Each coordinate's operations are the same in both, so the two must agree bit
for bit, whatever the number of iterations each coordinate needs. The operator's cache
(:func:`gr_prepare_once`) must hand back exactly what a fresh :func:`gr_prepare` makes, and prepare anew
when anything it depends on changed: a position (a sign of zero included), a mass, G or the source.
"""

from __future__ import annotations

import numpy as np
import pytest

from orbitsim.forces.gr import (
    GR_CACHE_ROWS,
    GR_WORK_ROWS,
    gr_accelerations_prepared,
    gr_operator_accelerations,
    gr_prepare,
    gr_prepare_once,
)


def _system(n: int, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    m = np.concatenate([[1.0], 10.0 ** rng.uniform(-7, -3, n - 1)])
    pos = rng.normal(0.0, 3.0, (3, n))
    vel = rng.normal(0.0, 0.5, (3, n))
    return m, pos, vel


@pytest.mark.parametrize("n", [2, 3, 5, 9])
@pytest.mark.parametrize("c", [3.0, 30.0, 1e4])  # v/c from 0.2 to 5e-5: 1 to 10 iterations, per coordinate
@pytest.mark.parametrize("src", [0, 1])
def test_the_operators_evaluation_is_the_one_at_a_time_solve_bit_for_bit(n, c, src):
    for seed in range(4):
        m, pos, vel = _system(n, seed)
        work = np.zeros((GR_WORK_ROWS, n))
        gr_prepare(pos, m, 1.0, src, work)
        one, every = np.zeros((3, n)), np.zeros((3, n))
        gr_accelerations_prepared(vel, m, 1.0, src, c, one, work)
        gr_operator_accelerations(vel, m, 1.0, src, c, every, work)
        assert np.max(np.abs(one)) > 0.0
        assert one.tobytes() == every.tobytes()


def _fresh(pos, m, G, src):
    work = np.zeros((GR_WORK_ROWS, pos.shape[1]))
    gr_prepare(pos, m, G, src, work)
    return work


def test_the_prepared_work_cache_prepares_again_when_its_inputs_change():
    m, pos, _ = _system(5, 7)
    cache = np.zeros((GR_CACHE_ROWS, 5))
    filled = gr_prepare_once(pos, m, 1.0, 0, cache).copy()
    assert filled.tobytes() == _fresh(pos, m, 1.0, 0).tobytes()
    stale = cache.copy()
    assert gr_prepare_once(pos, m, 1.0, 0, cache).tobytes() == filled.tobytes()  # the same inputs: reused
    assert cache.tobytes() == stale.tobytes()
    moved = pos.copy()
    moved[2, 3] = np.nextafter(moved[2, 3], np.inf)  # one ulp of one coordinate
    heavier = m.copy()
    heavier[2] *= 2.0
    zero, negative_zero = pos.copy(), pos.copy()
    zero[1, 4], negative_zero[1, 4] = 0.0, -0.0
    for p, mass, G, src in ((moved, m, 1.0, 0), (pos, heavier, 1.0, 0), (pos, m, 2.0, 0), (pos, m, 1.0, 2),
                            (zero, m, 1.0, 0), (negative_zero, m, 1.0, 0), (zero, m, 1.0, 0)):
        got = gr_prepare_once(p, mass, G, src, cache)
        assert got.tobytes() == _fresh(p, mass, G, src).tobytes()
        assert cache[GR_WORK_ROWS:GR_WORK_ROWS + 3].tobytes() == p.tobytes()  # the key is what it was made for
