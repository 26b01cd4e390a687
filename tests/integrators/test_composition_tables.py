"""Identities of the composition coefficient tables in :mod:`orbitsim.integrators.leapfrog`.

A symmetric composition of the (symmetric, second-order) DKD leapfrog with weights w_1..w_s is
consistent when sum w = 1, symmetric when the weights are a palindrome, and of order p only if the
odd power sums vanish: sum w^k = 0 for k = 3, 5, ..., p - 1 (the coefficients of the leapfrog's
own error terms h^3, h^5, ... in the composed map). These are necessary conditions; the full set
(with nested commutators) is checked indirectly by the local order on a harmonic oscillator below
and by the convergence test on the Kepler problem (tests/integrators/test_convergence.py).
"""

from __future__ import annotations

import numpy as np
import pytest

from orbitsim.integrators import leapfrog
from orbitsim.integrators.leapfrog import (
    LEAPFROG,
    LEAPFROG2_WEIGHTS,
    LEAPFROG4,
    LEAPFROG4_WEIGHTS,
    LEAPFROG6,
    LEAPFROG6_WEIGHTS,
    LEAPFROG8,
    LEAPFROG8_WEIGHTS,
    drift_coefficients,
)

#: order -> (table, number of stages)
TABLES = {
    2: (LEAPFROG2_WEIGHTS, 1),
    4: (LEAPFROG4_WEIGHTS, 3),
    6: (LEAPFROG6_WEIGHTS, 9),
    8: (LEAPFROG8_WEIGHTS, 17),
}

#: The published coefficients carry ~16 significant digits; sums of <= 17 terms of size <= 1.4
#: then leave residuals of a few 1e-15 (measured: at most 2.3e-15).
TABLE_TOL = 1e-14


@pytest.mark.parametrize("order", sorted(TABLES))
def test_table_length(order: int) -> None:
    weights, stages = TABLES[order]
    assert weights.shape == (stages,)


@pytest.mark.parametrize("order", sorted(TABLES))
def test_weights_sum_to_one(order: int) -> None:
    weights, _ = TABLES[order]
    assert abs(weights.sum() - 1.0) < TABLE_TOL


@pytest.mark.parametrize("order", sorted(TABLES))
def test_weights_are_palindromic(order: int) -> None:
    weights, _ = TABLES[order]
    # Exact: the mirror half is built from the same floats, not retyped.
    assert np.array_equal(weights, weights[::-1])


@pytest.mark.parametrize("order", sorted(TABLES))
def test_drift_coefficients_sum_to_one_and_mirror(order: int) -> None:
    weights, stages = TABLES[order]
    drifts = drift_coefficients(weights)
    assert drifts.shape == (stages + 1,)
    assert abs(drifts.sum() - 1.0) < TABLE_TOL
    assert np.array_equal(drifts, drifts[::-1])
    # Each drift is the mean of its neighbouring kicks (half kicks at the ends).
    padded = np.concatenate([[0.0], weights, [0.0]])
    assert np.allclose(drifts, 0.5 * (padded[:-1] + padded[1:]), rtol=0, atol=1e-16)  # exact up to 1 ulp


@pytest.mark.parametrize("order", [4, 6, 8])
def test_odd_power_sums_vanish(order: int) -> None:
    weights, _ = TABLES[order]
    for k in range(3, order, 2):
        assert abs(np.sum(weights**k)) < TABLE_TOL, f"order {order}: sum w^{k} = {np.sum(weights**k):.3e}"
    # ... and the next one does not (else the table would claim too little, or the check is void).
    # Measured: sum w^5 = -5.29 (order 4), sum w^7 = 0.090 (order 6), sum w^9 = -9.9e-4 (order 8).
    assert abs(np.sum(weights**(order + 1))) > 1e-4


def test_leapfrog4_is_yoshidas_triple_jump() -> None:
    w1 = 1.0 / (2.0 - 2.0 ** (1.0 / 3.0))
    expected = np.array([w1, 1.0 - 2.0 * w1, w1])
    # The table is stored to 30 digits and rounded once; the closed form rounds in a few
    # operations: they agree to a few ulps of numbers of size ~1.7.
    assert np.allclose(LEAPFROG4_WEIGHTS, expected, rtol=0, atol=1e-15)
    assert abs(np.sum(LEAPFROG4_WEIGHTS**3)) < TABLE_TOL


def test_records_use_the_tables() -> None:
    for record, weights in (
        (LEAPFROG, LEAPFROG2_WEIGHTS),
        (LEAPFROG4, LEAPFROG4_WEIGHTS),
        (LEAPFROG6, LEAPFROG6_WEIGHTS),
        (LEAPFROG8, LEAPFROG8_WEIGHTS),
    ):
        assert np.array_equal(record.kicks, weights), record.spec.name
        assert np.array_equal(record.drifts, drift_coefficients(weights)), record.spec.name
        assert record.spec.force_evals == weights.shape[0], record.spec.name
    assert leapfrog.palindrome((1.0, 2.0, 3.0)).tolist() == [1.0, 2.0, 3.0, 2.0, 1.0]


def test_order_table_is_rebounds_leapfrog_order() -> None:
    """One leapfrog, four orders: the record of each order declares it, and REBOUND's ``order`` setting
    (:data:`orbitsim.integrators.rebound_names.LEAPFROG_ORDERS`) names the same records."""
    from orbitsim.integrators.rebound_names import LEAPFROG_ORDERS
    from orbitsim.integrators.registry import get_integrator

    assert sorted(leapfrog.ORDERS) == [2, 4, 6, 8]
    for order, record in leapfrog.ORDERS.items():
        assert record.spec.order == order
        assert get_integrator(LEAPFROG_ORDERS[order]) is record


def _composed_oscillator_map(weights: np.ndarray, h: float) -> np.ndarray:
    """The 2x2 map of the composed DKD leapfrog for x'' = -x over one step h."""
    total = np.eye(2)
    for w in weights:
        s = w * h
        half_drift = np.array([[1.0, 0.5 * s], [0.0, 1.0]])
        kick = np.array([[1.0, 0.0], [-s, 1.0]])
        total = half_drift @ kick @ half_drift @ total
    return total


#: order -> step sizes h for the local-error fit: errors stay between ~1e-1 and ~1e-12.
LOCAL_LADDERS = {
    2: 0.8 * 2.0 ** (-np.arange(8) / 2),
    4: 0.8 * 2.0 ** (-np.arange(8) / 2),
    6: 0.8 * 2.0 ** (-np.arange(8) / 2),
    8: 1.6 * 2.0 ** (-np.arange(7) / 2),
}


@pytest.mark.parametrize("order", sorted(TABLES))
def test_local_order_on_harmonic_oscillator(order: int) -> None:
    """One composed step differs from the exact rotation by O(h^(p+1)), independently of the engine."""
    weights, _ = TABLES[order]
    hs = LOCAL_LADDERS[order]
    errors = []
    for h in hs:
        exact = np.array([[np.cos(h), np.sin(h)], [-np.sin(h), np.cos(h)]])
        errors.append(np.max(np.abs(_composed_oscillator_map(weights, h) - exact)))
    errors = np.array(errors)
    assert np.all(errors > 1e-13), errors  # above the round-off of a 2x2 product chain
    slope = np.polyfit(np.log(hs), np.log(errors), 1)[0]
    # Local error order p + 1; the largest h sit slightly outside the asymptotic regime (measured
    # slopes 2.99, 5.00, 6.94, 8.81), and a wrong order is >= 2 off for a symmetric method.
    assert abs(slope - (order + 1)) < 0.3, f"order {order}: local slope {slope:.3f}"
