"""Acceptance tests of the events engine (issue 15) that need no reference code: merges conserve
what they must, ``line`` catches what ``direct`` misses, the Hermite fit finds a minimum between
two steps, the comet's unresolved pericentre, and a watched run with nothing to report is the plain
run, bit for bit, for every integrator.

Each system is set up through the public :class:`orbitsim.simulation.Simulation`, with the events
of :mod:`orbitsim.events.config`; a run's samples are joined with :func:`collect`. The REBOUND
comparisons are in ``test_events_rebound.py``, the command line and checkpoints in
``test_events_cli.py``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from orbitsim.events.config import Collisions, Encounters, Escape, EventsConfig, Unresolved
from orbitsim.sampling import EveryPlan
from orbitsim.simulation import Simulation

EPS = np.finfo(np.float64).eps
#: au-yr-msun: GM_sun = 4 pi^2.
G_AU_YR = 4.0 * math.pi**2


def collect(sim: Simulation, steps: int, every: int = 1) -> dict[str, np.ndarray]:
    """Every sample of ``sim`` from its current step to ``steps``, joined: the chunk fields and
    ``offset`` (``extra["energy_offset"]``, zeros without events)."""
    chunks = list(sim.chunks(EveryPlan(steps, every)))
    out = {name: np.concatenate([getattr(c, name) for c in chunks])
           for name in ("step", "time", "kinetic", "potential", "momentum", "angular_momentum", "positions",
                        "velocities")}
    out["energy"] = out["kinetic"] + out["potential"]
    offsets = [(c.extra or {}).get("energy_offset") for c in chunks]
    out["offset"] = (np.concatenate(offsets) if all(o is not None for o in offsets)
                     else np.zeros_like(out["energy"]))
    return out


# -- 1. head-on collision with merge -----------------------------------------------------------

#: Masses whose every partial sum is exact in float64 (dyadic fractions), so "total mass is
#: bit-exact" is a fair demand: 0.5 + 0.25 = 0.75 and 0.75 + 0.25 = 1 with no rounding at all.
HEAD_ON_MASSES = np.array([0.5, 0.25, 0.25])
#: Bodies 0 and 1 fall together along x (radii 0.2 and 0.1, so they touch at separation 0.3);
#: body 2 is far (50) and stays out of it, so N goes 3 -> 2. A common drift gives the system a
#: momentum of about 0.4, so a relative momentum error is well defined.
HEAD_ON_DRIFT = np.array([0.3, 0.2, 0.1])
HEAD_ON_X = np.array([[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 50.0, 0.0]])
HEAD_ON_V = np.array([[0.1, 0.0, 0.0], [-0.1, 0.0, 0.0], [0.0, 0.0, 0.1]]) + HEAD_ON_DRIFT
HEAD_ON_RADII = np.array([0.2, 0.1, 0.0])
#: t = 3 covers the contact (t = 2.70) and 300 steps after it at dt = 1e-3.
HEAD_ON_T = 3.0


def head_on(dt: float, detect: str | None) -> Simulation:
    events = EventsConfig(collisions=Collisions(detect, "merge")) if detect else None
    return Simulation(HEAD_ON_MASSES, HEAD_ON_X, HEAD_ON_V, "verlet", dt, events=events,
                      radii=HEAD_ON_RADII if detect else None)


def merged_run(dt: float, detect: str) -> tuple[Simulation, dict[str, np.ndarray], int]:
    sim = head_on(dt, detect)
    samples = collect(sim, round(HEAD_ON_T / dt))
    collisions = [e for e in sim.watcher.log if e.kind == "collision"]
    assert len(collisions) == 1, sim.watcher.log
    return sim, samples, collisions[0].step


def conserved_error(samples: dict[str, np.ndarray]) -> np.ndarray:
    """(E + offset - E0) / |E0| at every sample."""
    e0 = samples["energy"][0]
    return (samples["energy"] + samples["offset"] - e0) / abs(e0)


@pytest.mark.parametrize("detect", ["direct", "line"])
def test_head_on_merge_conserves_mass_momentum_and_energy_with_offset(detect: str) -> None:
    dt = 1e-3
    sim, got, k = merged_run(dt, detect)
    # The same system without events: the same bits up to the merge (the watch never changes the
    # state), so its sample at the merge step is the state just before the merge.
    plain = collect(head_on(dt, None), round(HEAD_ON_T / dt))
    event = next(e for e in sim.watcher.log if e.kind == "collision")
    assert (event.i, event.j, event.outcome, event.into) == (0, 1, "merged", 0)
    assert event.extra == pytest.approx(0.3) and event.distance < event.extra  # touching: closer than r_0 + r_1
    assert got["step"][k] == k  # every step is sampled
    for name in ("positions", "velocities", "kinetic", "potential"):
        assert np.array_equal(got[name][:k], plain[name][:k]), name

    # N drops by one; the removed body's samples are NaN from the merge on.
    assert sim.n == 2 and list(sim.watcher.alive) == [0, 2]
    assert sim.watcher.removed_step[1] == k and sim.watcher.merged_into[1] == 0
    assert np.isnan(got["positions"][k:, 1]).all() and np.isfinite(got["positions"][k:, [0, 2]]).all()

    # Mass: bit-exact (one exact addition, see HEAD_ON_MASSES).
    assert sim.m.sum() == HEAD_ON_MASSES.sum() == 1.0
    assert sim.watcher.final_masses[0] == 0.75
    # The merged body: mass-weighted centre and velocity of the pre-merge state, volume-conserving
    # radius (a few roundings each: 1e-15 relative).
    x_pre, v_pre = plain["positions"][k], plain["velocities"][k]
    m = HEAD_ON_MASSES
    np.testing.assert_allclose(got["positions"][k, 0], (m[0] * x_pre[0] + m[1] * x_pre[1]) / 0.75, rtol=1e-15)
    np.testing.assert_allclose(got["velocities"][k, 0], (m[0] * v_pre[0] + m[1] * v_pre[1]) / 0.75, rtol=1e-15)
    assert sim.watcher.final_radii[0] == pytest.approx((0.2**3 + 0.1**3) ** (1 / 3), rel=1e-15)

    # Momentum: the merged velocity is one division per component, so M v_merged differs from
    # m_0 v_0 + m_1 v_1 by about one rounding: 1e-15 of |P| (|P| ~ 0.4 and every term has the
    # same sign, so there is no cancellation to magnify it).
    p_pre, p_post = plain["momentum"][k], got["momentum"][k]
    assert np.linalg.norm(p_post - p_pre) <= 1e-15 * np.linalg.norm(p_pre)

    # Energy: E + offset right after the merge equals E just before it (same step, pre-merge
    # state) to round-off: a few roundings of terms as large as T + |U|.
    scale = plain["kinetic"][k] + abs(plain["potential"][k])
    assert abs(got["energy"][k] + got["offset"][k] - plain["energy"][k]) <= 64 * EPS * scale
    assert got["offset"][k - 1] == 0.0 and got["offset"][k] != 0.0
    # ...and it stays there: after the merge a two-body system (the merged body and the distant
    # one, 50 apart) is integrated, whose own error is far below the error of the fall.
    err = conserved_error(got)
    assert np.abs(err[k:] - err[k]).max() <= 1e-3 * abs(err[k])


def test_head_on_merge_energy_error_converges_at_second_order() -> None:
    """The |(E + offset - E0) / E0| a merged run ends with is verlet's own: halving dt divides it
    by ~4. Measured at dt = 1e-3, 5e-4, 2.5e-4: 2.07e-4, 5.11e-5, 1.27e-5 (ratios 4.06, 4.03)."""
    finals = []
    for dt in (1e-3, 5e-4, 2.5e-4):
        _, got, _ = merged_run(dt, "direct")
        finals.append(abs(conserved_error(got)[-1]))
    slopes = np.log2(np.array(finals[:-1]) / np.array(finals[1:]))
    # Second order: slope 2; 0.2 allows for the contact being detected at a slightly different
    # separation at each dt (the first step end inside r_0 + r_1).
    assert np.all(np.abs(slopes - 2.0) < 0.2), (finals, slopes)


def fly_through(detect: str) -> Simulation:
    """Two massless bodies (radii 0.01, reach 0.02) meeting head-on at relative speed 10 with
    dt = 0.01: the separation along x goes 0.95, 0.85, ..., 0.05, -0.05, ...: every step end is
    at least 0.05 > 0.02 apart, yet they pass through each other during step 10."""
    x = np.array([[-0.475, 0.0, 0.0], [0.475, 0.0, 0.0]])
    v = np.array([[5.0, 0.0, 0.0], [-5.0, 0.0, 0.0]])
    return Simulation([0.0, 0.0], x, v, "verlet", 0.01, events=EventsConfig(collisions=Collisions(detect, "log")),
                      radii=[0.01, 0.01])


def test_line_detection_catches_a_pair_that_jumps_through_each_other_and_direct_misses_it() -> None:
    sims = {detect: fly_through(detect) for detect in ("direct", "line")}
    samples = {detect: collect(sim, 20) for detect, sim in sims.items()}
    separation = np.linalg.norm(samples["line"]["positions"][:, 0] - samples["line"]["positions"][:, 1], axis=1)
    assert separation.min() > 2 * 0.02  # no step end is anywhere near a contact
    assert [e for e in sims["direct"].watcher.log if e.kind == "collision"] == []
    hits = [e for e in sims["line"].watcher.log if e.kind == "collision"]
    assert len(hits) == 1, sims["line"].watcher.log
    assert (hits[0].i, hits[0].j, hits[0].step) == (0, 1, 10)
    assert hits[0].distance < 1e-12  # the segment passes through zero separation (exactly, up to round-off)
    assert hits[0].speed == pytest.approx(10.0, rel=1e-15)


# -- 3b. an encounter between two steps ----------------------------------------------------------

@pytest.mark.parametrize("phase", [0.5, 0.3, 0.7])
def test_encounter_between_two_steps_of_straight_line_flyby_is_caught(phase: float) -> None:
    """Two massless bodies pass each other on straight lines (no force acts), closest 0.02 apart
    at t = (3 + phase) dt, with dt = 1 and relative speed 2: every step end is at least 0.6 apart,
    far outside D = 0.1, but the minimum lies inside the step. r^2(t) is then a quadratic, so the
    cubic Hermite fit of r^2 is exact: the minimum must come out as 0.02 at the right time."""
    b, speed, dt, distance = 0.02, 2.0, 1.0, 0.1
    t_min = (3 + phase) * dt
    x = np.array([[-0.5 * speed * t_min, 0.5 * b, 0.0], [0.5 * speed * t_min, -0.5 * b, 0.0]])
    v = np.array([[0.5 * speed, 0.0, 0.0], [-0.5 * speed, 0.0, 0.0]])
    sim = Simulation([0.0, 0.0], x, v, "verlet", dt, events=EventsConfig(encounters=Encounters(distance=distance)))
    got = collect(sim, 8)
    separation = np.linalg.norm(got["positions"][:, 0] - got["positions"][:, 1], axis=1)
    assert separation.min() >= 0.6 > distance  # neither end of any step is within D
    encounters = [e for e in sim.watcher.outcome().events if e.kind == "encounter"]
    assert len(encounters) == 1, encounters
    e = encounters[0]
    assert (e.i, e.j, e.step_start, e.step) == (0, 1, 4, 4)
    assert e.distance == pytest.approx(b, rel=1e-6)  # exact fit: only round-off (relative 1e-6 of b)
    assert e.time == pytest.approx(t_min, abs=1e-6 * dt)
    assert e.speed == pytest.approx(speed, rel=1e-9)


# -- 4. the e = 0.99 comet -----------------------------------------------------------------------

#: Sun m = 1 and a massless comet with a = 1 au, e = 0.99 (q = 0.01 au), started at aphelion
#: (Q = 1.99 au), in au-yr-msun; perihelion at t = 0.5 yr, one orbit is 1 yr.
COMET_A, COMET_E = 1.0, 0.99


def comet(dt: float, eta: float = 1.0) -> Simulation:
    q_far = COMET_A * (1 + COMET_E)
    speed = math.sqrt(G_AU_YR * (2 / q_far - 1 / COMET_A))  # vis-viva at aphelion
    x = np.array([[0.0, 0.0, 0.0], [q_far, 0.0, 0.0]])
    v = np.array([[0.0, 0.0, 0.0], [0.0, speed, 0.0]])
    return Simulation([1.0, 0.0], x, v, "verlet", dt, G=G_AU_YR, events=EventsConfig(unresolved=Unresolved(eta)))


def unresolved_events(sim: Simulation, t_end: float = 1.0) -> list:
    collect(sim, round(t_end / sim.dt), max(1, round(0.1 / sim.dt)))
    return [e for e in sim.watcher.log if e.kind == "unresolved"]


def test_comet_at_a_large_dt_is_flagged_unresolved_and_named() -> None:
    """dt = 1e-3 yr is ~10x the comet's timescale at perihelion (tau ~ 9.2e-5 yr there): flagged
    once, on its way in, naming the comet (body 1) and the Sun it orbits, with a suggested dt below
    the step. Measured: flagged at t = 0.499 yr, 0.049 au from the Sun, suggested dt 8.9e-5 yr."""
    flagged = unresolved_events(comet(1e-3))
    assert len(flagged) == 1, flagged
    e = flagged[0]
    assert (e.i, e.j) == (1, 0)
    assert 0.45 < e.time <= 0.5 + 1e-3  # during the approach to perihelion (t = 0.5 yr)
    assert 0.0 < e.extra < 1e-3  # a suggested dt, shorter than the one used


def test_comet_at_a_small_dt_is_not_flagged() -> None:
    """dt = 1e-5 yr is ~9x shorter than tau at perihelion: no unresolved event over a whole orbit."""
    assert unresolved_events(comet(1e-5)) == []


def test_comet_run_at_the_suggested_dt_is_resolved() -> None:
    """The suggestion is a dt that resolves the whole passage, perihelion included (not only the
    state where the step was first found too long: 5.6e-4 yr there, which would be flagged again)."""
    suggested = unresolved_events(comet(1e-3))[0].extra
    assert unresolved_events(comet(suggested)) == []


# -- 6. without events, or with nothing to report, runs are unchanged ----------------------------

def quiet_system() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A star and two planets (body 0 dominant, as wisdom_holman needs) with radii far too small
    to touch; masses, positions, velocities, radii."""
    m = np.array([1.0, 1e-3, 3e-4])
    x = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.01], [0.0, 1.7, -0.02]])
    v = np.array([[0.0, 0.0, 0.0], [0.0, 1.0, 0.0], [-1.0 / math.sqrt(1.7), 0.0, 0.01]])
    return m, x, v, np.array([1e-3, 1e-5, 1e-5])


