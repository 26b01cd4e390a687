"""The layout of TRACE's ``work`` tuple: its slots, the frames it keeps, its counters and codes.

Shared by the step (:mod:`.core`), its Bulirsch-Stoer sub-step loops
(:mod:`.substeps`) and the engine front door (:mod:`orbitsim.integrators.trace`).
"""

from __future__ import annotations

from orbitsim.integrators.trace.switch import STATE_LENGTH

#: A BS sub-step loop ends when the proposed step falls below this fraction of the outer dt
#: (REBOUND's guard against a stalled clock).
MIN_SUBSTEP_FRACTION = 1e-14

#: Slots of the ``work`` tuple (:func:`make_work`). Arrays are grouped so that a step passes few
#: of them: every array argument of a jitted call costs an atomic reference-count round trip,
#: which took ~20% of a step's time before the grouping (measured with perf).
W_FRAMES, W_ACC, W_COM, W_ROWS, W_BS_REAL, W_BS_INT, W_PREV_X, W_INTERACTS, W_ENC, W_BOOK = range(10)
#: Collision slots (:mod:`.collide`): the radii (N,), the contacts of the step (``hits``) and
#: the codes and counts (``collide``).
W_RADII, W_HITS, W_COLLIDE = 10, 11, 12
N_SLOTS = 13
#: Planes of ``work[W_FRAMES]`` (4, 3, N): the democratic heliocentric state at the start of the
#: step (restored by a redo) and after the first jump (the encounter bodies' BS start).
F_BACKUP_POS, F_BACKUP_VEL, F_KEPLER_POS, F_KEPLER_VEL = range(4)

#: Counters in ``work[W_BOOK]``, after the ``ST_*`` flags: steps taken, steps rejected and redone,
#: encounter BS sub-steps tried and rejected, FULL steps (full_bs or full_ias15; named "full_bs_steps";
#: a redo counts again) and
#: their BS sub-steps, contacts found inside sub-steps, and the IAS15 steps of FULL_IAS15 steps.
C_STEPS, C_REDONE, C_ENC_SUBSTEPS, C_ENC_REJECTED, C_FULL_STEPS, C_FULL_SUBSTEPS, C_CONTACTS, C_FULL_IAS15 = range(
    STATE_LENGTH, STATE_LENGTH + 8)
COUNT_NAMES = ("steps", "redone", "encounter_bs_substeps", "encounter_bs_rejected", "full_bs_steps",
               "full_bs_substeps", "contacts", "full_ias15_steps")
BOOK_LENGTH = STATE_LENGTH + len(COUNT_NAMES)

#: ``ST_STATUS`` values: fine, a BS step produced nan (the run stops, as REBOUND's), or a FULL_IAS15
#: step failed (its step fell to nothing, or the state became non-finite).
STATUS_OK, STATUS_BS_NAN, STATUS_IAS15_FAILED = 0, 1, 2
