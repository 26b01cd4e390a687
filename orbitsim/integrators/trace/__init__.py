"""``trace``: the TRACE hybrid integrator in the engine (the step itself is :mod:`.core`).

A democratic heliocentric Wisdom-Holman map at the scenario's fixed ``dt`` that hands close
encounters (Hill-radius criterion with look-ahead) and pericentre passages (Pham, Rein & Spiegel
2024) to Bulirsch-Stoer, rejecting and redoing a step once when an encounter appears during it,
so the switching is time-reversible. Outputs fall on whole steps, as for every fixed-dt scheme.

Settings (REBOUND's names and defaults): ``r_crit_hill`` (3), ``peri_crit_eta`` (1) and
``peri_mode`` (``full_bs``: a pericentre step integrates the whole system with BS;
``partial_bs``: only the Kepler part of every body; ``full_ias15``: the whole system with a fresh
IAS15, :mod:`.ias15`).

State between steps: only ``pos``, ``vel`` and the time, which TRACE sums as ``t += dt`` (its BS
sub-steps run on the absolute clock, so the clock's last bits matter). The clock lives in ``work``
(``work.clock``: the time and the step count it belongs to), so a checkpoint restores it and a
resumed run continues bit for bit.

Massless bodies are test particles (REBOUND's ``testparticle_type = 0``) and must come after every
massive body.

Collisions (``events.collisions``): :func:`run_watched` arms the step's contact search inside the
Bulirsch-Stoer sub-steps (:mod:`.collide`); the merges it makes are taken out by
:mod:`orbitsim.events.driver` through :func:`take_merges`.

The package: :mod:`.core`, one step (REBOUND's ``step_try`` and its redo); :mod:`.switch`, the
switching criteria and the encounter bookkeeping; :mod:`.operators`, the democratic heliocentric
transforms and the jump; :mod:`.kepler`, the Kepler drift; :mod:`.forces`, the three right-hand
sides; :mod:`.bs`, the Bulirsch-Stoer step, and :mod:`.substeps`, its two sub-step loops;
:mod:`.ias15`, the ``full_ias15`` pericentre step; :mod:`.collide` and :mod:`.contacts`, contacts
inside the sub-steps; :mod:`.layout`, the ``work`` tuple; this module, the scheme's record
(:data:`TRACE`) and its run loops.

What TRACE takes from its neighbours, kept bit for bit with REBOUND 5.2.2 (tests/integrators/test_trace_core.py,
test_trace_engine.py, test_trace_ias15.py, test_trace_collisions.py):

* IAS15: the Gauss-Radau arithmetic of :mod:`orbitsim.integrators.ias15.core` is reused; only the
  try and its predictor-corrector passes are written again, around REBOUND's basic gravity
  (:mod:`.ias15` says why);
* the Kepler solver and the coordinate transforms are REBOUND's own, not
  :mod:`orbitsim.physics.kepler` and :mod:`orbitsim.physics.coordinates`, which round differently
  (:mod:`.kepler`, :mod:`.operators`);
* Bulirsch-Stoer: :mod:`.bs` is orbitsim's only one.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, NamedTuple

import numpy as np

from orbitsim._jit import jit, jit_inline
from orbitsim.events.bodies import HAND_MASSLESS_KEPLER, HAND_WHOLE_STEP
from orbitsim.events.kernels import after_step, remember_start
from orbitsim.integrators.base import (
    Integrator,
    IntegratorSpec,
    Setting,
    grid_time,
    record_sample,
    sample_loop,
    setting_defaults,
)
from orbitsim.integrators.trace.collide import H_MERGED, K_HITS, K_LOST
from orbitsim.integrators.trace.contacts import arm_collisions, post_contacts
from orbitsim.integrators.trace.core import PERI_MODES, active_count, counts_of, trace_steps
from orbitsim.integrators.trace.core import make_work as make_step_work
from orbitsim.integrators.trace.layout import (
    STATUS_IAS15_FAILED,
    STATUS_OK,
)
from orbitsim.integrators.trace.switch import FULL_IAS15, PARTIAL_BS, ST_CURRENT_C, ST_STATUS

__all__ = ["SETTINGS", "SPEC", "TRACE", "carry_over", "check_bodies", "counters", "failure_message", "handoff",
           "make_work", "run", "run_watched", "step", "take_merges", "validate_settings"]

SPEC = IntegratorSpec(
    name="trace",
    aliases=("hybrid",),
    order=2,
    symplectic=False,  # symplectic between switches; the switching itself is time-reversible, not symplectic
    reversible=False,  # reversible in exact arithmetic only where no BS step and no redo intervene
    force_evals=1,
    work_slots=0,
    fsal=False,
    summary="TRACE hybrid: democratic heliocentric Wisdom-Holman map, close encounters and pericentre passages "
    "by Bulirsch-Stoer with time-reversible switching (REBOUND's TRACE, bit for bit)",
    reference="Lu, Hernandez & Rein (2024), MNRAS 533, 3708; Pham, Rein & Spiegel (2024), OJAp 7, 1; "
    "Duncan, Levison & Lee (1998), AJ 116, 2067",
    module=__name__,
)

#: Settings a scenario may give (``integrator: {name: trace, r_crit_hill: 4}``): REBOUND's names and defaults.
SETTINGS: dict[str, Setting] = {
    "r_crit_hill": Setting(3.0, "a pair is an encounter, handed to Bulirsch-Stoer, within this many Hill radii "
                           "(the larger of the two), looking half a step ahead along the relative velocity"),
    "peri_crit_eta": Setting(1.0, "a body is near pericentre, and the step handed over, when dt > eta tau (tau: "
                             "Pham, Rein & Spiegel's 2024 timescale of its orbit about the star)"),
    "peri_mode": Setting("full_bs", "a pericentre step: full_bs integrates the whole system by Bulirsch-Stoer, "
                         "partial_bs only the Kepler parts (with the jump), full_ias15 the whole system by a "
                         "fresh IAS15", tuple(PERI_MODES)),
}

class TraceWork(NamedTuple):
    """A TRACE run's ``work``: a step's arrays (:class:`~.layout.StepWork`, the same fields first),
    then the clock (t, step of t) and the settings as numbers (r_crit_hill, peri_crit_eta) and
    codes (peri_mode, number of massive bodies)."""

    frames: np.ndarray
    acc: np.ndarray
    com: np.ndarray
    rows: np.ndarray
    bs_real: np.ndarray
    bs_int: np.ndarray
    prev_x: np.ndarray
    interacts: np.ndarray
    enc: np.ndarray
    book: np.ndarray
    radii: np.ndarray
    hits: np.ndarray
    collide: np.ndarray
    clock: np.ndarray
    real: np.ndarray
    codes: np.ndarray


def validate_settings(settings: Mapping[str, Any] | None) -> dict[str, Any]:
    """Check ``r_crit_hill`` (> 0), ``peri_crit_eta`` (>= 0) and ``peri_mode``; fill in defaults.

    A ``name`` key (the integrator name in the scenario mapping) is ignored. Raises ValueError
    naming the key.
    """
    given = {k: v for k, v in dict(settings or {}).items() if k != "name"}
    unknown = sorted(set(given) - set(SETTINGS))
    if unknown:
        raise ValueError(f"'{unknown[0]}' is not a trace setting (settings: {', '.join(SETTINGS)})")
    config = {**setting_defaults(SETTINGS), **given}
    for key, lowest, strict in (("r_crit_hill", 0.0, True), ("peri_crit_eta", 0.0, False)):
        value = config[key]
        if isinstance(value, bool) or not isinstance(value, int | float) or not np.isfinite(value) \
                or (value <= lowest if strict else value < lowest):
            raise ValueError(f"'{key}' must be a finite number {'>' if strict else '>='} 0, got {value!r}")
        config[key] = float(value)
    mode = str(config["peri_mode"]).strip().lower()
    if mode not in PERI_MODES:
        raise ValueError(f"'peri_mode' must be one of {', '.join(PERI_MODES)}, got {config['peri_mode']!r}")
    config["peri_mode"] = mode
    return config


def check_bodies(m: np.ndarray) -> None:
    """A central body with mass first, and massless bodies (test particles) after every massive
    one; raises ValueError saying which rule the masses break."""
    active_count(np.ascontiguousarray(m, dtype=np.float64))


def make_work(m: np.ndarray, G: float, settings: Mapping[str, Any] | None = None) -> TraceWork:
    """The step's scratch (:func:`.core.make_work`), the clock and the settings.

    Raises ValueError for invalid settings, a central body without mass, or a massless body
    before a massive one.
    """
    config = validate_settings(settings)
    masses = np.ascontiguousarray(m, dtype=np.float64)
    n_active = active_count(masses)
    clock = np.array([np.nan, -1.0])  # unset: the first call starts it at t0 + n dt
    real = np.array([config["r_crit_hill"], config["peri_crit_eta"]])
    codes = np.array([PERI_MODES[config["peri_mode"]], n_active], dtype=np.int64)
    return TraceWork(*make_step_work(masses.shape[0]), clock, real, codes)


def carry_over(old: tuple[Any, ...], new: tuple[Any, ...]) -> None:
    """After the bodies changed (a merge, a removal): keep the clock and the counters."""
    new.clock[:] = old.clock
    new.book[:] = old.book


def counters(work: tuple[Any, ...]) -> dict[str, int]:
    """Steps, steps redone, encounter and FULL_BS sub-steps (written to the trace's attributes)."""
    return counts_of(work)


def failure_message(work: tuple[Any, ...]) -> str | None:
    """Why the run stopped, when TRACE knows."""
    status = int(work.book[ST_STATUS])
    if status == STATUS_OK:
        return None
    if status == STATUS_IAS15_FAILED:
        return ("trace: the IAS15 of a full_ias15 pericentre step could not finish it (its step fell to nothing or "
                "the state became non-finite: a body passed through another; give the bodies radii and an events: "
                "collisions section, or use peri_mode full_bs)")
    return ("trace: a Bulirsch-Stoer sub-step of a close encounter produced nan (two bodies came closer than the "
            "encounter integrator can follow; give the bodies radii and an events: collisions section to merge or "
            "halt them at contact)")


def take_merges(work: tuple[Any, ...]) -> tuple[np.ndarray, np.ndarray]:
    """The merges TRACE made inside the last step (rows of
    :data:`~.collide.HIT_COLUMNS`) and the radii after them; the table is emptied.

    A body that merged away is still in the arrays, as a massless husk with radius 0, until the
    caller takes it out (:mod:`orbitsim.events.driver`).
    """
    collide, hits = work.collide, work.hits
    rows = hits[: min(int(collide[K_HITS]), hits.shape[0])].copy()
    lost = int(collide[K_LOST])
    collide[K_HITS] = 0
    collide[K_LOST] = 0
    if lost:
        raise RuntimeError(f"trace: {lost} merges inside one step did not fit the contact table")
    return rows[rows[:, H_MERGED] != 0.0], work.radii.copy()


@jit_inline
def _advance(pos, vel, m, force, dt, work, t0, n_done, n_to, with_ias15):
    """Steps from ``n_done`` to ``n_to`` on TRACE's summed clock (:func:`.core.trace_steps`, one call;
    ``with_ias15`` None leaves the full_ias15 pericentre step out of it); returns the steps reached."""
    _set_clock(work, t0, n_done, dt)  # first call, or a run that continues elsewhere: the clock of step n_done
    if n_done >= n_to:
        return n_done
    clock = work.clock
    real, codes = work.real, work.codes
    dt_last_done = 0.0 if n_done == 0 else dt  # as in one REBOUND run from the scenario's start
    t, taken = trace_steps(pos, vel, m, force.G, dt, clock[0], dt_last_done, n_to - n_done, real[0], real[1], codes[0],
                           codes[1], force.eps2, work.frames, work.acc, work.com, work.rows, work.bs_real, work.bs_int,
                           work.prev_x, work.interacts, work.enc, work.book, work.radii, work.hits, work.collide,
                           with_ias15)
    clock[0] = t
    n_done += taken
    clock[1] = n_done
    return n_done


@jit
def _set_clock(work, t0, n_done, dt):
    clock = work.clock
    if clock[1] != n_done:
        clock[0] = t0 + n_done * dt
        clock[1] = n_done


@jit
def step(pos, vel, acc, m, force, dt, work):
    """One step from the clock's time (t = 0 on a fresh ``work``), ``pos``/``vel`` in and out
    (``acc`` is not used)."""
    _one_step(pos, vel, m, force, dt, work, True)


@jit_inline
def _one_step(pos, vel, m, force, dt, work, with_ias15):
    n = max(int(work.clock[1]), 0)  # an unset clock (-1) is started at t = 0 by _advance
    _advance(pos, vel, m, force, dt, work, 0.0, n, n + 1, with_ias15)


@jit_inline
def advance(pos, vel, acc, m, force, dt, work, t0, n_done, n_to):
    """Steps from ``n_done`` to ``n_to`` on TRACE's clock; False when a step failed (a
    Bulirsch-Stoer sub-step produced nan, or a full_ias15 step could not finish)."""
    n_done = _advance(pos, vel, m, force, dt, work, t0, n_done, n_to, True)
    return n_done, work.book[ST_STATUS] == STATUS_OK


@jit_inline
def _advance_without_ias15(pos, vel, acc, m, force, dt, work, t0, n_done, n_to):
    """:func:`advance` for a run whose ``peri_mode`` is not full_ias15."""
    n_done = _advance(pos, vel, m, force, dt, work, t0, n_done, n_to, None)
    return n_done, work.book[ST_STATUS] == STATUS_OK


def _with_ias15(work: TraceWork) -> bool:
    """Whether a run needs the full_ias15 pericentre step compiled (its ``peri_mode``)."""
    return int(work.codes[0]) == FULL_IAS15


def run(state: tuple[np.ndarray, ...], force: Any, dt: float, work: TraceWork, t0: float, n_done: int,
        targets: np.ndarray, record: np.ndarray, out: Any) -> Any:
    """:func:`~orbitsim.integrators.base.sample_loop` of :func:`advance`, from the clock of step
    ``n_done`` (set when the run continues elsewhere). A run whose ``peri_mode`` is not full_ias15
    runs a kernel compiled without that step (:func:`.core.trace_steps`): a first run compiles less."""
    kernel = _run_any_mode if _with_ias15(work) else _run_without_ias15
    return kernel(state, force, dt, work, t0, n_done, targets, record, out)


@jit
def _run_any_mode(state, force, dt, work, t0, n_done, targets, record, out):
    _set_clock(work, t0, n_done, dt)
    return sample_loop(advance, grid_time, state, force, dt, work, t0, n_done, targets, record, out)


@jit
def _run_without_ias15(state, force, dt, work, t0, n_done, targets, record, out):
    _set_clock(work, t0, n_done, dt)
    return sample_loop(_advance_without_ias15, grid_time, state, force, dt, work, t0, n_done, targets, record, out)


@jit_inline
def _handoff(work):
    """What the last step integrated with Bulirsch-Stoer (or IAS15) rather than the fixed-dt map,
    for the events' unresolved-step check (:func:`orbitsim.events.bodies.handed_over`): the pairs
    flagged as encounters (``interacts``), the encounter set, whose orbits about the star BS
    integrated (every body in a partial_bs pericentre step), and the whole step in a full_bs or
    full_ias15 pericentre step. A massless body's orbit about the star is the Kepler drift, exact
    at any dt; TRACE never hands it over (its pericentre criterion skips test particles) and
    nothing else in the step depends on its own motion, so it is not judged either."""
    flags = HAND_MASSLESS_KEPLER
    if work.book[ST_CURRENT_C] != 0 and work.codes[0] != PARTIAL_BS:
        flags |= HAND_WHOLE_STEP
    return work.interacts, work.enc[0], flags


def handoff(work: tuple[Any, ...]) -> tuple[np.ndarray, np.ndarray, int]:
    """:func:`_handoff` of the last step, as copies (for the checks Python runs after a merge)."""
    pairs, bodies, flags = _handoff_now(work)
    return pairs.copy(), bodies.copy(), int(flags)


@jit
def _handoff_now(work):
    return _handoff(work)


def run_watched(state: tuple[np.ndarray, ...], force: Any, dt: float, work: TraceWork, t0: float, n_done: int,
                targets: np.ndarray, record: np.ndarray, out: Any, watch: Any) -> Any:
    """:func:`run` one :func:`step` at a time with the events watch after each (:mod:`orbitsim.events`).

    TRACE also searches its Bulirsch-Stoer sub-steps for contacts (:mod:`.collide`) when
    the scenario detects collisions. A step with such a contact that merges or halts returns
    to Python at once, without the end-of-step checks: Python takes the merged bodies out first
    and runs those checks on what is left (:mod:`orbitsim.events.driver`). Compiled without the
    full_ias15 step where ``peri_mode`` is another, as :func:`run`.
    """
    if _with_ias15(work):
        return _run_watched_any_mode(state, force, dt, work, t0, n_done, targets, record, out, watch)
    return _run_watched_without_ias15(state, force, dt, work, t0, n_done, targets, record, out, watch)


@jit
def _run_watched_any_mode(state, force, dt, work, t0, n_done, targets, record, out, watch):
    return _watched(state, force, dt, work, t0, n_done, targets, record, out, watch, True)


@jit
def _run_watched_without_ias15(state, force, dt, work, t0, n_done, targets, record, out, watch):
    return _watched(state, force, dt, work, t0, n_done, targets, record, out, watch, None)


@jit_inline
def _watched(state, force, dt, work, t0, n_done, targets, record, out, watch, with_ias15):
    _set_clock(work, t0, n_done, dt)
    arm_collisions(work.radii, work.collide, watch)
    pos, vel, _acc, m = state
    written = np.int64(0)  # not the literal 0: record_sample would compile twice (for Literal[int](0) and int64)
    for k in range(targets.shape[0]):
        while n_done < targets[k]:
            remember_start(watch, pos, vel)
            _one_step(pos, vel, m, force, dt, work, with_ias15)
            n_done += 1
            if work.book[ST_STATUS] != STATUS_OK:
                return written, n_done, False, False
            if post_contacts(watch, work.hits, work.collide, n_done):
                return written, n_done, True, True
            if after_step(watch, pos, vel, m, n_done, t0, dt, _handoff(work)):
                return written, n_done, True, True
        if record[k]:
            if not record_sample(written, n_done, grid_time(work, t0, n_done, dt), pos, vel, m, force, out):
                return written, n_done, False, False
            written += 1
    return written, n_done, True, False


TRACE = Integrator(
    spec=SPEC,
    step=step,
    run=run,
    run_watched=run_watched,
    settings=SETTINGS,
    validate_settings=validate_settings,
    make_work=make_work,
    carry_over=carry_over,
    check_bodies=check_bodies,
    failure_message=failure_message,
    counters=counters,
    take_merges=take_merges,
    handoff=handoff,
)
