"""A run without ``events:`` whose step is far too long for an orbit (issue 27, item 6).

The e = 0.99 comet at dt = P / 200 used to finish ``complete`` with nothing said. Now each body's
shortest timescale ahead is checked at the states between the run's jitted calls (no per-step
cost; the steps and their bits are untouched), and one warning, naming the body and the
``events:`` line that watches every step, goes to the summary and to the trace's attributes.
"""

from __future__ import annotations

import math
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

import orbitsim.events.sampled as sampled
from orbitsim.cli.main import cli
from orbitsim.events.timescales import INTERPRETED_MAX_N, orbit_timescales, orbit_timescales_python, timescales_of
from orbitsim.scenario import scenario_from_dict
from orbitsim.scenario_simulation import scenario_simulation

#: The issue's comet: a = 10 au (P = 31.6 yr), e = 0.99 (perihelion 0.1 au), from aphelion, at
#: dt = P / 200; its perihelion timescale is 0.0029 yr, 54 times shorter than the step.
COMET = """\
name: comet
units: au-yr-msun
integrator: {integrator}
dt: {dt}
t_end: 40
output: {{every: 10}}
bodies:
  - {{name: sun, m: 1.0, x: [0, 0, 0], v: [0, 0, 0]}}
  - {{name: comet, m: 0.0, primary: sun, a: 10.0, e: 0.99, M: 180}}
"""
P_OVER_200 = 31.6227766 / 200


def invoke(*args: str) -> tuple[int, str, str]:
    result = CliRunner().invoke(cli, list(args))
    assert "Traceback" not in result.output, result.output
    return result.exit_code, result.stdout, result.stderr


def run_comet(tmp_path: Path, dt: float, integrator: str = "verlet", extra: str = "") -> tuple[int, str, str, Path]:
    scenario = tmp_path / "comet.yaml"
    scenario.write_text(COMET.format(integrator=integrator, dt=dt) + extra, encoding="utf-8")
    out = tmp_path / "comet.h5"
    code, stdout, stderr = invoke("run", str(scenario), "-o", str(out), "--force")
    return code, stdout, stderr, out


def attrs(path: Path) -> dict[str, Any]:
    with h5py.File(path, "r") as f:
        return dict(f.attrs)


def test_the_comet_at_p_over_200_is_warned_about_once(tmp_path: Path) -> None:
    code, stdout, stderr, out = run_comet(tmp_path, P_OVER_200)
    assert code == 0 and "comet: complete" in stdout
    warnings = [line for line in stderr.splitlines() if "timescale" in line]
    assert len(warnings) == 1, stderr
    line = warnings[0]
    assert line.startswith("orbitsim: note: dt = 0.158 is longer than the timescale of comet's orbit about sun (")
    assert "tightest; seen at t = 0): a fixed step this long cannot follow it" in line
    assert "Add `events: {unresolved: true}` to the scenario to check every step" in line
    tau = float(line.split("or use dt <= ")[1])
    assert 0.002 < tau < 0.004  # the perihelion's: ~ sqrt(q^3 / GM) = 0.005 times a factor of order 1
    assert attrs(out)["unresolved_warning"] == line.removeprefix("orbitsim: note: ")


def test_the_comet_at_a_step_that_resolves_it_is_not_warned_about(tmp_path: Path) -> None:
    code, _, stderr, out = run_comet(tmp_path, 0.001)
    assert code == 0 and "timescale" not in stderr
    assert "unresolved_warning" not in attrs(out)


def test_a_run_with_events_is_left_to_its_watch(tmp_path: Path) -> None:
    code, stdout, stderr, out = run_comet(tmp_path, P_OVER_200, extra="events: {unresolved: false}\n")
    assert code == 0 and "timescale" not in stderr and "unresolved_warning" not in attrs(out)
    code, stdout, stderr, out = run_comet(tmp_path, P_OVER_200, extra="events: {unresolved: true}\n")
    assert "1 unresolved step (comet at t = " in stdout and "timescale" not in stderr


