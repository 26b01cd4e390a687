"""One step of TRACE, the time-reversible hybrid integrator (Lu, Hernandez & Rein 2024), jitted.

TRACE is a democratic heliocentric Wisdom-Holman map whose close encounters and pericentre
passages are handed to Bulirsch-Stoer. One step of size dt, from the inertial state:

1. :func:`~.trace_operators.inertial_to_dh`: heliocentric positions, barycentric velocities (the star's included),
   and the centre of mass, which drifts separately.
2. :func:`~.trace_switch.pre_step_check`: flag pairs that will come within ``r_crit_hill`` Hill
   radii during the first half step, and bodies near pericentre.
3. The step (REBOUND's ``step_try``, in :func:`_trace_step`):

   * no pericentre flag, or ``peri_mode = PARTIAL_BS``: kick(dt/2) jump(dt/2) Kepler(dt)
     jump(dt/2) kick(dt/2), where the kicks leave out the flagged pairs, and the bodies of the
     encounter set are taken back to their pre-drift state and integrated with BS under the Kepler
     force plus their flagged pairs (plus the jump term, with every body in the set, in a PARTIAL_BS
     pericentre step, whose jumps are skipped);
   * a pericentre flag with ``peri_mode = FULL_BS``: the whole system by BS in the inertial frame.

4. :func:`~.trace_switch.post_step_check` on the end state, looking back over the second half
   step; if it adds any flag, the step is redone once from the start with the union of flags.
5. :func:`~.trace_operators.dh_to_inertial`.

The port reproduces REBOUND 5.2.2's ``integrator_trace.c`` (with ``integrator_bs.c`` and WHFast's
Kepler solver) to the bit: the same operation order everywhere, the BS sub-step clock that starts
at the absolute time t, a fresh BS controller per Kepler step, FULL step and redo, and REBOUND's
centre-of-mass quirk: the centre of mass is not rolled back when a step is redone, so after a
redone step the system sits one extra ``dt * v_com`` further on (zero in the barycentric frame,
which is how TRACE is normally run; kept for parity).

Test particles: bodies ``n_active..N-1`` (massless, after all massive bodies), REBOUND's
``testparticle_type = 0``. Encounters that involve only test particles leave the massive bodies
exactly on their Kepler-drift state. Not in this module yet: collisions (see the hook comments in
:func:`_encounter_bs` and :func:`_full_bs_step`), FULL_IAS15, user forces.

References
----------
.. [1] Lu, T., Hernandez, D. M. & Rein, H. (2024), MNRAS 533, 3708 (TRACE).
.. [2] Pham, D., Rein, H. & Spiegel, D. S. (2024), OJAp 7, 1 (pericentre timescale).
.. [3] Duncan, M. J., Levison, H. F. & Lee, M. H. (1998), AJ 116, 2067 (democratic heliocentric).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from orbitsim._jit import jit, jit_inline
from orbitsim.integrators.trace_bs import (
    BS_ACCEPTED,
    BS_DT_PROPOSED,
    BS_INT_LENGTH,
    BS_NAN,
    BS_REAL_LENGTH,
    N_ROWS,
    R_Y,
    bs_reset,
    bs_step,
)
from orbitsim.integrators.trace_forces import ODE_ENCOUNTER, ODE_NEWTON, interaction_kick
from orbitsim.integrators.trace_kepler import PREV_X_LENGTH, kepler_drift
from orbitsim.integrators.trace_operators import dh_to_inertial, inertial_to_dh, jump, restore_state, save_state
from orbitsim.integrators.trace_switch import (
    FULL_BS,
    PARTIAL_BS,
    ST_CURRENT_C,
    ST_ENC_N,
    ST_ENC_N_ACTIVE,
    ST_FORCE_ACCEPT,
    ST_STATUS,
    ST_TPONLY,
    STATE_LENGTH,
    post_step_check,
    pre_step_check,
)

#: ``peri_mode`` by name (FULL_IAS15, REBOUND's mode 2, is not ported yet).
PERI_MODES = {"partial_bs": PARTIAL_BS, "full_bs": FULL_BS}

#: A BS sub-step loop ends when the proposed step falls below this fraction of the outer dt
#: (REBOUND's guard against a stalled clock).
MIN_SUBSTEP_FRACTION = 1e-14

#: Slots of the ``work`` tuple (:func:`make_work`). Arrays are grouped so that a step passes few
#: of them: every array argument of a jitted call costs an atomic reference-count round trip,
#: which took ~20% of a step's time before the grouping (measured with perf).
W_FRAMES, W_ACC, W_COM, W_ROWS, W_BS_REAL, W_BS_INT, W_PREV_X, W_INTERACTS, W_ENC, W_BOOK = range(10)
#: Planes of ``work[W_FRAMES]`` (4, 3, N): the democratic heliocentric state at the start of the
#: step (restored by a redo) and after the first jump (the encounter bodies' BS start).
F_BACKUP_POS, F_BACKUP_VEL, F_KEPLER_POS, F_KEPLER_VEL = range(4)

#: Counters in ``work[W_BOOK]``, after the ``ST_*`` flags: steps taken, steps rejected and redone,
#: encounter BS sub-steps tried and rejected, FULL_BS steps (tries: a redo counts again) and
#: their BS sub-steps.
C_STEPS, C_REDONE, C_ENC_SUBSTEPS, C_ENC_REJECTED, C_FULL_STEPS, C_FULL_SUBSTEPS = range(
    STATE_LENGTH, STATE_LENGTH + 6)
COUNT_NAMES = ("steps", "redone", "encounter_bs_substeps", "encounter_bs_rejected", "full_bs_steps",
               "full_bs_substeps")
BOOK_LENGTH = STATE_LENGTH + len(COUNT_NAMES)

#: ``ST_STATUS`` values: fine, or a BS step produced nan (the run stops, as REBOUND's).
STATUS_OK, STATUS_BS_NAN = 0, 1


def make_work(n_bodies: int) -> tuple[np.ndarray, ...]:
    """Scratch and bookkeeping arrays for TRACE steps of ``n_bodies`` bodies (slots ``W_*``).

    Nothing in it carries over from one step to the next except the counters: every step
    rebuilds its flags and its BS controller, as REBOUND does.
    """
    n = int(n_bodies)
    if n < 2:
        raise ValueError(f"TRACE needs a central body and at least one other body, got {n} bodies")
    return (
        np.zeros((4, 3, n)), np.zeros((3, n)), np.zeros(6),
        np.zeros((N_ROWS, 6 * n)), np.zeros(BS_REAL_LENGTH), np.zeros(BS_INT_LENGTH, dtype=np.int64),
        np.zeros(PREV_X_LENGTH),
        np.zeros((n, n), dtype=np.uint8), np.zeros((2, n), dtype=np.int64), np.zeros(BOOK_LENGTH, dtype=np.int64),
    )


def counts_of(work: tuple[np.ndarray, ...]) -> dict[str, int]:
    """The counters of ``work`` by name (:data:`COUNT_NAMES`)."""
    book = work[W_BOOK]
    return {name: int(book[C_STEPS + k]) for k, name in enumerate(COUNT_NAMES)}


@jit
def _gather_encounter(pos, vel, n_active, frames, enc, book):
    """Take the encounter bodies back to their pre-drift state and compact ``enc[0]`` (flags ->
    the list of their indices, star first); with test-particle-only encounters keep the massive
    bodies' drifted state in the Kepler planes for the restore. Returns (size, active size)."""
    n_enc = 0
    n_enc_active = 0
    keep_drifted = book[ST_TPONLY] != 0
    for i in range(pos.shape[1]):
        if not enc[0, i]:
            continue
        for c in range(3):
            x = pos[c, i]
            v = vel[c, i]
            pos[c, i] = frames[F_KEPLER_POS, c, i]
            vel[c, i] = frames[F_KEPLER_VEL, c, i]
            if i < n_active and keep_drifted:
                frames[F_KEPLER_POS, c, i] = x
                frames[F_KEPLER_VEL, c, i] = v
        enc[0, n_enc] = i
        n_enc += 1
        if i < n_active:
            n_enc_active += 1
    book[ST_ENC_N_ACTIVE] = n_enc_active
    return n_enc, n_enc_active


