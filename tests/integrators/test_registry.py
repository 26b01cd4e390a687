"""The integrator registry as a whole: every registered scheme, whatever it is, must pass these.

Loops over :data:`orbitsim.integrators.registry.INTEGRATORS`, so a newly registered scheme is
checked without editing this file. Scheme-specific physics lives in the other test files.
"""

from __future__ import annotations

import importlib
import math
import re
import subprocess
import sys
from dataclasses import fields
from pathlib import Path

import numpy as np
import pytest

from orbitsim.bench.systems import planets
from orbitsim.integrators.base import Integrator, IntegratorSpec, Setting
from orbitsim.integrators.registry import (
    INTEGRATORS,
    NAMES,
    RECORDS,
    SCHEMES,
    UnknownIntegratorError,
    canonical_name,
    get_integrator,
    get_spec,
    valid_names,
)
from orbitsim.simulation import Simulation, sample_steps_every, sample_steps_interval, simulate

#: The orders the issue's table declares for the schemes it lists.
DECLARED_ORDERS = {
    "euler": 1,
    "semi_implicit_euler": 1,
    "verlet": 2,
    "leapfrog": 2,
    "rk4": 4,
    "leapfrog4": 4,
    "leapfrog6": 6,
    "leapfrog8": 8,
}

SPEC_IDS = [spec.name for spec in INTEGRATORS]


def star_and_two_planets() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A hierarchical system (dominant body first) every kind of scheme can take: m, x, v (N, 3)."""
    m = np.array([1.0, 1e-3, 2e-4])
    x = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.7, 0.02]])
    v = np.array([[0.0, 0.0, 0.0], [0.0, 1.0, 0.01], [-1.0 / np.sqrt(1.7), 0.0, 0.0]])
    v[0] = -(m[1:, None] * v[1:]).sum(axis=0) / m[0]
    return m, x, v


def test_registry_is_not_empty_and_consistent() -> None:
    assert len(INTEGRATORS) == len(RECORDS) >= len(DECLARED_ORDERS)
    for record, spec in zip(RECORDS, INTEGRATORS, strict=True):
        assert record.spec is spec
        assert getattr(importlib.import_module(spec.module), spec.name.upper()) is record


@pytest.mark.parametrize("spec", INTEGRATORS, ids=SPEC_IDS)
def test_spec_is_complete(spec: IntegratorSpec) -> None:
    assert spec.name and spec.name == spec.name.strip().lower()
    assert len(spec.summary) > 10
    assert len(spec.reference) > 10
    assert isinstance(spec.order, int) and spec.order >= 1
    assert isinstance(spec.force_evals, int) and spec.force_evals >= 1
    assert spec.work_slots >= 0
    assert isinstance(spec.symplectic, bool) and isinstance(spec.reversible, bool)
    assert spec.names == (spec.name, *spec.aliases)


def test_names_and_aliases_are_unique() -> None:
    every = [name for spec in INTEGRATORS for name in spec.names]
    assert len(every) == len(set(every)), sorted(n for n in every if every.count(n) > 1)
    assert set(valid_names()) == set(every)


@pytest.mark.parametrize("spec", INTEGRATORS, ids=SPEC_IDS)
def test_every_name_and_alias_resolves(spec: IntegratorSpec) -> None:
    for name in spec.names:
        variants = {name, name.upper(), name.title(), name.replace("_", "-"), f"  {name} "}
        for variant in variants:
            assert get_spec(variant) is spec, variant
            assert canonical_name(variant) == spec.name


def test_documented_spellings() -> None:
    assert canonical_name("Velocity-Verlet") == "verlet"
    assert canonical_name("KDK") == "verlet"
    assert canonical_name("Symplectic-Euler") == "semi_implicit_euler"


@pytest.mark.parametrize("spec", INTEGRATORS, ids=SPEC_IDS)
def test_every_record_has_step_run_and_run_watched(spec: IntegratorSpec) -> None:
    """``run_watched`` is what a run with ``events:`` calls (orbitsim.events.kernels)."""
    record = get_integrator(spec.name)
    assert callable(record.step)
    assert callable(record.run)
    assert callable(record.run_watched)


#: Every hook of the record (orbitsim.integrators.base's numbered contract) that is a function.
HOOKS = ("step", "run", "run_watched", "validate_settings", "make_work", "carry_over", "check_bodies", "clock_time",
         "failure_message", "counters", "take_merges", "handoff", "check_chaos", "make_tangent")


def test_the_record_declares_every_hook() -> None:
    """The record's fields are the contract: the hooks, the settings, the run constants and the tables."""
    declared = {f.name for f in fields(Integrator)}
    assert declared == {"spec", *HOOKS, "settings", "run_constants", "kicks", "drifts", "run_chaos"}


