"""Whole Wisdom-Holman systems with their variational equations in SIMD lanes (orbitsim.ensemble.system_tangent_lanes)
against the scalar kernel (run_ensemble_variational), bit for bit: statuses, steps, every indicator, final states."""

from __future__ import annotations

import functools
from pathlib import Path

import h5py
import numpy as np
import pytest
from click.testing import CliRunner
from ensemble_helpers import assert_same_bits, by_thread_count, giants_systems, stopping_group

import orbitsim.ensemble
import orbitsim.ensemble.system_tangent_lanes as tangent_lanes
from orbitsim.chaos.megno import RESCALE_ABOVE
from orbitsim.cli.main import cli
from orbitsim.ensemble import run_ensemble
from orbitsim.ensemble.kernels import run_ensemble_variational
from orbitsim.ensemble.run import prepare_systems
from orbitsim.ensemble.status import COLLIDED, COMPLETE, DIVERGED, ESCAPED, LYAPUNOV, MEGNO, N_COLUMNS
from orbitsim.ensemble.system_lanes import LANES
from orbitsim.integrators.wisdom_holman.tangent import TANGENT_SCRATCH_ROWS
from orbitsim.physics.force_context import make_force
from orbitsim.physics.kepler_solver import setup_short

# `make test-slow` only: the lanes kernels and their scalar reference compile for ~80 s cold.
pytestmark = pytest.mark.slow

DT = 0.5
N_STEPS = 100


def _variation(k: int, n: int, seed: int = 1) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    return rng.standard_normal((k, 3, n)), rng.standard_normal((k, 3, n))


def _both(masses, pos, vel, **kwargs):
    """The lanes' result, after checking that it is the scalar kernel's bits (whole systems: shared_massive off,
    though none of these systems has a massless last body anyway)."""
    lanes = run_ensemble(masses, pos, vel, shared_massive=False, **kwargs)
    scalar = run_ensemble(masses, pos, vel, shared_massive=False, lanes=False, **kwargs)
    assert_same_bits(lanes, scalar)
    return lanes


@pytest.mark.parametrize(("k", "n", "watch"), [(20, 4, 1), (16, 2, 1), (5, 5, 3)])
def test_lanes_give_the_bits_of_the_scalar_kernel(k, n, watch):
    """Ordinary systems: 20 make a full group and a padded one; two-body systems have no pair to kick and only
    the (0, 1) pair in MEGNO's read; five bodies, another watched body, one group mostly padding."""
    masses, pos, vel = giants_systems(k, n)
    masses[:, 1] *= 1.0 + 0.1 * np.arange(k) / k  # masses, weights and Kepler parameters differ per lane too
    result = _both(masses, pos, vel, G=1.0, dt=DT, n_steps=N_STEPS, watch=watch, variation=_variation(k, n))
    assert (result.status == COMPLETE).all() and (result.steps == N_STEPS).all()
    assert np.isfinite(result.indicators[:, MEGNO]).all() and (result.indicators[:, MEGNO] > 0.0).all()
    assert np.isfinite(result.indicators[:, LYAPUNOV]).all()


def test_systems_that_stop_at_different_steps_stop_alone_with_the_scalar_kernels_bits():
    """One group: systems that escape and collide, each at a step of its own, and diverge (a drift that fails at
    once; a body so massive that the first kick overflows, so the second half drift fails), beside systems that
    run to the end, one with a tangent vector rescaled."""
    k = LANES
    masses, pos, vel, radii = stopping_group(k)
    dpos, dvel = _variation(k, 4)
    dpos[10] *= 2.0 ** 505  # |delta|^2 above 2^400 from the first step on: rescaled by 2^-200 twice
    dvel[10] *= 2.0 ** 505
    result = _both(masses, pos, vel, G=1.0, dt=DT, n_steps=300, escape_distance=60.0, radii=radii,
                   variation=(dpos, dvel))
    steps = {code: set(result.steps[result.status == code].tolist()) for code in (ESCAPED, COLLIDED, DIVERGED)}
    assert len(steps[ESCAPED]) == 3 and len(steps[COLLIDED]) == 3 and steps[DIVERGED] == {1}, steps
    assert min(steps[ESCAPED] | steps[COLLIDED]) > 1  # stopped after steps the others took too
    assert (result.status == COMPLETE).sum() == k - 8
    assert (result.steps[result.status == COMPLETE] == 300).all()
    assert result.status[10] == COMPLETE and np.isfinite(result.indicators[10, MEGNO])


