"""Axis specs: values, log spacing, groups of alternative keys, and every refusal."""

from __future__ import annotations

import numpy as np
import pytest

from orbitsim.stability.axes import MapSpecError, parse_axis

DOC = {"units": "nbody", "bodies": [{"name": "sun", "m": 1.0, "x": [0, 0, 0], "v": [0, 0, 0]},
                                    {"name": "b", "m": 1e-3, "primary": "sun", "P": 2.0, "e": 0.1, "f": 10}]}


def test_linear_and_log_values():
    assert np.array_equal(parse_axis("--x", "b.e=0:0.3:4", DOC).values, np.linspace(0, 0.3, 4))
    log = parse_axis("--x", "b.m=1e-6:1e-3:4", DOC, log=True)
    assert np.allclose(log.values, [1e-6, 1e-5, 1e-4, 1e-3], rtol=1e-12)  # geomspace's round-off
    assert log.log and log.index == 1


def test_setting_a_key_replaces_its_alternatives():
    axis = parse_axis("--x", "b.a=1:2:2", DOC)
    body = dict(DOC["bodies"][1])
    axis.apply(body, 1.5)
    assert body["a"] == 1.5 and "P" not in body
    anomaly = parse_axis("--y", "b.M=0:90:2", DOC)
    anomaly.apply(body, 45.0)
    assert body["M"] == 45.0 and "f" not in body


def test_a_log_axis_needs_a_positive_start():
    with pytest.raises(MapSpecError, match="needs LO > 0"):
        parse_axis("--x", "b.e=0:0.3:4", DOC, log=True)