@jit
def _encounter_bs(pos, vel, m, G, softening2, n_active, dt, t, frames, rows, bs_real, bs_int, interacts, enc,
                  book):
    """Re-integrate the encounter set over dt with BS (REBOUND ``reb_integrator_trace_bs_step``)."""
    n_enc, n_enc_active = _gather_encounter(pos, vel, n_active, frames, enc, book)
    bodies = enc[0]
    with_jump = book[ST_CURRENT_C] != 0
    length = 6 * n_enc
    bs_reset(bs_real, bs_int)
    # The sub-step clock is absolute: it starts at t, and the last sub-step is t_needed - t_sub.
    t_needed = t + dt
    t_sub = t
    h = dt  # the first trial is the whole step
    while t_sub < t_needed and abs(h / dt) > MIN_SUBSTEP_FRACTION:
        if t_sub + h > t_needed:
            h = t_needed - t_sub
        for k in range(n_enc):
            for c in range(3):
                rows[R_Y, 6 * k + c] = pos[c, bodies[k]]
                rows[R_Y, 6 * k + 3 + c] = vel[c, bodies[k]]
        for c in range(3):
            rows[R_Y, 3 + c] = 0.0  # the star rests at the heliocentric origin
        result = bs_step(rows, length, h, bs_real, bs_int, ODE_ENCOUNTER, m, G, softening2, bodies, n_enc,
                         n_enc_active, interacts, with_jump)
        book[C_ENC_SUBSTEPS] += 1
        if result == BS_NAN:
            book[ST_STATUS] = STATUS_BS_NAN
            return
        if result == BS_ACCEPTED:
            t_sub += h
        else:
            book[C_ENC_REJECTED] += 1
        h = bs_real[BS_DT_PROPOSED]
        # The star's entries are unchanged (position 0; its velocity is kept outside the ODE).
        for k in range(1, n_enc):
            for c in range(3):
                pos[c, bodies[k]] = rows[R_Y, 6 * k + c]
                vel[c, bodies[k]] = rows[R_Y, 6 * k + 3 + c]
        # Collision hook: after an accepted sub-step REBOUND searches the encounter set
        # (heliocentric frame, star velocity restored), merges, sets ST_FORCE_ACCEPT, rebuilds
        # the ODE if the set shrank, and re-centres on the star if it merged.
    if book[ST_TPONLY]:
        # Only test particles met massive bodies, which do not feel them: put the massive bodies
        # back exactly on their Kepler drift, so test particles never change them.
        for k in range(1, n_enc_active):
            for c in range(3):
                pos[c, bodies[k]] = frames[F_KEPLER_POS, c, bodies[k]]
                vel[c, bodies[k]] = frames[F_KEPLER_VEL, c, bodies[k]]


