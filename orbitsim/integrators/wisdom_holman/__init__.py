"""Wisdom-Holman map (WHFast arrangement): exact Kepler orbits about the star plus planet kicks.

For a dominant central body (body 0) the Hamiltonian splits into Kepler orbits and a small
interaction (:mod:`orbitsim.integrators.wisdom_holman.operators`). One step of size dt is

    Jacobi:                    K(dt/2) I(dt) K(dt/2)
    democratic heliocentric:   K(dt/2) J(dt/2) I(dt) J(dt/2) K(dt/2)

(K: Kepler drift in universal variables, I: interaction kick, J: the heliocentric jump). Its
error is O(eps dt^2) with eps the planet/star mass ratio, so steps can be hundreds of times larger
than a leapfrog's at the same accuracy. Second order, symplectic and time-reversible.

The arrangement is exactly REBOUND's WHFast with ``safe_mode = 0`` and
``keep_unsynchronized = 1`` (see :mod:`orbitsim.reference.wh_pairing`): the closing K(dt/2) of a
step and the opening K(dt/2) of the next are merged into one K(dt); an output copies the mapping
state, applies the owed K(dt/2) and the inverse corrector to the copy, and transforms it to
inertial coordinates. Symplectic correctors (orders 3-17, :mod:`~.correctors`) are applied
only at those output times and when the map starts.

The package: :mod:`.operators`, the map's operators (coordinate transforms, interaction kick,
jump) and the ``work`` layout; :mod:`.correctors`, the symplectic correctors; :mod:`.settings`,
the settings and their validation; :mod:`.state`, what a checkpoint saves and what a Kepler
failure left; this module, the map itself and the scheme's record (:data:`WISDOM_HOLMAN`).

Internal state (what a checkpoint must save to continue bit for bit)
--------------------------------------------------------------------
Between steps the scheme lives in ``work``, not in ``pos``/``vel``:

* ``mapping_positions``, ``mapping_velocities`` (3, N): the corrected Jacobi (or democratic
  heliocentric) state, column 0 the centre of mass, *after* the kick of the last step, i.e.
  still owing that step's closing K(dt/2) (phase "lagging");
* ``phase``: 0 not started (the next call derives the mapping state from ``pos``/``vel``),
  1 started but no step taken yet (the next drift is dt/2), 2 lagging (the next drift is dt);
* ``synced_positions``, ``synced_velocities`` (3, N): the inertial state the last
  synchronisation wrote. At every call the map continues from its internal state only if
  ``pos``/``vel`` still hold exactly these bits; if anything changed them, it restarts from
  ``pos``/``vel`` (as REBOUND recomputes Jacobi coordinates when particles were modified).

:func:`internal_state` and :func:`restore_internal_state` copy these arrays out and back.
``run`` synchronises ``pos``/``vel`` at every recorded sample and at the end of every call (on
a copy), so the internal state never depends on where outputs fall or how
:class:`orbitsim.simulation.Simulation` cuts the run into calls: same input, same bits.

Kepler failures
---------------
The jitted drift returns a status; on a failure ``run`` sets ``pos``/``vel`` to nan (so
orbitsim's divergence path stops the run), stores the status, body and step in ``work`` and
returns ``finite = False``. :func:`failure_message` turns that into one line (used in
:class:`orbitsim.simulation.SimulationResult`'s message) and :func:`raise_for_failure` raises
:class:`~orbitsim.physics.kepler.KeplerConvergenceError`.

References
----------
.. [1] Wisdom, J. & Holman, M. (1991), "Symplectic maps for the N-body problem", AJ 102, 1528.
.. [2] Rein, H. & Tamayo, D. (2015), "WHFast: a fast and unbiased implementation of a symplectic
       Wisdom-Holman integrator for long-term gravitational simulations", MNRAS 452, 376.
.. [3] Duncan, M. J., Levison, H. F. & Lee, M. H. (1998), AJ 116, 2067 (democratic heliocentric).
.. [4] Wisdom, J., Holman, M. & Touma, J. (1996), Fields Inst. Commun. 10, 217 (correctors).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from orbitsim._jit import jit, jit_inline
from orbitsim.events.kernels import watched_run
from orbitsim.forces.hooks import ByVelocityForces, no_velocity_operator, velocity_operator
from orbitsim.integrators.base import Integrator, IntegratorSpec, grid_time, sample_loop
from orbitsim.integrators.wisdom_holman.correctors import CORRECTOR_STAGES, apply_corrector
from orbitsim.integrators.wisdom_holman.operators import (
    F_PHASE,
    JACOBI,
    PHASE_LAGGING,
    PHASE_SYNCED,
    PHASE_UNSET,
    WHWork,
    com_drift,
    from_inertial,
    interaction_kick,
    jump,
    to_inertial_pos,
    to_inertial_vel,
)
from orbitsim.integrators.wisdom_holman.operators import record_failure as _fail
from orbitsim.integrators.wisdom_holman.settings import COORDINATE_IDS, SETTINGS, validate_settings
from orbitsim.integrators.wisdom_holman.state import (
    failure_message,
    internal_state,
    raise_for_failure,
    restore_internal_state,
)
from orbitsim.integrators.wisdom_holman.tangent import check_chaos, run_chaos
from orbitsim.physics.coordinates import jacobi_weights
from orbitsim.physics.kepler import (
    KEPLER_OK,
    KEPLER_SCRATCH_ROWS,
    KeplerConvergenceError,
    kepler_drift_bodies,
)

__all__ = [
    "SETTINGS",
    "SPEC",
    "WISDOM_HOLMAN",
    "KeplerConvergenceError",
    "check_bodies",
    "failure_message",
    "internal_state",
    "make_work",
    "raise_for_failure",
    "restore_internal_state",
    "run",
    "run_chaos",
    "run_watched",
    "step",
    "validate_settings",
]

SPEC = IntegratorSpec(
    name="wisdom_holman",
    aliases=("wh",),
    order=2,
    symplectic=True,
    reversible=True,
    force_evals=1,
    work_slots=0,
    fsal=False,
    summary="Wisdom-Holman map (REBOUND WHFast arrangement): Kepler drifts about body 0 plus planet "
    "kicks; Jacobi or democratic heliocentric coordinates, optional symplectic correctors",
    reference="Wisdom & Holman (1991), AJ 102, 1528; Rein & Tamayo (2015), MNRAS 452, 376 (WHFast); "
    "Wisdom, Holman & Touma (1996), Fields Inst. Commun. 10, 217 (correctors)",
    module=__name__,
)

def check_bodies(m: np.ndarray) -> None:
    """The map drifts every body about body 0: raises ValueError unless ``m[0] > 0``."""
    if len(m) < 1 or not m[0] > 0.0:
        raise ValueError("wisdom_holman needs a central body: the first body's mass must be > 0")


def make_work(m: np.ndarray, G: float, settings: Mapping[str, Any] | None = None) -> WHWork:
    """Build the ``work`` (:class:`~.operators.WHWork`: mapping state, scratch, constants) for masses ``m`` (N,).

    Raises ValueError for invalid settings or a central body without mass (``m[0] <= 0``).
    """
    config = validate_settings(settings)
    m = np.ascontiguousarray(m, dtype=np.float64)
    n = m.shape[0]
    check_bodies(m)
    coordinates = COORDINATE_IDS[config["coordinates"]]
    if coordinates == JACOBI:
        mu = G * np.cumsum(m)  # G M_i, M_i summed left to right
    else:
        mu = np.full(n, G * m[0])
    # no corrector: None, a type of its own, so a run without one compiles none (apply_corrector)
    stage_a, stage_b = CORRECTOR_STAGES[config["corrector"]] if config["corrector"] else (None, None)
    flags = np.zeros(4, dtype=np.int64)
    flags[F_PHASE] = PHASE_UNSET
    state = tuple(np.zeros((3, n)) for _ in range(8))
    return WHWork(
        *state,
        weights=jacobi_weights(m),
        mu=np.ascontiguousarray(mu),
        stage_a=None if stage_a is None else stage_a.copy(),
        stage_b=None if stage_b is None else stage_b.copy(),
        flags=flags,
        config=np.array([coordinates, config["corrector"]], dtype=np.int64),
        kscratch=np.zeros((KEPLER_SCRATCH_ROWS, n)),
        kstage=np.zeros(n, dtype=np.int64),
        heliocentric=None if coordinates == JACOBI else np.int64(coordinates),
    )


@jit_inline
def _state_changed(pos, vel, work):
    """True unless ``pos``, ``vel`` hold exactly the bits of the last synchronisation."""
    last_pos = work.last_pos
    last_vel = work.last_vel
    for c in range(3):
        for i in range(pos.shape[1]):
            if pos[c, i] != last_pos[c, i] or vel[c, i] != last_vel[c, i]:
                return True
    return False


@jit_inline
def _copy_state(pos, vel, to_pos, to_vel):
    """to_pos, to_vel = pos, vel (3, N), by explicit loops: a slice assignment costs more than a
    planetary system's copy (with velocity-dependent forces the map restarts every step)."""
    for c in range(3):
        for i in range(pos.shape[1]):
            to_pos[c, i] = pos[c, i]
            to_vel[c, i] = vel[c, i]


