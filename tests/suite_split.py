"""Which cases of a parametrized test run in ``make test`` and which wait for ``make test-slow``.

``make test`` is the loop to run after a change, meant to take five minutes on a fresh clone (an empty Numba
cache, two cores; 9:45 measured at this split): there each
property is checked on the cases that compile little, and the cases that each compile a kernel family of
their own (tens of seconds cold) run in ``make test-slow``, which CI runs too.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

import pytest


def fast_only(values: Iterable[Any], fast: Iterable[Any]) -> list[Any]:
    """``values`` as parametrize cases, those not in ``fast`` marked slow (kept, run by ``make test-slow``)."""
    keep = list(fast)
    cases = list(values)
    missing = [f for f in keep if f not in cases]
    if missing:
        raise ValueError(f"fast cases {missing} are not among the cases {cases}")
    return [v if v in keep else pytest.param(v, marks=pytest.mark.slow) for v in cases]
