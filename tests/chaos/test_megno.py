"""MEGNO's running sums are REBOUND's: transcribed C, rescaling that moves no bit, REBOUND's own numbers."""

from __future__ import annotations

import numpy as np

from orbitsim.chaos.megno import (
    deltad_delta,
    lyapunov,
    megno_start,
    megno_update,
    megno_value,
    random_initial_variation,
    rescale_power_of_two,
)


def _rebound_update(s: dict, t: float, dY: float, dt: float) -> None:
    """``reb_tools_megno_update`` line by line, in Python floats."""
    s["Ys"] += dY
    Y = s["Ys"] / (t - s["t0"])
    s["Yss"] += Y * dt
    s["n"] += 1
    s["mean_t"] += (t - s["t0"] - s["mean_t"]) / float(s["n"])
    megno = s["Yss"] / (t - s["t0"])
    s["mean_Y"] += (megno - s["mean_Y"]) / float(s["n"])
    s["cov"] += (float(s["n"]) - 1.0) / float(s["n"]) * (t - s["t0"] - s["mean_t"]) * (megno - s["mean_Y"])
    s["var"] += (float(s["n"]) - 1.0) / float(s["n"]) * (t - s["t0"] - s["mean_t"]) * (t - s["t0"] - s["mean_t"])


def test_update_is_rebounds_bit_for_bit() -> None:
    rng = np.random.default_rng(5)
    t0, dt = 3.0, 0.01
    ref = {"Ys": 0.0, "Yss": 0.0, "n": 0, "mean_t": 0.0, "mean_Y": 0.0, "cov": 0.0, "var": 0.0, "t0": t0}
    state = megno_start(t0)
    t = t0
    for _ in range(500):
        t += dt
        dY = 2 * dt * (t - t0) * rng.normal(0.5, 0.1)
        state = megno_update(state, t, dY, dt)
        _rebound_update(ref, t, dY, dt)
    assert state.ys == ref["Ys"] and state.yss == ref["Yss"] and state.n == ref["n"]
    assert state.cov_yt == ref["cov"] and state.var_t == ref["var"]
    assert megno_value(state, t) == ref["Yss"] / (t - t0)
    assert lyapunov(state) == ref["cov"] / ref["var"]
    assert megno_value(megno_start(t0), t0) == 0.0 and lyapunov(megno_start(t0)) == 0.0


def test_growth_rate_is_recovered_as_the_slope() -> None:
    # delta growing as exp(lam t): (delta'.delta)/(delta.delta) = lam, <Y> -> lam t / 2 and the slope -> lam / 2
    lam, dt = 0.3, 1e-3
    state = megno_start(0.0)
    t = 0.0
    for _ in range(20000):
        t += dt
        state = megno_update(state, t, 2 * dt * t * lam, dt)
    # the slope of <Y> = lam t / 2 - lam dt / 4: discretisation only, 1e-3 relative
    assert abs(lyapunov(state) - lam / 2) < 1e-3 * lam


def test_rescaling_moves_no_bit_of_the_ratio() -> None:
    rng = np.random.default_rng(2)
    dpos, dvel, dacc = (rng.standard_normal((3, 4)) * 2.0**300 for _ in range(3))
    before = deltad_delta(dpos, dvel, dacc / 2.0**300)
    halvings = rescale_power_of_two(dpos, dvel)
    assert halvings == 1
    # dacc is linear in dpos: scale it the same way
    after = deltad_delta(dpos, dvel, dacc / 2.0**300 * 2.0**-200)
    assert after == before
    assert rescale_power_of_two(dpos, dvel) == 0


def test_random_variation_has_unit_norm_per_body_and_is_seeded() -> None:
    dpos, dvel = random_initial_variation(5, seed=7)
    norms = np.sqrt(np.sum(dpos**2, axis=0) + np.sum(dvel**2, axis=0))
    assert np.allclose(norms, 1.0, rtol=1e-15)  # one division by a square root: round-off
    again = random_initial_variation(5, seed=7)
    assert np.array_equal(again[0], dpos) and np.array_equal(again[1], dvel)
    assert not np.array_equal(random_initial_variation(5, seed=8)[0], dpos)
