"""The unresolved-step check under ``trace`` (issue 27, item 5).

TRACE hands close encounters (within ``r_crit_hill`` Hill radii) and pericentre passages
(``peri_crit_eta``) to Bulirsch-Stoer, so a step "too long" for them is no error: a
200-planetesimal disc logged 123 unresolved events in 500 yr, about 18 for every real collision,
each advising a dt TRACE does not need. Now only what TRACE stepped with its fixed dt is judged,
and the advice names TRACE's own knobs. Fixed-dt schemes are judged as before (the controls).
"""

from __future__ import annotations

from typing import Any

import pytest

from orbitsim.events.log import Event, unresolved_fix
from orbitsim.scenario import scenario_from_dict
from orbitsim.scenario_simulation import scenario_simulation

#: REBOUND's test_simple_collision state (tests/integrators/test_trace_collisions.py) without radii: p2
#: (m = 1e-8) passes ~0.001 from p1 (m = 1e-5) at t = 0.56, inside p1's Hill sphere, closer than
#: p1 pulls harder than the star (0.0014), where a step of 0.01 is far too long (tau ~ 2e-4).
ENCOUNTER = [{"name": "star", "m": 1.0, "x": [0.0, 0.0, 0.0], "v": [0.0, 0.0, 0.0]},
             {"name": "p1", "m": 1.0e-05, "x": [0.44999999999999996, 0.0, 0.0], "v": [0.0, 1.5634797372812, 0.0]},
             {"name": "p2", "m": 1.0e-08, "x": [0.22047437147767954, -0.30187495012979704, 0.0],
              "v": [1.1881053832166133, 1.4562235287762688, 0.0]}]


def eccentric(mass: float) -> list[dict[str, Any]]:
    """A star, a Jupiter at 5, and a body on e = 0.99 at a = 1 (pericentre 0.01, tau there ~6e-4),
    from its apocentre: its pericentre passage at t ~ pi falls inside the run's 200 steps of 0.05."""
    return [{"name": "star", "m": 1.0, "x": [0, 0, 0], "v": [0, 0, 0]},
            {"name": "jup", "m": 1e-3, "primary": "star", "a": 5.0, "M": 0},
            {"name": "comet", "m": mass, "primary": "star", "a": 1.0, "e": 0.99, "M": 180}]


def unresolved(integrator: Any, bodies: list[dict[str, Any]], dt: float, steps: int,
               collisions: bool = False) -> tuple[list[str], list[str]]:
    """The run's unresolved events as their ``details`` text, and the kinds of all its events."""
    events: dict[str, Any] = {"unresolved": True}
    if collisions:
        events["collisions"] = {"detect": "direct", "resolve": "merge"}
    sc = scenario_from_dict({"name": "u", "integrator": integrator, "dt": dt, "steps": steps,
                             "output": {"every": 10}, "events": events, "bodies": bodies})
    sim = scenario_simulation(sc)
    for _ in sim.chunks(sc.sample_plan(), record_positions=False):
        pass
    table = sim.watcher.outcome().table(sc.names)
    details = [str(d) for d, kind in zip(table["details"], table["kind"], strict=True) if kind == "unresolved"]
    return details, [str(kind) for kind in table["kind"]]


def test_an_encounter_trace_hands_to_bulirsch_stoer_is_not_unresolved() -> None:
    details, _ = unresolved("trace", ENCOUNTER, 0.01, 100)
    assert details == []
    # the control: leapfrog takes the same encounter with the fixed step, and is told to shorten it
    details, _ = unresolved("leapfrog", ENCOUNTER, 0.01, 100)
    assert len(details) == 1 and details[0].startswith("p2: the step is longer than its orbit about p1")
    assert details[0].endswith("use dt <= 0.00075")


def test_a_collision_inside_an_encounter_comes_without_an_unresolved_step() -> None:
    """The issue's disc in small: each merge used to come with an unresolved step of the pair."""
    details, kinds = unresolved("trace", [{**b, "r": r} for b, r in zip(ENCOUNTER, (0.0, 1.6e-4, 4e-5),
                                                                           strict=True)],
                                0.01, 100, collisions=True)
    assert kinds == ["collision"] and details == []


def test_an_encounter_trace_leaves_to_the_fixed_step_is_unresolved_with_its_knob() -> None:
    """With r_crit_hill = 0.001 (6.7e-6 at p1) TRACE no longer switches the pass at ~0.001."""
    details, _ = unresolved({"name": "trace", "r_crit_hill": 0.001}, ENCOUNTER, 0.01, 100)
    assert len(details) == 1 and details[0].startswith("p2: the step is longer than its orbit about p1")
    assert "trace stepped this pair with the fixed dt" in details[0]
    assert "r_crit_hill = 0.001 Hill radii" in details[0] and "raise r_crit_hill, or use dt <= " in details[0]