@pytest.mark.parametrize("spec", INTEGRATORS, ids=SPEC_IDS)
def test_run_chaos_is_declared_or_none_and_the_defaults_have_variations(spec: IntegratorSpec) -> None:
    """``run_chaos`` (contract item 17) is a jitted loop or None; a scheme that has one has variational
    equations with its default settings (tests/chaos/test_chaos_contract.py runs each of them)."""
    record = get_integrator(spec.name)
    if record.run_chaos is None:
        return
    assert callable(record.run_chaos)
    assert record.check_chaos(record.default_settings()) is None
    # item 19: whatever the scheme's tangent record, it holds copies of the vector and the halvings count
    dpos, dvel = np.arange(6.0).reshape(3, 2), -np.arange(6.0).reshape(3, 2)
    tangent = record.make_tangent(dpos, dvel, 3)
    assert np.array_equal(tangent.dpos, dpos) and np.array_equal(tangent.dvel, dvel)
    assert not np.shares_memory(tangent.dpos, dpos) and not np.shares_memory(tangent.dvel, dvel)
    assert tangent.halvings.dtype == np.int64 and tangent.halvings.tolist() == [3]


@pytest.mark.parametrize("spec", INTEGRATORS, ids=SPEC_IDS)
def test_every_scheme_fits_the_record(spec: IntegratorSpec) -> None:
    """Every registered scheme is a record whose hooks all answer on a fresh work, with one settings shape:
    a doc string per setting, defaults that its own validation returns unchanged, and choices it accepts."""
    record = get_integrator(spec.name)
    assert isinstance(record, Integrator) and record.spec is spec
    for hook in HOOKS:
        assert callable(getattr(record, hook)), hook
    for key, setting in record.settings.items():
        assert isinstance(setting, Setting) and key == key.strip().lower(), key
        assert len(setting.doc) > 20 and "\n" not in setting.doc, key
        if setting.choices:
            assert setting.default in setting.choices, key
            for choice in setting.choices:
                assert record.validate_settings({key: choice})[key] == choice, (key, choice)
    assert record.validate_settings({}) == record.default_settings()
    assert record.validate_settings({"name": spec.name}) == record.default_settings()
    with pytest.raises(ValueError, match="no_such_setting"):
        record.validate_settings({"no_such_setting": 1})
    m, _, _ = star_and_two_planets()
    record.check_bodies(m)
    work = record.make_work(m, 1.0, {})
    fresh = record.make_work(m, 1.0, record.default_settings())
    record.carry_over(work, fresh)
    assert record.clock_time(work, 0.25) == 0.25  # nothing stepped: the grid's time
    assert record.failure_message(work) is None
    counters = record.counters(work)
    assert counters is None or (counters and all(value == 0 for key, value in counters.items() if key != "dt_next"))
    merges = record.take_merges(work)
    assert merges is None or len(merges[0]) == 0
    handoff = record.handoff(work)
    assert handoff is None or len(handoff) == 3
    for index in record.run_constants:
        assert isinstance(work, tuple) and 0 <= index < len(work)
    assert (record.kicks is None) == (record.drifts is None)
    if record.kicks is not None:
        assert record.kicks.shape[0] == spec.force_evals and record.drifts.shape[0] == spec.force_evals + 1


#: ``getattr``/``hasattr`` of one of the hooks the record declares (what callers did before it existed).
_HOOK_LOOKUP = re.compile(r"\b(getattr|hasattr)\([^)]*[\"'](make_work|carry_over|clock_time|failure_message|counters|"
                          r"take_merges|check_bodies|handoff|SETTINGS|validate_settings|RUN_CONSTANTS|KICKS|DRIFTS)[\"']")


