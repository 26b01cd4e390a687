"""TRACE's two Bulirsch-Stoer sub-step loops, with the collision search after each accepted one.

* :func:`encounter_bs`: the bodies of the encounter set, taken back to their state before the
  Kepler drift, re-integrated over the outer dt in democratic heliocentric coordinates under the
  star's pull and their flagged pairs (REBOUND ``reb_integrator_trace_bs_step``);
* :func:`full_bs_step`: a pericentre step in ``full_bs`` mode, the whole system in the inertial
  frame on the plain Newtonian problem (:func:`full_ias15` does the same with IAS15, ``full_ias15``
  mode, through :mod:`.ias15`).

Both run on the absolute clock from t (REBOUND's BS sub-steps do, and the clock's last bits
decide the last sub-step), with a fresh controller, and both differ from REBOUND's only in what
REBOUND does with a collision that orbitsim resolves otherwise (:mod:`.collide`): a body
that merged away stays in the arrays as a massless husk, out of the ODE, until the step ends.

The ODE's kind and the flags go to :func:`.bs.bs_step` and :func:`_collide` as run-time values
(``np.int64(ODE_NEWTON)``, ``np.bool_(False)``), not as the constants themselves: Numba types a
module constant as a literal and compiles a callee once per literal, so the two loops compiled
``bs_step`` and its midpoint step twice (8.7 s more CPU on a cold ``many_encounters`` run). The
callees branch on the value at run time, with the same operations.
"""

from __future__ import annotations

import numpy as np

from orbitsim._jit import jit
from orbitsim.integrators.ias15.core import CLOCK_DT_LAST_DONE, COUNT_ACCEPTED
from orbitsim.integrators.trace.bs import (
    BS_ACCEPTED,
    BS_DT_PROPOSED,
    BS_FIRST_OR_LAST_STEP,
    BS_NAN,
    R_Y,
    bs_reset,
    bs_step,
)
from orbitsim.integrators.trace.collide import DETECT_NONE, K_DETECT, collide_set
from orbitsim.integrators.trace.forces import ODE_ENCOUNTER, ODE_NEWTON
from orbitsim.integrators.trace.ias15 import STATUS_OK as IAS15_OK
from orbitsim.integrators.trace.ias15 import full_ias15_step, new_full_ias15_work
from orbitsim.integrators.trace.layout import (
    C_CONTACTS,
    C_ENC_REJECTED,
    C_ENC_SUBSTEPS,
    C_FULL_IAS15,
    C_FULL_SUBSTEPS,
    F_KEPLER_POS,
    F_KEPLER_VEL,
    MIN_SUBSTEP_FRACTION,
    STATUS_BS_NAN,
    STATUS_IAS15_FAILED,
)
from orbitsim.integrators.trace.operators import dh_to_inertial, inertial_to_dh
from orbitsim.integrators.trace.switch import ST_CURRENT_C, ST_ENC_N_ACTIVE, ST_FORCE_ACCEPT, ST_STATUS, ST_TPONLY


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
def _collide(pos, vel, m, G, bodies, n_set, n_set_active, h, t_sub, radii, hits, collide, bs_int, book,
             heliocentric):
    """The contact search after an accepted sub-step; returns the set's new (size, active size).

    A contact makes the step final; a merge shrinks the ODE (a fresh BS start, as REBOUND's
    re-created ODE); a merge into the star moves the star off the heliocentric origin, so every
    position is shifted back (REBOUND does the same; the star's new velocity is kept).
    """
    n_new, n_new_active, contacts = collide_set(pos, vel, m, radii, G, bodies, n_set, n_set_active, h, t_sub,
                                                hits, collide)
    if contacts == 0:
        return n_set, n_set_active
    book[ST_FORCE_ACCEPT] = 1
    book[C_CONTACTS] += contacts
    if n_new != n_set:
        bs_int[BS_FIRST_OR_LAST_STEP] = 1
    if heliocentric and (pos[0, 0] != 0.0 or pos[1, 0] != 0.0 or pos[2, 0] != 0.0):
        x0, y0, z0 = pos[0, 0], pos[1, 0], pos[2, 0]
        for i in range(pos.shape[1]):
            pos[0, i] -= x0
            pos[1, i] -= y0
            pos[2, i] -= z0
    return n_new, n_new_active


