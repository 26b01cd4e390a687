"""The operators a Wisdom-Holman map is composed of (jitted, in place, no allocation).

Hamiltonian splitting (Wisdom & Holman 1991; Rein & Tamayo 2015, section 2):

    H = H_Kepler + H_interaction (+ H_jump in democratic heliocentric coordinates).

* **Kepler drift** ``K(h)``: each body i >= 1 follows a Kepler orbit about the parameter
  ``mu_i`` for a time h (:func:`orbitsim.physics.kepler.kepler_drift_bodies`). Jacobi:
  ``mu_i = G M_i``, ``M_i = m_0 + ... + m_i``; democratic heliocentric: ``mu_i = G m_0``.
  The centre of mass (column 0) drifts with its constant velocity (:func:`com_drift`).
* **Interaction kick** ``I(h)``: velocities change by h times the accelerations of
  H_interaction, evaluated at the inertial positions (:func:`interaction_kick`).

  - Jacobi: ``H_int = -sum_{i<j} G m_i m_j / r_ij + sum_{i>=1} G m_i M_{i-1} / |r'_i|``. The
    (0, 1) pair cancels body 1's Kepler term exactly, so both are left out; the pair sum of
    the others gives inertial accelerations a_k, and the Jacobi-velocity kick of body i is
    ``(A a)_i + G M_i r'_i / |r'_i|^3`` for i >= 2, where A is the (linear) Jacobi map.
  - Democratic heliocentric: ``H_int = -sum_{1<=i<j} G m_i m_j / r_ij``; the barycentric
    velocities receive the pair accelerations of the planets, no term involves the star.
* **Jump** ``J(h)`` (democratic heliocentric only): ``Q_i += h P / m_0``,
  ``P = sum_{i>=1} m_i V_i`` (Duncan, Levison & Lee 1998, eq. 6).

Softening, when the force context has one, is applied to the pair terms only (the Kepler parts
are unsoftened), as REBOUND does.

The ``work`` built by :func:`orbitsim.integrators.wisdom_holman.make_work` holds the
mapping state and the scratch, a :class:`WHWork` whose fields are named below.

Speed note: every jitted call that takes arrays, and every array taken out of a tuple, costs
Numba a reference-count round trip (two calls into its runtime with atomic updates, ~15 ns
measured; LLVM inlines none of it). At N = 5 a whole step is ~300 ns, so the per-step code takes
its arrays out of ``work`` once per ``run`` call and is written as few, larger functions: a step
is one Kepler call, one kick call and one pair-sum call. That took the N = 5 step from 0.55 to
0.33 us.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from orbitsim._jit import jit, stop_requested
from orbitsim.forces.hooks import add_kick_forces
from orbitsim.integrators.wisdom_holman.settings import COORDINATE_IDS
from orbitsim.physics.coordinates import (
    democratic_heliocentric_to_inertial_pos,
    democratic_heliocentric_to_inertial_vel,
    inertial_to_democratic_heliocentric,
    inertial_to_jacobi,
    jacobi_to_inertial,
)

#: Coordinate ids (the ``coordinates`` setting), dispatched by :func:`to_inertial_pos` and co.
JACOBI = COORDINATE_IDS["jacobi"]
DEMOCRATIC_HELIOCENTRIC = COORDINATE_IDS["democratic_heliocentric"]

class WHWork(NamedTuple):
    """The ``work`` of a Wisdom-Holman run (:func:`orbitsim.integrators.wisdom_holman.make_work`)."""

    jpos: np.ndarray  #: (3, N) mapping positions (Jacobi or democratic heliocentric); column 0 = centre of mass
    jvel: np.ndarray  #: (3, N) mapping velocities
    spos: np.ndarray  #: (3, N) copy of the mapping state, advanced to an output time by the synchronisation
    svel: np.ndarray  #: (3, N) its velocities
    ipos: np.ndarray  #: (3, N) inertial positions at which the kick is evaluated
    iacc: np.ndarray  #: (3, N) accelerations of the interaction Hamiltonian
    last_pos: np.ndarray  #: (3, N) inertial state written by the last synchronisation
    last_vel: np.ndarray  #: (3, N) its velocities
    weights: np.ndarray  #: (N,) Jacobi weights m_i / M_i
    mu: np.ndarray  #: (N,) Kepler parameter of each body
    stage_a: np.ndarray | None  #: (S,) corrector stages: Kepler coefficients, in units of dt (None: no corrector)
    stage_b: np.ndarray | None  #: (S,) corrector stages: kick coefficients, in units of dt (None: no corrector)
    flags: np.ndarray  #: int64 (4,): phase, failure status, failing body, failing step (F_* below)
    config: np.ndarray  #: int64 (2,): coordinates id, corrector order
    kscratch: np.ndarray  #: (KEPLER_SCRATCH_ROWS, N) per-body scratch of the Kepler solver
    kstage: np.ndarray  #: int64 (N,) per-body stage of the Kepler solver
    #: None in Jacobi coordinates, else DEMOCRATIC_HELIOCENTRIC: the operators take it as their ``heliocentric``
    #: argument, and Numba removes a branch on an argument that is None before typing, so a Jacobi run
    #: compiles no democratic heliocentric code (1.5-2 s of a first run when ``config[0]`` chose at run time).
    #: Set by make_work from the settings, as ``config[0]`` is: not in a checkpoint (CHECKPOINT_DERIVED).
    heliocentric: np.int64 | None

    #: Fields a checkpoint leaves out (:mod:`orbitsim.checkpoint.state`): made from the settings again.
    CHECKPOINT_DERIVED = ("heliocentric",)
    #: Fields a checkpoint must match, not overwrite: the settings they hold chose the run's compiled code
    #: (``heliocentric``), so a checkpoint of other coordinates or another corrector is refused.
    CHECKPOINT_COMPARED = ("config",)


#: Phases of ``work.flags[F_PHASE]``: not started (the next call derives the mapping state from
#: ``pos``/``vel``), started but no step taken yet (the next drift is dt/2), lagging (the next is dt).
PHASE_UNSET, PHASE_SYNCED, PHASE_LAGGING = 0, 1, 2

#: Slots of ``work.flags``.
F_PHASE = 0
F_STATUS = 1
F_BODY = 2
F_STEP = 3


@jit
def com_drift(jpos, jvel, h):
    """The centre of mass (column 0) moves with its constant velocity."""
    for c in range(3):
        jpos[c, 0] += h * jvel[c, 0]


@jit
def jump(hpos, hvel, m, h, heliocentric):
    """Democratic heliocentric jump: ``Q_i += h P / m_0`` for i >= 1 (nothing in Jacobi coordinates,
    ``heliocentric`` None: compiled empty there)."""
    if heliocentric is None:
        return
    n = hpos.shape[1]
    for c in range(3):
        p = 0.0
        for i in range(1, n):
            p += m[i] * hvel[c, i]
        shift = h * (p / m[0])
        for i in range(1, n):
            hpos[c, i] += shift


@jit
def to_inertial_pos(jpos, m, weights, heliocentric, dst):
    """Inertial positions of mapping positions ``jpos`` into ``dst`` (``heliocentric``: None for Jacobi
    coordinates, :attr:`WHWork.heliocentric`)."""
    if heliocentric is None:
        jacobi_to_inertial(jpos, weights, dst)
    else:
        democratic_heliocentric_to_inertial_pos(jpos, m, dst)


@jit
def to_inertial_vel(jvel, m, weights, heliocentric, dst):
    """Inertial velocities of mapping velocities ``jvel`` into ``dst``."""
    if heliocentric is None:
        jacobi_to_inertial(jvel, weights, dst)
    else:
        democratic_heliocentric_to_inertial_vel(jvel, m, dst)


@jit
def from_inertial(pos, vel, m, weights, heliocentric, jpos, jvel):
    """Mapping coordinates of the inertial state ``pos``, ``vel`` into ``jpos``, ``jvel``."""
    if heliocentric is None:
        inertial_to_jacobi(pos, weights, jpos)
        inertial_to_jacobi(vel, weights, jvel)
    else:
        inertial_to_democratic_heliocentric(pos, vel, m, jpos, jvel)


@jit
def interaction_accelerations(pos, m, G, eps2, heliocentric, acc):
    """Pair accelerations of H_interaction at inertial ``pos`` into ``acc`` (3, N).

    Jacobi leaves out the (0, 1) pair; democratic heliocentric every pair with body 0. Each pair
    is computed once (Newton's third law), in exact arithmetic. Before each row it looks at
    :func:`~orbitsim._jit.stop_requested`, as the direct-sum force loop does.
    """
    n = pos.shape[1]
    for c in range(3):
        for i in range(n):
            acc[c, i] = 0.0
    first = 0 if heliocentric is None else 1
    for i in range(first, n):
        if stop_requested():  # a stop (orbitsim.stopping): the caller undoes the call
            return
        xi, yi, zi = pos[0, i], pos[1, i], pos[2, i]
        axi = 0.0
        ayi = 0.0
        azi = 0.0
        start = 2 if i == 0 else i + 1
        for j in range(start, n):
            dx = pos[0, j] - xi
            dy = pos[1, j] - yi
            dz = pos[2, j] - zi
            r2 = dx * dx + dy * dy + dz * dz + eps2
            g_r3 = G / (r2 * math.sqrt(r2))
            mj = m[j] * g_r3
            mi = m[i] * g_r3
            axi += mj * dx
            ayi += mj * dy
            azi += mj * dz
            acc[0, j] -= mi * dx
            acc[1, j] -= mi * dy
            acc[2, j] -= mi * dz
        acc[0, i] += axi
        acc[1, i] += ayi
        acc[2, i] += azi


@jit
def interaction_kick(jpos, jvel, m, G, eps2, h, heliocentric, weights, mu, ipos, acc, force):
    """The kick ``I(h)`` of the mapping state ``jpos``, ``jvel``; ``ipos``, ``acc`` are scratch.

    ``force``: the run's force context, whose position-only forces are added to the inertial
    accelerations before their Jacobi transform, as REBOUND's WHFast adds ``additional_forces``
    (:func:`orbitsim.forces.hooks.add_kick_forces`); a context without forces, or None (the
    correctors' kicks), compiles to the kick without them. ``heliocentric``: None for Jacobi coordinates
    (:attr:`WHWork.heliocentric`).

    Jacobi: the inertial positions (:func:`~orbitsim.physics.coordinates.jacobi_to_inertial`),
    the pair accelerations, their Jacobi transform
    (:func:`~orbitsim.physics.coordinates.inertial_to_jacobi`) plus ``G M_i r'_i / |r'_i|^3`` for
    i >= 2, times h. The two transforms are written out here rather than called: this runs every
    step, and each array-taking call costs a reference-count round trip (module docstring).
    """
    n = jpos.shape[1]
    if heliocentric is None:
        for c in range(3):
            com = jpos[c, 0]
            for i in range(n - 1, 0, -1):
                rel = jpos[c, i]
                com = com - weights[i] * rel
                ipos[c, i] = rel + com
            ipos[c, 0] = com
    else:
        democratic_heliocentric_to_inertial_pos(jpos, m, ipos)
    interaction_accelerations(ipos, m, G, eps2, heliocentric, acc)
    add_kick_forces(force, ipos, m, acc)
    if heliocentric is not None:
        for c in range(3):
            for i in range(1, n):
                jvel[c, i] += h * acc[c, i]
        return
    for c in range(3):
        com = acc[c, 0]
        for i in range(1, n):
            rel = acc[c, i] - com
            acc[c, i] = rel
            com = com + weights[i] * rel
    for i in range(1, n):
        ax, ay, az = acc[0, i], acc[1, i], acc[2, i]
        if i > 1:
            x, y, z = jpos[0, i], jpos[1, i], jpos[2, i]
            r2 = x * x + y * y + z * z
            k = mu[i] / (r2 * math.sqrt(r2))
            ax += k * x
            ay += k * y
            az += k * z
        jvel[0, i] += h * ax
        jvel[1, i] += h * ay
        jvel[2, i] += h * az


@jit
def record_failure(pos, vel, work, status, body, step_index):
    """Record a Kepler failure and poison the state so the divergence path reports it."""
    flags = work.flags
    flags[F_STATUS] = status
    flags[F_BODY] = body
    flags[F_STEP] = step_index
    flags[F_PHASE] = PHASE_UNSET
    pos[:, :] = np.nan
    vel[:, :] = np.nan