def test_no_caller_looks_a_hook_up_by_name() -> None:
    """Callers use the record's declared hooks, never an optional attribute of a module."""
    package = Path(importlib.import_module("orbitsim").__file__).parent
    found = [f"{path.relative_to(package)}:{number}" for path in sorted(package.rglob("*.py"))
             for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1)
             if _HOOK_LOOKUP.search(line)]
    assert found == []
    assert _HOOK_LOOKUP.search('counters = getattr(self.sim.module, "counters", None)')  # the check can fail


#: Schemes whose step, compiled beside their run, is a family of its own (TRACE ~1 min cold, Wisdom-Holman
#: ~15 s): make test-slow checks their step against their run. make test keeps Wisdom-Holman's in
#: test_wisdom_holman.py, and TRACE's steps against REBOUND's in test_trace_core.py and test_trace_ias15.py.
STEP_RUN_SLOW = {"trace", "wisdom_holman"}


def _step_run_cases() -> list:
    """Every scheme at N = 3 (all pairs, N <= 48) and at N = 60 (the third-law rows). A scheme's
    step and run compiled for the rows' context are two more specialisations (about 5-40 s on a cold
    cache) that only this test needs, and the rows kernel is the same whatever scheme calls it:
    `make test` runs N = 60 with verlet, `make test-slow` with every other scheme."""
    return [pytest.param(spec, n, id=f"{spec.name}-{n}",
                         marks=pytest.mark.slow if (n == 60 and spec.name != "verlet") or spec.name in STEP_RUN_SLOW
                         else ())
            for n in (3, 60) for spec in INTEGRATORS]


@pytest.mark.parametrize(("spec", "n"), _step_run_cases())
def test_step_gives_the_same_bits_as_run(spec: IntegratorSpec, n: int) -> None:
    """``step`` and ``run`` write each scheme's steps once (``advance``) but reach them by different
    paths; the contract is that stepping one at a time and running straight through agree exactly."""
    m, x, v = planets(n, seed=4)
    steps, dt = 7, 1e-3
    stepped = Simulation(m, x, v, spec.name, dt)
    record = get_integrator(spec.name)
    for _ in range(steps):
        record.step(stepped.pos, stepped.vel, stepped.acc, stepped.m, stepped.force, dt, stepped.work)
    ran = Simulation(m, x, v, spec.name, dt)
    (chunk,) = ran.chunks(np.array([steps]))
    assert chunk.step.tolist() == [steps]
    np.testing.assert_array_equal(chunk.positions[0], stepped.pos.T)
    np.testing.assert_array_equal(chunk.velocities[0], stepped.vel.T)
    assert not np.array_equal(stepped.pos.T, x)


def test_module_names_are_the_spec_names() -> None:
    """A scheme's own name is looked up by importing the module :data:`SCHEMES` names for it."""
    assert [record.spec.name for record in RECORDS] == list(NAMES)
    assert [record.spec.module.rsplit(".", 1)[-1] for record in RECORDS] == [module for _, module in SCHEMES]