def test_the_check_leaves_the_run_bit_for_bit(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The same run with and without the check: every dataset the same bits."""
    _, _, stderr, checked = run_comet(tmp_path, P_OVER_200)
    assert "timescale" in stderr
    plain = tmp_path / "plain.h5"
    checked.rename(plain)
    monkeypatch.setattr(sampled, "step_check", lambda scenario, sim: None)
    _, _, stderr, unchecked = run_comet(tmp_path, P_OVER_200)
    assert "timescale" not in stderr
    with h5py.File(plain, "r") as a, h5py.File(unchecked, "r") as b:
        names = [n for n in ("time", "step", "energy", "positions", "velocities", "momentum") if n in a]
        assert len(names) == 6
        for name in names:
            assert np.array_equal(a[name][()].view(np.uint8), b[name][()].view(np.uint8)), name


def eccentric(mass: float, integrator: Any) -> Any:
    """A star, a Jupiter at 5 and a body on e = 0.99 at a = 1 (pericentre tau ~6e-4), dt = 0.05."""
    return scenario_from_dict({
        "name": "ecc", "integrator": integrator, "dt": 0.05, "steps": 10, "bodies": [
            {"name": "star", "m": 1.0, "x": [0, 0, 0], "v": [0, 0, 0]},
            {"name": "jup", "m": 1e-3, "primary": "star", "a": 5.0, "M": 0},
            {"name": "comet", "m": mass, "primary": "star", "a": 1.0, "e": 0.99, "M": 180}]})


def warning_at_start(scenario: Any) -> str:
    sim = scenario_simulation(scenario)
    check = sampled.step_check(scenario, sim)
    assert check is not None
    return check.warning


def test_under_trace_only_what_trace_steps_with_the_fixed_dt_is_warned_about() -> None:
    assert "comet's orbit about star" in warning_at_start(eccentric(1e-9, "leapfrog"))  # the control
    assert warning_at_start(eccentric(1e-9, "trace")) == ""  # its pericentre switch takes the passage
    assert warning_at_start(eccentric(0.0, {"name": "trace", "peri_crit_eta": 100})) == ""  # a Kepler drift
    text = warning_at_start(eccentric(1e-9, {"name": "trace", "peri_crit_eta": 100}))
    assert "comet's orbit about star" in text and "trace steps it with the fixed dt" in text
    eta = float(text.split("lower peri_crit_eta below ")[1].split()[0])
    assert 1 < eta < 100  # dt / tau: a peri_crit_eta below it switches the passage to Bulirsch-Stoer
    assert "(now 100), or use dt <= " in text


def test_under_trace_a_pair_outside_r_crit_hill_is_warned_about_with_its_knob() -> None:
    """p2 0.001 from p1 (m = 1e-5), inside p1's Hill sphere (0.0067): TRACE flags it at r_crit_hill
    = 3 but not at 0.01; leapfrog (the control) is warned about either way."""
    bodies = [{"name": "star", "m": 1.0, "x": [0, 0, 0], "v": [0, 0, 0]},
              {"name": "p1", "m": 1e-5, "x": [0.45, 0, 0], "v": [0, 1.4907, 0]},
              {"name": "p2", "m": 1e-8, "x": [0.451, 0, 0], "v": [0, 1.4907 + 0.1, 0]}]

    def scenario(integrator: Any) -> Any:
        return scenario_from_dict({"name": "pair", "integrator": integrator, "dt": 0.01, "steps": 10,
                                   "bodies": bodies})

    assert "p2's orbit about p1" in warning_at_start(scenario("leapfrog"))
    assert warning_at_start(scenario("trace")) == ""
    text = warning_at_start(scenario({"name": "trace", "r_crit_hill": 0.01}))
    assert "p2's orbit about p1" in text and "raise r_crit_hill above " in text and "(now 0.01)" in text


def test_timescales_are_the_pericentre_ones_ahead() -> None:
    """A circular orbit: tau = sqrt(r^3 / G M) (|a'| = |a| w, |a''| = |a| w^2 in eq. 16); an
    eccentric one seen at apocentre: the tau of the same orbit seen at its pericentre."""
    G, M, r = 1.0, 1.0, 2.0
    m = np.array([M, 0.0])

    def timescales(x: list[float], v: list[float]) -> tuple[float, int, float]:
        pos = np.array([[0.0, x[0]], [0.0, x[1]], [0.0, x[2]]])
        vel = np.array([[0.0, v[0]], [0.0, v[1]], [0.0, v[2]]])
        tau, attractor, closest = np.empty(2), np.empty(2, dtype=np.int64), np.empty(2)
        orbit_timescales(pos, vel, m, G, 0.0, tau, attractor, closest)
        assert tau[0] == math.inf and attractor[0] == -1  # a massless body pulls nothing
        return float(tau[1]), int(attractor[1]), float(closest[1])

    tau, attractor, closest = timescales([r, 0, 0], [0, math.sqrt(G * M / r), 0])
    assert attractor == 0 and closest == r
    assert tau == pytest.approx(math.sqrt(r**3 / (G * M)), rel=1e-12)  # closed forms, a few roundings apart
    a, e = 1.0, 0.9
    q, Q = a * (1 - e), a * (1 + e)
    v_q, v_Q = math.sqrt(G * M * (1 + e) / q), math.sqrt(G * M * (1 - e) / Q)
    at_peri, _, where_peri = timescales([q, 0, 0], [0, v_q, 0])
    at_apo, _, where_apo = timescales([-Q, 0, 0], [0, -v_Q, 0])
    assert where_apo == pytest.approx(q, rel=1e-12) and where_peri == pytest.approx(q, rel=1e-12)
    assert at_apo == pytest.approx(at_peri, rel=1e-9)  # q from (E, h) at apocentre: rounding of 1 - e^2 terms
    # softening: no timescale below a circular orbit's at r = eps
    pos = np.array([[0.0, q], [0.0, 0.0], [0.0, 0.0]])
    vel = np.array([[0.0, 0.0], [0.0, v_q], [0.0, 0.0]])
    tau_s, attractor_s, closest_s = np.empty(2), np.empty(2, dtype=np.int64), np.empty(2)
    orbit_timescales(pos, vel, m, G, 0.5**2, tau_s, attractor_s, closest_s)
    assert tau_s[1] == pytest.approx(math.sqrt(0.5**3 / (G * M)), rel=1e-12)


def _random_states(seed: int, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A star, massive and massless bodies (two of equal mass) on bound and unbound orbits."""
    rng = np.random.default_rng(seed)
    m = np.concatenate([[1.0], rng.uniform(0.0, 1e-2, n - 1)])
    m[rng.integers(1, n, size=max(1, n // 4))] = 0.0
    m[-1] = m[-2] = 3e-3
    pos = rng.normal(size=(3, n)) * rng.uniform(0.1, 5.0, size=n)
    vel = rng.normal(size=(3, n)) * rng.uniform(0.0, 2.0, size=n)
    return pos, vel, m


@pytest.mark.parametrize("eps2", [0.0, 0.01])
@pytest.mark.parametrize("seed", range(8))
def test_the_interpreted_timescales_are_the_compiled_bits(seed: int, eps2: float,
                                                         monkeypatch: pytest.MonkeyPatch) -> None:
    """The interpreted check (what a run's looks use, nothing to compile: numpy for the attractors,
    the interpreter for the rest) gives the compiled kernel's outputs bit for bit: same operations in
    the same order on IEEE doubles. The last two states go through the numpy search in blocks of a
    few rows, as a large N does."""
    import orbitsim.events.timescales as timescales

    n = [2, 3, 5, 9, 17, 33, 64, 201][seed]
    if seed >= 6:
        monkeypatch.setattr(timescales, "_PAIRS_PER_BLOCK", 7 * n)
    pos, vel, m = _random_states(seed, n)
    outputs = []
    for kernel in (orbit_timescales, orbit_timescales_python):
        tau, attractor, closest = np.empty(n), np.empty(n, dtype=np.int64), np.empty(n)
        kernel(pos, vel, m, 1.0, eps2, tau, attractor, closest)
        outputs.append((tau.tobytes(), attractor.tobytes(), closest.tobytes()))
    assert outputs[0] == outputs[1]
    assert np.isfinite(np.frombuffer(outputs[0][0])).any()  # the states exercise the timescale, not only inf


def test_the_interpreted_attractors_break_ties_and_skip_coincident_bodies_as_compiled() -> None:
    """The cases where a search in another order could pick another body: two bodies pulling equally
    (the first one wins), a body on top of another (r = 0: left out), only massless neighbours (none)."""
    pos = np.array([[0.0, 1.0, -1.0, 0.0, 0.0, 5.0, 5.0, 9.0],
                    [0.0, 0.0, 0.0, 2.0, 2.0, 0.0, 0.0, 9.0],
                    [0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 9.0]])
    vel = np.zeros((3, 8))
    vel[1, 1:] = 0.3
    m = np.array([1.0, 1e-3, 1e-3, 0.0, 2e-3, 0.0, 0.0, 0.0])
    outputs = []
    for kernel in (orbit_timescales, orbit_timescales_python):
        tau, attractor, closest = np.empty(8), np.empty(8, dtype=np.int64), np.empty(8)
        kernel(pos, vel, m, 1.0, 0.0, tau, attractor, closest)
        outputs.append((tau.tobytes(), attractor.tobytes(), closest.tobytes(), attractor.copy()))
    assert outputs[0][:3] == outputs[1][:3]
    attractor = outputs[0][3]
    assert attractor[0] == 1  # bodies 1 and 2 pull the star equally: the first
    assert attractor[3] == 0 and attractor[4] == 0  # 3 sits on 4 (r = 0, left out): the star, for both
    assert attractor[5] == 0 and attractor[6] == 0  # 5 and 6 coincide and are massless


def test_timescales_of_compiles_only_for_many_bodies_a_non_finite_state_or_a_spent_budget(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """Where the interpreter is not used: above INTERPRETED_MAX_N bodies, for a state with a nan
    (math.sqrt of a nan must not raise), and once the process has spent INTERPRETED_BUDGET_S on
    interpreted looks (so a run that looks often compiles after all)."""
    import orbitsim.events.timescales as timescales

    calls: list[str] = []
    monkeypatch.setattr(timescales, "_interpreted_seconds", [0.0])
    monkeypatch.setattr(timescales, "_compiled_at_hand", lambda: False)  # a cold cache
    monkeypatch.setattr(timescales, "orbit_timescales", lambda *a: calls.append("compiled"))
    monkeypatch.setattr(timescales, "orbit_timescales_python", lambda *a: calls.append("python"))
    for n, poison in [(INTERPRETED_MAX_N, False), (INTERPRETED_MAX_N + 1, False), (3, True), (3, False)]:
        pos, vel, m = _random_states(1, n)
        if poison:
            vel[1, 2] = np.nan
        timescales_of(pos, vel, m, 1.0, 0.0, np.empty(n), np.empty(n, dtype=np.int64), np.empty(n))
    assert calls == ["python", "compiled", "compiled", "python"]
    monkeypatch.setattr(timescales, "_interpreted_seconds", [timescales.INTERPRETED_BUDGET_S])
    pos, vel, m = _random_states(1, 3)
    timescales_of(pos, vel, m, 1.0, 0.0, np.empty(3), np.empty(3, dtype=np.int64), np.empty(3))
    assert calls[-1] == "compiled"


def test_timescales_of_goes_compiled_from_the_first_look_where_the_kernel_is_at_hand(
        monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    """A warm run pays no interpreted looks: once the kernel is compiled in the process, or sits in
    Numba's cache on disk (a fresh process with that cache), the first look is compiled."""
    import orbitsim.events.timescales as timescales

    pos, vel, m = _random_states(2, 40)
    orbit_timescales(pos, vel, m, 1.0, 0.0, np.empty(40), np.empty(40, dtype=np.int64), np.empty(40))
    assert timescales._compiled_at_hand()
    probe = ("import numpy as np, orbitsim.events.timescales as t\n"
             "print(t._compiled_at_hand())\n"
             "n = 3; t.orbit_timescales(np.ones((3, n)) * np.arange(n), np.zeros((3, n)), np.ones(n), 1.0, 0.0,"
             " np.empty(n), np.empty(n, dtype=np.int64), np.empty(n))\n"
             "print(t._compiled_at_hand())\n")
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", "NUMBA_DISABLE_JIT")}
    env["ORBITSIM_CACHE_DIR"] = str(tmp_path / "cache")
    cold = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, env=env, timeout=600)
    warm = subprocess.run([sys.executable, "-c", probe.split("n = 3")[0]], capture_output=True, text=True, env=env,
                          timeout=600)
    assert cold.stdout.split() == ["False", "True"], cold.stderr
    assert warm.stdout.split() == ["True"], warm.stderr


def test_the_pairs_examined_stay_within_the_budget(monkeypatch: pytest.MonkeyPatch) -> None:
    """The mechanism that bounds the check's cost: pairs examined <= FREE_PAIRS + 1/PAIR_SHARE of
    the pairs the steps visited (counted, not timed). The state is looked at after every step of
    the count here; a run looks once per chunk of samples."""
    sc = scenario_from_dict({"name": "d", "integrator": "leapfrog", "dt": 1e-3, "steps": 4000,
                             "generator": {"kind": "disc", "n": 63, "seed": 1, "r_min": 1.0, "r_max": 2.0}})
    monkeypatch.setattr(sampled, "FREE_PAIRS", 2016 * 3)  # the first three states of 64 bodies
    sim = scenario_simulation(sc)
    check = sampled.step_check(sc, sim)
    assert check is not None and check.pairs_examined == 2016  # the start is checked
    for step in range(1, 4001):
        sim.steps_done = step  # as if the run had got there (the check reads only the count and the state)
        check.look(sim)
        assert check.pairs_examined <= sampled.FREE_PAIRS + step * 2016 // sampled.PAIR_SHARE
    # 4000 steps of leapfrog visit 4000 x 2016 pairs (one force evaluation a step): 1/512 of that is
    # 7.8 states' worth, plus the 3 free ones
    assert check.pairs_examined == 2016 * 10 and check.warning == ""