#: Everything on, nothing to report: contacts (``line``, the costlier check, with merge),
#: encounters closer than 1e-6, escapes beyond 1e6 (removed), unresolved steps at eta = 1.
EVERYTHING_QUIET = EventsConfig(collisions=Collisions("line", "merge"), encounters=Encounters(distance=1e-6),
                                escape=Escape(1e6, "remove"), unresolved=Unresolved(1.0))


def _integrators() -> list:
    """Every registered integrator; all but verlet (whose watched loop the other tests here compile
    anyway) are ``slow``. Measured with an empty Numba cache on the shared 2-core machine: 135 s
    for all nine (5-14 s a scheme, 35 s for the first, which compiles the shared kernels, and 44 s
    for wisdom_holman); 32 s with the shared kernels cached; well under 1 s each when warm."""
    from orbitsim.integrators.registry import INTEGRATORS

    return [pytest.param(spec.name, marks=() if spec.name == "verlet" else pytest.mark.slow)
            for spec in INTEGRATORS]


@pytest.mark.parametrize("integrator", _integrators())
def test_watched_run_with_nothing_to_report_is_bit_identical_to_plain_run(integrator: str) -> None:
    """One short run per integrator: 200 steps of dt = 1e-3, a sample every 10."""
    m, x, v, radii = quiet_system()
    plain = Simulation(m, x, v, integrator, 1e-3)
    watched = Simulation(m, x, v, integrator, 1e-3, events=EVERYTHING_QUIET, radii=radii)
    a, b = collect(plain, 200, 10), collect(watched, 200, 10)
    assert watched.watcher.log == [] and watched.watcher.outcome().events == ()
    for name in ("step", "time", "kinetic", "potential", "momentum", "angular_momentum", "positions", "velocities"):
        assert np.array_equal(a[name], b[name]), name
    assert not b["offset"].any()
    for name in ("pos", "vel", "acc"):
        assert np.array_equal(getattr(plain, name), getattr(watched, name)), name