def test_looking_up_a_scheme_by_name_imports_only_that_scheme() -> None:
    """A run's start-up imports the scheme it runs, not the other eight (about 50 ms)."""
    code = (
        "import sys; from orbitsim.integrators.registry import SCHEMES, get_integrator; "
        "assert get_integrator('Verlet').spec.name == 'verlet'; "
        "print(sorted({m for _, m in SCHEMES if 'orbitsim.integrators.' + m in sys.modules}))"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.split() == ["['verlet']"]


@pytest.mark.parametrize("bad", ["no_such_scheme", "verlet2", "", "leap frog"])
def test_unknown_name_lists_every_valid_name(bad: str) -> None:
    with pytest.raises(UnknownIntegratorError) as info:
        get_integrator(bad)
    assert isinstance(info.value, ValueError)
    message = str(info.value)
    for spec in INTEGRATORS:
        for name in spec.names:
            assert name in message, name


def test_non_string_name_is_an_unknown_integrator() -> None:
    with pytest.raises(UnknownIntegratorError):
        get_integrator(None)  # type: ignore[arg-type]


# -- REBOUND's names and the nearest name (issue 27, item 14) --------------------------------------------------

@pytest.mark.parametrize(("bad", "nearest"), [("leapfrg", "leapfrog"), ("rk45", "rk4"), ("ias16", "ias15"),
                                              ("wisdom-holmann", "wisdom_holman"), ("trac", "trace"),
                                              ("verlett", "verlet"), ("whfats", "whfast")])
def test_an_unknown_name_suggests_the_nearest_one(bad: str, nearest: str) -> None:
    with pytest.raises(UnknownIntegratorError, match=f"^unknown integrator {bad!r}; did you mean {nearest!r}\\?"):
        get_integrator(bad)


@pytest.mark.parametrize("name", ["whfast", "WHFast", " whfast "])
def test_whfast_is_wisdom_holman(name: str) -> None:
    assert get_spec(name).name == "wisdom_holman" and canonical_name(name) == "wisdom_holman"


def _two_bodies(integrator: object) -> dict:
    return {"integrator": integrator, "dt": 0.01, "steps": 5,
            "bodies": [{"name": "a", "m": 1.0, "x": [0, 0, 0], "v": [0, 0, 0]},
                       {"name": "b", "m": 1e-3, "x": [1, 0, 0], "v": [0, 1, 0]}]}


@pytest.mark.parametrize(("rebound", "orbitsim"), [
    ("whfast", "wisdom_holman"),
    ({"name": "whfast", "corrector": 5}, {"name": "wisdom_holman", "corrector": 5}),
    ({"name": "leapfrog", "order": 2}, "leapfrog"),
    ({"name": "leapfrog", "order": 4}, "leapfrog4"),
    ({"name": "leapfrog", "order": 6}, "leapfrog6"),
    ({"name": "leapfrog", "order": 8}, "leapfrog8"),
])
def test_rebound_names_in_a_scenario_run_the_same_bits_and_say_so(rebound: object, orbitsim: object) -> None:
    """A REBOUND name resolves to the very scenario (same text, same SHA-256) its orbitsim name gives, and
    the loader records a note that ``orbitsim validate`` prints."""
    from orbitsim.scenario import scenario_from_dict

    ported, native = scenario_from_dict(_two_bodies(rebound)), scenario_from_dict(_two_bodies(orbitsim))
    assert ported.to_yaml() == native.to_yaml() and ported.integrator == native.integrator
    assert any("REBOUND's" in note and native.integrator in note for note in ported.input_notes)
    assert not any("REBOUND" in note for note in native.input_notes)


@pytest.mark.parametrize("name", ["ias15", "trace"])
def test_ias15_and_trace_are_the_same_names_with_the_same_settings(name: str) -> None:
    """REBOUND's ias15 (epsilon, min_dt) and trace (r_crit_hill, peri_crit_eta, peri_mode) settings are
    orbitsim's: the keys a REBOUND script sets are accepted as they are."""
    from orbitsim.integrators.rebound_names import CLOSEST, SAME_SCHEME

    rebound_keys = {"ias15": {"epsilon", "min_dt"}, "trace": {"r_crit_hill", "peri_crit_eta", "peri_mode"}}[name]
    assert get_spec(name).name == name and name not in SAME_SCHEME and name not in CLOSEST
    assert rebound_keys <= set(get_integrator(name).settings)


def test_rebound_schemes_orbitsim_lacks_name_the_closest_one() -> None:
    """Every REBOUND scheme without a counterpart is refused in one line that names an orbitsim scheme to use
    (except the shearing sheet's and 'none', which have none)."""
    from orbitsim.integrators.rebound_names import CLOSEST

    for rebound_name in [*CLOSEST, "saba1", "SABA(10,6,4)", "sabacm"]:
        with pytest.raises(UnknownIntegratorError) as info:
            get_integrator(rebound_name)
        message = str(info.value)
        assert "\n" not in message and "REBOUND's" in message, message
        if rebound_name not in ("sei", "none"):
            suggested = message.split("is not in orbitsim; ", 1)[1]
            assert any(name in suggested for name in NAMES), message


def test_the_rebound_names_are_rebounds() -> None:
    """Each name the table maps or refuses is one REBOUND itself accepts (a typo there would map nothing)."""
    rebound = pytest.importorskip("rebound")
    from orbitsim.integrators.rebound_names import CLOSEST, LEAPFROG_ORDERS, SAME_SCHEME

    sim = rebound.Simulation()
    for name in [*SAME_SCHEME, *CLOSEST, "leapfrog", "ias15", "trace"]:
        sim.integrator = name  # raises for a name REBOUND does not know
    with pytest.raises(Exception, match="not found"):  # the check above can fail
        sim.integrator = "whfest"
    sim.integrator = "leapfrog"
    for order in LEAPFROG_ORDERS:
        sim.integrator.order = order  # REBOUND 5's leapfrog order setting (orbitsim.io.rebound_file reads it)
        assert int(sim.integrator.order) == order


@pytest.mark.parametrize("spec", INTEGRATORS, ids=SPEC_IDS)
def test_declared_order_matches_the_issue_table(spec: IntegratorSpec) -> None:
    if spec.name in DECLARED_ORDERS:
        assert spec.order == DECLARED_ORDERS[spec.name]
    else:
        assert spec.order >= 1  # a scheme the table does not list: at least consistent


# TRACE's run compiles for ~30 s cold: make test-slow (tests/integrators/test_trace_core.py runs TRACE in make test).
@pytest.mark.parametrize("spec", [pytest.param(s, marks=pytest.mark.slow) if s.name == "trace" else s
                                  for s in INTEGRATORS], ids=SPEC_IDS)
def test_tiny_run_of_every_integrator(spec: IntegratorSpec) -> None:
    m, x, v = star_and_two_planets()
    dt = 1e-3
    result = simulate(m, x, v, integrator=spec.name, dt=dt, steps=20, every=5, G=1.0)
    assert result.status == "complete" and result.steps_done == 20
    assert result.integrator == spec.name
    assert result.step.tolist() == [0, 5, 10, 15, 20]
    # The timestep is never shortened: sample times are exactly step * dt.
    assert np.array_equal(result.time, result.step * dt)
    assert np.all(np.isfinite(result.final_positions))
    # 20 steps of 1e-3 on orbits of period ~2 pi: every scheme of order >= 1 keeps the
    # energy to ~dt = 1e-3 (measured worst: explicit Euler, 3.7e-5); a broken step gives O(1).
    assert result.max_abs_energy_error < 1e-3
    assert not np.array_equal(result.final_positions, x)


# --- sampling never shortens the step --------------------------------------------------------


@pytest.mark.parametrize(
    ("n_steps", "dt", "interval"),
    [(1000, 0.1, 0.3), (1000, 0.1, 0.7), (997, 0.01, 0.0333), (500, 0.3, 0.1), (100, 1e-3, 0.01), (10, 0.7, 7.0)],
)
def test_interval_samples_land_on_the_last_whole_step(n_steps: int, dt: float, interval: float) -> None:
    steps = sample_steps_interval(n_steps, dt, interval)
    assert steps[0] == 0 and steps[-1] == n_steps
    assert np.all(np.diff(steps) > 0)
    expected = set()
    for k in range(math.floor(n_steps * dt / interval) + 1):
        wanted = k * interval
        n = min(int(wanted // dt) + 2, n_steps)
        while n > 0 and n * dt > wanted:  # the last whole step at or before the wanted time
            n -= 1
        n_k = n
        assert n_k * dt <= wanted or n_k == 0
        assert wanted < (n_k + 1) * dt or n_k == n_steps
        assert n_k in steps, (k, n_k)
        expected.add(n_k)
    expected.add(n_steps)
    assert set(steps.tolist()) == expected


def test_interval_sampled_run_has_exact_step_times() -> None:
    m, x, v = star_and_two_planets()
    dt, n_steps = 0.1, 200
    plan = sample_steps_interval(n_steps, dt, 0.7)
    result = simulate(m, x, v, integrator="verlet", dt=dt, steps=n_steps, sample_steps=plan)
    assert np.array_equal(result.step, plan)
    assert np.array_equal(result.time, plan * dt)
    assert result.steps_done == n_steps


def test_every_plan_always_ends_on_the_last_step() -> None:
    assert sample_steps_every(10, 3).tolist() == [0, 3, 6, 9, 10]
    assert sample_steps_every(9, 3).tolist() == [0, 3, 6, 9]
    assert sample_steps_every(0, 5).tolist() == [0]
