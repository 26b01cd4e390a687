"""Sampling plans: produced block by block, they give the very steps of the whole-array construction."""

from __future__ import annotations

from collections.abc import Iterator

import naive
import numpy as np
import pytest

import orbitsim.simulation
from orbitsim.sampling import (
    BLOCK_SAMPLES,
    EveryPlan,
    ExplicitPlan,
    IntervalPlan,
    SamplePlan,
    SimulationError,
    sample_steps_every,
    sample_steps_interval,
)
from orbitsim.scenario import scenario_from_dict
from orbitsim.simulation import Simulation

EVERY_CASES = [(10, 3), (9, 3), (0, 5), (1, 1), (5, 1), (100, 100), (100, 101), (1000, 7), (3 * BLOCK_SAMPLES + 5, 1),
               (2 * BLOCK_SAMPLES, 2)]
INTERVAL_CASES = [
    # those of tests/integrators/test_registry.py, whose expected steps are derived there from the definition
    (1000, 0.1, 0.3), (1000, 0.1, 0.7), (997, 0.01, 0.0333), (500, 0.3, 0.1), (100, 1e-3, 0.01), (10, 0.7, 7.0),
    (0, 0.1, 0.3),  # no step at all: only step 0
    (10, 0.3, 1.0),  # the end time is not a sample time
    (10, 0.1, 100.0),  # one sample time, then the last step
    (1000, 0.1, 0.1),  # interval == dt
    (300, 0.1, 0.03),  # interval < dt: times collapse, every step sampled
    (200_000, 1e-3, 1e-3),  # more samples than a block
    (150_000, 0.01, 0.0037),  # a block boundary falls among collapsing times
]


def joined(blocks: Iterator[np.ndarray], size: int) -> np.ndarray:
    """The blocks joined, after checking each is a non-empty int64 array of at most ``size``."""
    parts = list(blocks)
    for block in parts:
        assert block.dtype == np.int64 and 0 < block.size <= size
    return np.concatenate([np.zeros(0, dtype=np.int64), *parts])