@jit_inline
def _remember(pos, vel, work):
    _copy_state(pos, vel, work.last_pos, work.last_vel)


@jit_inline
def _start(pos, vel, m, force, dt, work):
    """Mapping state from the inertial ``pos``, ``vel``, then the corrector C; returns (status, body)."""
    jpos = work.jpos
    jvel = work.jvel
    from_inertial(pos, vel, m, work.weights, work.heliocentric, jpos, jvel)
    _remember(pos, vel, work)
    flags = work.flags
    for k in range(flags.shape[0]):
        flags[k] = 0
    flags[F_PHASE] = PHASE_SYNCED
    return apply_corrector(jpos, jvel, m, force, dt, 1.0, work, work.stage_a, work.stage_b)


@jit_inline
def _synchronize(pos, vel, m, force, dt, work):
    """Inertial state at the current step into ``pos``, ``vel``, from a copy of the mapping state."""
    if work.flags[F_PHASE] != PHASE_LAGGING:
        return KEPLER_OK, 0  # no step since the start: pos, vel still hold the start state
    spos = work.spos
    svel = work.svel
    _copy_state(work.jpos, work.jvel, spos, svel)
    half = 0.5 * dt
    status, body = kepler_drift_bodies(spos, svel, work.mu, half, 1, work.kscratch, work.kstage)
    if status != KEPLER_OK:
        return status, body
    com_drift(spos, svel, half)
    status, body = apply_corrector(spos, svel, m, force, dt, -1.0, work, work.stage_a, work.stage_b)
    if status != KEPLER_OK:
        return status, body
    to_inertial_pos(spos, m, work.weights, work.heliocentric, pos)
    to_inertial_vel(svel, m, work.weights, work.heliocentric, vel)
    _remember(pos, vel, work)
    return KEPLER_OK, 0


