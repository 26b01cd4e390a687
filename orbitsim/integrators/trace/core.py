"""One step of TRACE, the time-reversible hybrid integrator (Lu, Hernandez & Rein 2024), jitted.

TRACE is a democratic heliocentric Wisdom-Holman map whose close encounters and pericentre
passages are handed to Bulirsch-Stoer. One step of size dt, from the inertial state:

1. :func:`~.operators.inertial_to_dh`: heliocentric positions, barycentric velocities (the star's included),
   and the centre of mass, which drifts separately.
2. :func:`~.switch.pre_step_check`: flag pairs that will come within ``r_crit_hill`` Hill
   radii during the first half step, and bodies near pericentre.
3. The step (REBOUND's ``step_try``, in :func:`trace_steps`):

   * no pericentre flag, or ``peri_mode = PARTIAL_BS``: kick(dt/2) jump(dt/2) Kepler(dt)
     jump(dt/2) kick(dt/2), where the kicks leave out the flagged pairs, and the bodies of the
     encounter set are taken back to their pre-drift state and integrated with BS under the Kepler
     force plus their flagged pairs (plus the jump term, with every body in the set, in a PARTIAL_BS
     pericentre step, whose jumps are skipped);
   * a pericentre flag with ``peri_mode = FULL_BS``: the whole system by BS in the inertial frame.

4. :func:`~.switch.post_step_check` on the end state, looking back over the second half
   step; if it adds any flag, the step is redone once from the start with the union of flags.
5. :func:`~.operators.dh_to_inertial`.

The port reproduces REBOUND 5.2.2's ``integrator_trace.c`` (with ``integrator_bs.c`` and WHFast's
Kepler solver) to the bit: the same operation order everywhere, the BS sub-step clock that starts
at the absolute time t, a fresh BS controller per Kepler step, FULL step and redo, and REBOUND's
centre-of-mass quirk: the centre of mass is not rolled back when a step is redone, so after a
redone step the system sits one extra ``dt * v_com`` further on (zero in the barycentric frame,
which is how TRACE is normally run; kept for parity).

Test particles: bodies ``n_active..N-1`` (massless, after all massive bodies), REBOUND's
``testparticle_type = 0``. Encounters that involve only test particles leave the massive bodies
exactly on their Kepler-drift state.

Collisions: when the caller sets radii and codes in the work (:mod:`.contacts`), the
Bulirsch-Stoer sub-step loops (:mod:`.substeps`) search for contacts after every accepted
sub-step and merge, halt or log them (:mod:`.collide`). The FULL_IAS15 pericentre step is
:mod:`.ias15`'s. Forces beyond Newtonian gravity are not applied: a run with forces refuses
``trace`` (:mod:`orbitsim.forces.compat`).

References
----------
.. [1] Lu, T., Hernandez, D. M. & Rein, H. (2024), MNRAS 533, 3708 (TRACE).
.. [2] Pham, D., Rein, H. & Spiegel, D. S. (2024), OJAp 7, 1 (pericentre timescale).
.. [3] Duncan, M. J., Levison, H. F. & Lee, M. H. (1998), AJ 116, 2067 (democratic heliocentric).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from orbitsim._jit import jit
from orbitsim.integrators.trace.bs import BS_INT_LENGTH, BS_REAL_LENGTH, N_ROWS
from orbitsim.integrators.trace.collide import COLLIDE_LENGTH, HIT_COLUMNS, K_DETECT
from orbitsim.integrators.trace.forces import interaction_kick
from orbitsim.integrators.trace.kepler import PREV_X_LENGTH, kepler_drift
from orbitsim.integrators.trace.layout import (
    BOOK_LENGTH,
    C_FULL_STEPS,
    C_REDONE,
    C_STEPS,
    COUNT_NAMES,
    F_BACKUP_POS,
    F_KEPLER_POS,
    STATUS_BS_NAN,
    STATUS_IAS15_FAILED,
    STATUS_OK,
    StepWork,
)
from orbitsim.integrators.trace.operators import dh_to_inertial, inertial_to_dh, jump, restore_state, save_state
from orbitsim.integrators.trace.substeps import encounter_bs, full_bs_step, full_ias15
from orbitsim.integrators.trace.switch import (
    FULL_BS,
    FULL_IAS15,
    PARTIAL_BS,
    ST_CURRENT_C,
    ST_ENC_N,
    ST_FORCE_ACCEPT,
    ST_STATUS,
    post_step_check,
    pre_step_check,
)

__all__ = ["PERI_MODES", "STATUS_BS_NAN", "STATUS_OK", "active_count", "advance", "counts_of", "make_work",
           "trace_run", "trace_step", "trace_steps"]

#: ``peri_mode`` by name (REBOUND's modes 0, 1, 2).
PERI_MODES = {"partial_bs": PARTIAL_BS, "full_bs": FULL_BS, "full_ias15": FULL_IAS15}

#: Rows of the contact table beyond one per body (merges need at most N - 1 rows a step; contacts
#: that only log or halt are recorded once per pair and step, and a full table is reported).
EXTRA_HIT_ROWS = 64


def make_work(n_bodies: int) -> tuple[np.ndarray, ...]:
    """Scratch and bookkeeping arrays for TRACE steps of ``n_bodies`` bodies (slots ``W_*``).

    Nothing in it carries over from one step to the next except the counters: every step
    rebuilds its flags and its BS controller, as REBOUND does. Collisions are off until the
    caller sets the radii and the codes (:mod:`.collide`).
    """
    n = int(n_bodies)
    if n < 2:
        raise ValueError(f"TRACE needs a central body and at least one other body, got {n} bodies")
    return StepWork(
        np.zeros((4, 3, n)), np.zeros((3, n)), np.zeros(6),
        np.zeros((N_ROWS, 6 * n)), np.zeros(BS_REAL_LENGTH), np.zeros(BS_INT_LENGTH, dtype=np.int64),
        np.zeros(PREV_X_LENGTH),
        np.zeros((n, n), dtype=np.uint8), np.zeros((2, n), dtype=np.int64), np.zeros(BOOK_LENGTH, dtype=np.int64),
        np.zeros(n), np.zeros((n + EXTRA_HIT_ROWS, len(HIT_COLUMNS))), np.zeros(COLLIDE_LENGTH, dtype=np.int64),
    )


def counts_of(work: tuple[np.ndarray, ...]) -> dict[str, int]:
    """The counters of ``work`` by name (:data:`COUNT_NAMES`)."""
    book = work.book
    return {name: int(book[C_STEPS + k]) for k, name in enumerate(COUNT_NAMES)}


@jit
def trace_steps(pos, vel, m, G, dt, t, dt_last_done, n_steps, r_crit_hill, peri_crit_eta, peri_mode, n_active,
                softening2, frames, acc, com, rows, bs_real, bs_int, prev_x, interacts, enc, book, radii, hits,
                collide, with_ias15):
    """Up to ``n_steps`` steps (:func:`trace_step`) on the unpacked work arrays, from time t summed as
    ``t += dt``; the first step reads ``dt_last_done``, the others dt. Stops after a step that failed
    (``book[ST_STATUS]``). Returns the time reached and the steps taken.

    ``with_ias15``: None when ``peri_mode`` is not FULL_IAS15, which leaves the FULL_IAS15 step (and
    the IAS15 it compiles, a fifth of TRACE's first-run compilation) out of this compilation: Numba
    prunes a branch on an argument that is None before it types the function. Anything else (True)
    compiles every mode.

    The try and the redo (REBOUND's ``step_try``) are one loop here rather than a function: a
    call with these 13 arrays cost more than the operators of a step without encounters. For the
    same reason the operators and checks a step calls are inlined here, and the loop over steps is
    this function's own: every run loop calls it once per stretch of steps. (Written as an inlined
    step, the step's IR, some 4,700 variables after its own inlining, was deep-copied block by block
    into each loop, and a first run spent 9 s of its CPU copying it.)
    """
    taken = 0
    while taken < n_steps:
        if taken > 0:
            dt_last_done = dt  # a full_ias15 step returns its own for a redo within the step
        inertial_to_dh(pos, vel, m, n_active, com)
        save_state(pos, vel, frames, F_BACKUP_POS)
        book[ST_FORCE_ACCEPT] = 0
        hill6 = acc[0]  # scratch of the checks: free there, as the kick overwrites acc before it reads it
        star_radius = radii[0] if collide[K_DETECT] != 0 else 0.0
        pre_step_check(pos, vel, m, G, dt, n_active, r_crit_hill, peri_crit_eta, peri_mode, interacts, enc, book,
                       hill6, star_radius)
        for attempt in range(2):
            if attempt == 1:
                # Redo once, from the start, with the union of the flags if the end state added any;
                # never after a collision (ST_FORCE_ACCEPT), which cannot be undone.
                if book[ST_STATUS] != STATUS_OK or book[ST_FORCE_ACCEPT] or not post_step_check(
                        pos, vel, m, G, dt, n_active, r_crit_hill, peri_crit_eta, peri_mode, interacts, enc, book,
                        hill6, star_radius):
                    break
                book[C_REDONE] += 1
                restore_state(pos, vel, frames, F_BACKUP_POS)
            current_c = book[ST_CURRENT_C] != 0
            if current_c and peri_mode != PARTIAL_BS:
                book[C_FULL_STEPS] += 1
                if peri_mode == FULL_BS:
                    full_bs_step(pos, vel, m, G, softening2, n_active, dt, t, com, rows, bs_real, bs_int, interacts,
                                 enc, book, radii, hits, collide)
                elif with_ias15 is None:
                    book[ST_STATUS] = STATUS_IAS15_FAILED  # never reached: the caller passes None for other modes only
                else:
                    # A redo after this try passes on the try's last IAS15 step (REBOUND's dt_last_done).
                    dt_last_done = full_ias15(pos, vel, acc, m, G, softening2, n_active, dt, t, dt_last_done, com,
                                              book)
                continue
            half = dt / 2.0
            interaction_kick(pos, vel, m, G, softening2, n_active, interacts, acc, half)
            if not current_c:  # a PARTIAL_BS pericentre step moves the jump into the BS equations
                jump(pos, vel, m, n_active, half)
            # Kepler drift of every body about the star; the encounter set is then redone with BS
            # from the state before the drift (saved only when there is one: nothing else reads it).
            if book[ST_ENC_N] >= 2:
                save_state(pos, vel, frames, F_KEPLER_POS)
            mu = G * m[0]
            for i in range(1, pos.shape[1]):
                (pos[0, i], pos[1, i], pos[2, i], vel[0, i], vel[1, i], vel[2, i]) = kepler_drift(
                    pos[0, i], pos[1, i], pos[2, i], vel[0, i], vel[1, i], vel[2, i], mu, dt, prev_x)
            if book[ST_ENC_N] >= 2:
                encounter_bs(pos, vel, m, G, softening2, n_active, dt, t, frames, rows, bs_real, bs_int, interacts,
                             enc, book, radii, hits, collide)
            for c in range(3):
                com[c] += dt * com[3 + c]
            if not current_c:
                jump(pos, vel, m, n_active, half)
            interaction_kick(pos, vel, m, G, softening2, n_active, interacts, acc, half)
        dh_to_inertial(pos, vel, m, n_active, com)
        book[C_STEPS] += 1
        t += dt
        taken += 1
        if book[ST_STATUS] != STATUS_OK:
            break
    return t, taken


@jit
def trace_step(pos, vel, m, G, dt, t, dt_last_done, r_crit_hill, peri_crit_eta, peri_mode, n_active, softening,
               work):
    """One TRACE step of dt from time t; inertial ``pos``, ``vel`` (3, N) updated in place.

    ``m`` (N,): masses, body 0 the central one; bodies ``n_active..N-1`` are test particles.
    ``peri_mode``: one of :data:`PERI_MODES`' values. ``dt_last_done``: REBOUND's, which a
    FULL_IAS15 step reads (0 on the first step of a run, else the last dt). The caller advances t
    (``t += dt``, as REBOUND). ``work``: :func:`make_work`.
    """
    frames, acc, com, rows, bs_real, bs_int, prev_x, interacts, enc, book, radii, hits, collide = work
    trace_steps(pos, vel, m, G, dt, t, dt_last_done, 1, r_crit_hill, peri_crit_eta, peri_mode, n_active,
                softening * softening, frames, acc, com, rows, bs_real, bs_int, prev_x, interacts, enc, book, radii,
                hits, collide, True)


@jit
def trace_run(pos, vel, m, G, dt, t0, n_steps, r_crit_hill, peri_crit_eta, peri_mode, n_active, softening,
              dt_last_done, work):
    """``n_steps`` TRACE steps of dt from t0 (see :func:`trace_step`); returns the final time.

    Stops early if a BS step produced nan (``work.book[ST_STATUS]``).
    """
    frames, acc, com, rows, bs_real, bs_int, prev_x, interacts, enc, book, radii, hits, collide = work
    t, _ = trace_steps(pos, vel, m, G, dt, t0, dt_last_done, n_steps, r_crit_hill, peri_crit_eta, peri_mode, n_active,
                       softening * softening, frames, acc, com, rows, bs_real, bs_int, prev_x, interacts, enc, book,
                       radii, hits, collide, True)
    return t


def active_count(m: np.ndarray) -> int:
    """Number of massive bodies; massless ones (test particles) must all come after them."""
    massive = np.asarray(m) > 0.0
    n_active = int(np.count_nonzero(massive))
    if not massive[0]:
        raise ValueError("TRACE needs a central body (index 0) with a mass > 0")
    if not np.all(massive[:n_active]):
        raise ValueError("test particles (m = 0) must come after every massive body")
    return n_active


def advance(pos: np.ndarray, vel: np.ndarray, m: np.ndarray, G: float, dt: float, t0: float, n_steps: int, *,
            r_crit_hill: float = 3.0, peri_crit_eta: float = 1.0, peri_mode: str = "full_bs",
            softening: float = 0.0, work: tuple[np.ndarray, ...] | None = None, dt_last_done: float = 0.0,
            ) -> tuple[float, dict[str, Any]]:
    """Validate and take ``n_steps`` TRACE steps in place; returns the final time and the counters.

    ``pos``, ``vel``: C-contiguous float64 (3, N) inertial arrays, changed in place; ``m`` (N,):
    the central body first, test particles (m = 0) after every massive body. ``work`` (from
    :func:`make_work`) carries the counters across calls; the time is summed as ``t += dt``.
    ``dt_last_done``: REBOUND's before the first step (0 at the start of an ``integrate``, else
    the last step's dt), which a ``full_ias15`` pericentre step reads.
    """
    if peri_mode not in PERI_MODES:
        raise ValueError(f"peri_mode must be one of {sorted(PERI_MODES)}, got {peri_mode!r}")
    for name, arr in (("pos", pos), ("vel", vel)):
        if not (isinstance(arr, np.ndarray) and arr.dtype == np.float64 and arr.ndim == 2 and arr.shape[0] == 3
                and arr.flags.c_contiguous and arr.flags.writeable):
            raise ValueError(f"{name} must be a writeable C-contiguous float64 array of shape (3, N)")
    masses = np.ascontiguousarray(m, dtype=np.float64)
    if masses.shape != (pos.shape[1],) or vel.shape != pos.shape:
        raise ValueError("pos, vel and m must describe the same N bodies")
    if not (np.isfinite(dt) and dt > 0.0):
        raise ValueError(f"dt must be a finite number > 0, got {dt!r}")
    if not (np.isfinite(G) and G > 0.0 and np.all(np.isfinite(masses)) and np.all(masses >= 0.0)):
        raise ValueError("G must be finite and > 0, the masses finite and >= 0")
    if not (r_crit_hill > 0.0 and peri_crit_eta >= 0.0 and softening >= 0.0):
        raise ValueError("r_crit_hill must be > 0, peri_crit_eta and softening >= 0")
    n_active = active_count(masses)
    if work is None:
        work = make_work(pos.shape[1])
    elif work.frames.shape[2] != pos.shape[1]:
        raise ValueError(f"work was made for {work.frames.shape[2]} bodies, not {pos.shape[1]}")
    t = trace_run(pos, vel, masses, float(G), float(dt), float(t0), int(n_steps), float(r_crit_hill),
                  float(peri_crit_eta), PERI_MODES[peri_mode], n_active, float(softening), float(dt_last_done), work)
    counts: dict[str, Any] = counts_of(work)
    counts["status"] = int(work.book[ST_STATUS])
    return float(t), counts