def check_plan(plan: SamplePlan, expected: np.ndarray) -> None:
    """Blocks of any size, counts and resumption points all agree with the whole array."""
    assert np.array_equal(plan.steps(), expected)
    assert plan.count() == expected.size
    small = (1, 3, 64) if expected.size < 5000 else (999,)  # tiny blocks of long plans take seconds
    for size in (*small, BLOCK_SAMPLES):
        assert np.array_equal(joined(plan.blocks(size), size), expected), size
    n = int(expected[-1])
    for after in sorted({-5, -1, 0, 1, n // 3, n // 2 + 1, n - 1, n, n + 4}):
        rest = plan.after_step(after)
        assert np.array_equal(joined(rest.blocks(small[-1]), small[-1]), expected[expected > after]), after
        assert rest.count() == np.count_nonzero(expected > after), after


@pytest.mark.parametrize(("n_steps", "every"), EVERY_CASES)
def test_every_plan_equals_the_whole_array(n_steps: int, every: int) -> None:
    expected = naive.sample_steps_every(n_steps, every)
    check_plan(EveryPlan(n_steps, every), expected)
    assert np.array_equal(sample_steps_every(n_steps, every), expected)


@pytest.mark.parametrize(("n_steps", "dt", "interval"), INTERVAL_CASES)
def test_interval_plan_equals_the_whole_array(n_steps: int, dt: float, interval: float) -> None:
    expected = naive.sample_steps_interval(n_steps, dt, interval)
    check_plan(IntervalPlan(n_steps, dt, interval), expected)
    assert np.array_equal(sample_steps_interval(n_steps, dt, interval), expected)


def test_random_interval_plans_equal_the_whole_array() -> None:
    rng = np.random.default_rng(20240611)
    for _ in range(60):
        n_steps = int(rng.integers(0, 5000))
        dt = float(10.0 ** rng.uniform(-4, 1))
        interval = dt * float(10.0 ** rng.uniform(-1.5, 2))
        expected = naive.sample_steps_interval(n_steps, dt, interval)
        plan = IntervalPlan(n_steps, dt, interval)
        assert np.array_equal(joined(plan.blocks(61), 61), expected), (n_steps, dt, interval)
        after = int(rng.integers(-1, n_steps + 1))
        assert np.array_equal(plan.after_step(after).steps(), expected[expected > after]), (n_steps, dt, after)


@pytest.mark.parametrize(
    "output",
    [{"every": 3}, {"every": 1}, {"interval": 0.25}, {"interval": 0.007}, {}],
)
@pytest.mark.parametrize("length", [{"steps": 997}, {"t_end": 10.0}, {"t_end": 9.996}, {"t_end": 0.05}])
def test_scenario_plans_equal_the_whole_array(output: dict, length: dict) -> None:
    doc = {"name": "s", "integrator": "verlet", "dt": 0.01, **length, "output": output,
           "bodies": [{"name": "a", "m": 1.0, "x": [0, 0, 0], "v": [0, 0, 0]},
                      {"name": "b", "m": 1e-3, "x": [1, 0, 0], "v": [0, 1, 0]}]}
    s = scenario_from_dict(doc)
    if s.interval is None:
        expected = naive.sample_steps_every(s.steps, int(s.sample_every))
    else:
        expected = naive.sample_steps_interval(s.steps, s.dt, s.interval)
    check_plan(s.sample_plan(), expected)
    assert np.array_equal(s.sample_steps(), expected)


def test_long_plans_stay_in_bounded_blocks() -> None:
    """10^7 samples never need more than one block at a time."""
    assert EveryPlan(10**7, 1).count() == 10**7 + 1
    sizes = [block.size for block in EveryPlan(10**7, 1).blocks()]
    assert max(sizes) == BLOCK_SAMPLES and sum(sizes) == 10**7 + 1
    plan = IntervalPlan(10**6, 1e-3, 1e-3)
    assert max(block.size for block in plan.blocks()) <= BLOCK_SAMPLES
    assert plan.count() == 10**6 + 1


def test_invalid_plans_are_refused() -> None:
    with pytest.raises(SimulationError, match="every must be >= 1"):
        EveryPlan(10, 0)
    for interval in (0.0, -1.0, float("nan"), float("inf")):
        with pytest.raises(SimulationError, match="interval must be a positive number"):
            IntervalPlan(10, 0.1, interval)
    with pytest.raises(SimulationError, match="must increase"):
        ExplicitPlan(np.array([0, 5, 5]))


class SmallBlocks(SamplePlan):
    """A plan whose blocks are tiny, so that one call's targets span several of them."""

    def __init__(self, plan: SamplePlan, size: int) -> None:
        self.plan, self.size, self.after = plan, size, plan.after

    def blocks(self, size: int = BLOCK_SAMPLES) -> Iterator[np.ndarray]:
        return self.plan.blocks(self.size)


def run_chunks(plan: SamplePlan | np.ndarray) -> list:
    m = np.array([1.0, 1e-3, 1e-4])
    x = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, -1.5, 0.1]])
    v = np.array([[0.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.8, 0.0, 0.0]])
    return list(Simulation(m, x, v, "verlet", 0.01).chunks(plan, record_positions=True))


@pytest.mark.parametrize("block", [1, 2, 3, 7, 1000])
def test_calls_are_cut_as_with_the_whole_array(block: int, monkeypatch: pytest.MonkeyPatch) -> None:
    """Whatever the block size, each call gets the targets it would get from the whole array."""
    # 5 samples a call (with positions of 3 bodies, 224 bytes a sample); the first call's step
    # budget (2e5 / N^2 = 22222 steps) covers the run, so the cut does not depend on timing.
    monkeypatch.setattr(orbitsim.simulation, "MAX_BUFFER_BYTES", 5 * 224)
    plan = IntervalPlan(300, 0.01, 0.023)
    whole = run_chunks(naive.sample_steps_interval(300, 0.01, 0.023))
    lazy = run_chunks(SmallBlocks(plan, block))
    assert [len(c) for c in lazy] == [len(c) for c in whole] == [5] * 26 + [2]
    for name in ("step", "time", "kinetic", "potential", "momentum", "positions", "velocities"):
        assert np.array_equal(np.concatenate([getattr(c, name) for c in lazy]),
                              np.concatenate([getattr(c, name) for c in whole])), name


def test_a_plan_behind_the_state_is_refused() -> None:
    m = np.array([1.0, 1e-3])
    x = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    v = np.array([[0.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    sim = Simulation(m, x, v, "verlet", 0.01)
    list(sim.chunks(EveryPlan(20, 5), record_positions=False))
    with pytest.raises(SimulationError, match="at or after the current step"):
        list(sim.chunks(EveryPlan(40, 5), record_positions=False))
    chunks = list(sim.chunks(EveryPlan(40, 5).after_step(sim.steps_done), record_positions=False))
    assert np.concatenate([c.step for c in chunks]).tolist() == [25, 30, 35, 40]