@jit_inline
def _ensure_started(pos, vel, m, force, dt, work, n_done):
    """Continue from the internal state, or (re)start from ``pos``/``vel``; False on failure."""
    if work.flags[F_PHASE] != PHASE_UNSET and not _state_changed(pos, vel, work):
        return True
    status, body = _start(pos, vel, m, force, dt, work)
    if status != KEPLER_OK:
        _fail(pos, vel, work, status, body, n_done)
        return False
    return True


@jit_inline
def step(pos, vel, acc, m, force, dt, work):
    """One step, ``pos``/``vel`` in and out (``acc`` is not used); same bits as :func:`run`.

    Inlined, with the restart and synchronisation around it (``_ensure_started``, ``_start``,
    ``_synchronize``): with velocity-dependent forces :func:`advance_split` takes this step every step,
    and the calls' reference counts on ``work``'s arrays cost ~8% of a Wisdom-Holman + ``gr`` step
    of the Solar System (and compiling them apart took longer than inlined)."""
    # int64 values, not literals: a literal argument compiles a callee once more for its own type.
    no_step, zero, one = np.int64(-1), np.int64(0), np.int64(1)
    if not _ensure_started(pos, vel, m, force, dt, work, no_step):
        return
    _, status, body = _advance_to(one, zero, m, force, dt, work)
    if status == KEPLER_OK:
        status, body = _synchronize(pos, vel, m, force, dt, work)
    if status != KEPLER_OK:
        _fail(pos, vel, work, status, body, no_step)


@jit_inline
def _advance_to(target, n_done, m, force, dt, work):
    """Steps of the mapping state until ``n_done == target``; returns ``(n_done, status, body)``.

    One step: K(h) (h = dt/2 after a start, else dt, merging the owed closing half drift),
    [J(dt/2)], I(dt), [J(dt/2)]; the mapping state then owes K(dt/2) (phase lagging). The arrays
    are taken out of ``work`` once per call and the step is written out here, not in a helper
    called per step, since every array-taking call costs a reference-count round trip. Inlined into
    its caller (one per kernel: ``advance`` or ``step``): compiled apart it was one more library that
    linked, optimised and compiled the Kepler drift and the kick again (0.5 s of a first run).
    """
    jpos, jvel = work.jpos, work.jvel
    flags = work.flags
    heliocentric = work.heliocentric  # None in Jacobi coordinates: the jumps compile empty, and never run
    jumps = heliocentric is not None
    weights, mu = work.weights, work.mu
    ipos, acc = work.ipos, work.iacc
    ks, kstage = work.kscratch, work.kstage
    G = force.G
    eps2 = force.eps2
    half = 0.5 * dt
    while n_done < target:
        h = half if flags[F_PHASE] == PHASE_SYNCED else dt
        status, body = kepler_drift_bodies(jpos, jvel, mu, h, 1, ks, kstage)
        if status != KEPLER_OK:
            return n_done, status, body
        for c in range(3):
            jpos[c, 0] += h * jvel[c, 0]  # the centre of mass drifts
        if jumps:
            jump(jpos, jvel, m, half, heliocentric)
        interaction_kick(jpos, jvel, m, G, eps2, dt, heliocentric, weights, mu, ipos, acc, force)
        if jumps:
            jump(jpos, jvel, m, half, heliocentric)
        flags[F_PHASE] = PHASE_LAGGING
        n_done += 1
    return n_done, KEPLER_OK, 0