@pytest.mark.parametrize("settings", [{}, {"peri_mode": "partial_bs"}, {"peri_mode": "full_ias15"}])
def test_a_pericentre_trace_hands_over_is_not_unresolved(settings: dict[str, Any]) -> None:
    details, _ = unresolved({"name": "trace", **settings}, eccentric(1e-9), 0.05, 200)
    assert details == []


def test_a_pericentre_trace_leaves_to_the_fixed_step_is_unresolved_with_its_knob() -> None:
    """peri_crit_eta = 100 switches only when tau < dt / 100: the passage (tau ~ 6e-4) is not."""
    details, _ = unresolved({"name": "trace", "peri_crit_eta": 100}, eccentric(1e-9), 0.05, 200)
    assert details and all(d.startswith("comet: the step is longer than its orbit about star") for d in details)
    assert all("peri_crit_eta = 100, did not hand it to Bulirsch-Stoer): lower peri_crit_eta, or use dt <= " in d
               for d in details)
    # the control: leapfrog is judged on the same passage
    assert unresolved("leapfrog", eccentric(1e-9), 0.05, 200)[0]


def test_a_massless_body_about_the_star_is_a_kepler_drift_under_trace() -> None:
    """TRACE solves a test particle's orbit about the star exactly, whatever dt, and never switches
    it (REBOUND's pericentre criterion skips test particles): nothing to judge, even where its
    switch would not act."""
    assert unresolved({"name": "trace", "peri_crit_eta": 100}, eccentric(0.0), 0.05, 200)[0] == []
    assert unresolved("leapfrog", eccentric(0.0), 0.05, 200)[0]  # a fixed-dt scheme is judged


def test_the_fix_is_worded_for_the_scheme() -> None:
    about_star = Event("unresolved", 5, 5, 0.5, 2, 0, 0.1, 3.0, 1.25e-4)
    between = Event("unresolved", 5, 5, 0.5, 2, 1, 0.1, 3.0, 1.25e-4)
    assert unresolved_fix(about_star) == "use dt <= 0.000125"
    assert unresolved_fix(between, "leapfrog4", {}) == "use dt <= 0.000125"
    assert "lower peri_crit_eta, or use dt <= 0.000125" in unresolved_fix(about_star, "trace", {"peri_crit_eta": 2})
    assert "raise r_crit_hill, or use dt <= 0.000125" in unresolved_fix(between, "trace", {"r_crit_hill": 3.0})
    assert unresolved_fix(between, "ias15", {"epsilon": 1e-9, "adaptive": True}) == (
        "ias15 chose a step longer than 0.000125 here: lower its epsilon (now 1e-09)")
    assert unresolved_fix(between, "ias15", {"adaptive": False}) == "use dt <= 0.000125"  # constant steps of dt


def test_the_check_leaves_out_exactly_what_the_handoff_names() -> None:
    """The kernel's rule (orbitsim.events.bodies.handed_over), step by step: a star, a massive
    body 1 close to body 2 (each other's attractor, a step far too long for them), and a massless
    body 3 on a tight orbit about the star (also far too long). What a handoff names is not judged."""
    import numpy as np

    from orbitsim.events.bodies import HAND_MASSLESS_KEPLER, HAND_WHOLE_STEP
    from orbitsim.events.config import EventsConfig
    from orbitsim.events.kernels import after_step
    from orbitsim.events.watch import build_watch, drain

    m = np.array([1.0, 1e-3, 1e-3, 0.0])
    pos = np.ascontiguousarray(np.array([[0.0, 1.0, 1.001, 0.01], [0.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0]]))
    vel = np.ascontiguousarray(np.array([[0.0, 0.0, 0.0, 0.0], [0.0, 1.0, 1.5, 10.0], [0.0, 0.0, 0.0, 0.0]]))
    n = len(m)

    def judged(handoff: Any) -> list[tuple[int, int]]:
        watch = build_watch(EventsConfig(), m, np.zeros(n), 1.0)
        watch.prev[0], watch.prev[1] = pos, vel  # the step "started" where it ended: no pericentre passed
        after_step(watch, pos, vel, m, 1, 0.0, 0.1, handoff)
        events, _ = drain(watch, np.arange(n))
        return sorted((e.i, e.j) for e in events if e.kind == "unresolved")

    none = (np.zeros((n, n), dtype=np.uint8), np.zeros(n, dtype=np.int64), 0)
    assert judged(None) == [(1, 2), (3, 0)]  # the equal pair under its lower index; the massless body
    assert judged(none) == [(1, 2), (3, 0)]  # an empty handoff changes nothing
    pair = none[0].copy()
    pair[1, 2] = 1
    assert judged((pair, none[1], 0)) == [(3, 0)]  # the encounter went to Bulirsch-Stoer
    bodies = none[1].copy()
    bodies[3] = 1
    assert judged((none[0], bodies, 0)) == [(1, 2)]  # body 3's orbit about body 0 went to it
    assert judged((none[0], none[1], HAND_MASSLESS_KEPLER)) == [(1, 2)]  # a massless body's Kepler drift
    assert judged((none[0], none[1], HAND_WHOLE_STEP)) == []  # the whole step did