@jit
def _full_bs_step(pos, vel, m, G, softening2, n_active, dt, t, com, rows, bs_real, bs_int, interacts, enc, book):
    """The whole step by BS on the inertial Newtonian problem (the FULL_BS pericentre step)."""
    n = pos.shape[1]
    # Uses the stored centre of mass; after a rejected try it has already moved on (module doc).
    dh_to_inertial(pos, vel, m, n_active, com)
    length = 6 * n
    bs_reset(bs_real, bs_int)
    t_needed = t + dt
    t_sub = t
    h = dt
    while t_sub < t_needed and abs(h / dt) > MIN_SUBSTEP_FRACTION:
        for k in range(n):
            for c in range(3):
                rows[R_Y, 6 * k + c] = pos[c, k]
                rows[R_Y, 6 * k + 3 + c] = vel[c, k]
        result = bs_step(rows, length, h, bs_real, bs_int, ODE_NEWTON, m, G, softening2, enc[0], n, n_active,
                         interacts, False)
        book[C_FULL_SUBSTEPS] += 1
        if result == BS_NAN:
            book[ST_STATUS] = STATUS_BS_NAN
            break
        if result == BS_ACCEPTED:
            t_sub += h
        h = bs_real[BS_DT_PROPOSED]
        if t_sub + h > t_needed:
            h = t_needed - t_sub  # here the clamp follows the proposal (REBOUND's order)
        for k in range(n):
            for c in range(3):
                pos[c, k] = rows[R_Y, 6 * k + c]
                vel[c, k] = rows[R_Y, 6 * k + 3 + c]
        # Collision hook: after an accepted sub-step REBOUND searches all pairs (inertial frame),
        # merges and sets ST_FORCE_ACCEPT.
    # Recomputes the centre of mass from the new state.
    inertial_to_dh(pos, vel, m, n_active, com)