@jit_inline
def advance(pos, vel, acc, m, force, dt, work, t0, n_done, n_to):
    """Steps from ``n_done`` to ``n_to``, then ``pos``/``vel`` synchronised (on a copy of the
    mapping state, which goes on unsynchronised); False on a Kepler failure, recorded in ``work``
    with the state poisoned (:func:`_fail`). For a context without velocity-dependent forces
    (:func:`advance_split` is the other loop; :data:`run` picks)."""
    no_velocity_operator(force)
    if not _ensure_started(pos, vel, m, force, dt, work, n_done):
        return n_done, False
    n_done, status, body = _advance_to(n_to, n_done, m, force, dt, work)
    if status != KEPLER_OK:
        _fail(pos, vel, work, status, body, n_done + 1)
        return n_done, False
    status, body = _synchronize(pos, vel, m, force, dt, work)
    if status != KEPLER_OK:
        _fail(pos, vel, work, status, body, n_done)
        return n_done, False
    return n_done, True


@jit_inline
def advance_split(pos, vel, acc, m, force, dt, work, t0, n_done, n_to):
    """:func:`advance` with velocity-dependent forces: each step is ``V(dt/2) S(dt) V(dt/2)``, S a step
    synchronised at its end. The operators change the inertial velocities, so the map restarts from the
    inertial state after each (``_ensure_started`` sees the change), as REBOUND's WHFast does in safe mode
    when an operator modified the particles (REBOUNDx's arrangement for WHFast)."""
    half = 0.5 * dt
    while n_done < n_to:
        velocity_operator(force, pos, vel, m, half)
        step(pos, vel, acc, m, force, dt, work)
        velocity_operator(force, pos, vel, m, half)
        n_done += 1
    return n_done, True


@jit
def _run_plain(state, force, dt, work, t0, n_done, targets, record, out):
    """:func:`~orbitsim.integrators.base.sample_loop` of :func:`advance`: synchronises only at samples
    and at the end of the call. The map continues from its internal state, or restarts from
    ``pos``/``vel`` if they changed, at the start of every call."""
    pos, vel, _, m = state
    if not _ensure_started(pos, vel, m, force, dt, work, n_done):
        return 0, n_done, False
    return sample_loop(advance, grid_time, state, force, dt, work, t0, n_done, targets, record, out)


@jit
def _run_split(state, force, dt, work, t0, n_done, targets, record, out):
    """:func:`~orbitsim.integrators.base.sample_loop` of :func:`advance_split` (restarts at every step)."""
    return sample_loop(advance_split, grid_time, state, force, dt, work, t0, n_done, targets, record, out)


@jit
def _run_watched_plain(state, force, dt, work, t0, n_done, targets, record, out, watch):
    """:func:`_run_plain` one step at a time with the events watch after each (:mod:`orbitsim.events`)."""
    return watched_run(advance, state, force, dt, work, t0, n_done, targets, record, out, watch)


@jit
def _run_watched_split(state, force, dt, work, t0, n_done, targets, record, out, watch):
    """:func:`_run_split` one step at a time with the events watch after each."""
    return watched_run(advance_split, state, force, dt, work, t0, n_done, targets, record, out, watch)


#: The scheme's sampled run and its watched run, each the kernel of the call's forces (:class:`ByVelocityForces`):
#: one kernel for both loops would type and compile the loop it never runs (2 s of a first run).
run = ByVelocityForces(_run_plain, _run_split)
run_watched = ByVelocityForces(_run_watched_plain, _run_watched_split)


WISDOM_HOLMAN = Integrator(
    spec=SPEC,
    step=step,
    run=run,
    run_watched=run_watched,
    settings=SETTINGS,
    validate_settings=validate_settings,
    make_work=make_work,
    check_bodies=check_bodies,
    failure_message=failure_message,
    run_chaos=run_chaos,
    check_chaos=check_chaos,
)