@jit
def encounter_bs(pos, vel, m, G, softening2, n_active, dt, t, frames, rows, bs_real, bs_int, interacts, enc,
                 book, radii, hits, collide):
    """Re-integrate the encounter set over dt with BS (REBOUND ``reb_integrator_trace_bs_step``)."""
    n_enc, n_enc_active = _gather_encounter(pos, vel, n_active, frames, enc, book)
    bodies = enc[0]
    with_jump = book[ST_CURRENT_C] != 0
    search = collide[K_DETECT] != DETECT_NONE
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
        result = bs_step(rows, 6 * n_enc, h, bs_real, bs_int, np.int64(ODE_ENCOUNTER), m, G, softening2, bodies,
                         n_enc, n_enc_active, interacts, with_jump)
        book[C_ENC_SUBSTEPS] += 1
        if result == BS_NAN:
            book[ST_STATUS] = STATUS_BS_NAN
            return
        accepted = result == BS_ACCEPTED
        if accepted:
            t_sub += h
        else:
            book[C_ENC_REJECTED] += 1
        taken = h
        h = bs_real[BS_DT_PROPOSED]
        # The star's entries are unchanged (position 0; its velocity is kept outside the ODE).
        for k in range(1, n_enc):
            for c in range(3):
                pos[c, bodies[k]] = rows[R_Y, 6 * k + c]
                vel[c, bodies[k]] = rows[R_Y, 6 * k + 3 + c]
        if accepted and search:
            n_enc, n_enc_active = _collide(pos, vel, m, G, bodies, n_enc, n_enc_active, taken, t_sub, radii, hits,
                                           collide, bs_int, book, np.bool_(True))
    if book[ST_TPONLY]:
        # Only test particles met massive bodies, which do not feel them: put the massive bodies
        # back exactly on their Kepler drift, so test particles never change them.
        for k in range(1, n_enc_active):
            for c in range(3):
                pos[c, bodies[k]] = frames[F_KEPLER_POS, c, bodies[k]]
                vel[c, bodies[k]] = frames[F_KEPLER_VEL, c, bodies[k]]


@jit
def full_bs_step(pos, vel, m, G, softening2, n_active, dt, t, com, rows, bs_real, bs_int, interacts, enc, book,
                 radii, hits, collide):
    """The whole step by BS on the inertial Newtonian problem (the FULL_BS pericentre step).

    The ODE's bodies are listed in ``enc[1]`` (every body; a merge takes one out), which the
    post-step check of a FULL step does not read.
    """
    n = pos.shape[1]
    bodies = enc[1]
    for i in range(n):
        bodies[i] = i
    n_set = n
    n_set_active = n_active
    search = collide[K_DETECT] != DETECT_NONE
    # Uses the stored centre of mass; after a rejected try it has already moved on (module doc).
    dh_to_inertial(pos, vel, m, n_active, com)
    bs_reset(bs_real, bs_int)
    t_needed = t + dt
    t_sub = t
    h = dt
    while t_sub < t_needed and abs(h / dt) > MIN_SUBSTEP_FRACTION:
        for k in range(n_set):
            for c in range(3):
                rows[R_Y, 6 * k + c] = pos[c, bodies[k]]
                rows[R_Y, 6 * k + 3 + c] = vel[c, bodies[k]]
        result = bs_step(rows, 6 * n_set, h, bs_real, bs_int, np.int64(ODE_NEWTON), m, G, softening2, bodies, n_set,
                         n_set_active, interacts, np.bool_(False))
        book[C_FULL_SUBSTEPS] += 1
        if result == BS_NAN:
            book[ST_STATUS] = STATUS_BS_NAN
            break
        accepted = result == BS_ACCEPTED
        taken = h
        if accepted:
            t_sub += h
        h = bs_real[BS_DT_PROPOSED]
        if t_sub + h > t_needed:
            h = t_needed - t_sub  # here the clamp follows the proposal (REBOUND's order)
        for k in range(n_set):
            for c in range(3):
                pos[c, bodies[k]] = rows[R_Y, 6 * k + c]
                vel[c, bodies[k]] = rows[R_Y, 6 * k + 3 + c]
        if accepted and search:
            n_set, n_set_active = _collide(pos, vel, m, G, bodies, n_set, n_set_active, taken, t_sub, radii, hits,
                                           collide, bs_int, book, np.bool_(False))
    # Recomputes the centre of mass from the new state.
    inertial_to_dh(pos, vel, m, n_active, com)


@jit
def full_ias15(pos, vel, acc, m, G, softening2, n_active, dt, t, dt_last_done, com, book):
    """The whole step by a fresh IAS15 on the inertial Newtonian problem (the FULL_IAS15 pericentre
    step, :func:`.ias15.full_ias15_step`). Returns REBOUND's ``dt_last_done`` for a redo of
    this step: the last IAS15 step taken.

    Contacts are not searched inside it (REBOUND does, after every IAS15 step): IAS15 would go on
    integrating a merged-away body, which sets its steps. The end-of-step checks see them.
    """
    # Uses the stored centre of mass, as full_bs_step does.
    dh_to_inertial(pos, vel, m, n_active, com)
    ias15_work = new_full_ias15_work(pos.shape[1])
    status = full_ias15_step(pos, vel, acc, m, G, softening2, n_active, dt, t, dt_last_done, ias15_work)
    book[C_FULL_IAS15] += ias15_work.counts[COUNT_ACCEPTED]
    if status != IAS15_OK:
        book[ST_STATUS] = STATUS_IAS15_FAILED
    inertial_to_dh(pos, vel, m, n_active, com)
    return ias15_work.clock[CLOCK_DT_LAST_DONE]