@jit_inline
def _trace_step(pos, vel, m, G, dt, t, r_crit_hill, peri_crit_eta, peri_mode, n_active, softening2, frames, acc,
                com, rows, bs_real, bs_int, prev_x, interacts, enc, book):
    """:func:`trace_step` on the unpacked work arrays.

    The try and the redo (REBOUND's ``step_try``) are one loop here rather than a function: a
    call with these 13 arrays cost more than the operators of a step without encounters. For the
    same reason this step, and the operators and checks it calls, are inlined into the run loops.
    """
    inertial_to_dh(pos, vel, m, n_active, com)
    save_state(pos, vel, frames, F_BACKUP_POS)
    book[ST_FORCE_ACCEPT] = 0
    hill6 = acc[0]  # scratch of the checks: free there, as the kick overwrites acc before it reads it
    pre_step_check(pos, vel, m, G, dt, n_active, r_crit_hill, peri_crit_eta, peri_mode, interacts, enc, book,
                   hill6)
    for attempt in range(2):
        if attempt == 1:
            # Redo once, from the start, with the union of the flags if the end state added any;
            # never after a collision (ST_FORCE_ACCEPT), which cannot be undone.
            if book[ST_STATUS] != STATUS_OK or book[ST_FORCE_ACCEPT] or not post_step_check(
                    pos, vel, m, G, dt, n_active, r_crit_hill, peri_crit_eta, peri_mode, interacts, enc, book,
                    hill6):
                break
            book[C_REDONE] += 1
            restore_state(pos, vel, frames, F_BACKUP_POS)
        current_c = book[ST_CURRENT_C] != 0
        if current_c and peri_mode != PARTIAL_BS:
            book[C_FULL_STEPS] += 1
            _full_bs_step(pos, vel, m, G, softening2, n_active, dt, t, com, rows, bs_real, bs_int, interacts, enc,
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
            _encounter_bs(pos, vel, m, G, softening2, n_active, dt, t, frames, rows, bs_real, bs_int, interacts,
                          enc, book)
        for c in range(3):
            com[c] += dt * com[3 + c]
        if not current_c:
            jump(pos, vel, m, n_active, half)
        interaction_kick(pos, vel, m, G, softening2, n_active, interacts, acc, half)
    dh_to_inertial(pos, vel, m, n_active, com)
    book[C_STEPS] += 1


@jit
def trace_step(pos, vel, m, G, dt, t, r_crit_hill, peri_crit_eta, peri_mode, n_active, softening, work):
    """One TRACE step of dt from time t; inertial ``pos``, ``vel`` (3, N) updated in place.

    ``m`` (N,): masses, body 0 the central one; bodies ``n_active..N-1`` are test particles.
    ``peri_mode``: :data:`~.trace_switch.PARTIAL_BS` or :data:`~.trace_switch.FULL_BS`. The
    caller advances t (``t += dt``, as REBOUND). ``work``: :func:`make_work`.
    """
    frames, acc, com, rows, bs_real, bs_int, prev_x, interacts, enc, book = work
    _trace_step(pos, vel, m, G, dt, t, r_crit_hill, peri_crit_eta, peri_mode, n_active, softening * softening,
                frames, acc, com, rows, bs_real, bs_int, prev_x, interacts, enc, book)


@jit
def trace_run(pos, vel, m, G, dt, t0, n_steps, r_crit_hill, peri_crit_eta, peri_mode, n_active, softening, work):
    """``n_steps`` TRACE steps of dt from t0 (see :func:`trace_step`); returns the final time.

    Stops early if a BS step produced nan (``work[W_BOOK][ST_STATUS]``).
    """
    frames, acc, com, rows, bs_real, bs_int, prev_x, interacts, enc, book = work
    softening2 = softening * softening
    t = t0
    for _ in range(n_steps):
        _trace_step(pos, vel, m, G, dt, t, r_crit_hill, peri_crit_eta, peri_mode, n_active, softening2, frames,
                    acc, com, rows, bs_real, bs_int, prev_x, interacts, enc, book)
        t += dt
        if book[ST_STATUS] != STATUS_OK:
            break
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
            softening: float = 0.0, work: tuple[np.ndarray, ...] | None = None) -> tuple[float, dict[str, Any]]:
    """Validate and take ``n_steps`` TRACE steps in place; returns the final time and the counters.

    ``pos``, ``vel``: C-contiguous float64 (3, N) inertial arrays, changed in place; ``m`` (N,):
    the central body first, test particles (m = 0) after every massive body. ``work`` (from
    :func:`make_work`) carries the counters across calls; the time is summed as ``t += dt``.
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
    elif work[W_FRAMES].shape[2] != pos.shape[1]:
        raise ValueError(f"work was made for {work[W_FRAMES].shape[2]} bodies, not {pos.shape[1]}")
    t = trace_run(pos, vel, masses, float(G), float(dt), float(t0), int(n_steps), float(r_crit_hill),
                  float(peri_crit_eta), PERI_MODES[peri_mode], n_active, float(softening), work)
    counts: dict[str, Any] = counts_of(work)
    counts["status"] = int(work[W_BOOK][ST_STATUS])
    return float(t), counts
