"""Every scheme against its slow numpy reference in ``tests/naive.py``: a few steps, tight tolerance.

The system has five massive bodies, softening and one zero-mass test body, so the test covers the
softened pair sum, the zero-mass path (feels gravity, exerts none) and each scheme's order of
drifts, kicks and force evaluations. A scheme that reused a stale acceleration, swapped a kick and
a drift, or mis-merged two drifts would differ at the 1e-3 level, not at 1e-13.

Wisdom-Holman, IAS15 and TRACE have no numpy reference here: each is REBOUND's scheme (its record
says so), and REBOUND, the code it ports, is its reference, compared step for step in the test named
in :data:`REBOUND_REFERENCED` (a numpy Wisdom-Holman or TRACE would need a second universal-variable
Kepler solver, and a numpy IAS15 a second predictor-corrector with its step control: copies of what
they would check). :func:`test_every_scheme_has_one_reference` holds the lists to the registry.
"""

from __future__ import annotations

from fractions import Fraction
from pathlib import Path

import naive
import numpy as np
import pytest

from orbitsim.integrators.registry import INTEGRATORS
from orbitsim.simulation import simulate

G = 1.0
EPS = 0.05
DT = 0.01
STEPS = 4

#: Schemes with a reference in naive.py.
REFERENCE_SCHEMES = tuple(naive.STEPS)
#: REBOUND's schemes: the test (under tests/) that holds each to REBOUND.
REBOUND_REFERENCED = {
    "wisdom_holman": "integrators/test_wisdom_holman.py::test_agrees_with_rebound_whfast_after_1000_steps",
    "ias15": "integrators/test_ias15.py::test_giants_agree_with_rebound_sample_by_sample",
    "trace": "integrators/test_trace_engine.py::test_orbitsim_run_is_rebounds_trace_bit_for_bit",
}
TESTS = Path(__file__).resolve().parents[1]


def five_bodies_and_a_test_body() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(20240611)
    m = np.array([1.0, 0.3, 0.02, 0.1, 0.005, 0.0])
    x = rng.uniform(-1.0, 1.0, size=(6, 3))
    v = rng.uniform(-0.5, 0.5, size=(6, 3))
    return m, x, v


def test_every_reference_scheme_is_registered() -> None:
    names = {spec.name for spec in INTEGRATORS}
    assert set(REFERENCE_SCHEMES) <= names


def test_every_scheme_has_one_reference() -> None:
    """Every registered scheme has a numpy reference here or is REBOUND's scheme with a named test
    against REBOUND: a new scheme fails here until it has one of the two."""
    by_name = {spec.name: spec for spec in INTEGRATORS}
    assert set(REFERENCE_SCHEMES) | set(REBOUND_REFERENCED) == set(by_name)
    assert not set(REFERENCE_SCHEMES) & set(REBOUND_REFERENCED)
    for name, test_id in REBOUND_REFERENCED.items():
        assert "REBOUND" in by_name[name].summary, name  # the record says whose scheme it is
        path, function = test_id.split("::")
        assert f"def {function}(" in (TESTS / path).read_text(encoding="utf-8"), test_id


@pytest.mark.parametrize("name", REFERENCE_SCHEMES)
def test_scheme_matches_naive_reference(name: str) -> None:
    m, x0, v0 = five_bodies_and_a_test_body()
    result = simulate(m, x0, v0, integrator=name, dt=DT, steps=STEPS, every=STEPS, G=G, softening=EPS)
    x_ref, v_ref = naive.run(name, x0, v0, m, G, EPS, DT, STEPS)
    # The engine's force sum is reassociated and uses Newton's third law (~4e-15 relative per
    # evaluation, docs/design.md#fast-kernels); a few steps keep that well below 1e-13.
    tol = 1e-13
    x_err = np.max(np.abs(result.final_positions - x_ref)) / np.max(np.abs(x_ref))
    v_err = np.max(np.abs(result.final_velocities - v_ref)) / np.max(np.abs(v_ref))
    assert x_err < tol, f"{name}: positions differ by {x_err:.2e} (relative)"
    assert v_err < tol, f"{name}: velocities differ by {v_err:.2e} (relative)"
    # And the run really moved the system (the test would be empty otherwise).
    assert np.max(np.abs(x_ref - x0)) > 1e-3


def test_references_differ_from_each_other() -> None:
    """Negative control: at dt = 0.05 every pair of references differs by far more than the 1e-13
    tolerance, so a registry entry wired to the wrong step function cannot pass the test above."""
    m, x0, v0 = five_bodies_and_a_test_body()
    finals = {name: naive.run(name, x0, v0, m, G, EPS, 0.05, STEPS)[0] for name in REFERENCE_SCHEMES}
    for a in REFERENCE_SCHEMES:
        for b in REFERENCE_SCHEMES:
            if a < b:
                diff = np.max(np.abs(finals[a] - finals[b])) / np.max(np.abs(finals[a]))
                # The closest pair, leapfrog6/leapfrog8, differs by the sixth-order local error
                # (~dt^7 ~ 1e-10 here): 100x the tolerance is a safe floor for every pair.
                assert diff > 1e-11, (a, b, diff)


def test_kicks_and_drifts_are_not_contracted_into_fma() -> None:
    """h*a + v must round the product before the sum (as numpy and REBOUND do), not fuse them.

    With h = a = 1 + 2^-30 and v = -(1 + 2^-29) the exact product is 1 + 2^-29 + 2^-60: rounded
    first it cancels v exactly (0.0); fused, the 2^-60 survives.
    """
    from orbitsim.integrators.base import drift, kick

    h = 1.0 + 2.0**-30
    start = -(1.0 + 2.0**-29)
    vel = np.full((3, 2), start)
    kick(vel, np.full((3, 2), h), h)
    assert np.all(vel == 0.0), vel
    pos = np.full((3, 2), start)
    drift(pos, np.full((3, 2), h), h)
    assert np.all(pos == 0.0), pos
    # The control is real: the exact h*h + v is 2^-60, which a fused multiply-add would return.
    assert Fraction(h) * Fraction(h) + Fraction(start) == Fraction(1, 2**60)