def test_systems_that_diverge_at_steps_of_their_own():
    """Without an escape distance a massive Uranus flings the others to non-finite states: with m = 1e200 in the
    first step, with m = 1e140 in the second (its first leaves them finite and far); one padded group."""
    masses, pos, vel = giants_systems(5)
    masses[1, 3], masses[3, 3] = 1e200, 1e140
    result = _both(masses, pos, vel, G=1.0, dt=DT, n_steps=N_STEPS, variation=_variation(5, 4))
    assert result.status.tolist() == [COMPLETE, DIVERGED, COMPLETE, DIVERGED, COMPLETE]
    assert result.steps.tolist() == [N_STEPS, 1, N_STEPS, 2, N_STEPS]


def _kernels(masses, pos, vel, dpos, dvel, n_steps):
    """Both kernels called as run_ensemble calls them, on copies of the tangent vectors, which each leaves with
    every system's last tangent vector: ``{lanes: (dpos, dvel, indicators)}``."""
    out = {}
    for lanes in (True, False):
        m, p, v, radii, _, weights, mu = prepare_systems(masses, pos, vel, G=1.0, dt=DT, n_steps=n_steps,
                                                         escape_distance=np.inf, radii=None, watch=1)
        k, n = m.shape
        dp, dv = dpos.copy(), dvel.copy()
        status, steps, cols = np.zeros(k, dtype=np.int64), np.zeros(k, dtype=np.int64), np.zeros((k, N_COLUMNS))
        force = make_force(1.0, 0.0, n)
        rest = (DT, 0.0, np.int64(n_steps), np.inf, radii, False, np.int64(1), weights, mu,
                np.zeros((k, TANGENT_SCRATCH_ROWS, 3, n)), np.zeros(0), status, steps, cols)
        if lanes:
            tangent_lanes.run_ensemble_variational_lanes(p, v, dp, dv, m, force.G, force.eps2, *rest)
        else:
            run_ensemble_variational(p, v, dp, dv, m, force, *rest)
        out[lanes] = (dp, dv, cols)
    return out


def test_a_rescaled_lane_leaves_the_scalar_kernels_tangent_vector_and_indicators():
    """Lanes 1 and 3 start with the tangent vector of lanes 0 and 2 times 2^505 and 2^199.75 (just under the
    bar, which it crosses as it grows): both are rescaled as the scalar kernel rescales them (the same last
    tangent vectors, bit for bit), and an exact power-of-two rescaling moves no bit of MEGNO or the mLCE."""
    k = 4
    masses, pos, vel = giants_systems(k)
    pos[:] = pos[0]  # four copies of one system
    dpos, dvel = _variation(1, 4)
    dpos, dvel = np.repeat(dpos, k, axis=0), np.repeat(dvel, k, axis=0)
    norm = np.sqrt((dpos[0] ** 2).sum() + (dvel[0] ** 2).sum())
    scales = (1.0, 2.0 ** 505, 1.0, 2.0 ** 199.75 / norm)
    for lane, scale in enumerate(scales):
        dpos[lane] *= scale
        dvel[lane] *= scale
    runs = _kernels(masses, pos, vel, dpos, dvel, 200)
    (ldp, ldv, lcols), (sdp, sdv, scols) = runs[True], runs[False]
    assert ldp.tobytes() == sdp.tobytes() and ldv.tobytes() == sdv.tobytes() and lcols.tobytes() == scols.tobytes()
    final2 = (ldp ** 2).sum(axis=(1, 2)) + (ldv ** 2).sum(axis=(1, 2))
    assert final2[1] == final2[0] * 2.0 ** (2 * (505 - 400))  # rescaled twice, by 2^-200 each time: exact
    # lane 3 crossed the bar after its start and was rescaled once (its scale is no power of two: its vector is
    # lane 2's times it to round-off, a relative 1e-9 far above 200 steps' rounding)
    assert final2[3] == pytest.approx(final2[2] * scales[3] ** 2 * 2.0 ** -400, rel=1e-9)
    assert final2[3] <= RESCALE_ABOVE < final2[2] * scales[3] ** 2
    assert lcols[1, MEGNO] == lcols[0, MEGNO] and lcols[1, LYAPUNOV] == lcols[0, LYAPUNOV]


