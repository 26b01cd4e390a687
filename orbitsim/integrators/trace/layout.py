"""The layout of TRACE's ``work``: its arrays, the frames it keeps, its counters and codes.

Shared by the step (:mod:`.core`), its Bulirsch-Stoer sub-step loops
(:mod:`.substeps`) and the engine front door (:mod:`orbitsim.integrators.trace`).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from orbitsim.integrators.trace.switch import STATE_LENGTH

#: A BS sub-step loop ends when the proposed step falls below this fraction of the outer dt
#: (REBOUND's guard against a stalled clock).
MIN_SUBSTEP_FRACTION = 1e-14

class StepWork(NamedTuple):
    """The arrays of a TRACE step (:func:`.core.make_work`). Arrays are grouped so that a step passes
    few of them: every array argument of a jitted call costs an atomic reference-count round trip,
    which took ~20% of a step's time before the grouping (measured with perf)."""

    frames: np.ndarray  #: (4, 3, N) the planes F_* below
    acc: np.ndarray  #: (3, N) accelerations
    com: np.ndarray  #: (6,) the centre of mass's position and velocity
    rows: np.ndarray  #: (N_ROWS, 6N) scratch rows of the Bulirsch-Stoer state
    bs_real: np.ndarray  #: Bulirsch-Stoer's real state
    bs_int: np.ndarray  #: Bulirsch-Stoer's integer state
    prev_x: np.ndarray  #: positions before the step (the encounter check)
    interacts: np.ndarray  #: (N, N) uint8: the pairs in an encounter
    enc: np.ndarray  #: (2, N) int64: the encounter bodies
    book: np.ndarray  #: int64 (BOOK_LENGTH,): the ST_* flags, then the counters C_* below
    radii: np.ndarray  #: (N,) collision radii (:mod:`.collide`)
    hits: np.ndarray  #: the contacts of the step
    collide: np.ndarray  #: int64 the collision codes and counts


#: Planes of ``work.frames`` (4, 3, N): the democratic heliocentric state at the start of the
#: step (restored by a redo) and after the first jump (the encounter bodies' BS start).
F_BACKUP_POS, F_BACKUP_VEL, F_KEPLER_POS, F_KEPLER_VEL = range(4)

#: Counters in ``work.book``, after the ``ST_*`` flags: steps taken, steps rejected and redone,
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