def test_a_lane_outside_the_vector_drift_takes_the_scalar_drift_and_keeps_its_bits():
    """Uranus so close to the Sun in two systems (one per group) that half a step is longer than half its
    period: those lanes are drifted by kepler_drift_tangent beside lanes that stay on the vector path."""
    k = 20
    masses, pos, vel = giants_systems(k)
    close = [5, 17]
    for i in close:
        pos[i, :, 3] = pos[i, :, 0] + np.array([0.05, 0.0, 0.0])
        vel[i, :, 3] = vel[i, :, 0] + np.array([0.0, 1.0 / np.sqrt(0.05), 0.0])
    assert not setup_short(0.05, 1.0 / 0.05, 0.0, 1.0, 0.5 * DT)[4]  # the vector path refuses it
    result = _both(masses, pos, vel, G=1.0, dt=DT, n_steps=N_STEPS, variation=_variation(k, 4))
    assert (result.status[close] == COMPLETE).all()  # they ran the whole way on the scalar drift


def test_no_steps_and_one_step():
    masses, pos, vel = giants_systems(3)
    for n_steps in (0, 1):
        result = _both(masses, pos, vel, G=1.0, dt=DT, n_steps=n_steps, variation=_variation(3, 4))
        assert (result.steps == n_steps).all()
        assert (result.indicators[:, MEGNO] == 0.0).all() == (n_steps == 0)  # MEGNO is 0 at the start time


def test_lane_bits_do_not_depend_on_chunking_or_threads():
    k = 20
    masses, pos, vel = giants_systems(k)
    vel[3, :, 3] *= 3.0  # one escapes
    dpos, dvel = _variation(k, 4)
    kwargs = {"G": 1.0, "dt": DT, "n_steps": 300, "escape_distance": 60.0}
    whole = run_ensemble(masses, pos, vel, variation=(dpos, dvel), **kwargs)
    assert whole.status[3] == ESCAPED
    parts = [run_ensemble(masses[i:j], pos[i:j], vel[i:j], variation=(dpos[i:j], dvel[i:j]), **kwargs)
             for i, j in ((0, 3), (3, 20))]
    for name in ("status", "steps", "indicators", "pos", "vel"):
        assert getattr(whole, name).tobytes() == np.concatenate([getattr(p, name) for p in parts]).tobytes()
    runs = by_thread_count(lambda: run_ensemble(masses, pos, vel, variation=(dpos, dvel), **kwargs))
    for other in runs.values():
        assert_same_bits(whole, other)


SCENARIO = """\
name: massive_axis
units: nbody
integrator: wisdom_holman
dt: 0.5
t_end: 40
bodies:
  - {name: sun, m: 1.0, x: [0, 0, 0], v: [0, 0, 0]}
  - {name: jupiter, m: 0.000954791915, primary: sun, a: 5.2, e: 0.048, M: 10}
  - {name: saturn, m: 0.000285885672, primary: sun, a: 9.54, e: 0.054, M: 200, inc: 2.5}
  - {name: planet, m: 0, primary: sun, a: 7.0, e: 0.1, M: 30}
"""


def test_a_map_over_a_massive_bodys_mass_has_the_scalar_kernels_bits(tmp_path: Path, monkeypatch):
    """``orbitsim map --x jupiter.m=...``: every pixel's massive bodies differ, so the map runs whole systems,
    in the lanes (the kernel is called) and with run_ensemble(lanes=False) gives the same map.h5 bits."""
    scenario = tmp_path / "s.yaml"
    scenario.write_text(SCENARIO, encoding="utf-8")
    args = ["map", str(scenario), "--x", "jupiter.m=0.0005:0.004:3", "--y", "planet.e=0:0.3:2", "--t-end", "40",
            "--quiet"]
    calls = []
    original = tangent_lanes.run_ensemble_variational_lanes

    def counted(*a):
        calls.append((a[0].shape[0], int(a[9])))  # (systems, steps)
        return original(*a)

    monkeypatch.setattr(tangent_lanes, "run_ensemble_variational_lanes", counted)
    assert CliRunner().invoke(cli, [*args, "-o", str(tmp_path / "lanes")]).exit_code == 0
    # the map readies its kernels with chunk 0's pixels for no step, then every pixel runs in the lanes
    assert calls == [(6, 0), (6, 80)]
    monkeypatch.setattr(orbitsim.ensemble, "run_ensemble", functools.partial(run_ensemble, lanes=False))
    assert CliRunner().invoke(cli, [*args, "-o", str(tmp_path / "scalar")]).exit_code == 0
    assert len(calls) == 2  # the scalar kernel ran this one
    grids = []
    for name in ("lanes", "scalar"):
        with h5py.File(tmp_path / name / "map.h5", "r") as f:
            grids.append({key: f["indicators"][key][()].tobytes() for key in f["indicators"]}
                         | {"status": f["status"][()].tobytes(), "stop_time": f["stop_time"][()].tobytes()})
    assert grids[0] == grids[1]
    assert len(grids[0]) == 8  # the six indicators, the status and the stop time
