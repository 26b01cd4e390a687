"""The stepping loops of runs with forces: every integrator's ``run`` contract, forces included.

Each entry has the contract of :mod:`orbitsim.integrators.base`'s
``run(state, force, dt, work, t0, n_done, targets, record, out)``, with ``force`` the forced
context of :func:`orbitsim.forces.hooks.forced_context`. :func:`forced_run` picks the one for an
integrator. How each family applies the forces:

* **Position-only forces** (``gr_potential``, ``harmonics``) are added to gravity wherever a
  scheme evaluates it: inside every kick of semi_implicit_euler, verlet and the DKD compositions
  (leapfrog, leapfrog4/6/8, by their coefficient tables), inside Wisdom-Holman's interaction kick
  before the Jacobi transform (as REBOUND's WHFast does), and in the derivative of euler, rk4 and
  ias15. The symplectic maps stay symplectic: the forces derive from a potential.
* **Velocity-dependent forces** (``gr``, ``migration``; ``gr_full`` only with rk4, ias15) are part
  of the derivative of euler, rk4 and ias15 (IAS15 then predicts the velocities at its nodes, as
  REBOUND does). In the symplectic schemes they are their own operator, ``V(dt/2) S(dt) V(dt/2)``
  with S the scheme's step and V REBOUNDx's ``integrate_force`` (implicit midpoint): naive
  velocity-dependent kicks give qualitatively wrong long-term answers (Tamayo, Rein, Shi &
  Hernandez 2020, MNRAS 491, 2885). Wisdom-Holman then synchronises after every step, as a
  REBOUNDx operator forces WHFast to.

IAS15 and Wisdom-Holman run their own ``run`` with the forced context: their force hooks
(:mod:`orbitsim.forces.hooks`) do the rest. Every loop evaluates the accelerations afresh at the
start of a call with the same arithmetic as at the end of a step, so however a run is cut into
calls (chunks, checkpoints) the bits are the same.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from orbitsim._jit import jit, jit_inline
from orbitsim.forces.kernels import add_position_forces, add_velocity_forces, velocity_operator
from orbitsim.integrators.base import Integrator, drift, kick, kick_drift, record_sample
from orbitsim.integrators.ias15 import run as ias15_run
from orbitsim.integrators.rk4 import B_WEIGHTS, C_NODES, _stage
from orbitsim.integrators.wisdom_holman import run as wh_run
from orbitsim.integrators.wisdom_holman import step as wh_step
from orbitsim.physics.gravity import SMALL_N_MAX, accelerations, all_pairs_accelerations

#: Scheme ids of :func:`run_fixed`.
EULER, KICK_DRIFT, VERLET, DKD, RK4 = range(5)
_FIXED = {"euler": EULER, "semi_implicit_euler": KICK_DRIFT, "verlet": VERLET, "rk4": RK4}
_NO_TABLE = np.zeros(0)


@jit_inline
def _accelerations(pos, vel, m, force, acc, with_velocity):
    """acc = gravity + position-only forces at ``pos`` (+ velocity-dependent ones at (pos, vel)).
    The same arithmetic as IAS15's end of step with its hooks (orbitsim.integrators.ias15.core.step_try)."""
    G = force[0]
    ids, source, params, per_body, scratch = force[4][0], force[4][1], force[4][2], force[4][3], force[4][4]
    if pos.shape[1] <= SMALL_N_MAX:
        all_pairs_accelerations(pos, m, G, force[1], acc)
    else:
        accelerations(pos, m, G, force[1], acc, force[2], force[3])
    add_position_forces(pos, m, G, ids, source, params, per_body, acc)
    if with_velocity:
        add_velocity_forces(pos, vel, m, G, ids, source, params, per_body, acc, scratch)


@jit_inline
def _operator(pos, vel, m, force, h):
    """REBOUNDx's velocity operator over ``h`` (positions fixed), if any force needs it."""
    extra = force[4]
    if extra[6]:
        velocity_operator(pos, vel, m, force[0], extra[0], extra[1], extra[2], extra[3], h, extra[4])


@jit
def refresh_accelerations(pos, vel, m, force, acc, with_velocity):
    """``acc`` at the current state (gravity and forces), as the loops leave it after a step."""
    _accelerations(pos, vel, m, force, acc, with_velocity)


@jit_inline
def _rk4_step(pos, vel, acc, m, force, dt, work):
    """One RK4 step of (x, v)' = (v, a(x, v)); the stage velocities are in k_x (rk4._stage)."""
    x0, v0, sum_x, sum_v, k_x = work[0], work[1], work[2], work[3], work[4]
    x0[:, :] = pos
    v0[:, :] = vel
    k_x[:, :] = vel
    sum_x[:, :] = 0.0
    sum_v[:, :] = 0.0
    last = B_WEIGHTS[3]
    for s in range(3):
        _stage(pos, x0, v0, k_x, acc, C_NODES[s] * dt, B_WEIGHTS[s], sum_x, sum_v)
        _accelerations(pos, k_x, m, force, acc, True)
    for c in range(3):
        for i in range(pos.shape[1]):
            pos[c, i] = x0[c, i] + dt * (sum_x[c, i] + last * k_x[c, i])
            vel[c, i] = v0[c, i] + dt * (sum_v[c, i] + last * acc[c, i])
    _accelerations(pos, vel, m, force, acc, True)


@jit_inline
def _symplectic_step(scheme, pos, vel, acc, m, force, dt, drifts, kicks):
    """One step of a symplectic scheme with the position-only forces in its kicks."""
    if scheme == KICK_DRIFT:
        kick_drift(pos, vel, acc, dt, dt)
        _accelerations(pos, vel, m, force, acc, False)
    elif scheme == VERLET:
        kick(vel, acc, 0.5 * dt)
        drift(pos, vel, dt)
        _accelerations(pos, vel, m, force, acc, False)
        kick(vel, acc, 0.5 * dt)
    else:
        drift(pos, vel, dt * drifts[0])
        for s in range(kicks.shape[0]):
            _accelerations(pos, vel, m, force, acc, False)
            kick_drift(pos, vel, acc, dt * kicks[s], dt * drifts[s + 1])


@jit_inline
def _advance(pos, vel, acc, m, force, dt, work, steps, scheme, drifts, kicks):
    """``steps`` steps of ``scheme``; ``acc`` holds the scheme's accelerations at the state."""
    for _ in range(steps):
        if scheme == EULER:
            for c in range(3):
                for i in range(pos.shape[1]):
                    v_old = vel[c, i]
                    vel[c, i] = v_old + dt * acc[c, i]
                    pos[c, i] += dt * v_old
            _accelerations(pos, vel, m, force, acc, True)
        elif scheme == RK4:
            _rk4_step(pos, vel, acc, m, force, dt, work)
        else:
            _operator(pos, vel, m, force, 0.5 * dt)
            _symplectic_step(scheme, pos, vel, acc, m, force, dt, drifts, kicks)
            _operator(pos, vel, m, force, 0.5 * dt)


@jit_inline
def _advance_wh_operator(pos, vel, acc, m, force, dt, work, steps, scheme, drifts, kicks):
    """Wisdom-Holman with velocity-dependent forces: ``V(dt/2)``, a synchronised step, ``V(dt/2)``.

    The map restarts from the inertial state after each operator (wisdom_holman's
    ``_ensure_started`` sees the changed velocities), as REBOUND's WHFast does when an operator
    modified the particles. ``scheme``, ``drifts``, ``kicks`` are unused (:func:`_sample_loop`)."""
    for _ in range(steps):
        _operator(pos, vel, m, force, 0.5 * dt)
        wh_step(pos, vel, acc, m, force, dt, work)
        _operator(pos, vel, m, force, 0.5 * dt)


@jit_inline
def _sample_loop(advance, state, force, dt, work, t0, n_done, targets, record, out, scheme, drifts, kicks):
    """The ``run`` contract's loop over targets and samples around an ``advance`` (inlined, so
    ``advance`` is resolved when the caller compiles and the caller still caches)."""
    pos, vel, acc, m = state
    written = 0
    for k in range(targets.shape[0]):
        if n_done < targets[k]:
            advance(pos, vel, acc, m, force, dt, work, targets[k] - n_done, scheme, drifts, kicks)
            n_done = targets[k]
        if record[k] and not record_sample(written, n_done, t0, dt, pos, vel, m, force, out):
            return written, n_done, False
        written += record[k]
    return written, n_done, True


@jit
def run_fixed(state, force, dt, work, t0, n_done, targets, record, out, scheme, drifts, kicks):
    """The ``run`` loop of the fixed-step schemes with forces (``scheme``: EULER ... RK4; the DKD
    compositions give their ``drifts`` and ``kicks`` tables)."""
    pos, vel, acc, m = state
    _accelerations(pos, vel, m, force, acc, scheme == EULER or scheme == RK4)
    return _sample_loop(_advance, state, force, dt, work, t0, n_done, targets, record, out, scheme, drifts, kicks)


@jit
def run_wh_operator(state, force, dt, work, t0, n_done, targets, record, out):
    """Wisdom-Holman's ``run`` with velocity-dependent forces (:func:`_advance_wh_operator`)."""
    return _sample_loop(_advance_wh_operator, state, force, dt, work, t0, n_done, targets, record, out, DKD,
                        _NO_TABLE, _NO_TABLE)


@jit
def run_ias15(state, force, dt, work, t0, n_done, targets, record, out):
    """IAS15's own grid loop with the forced context (its hooks add the forces at every node)."""
    pos, vel, acc, m = state
    _accelerations(pos, vel, m, force, acc, force[4][6])
    return ias15_run(state, force, dt, work, t0, n_done, targets, record, out)


def forced_run(record: Integrator) -> Callable[..., Any]:
    """The forced ``run`` for an integrator's record (its name decides, and a composition's tables);
    raises ValueError for one that cannot take forces (trace)."""
    name = record.spec.name
    if name in _FIXED:
        scheme = _FIXED[name]
        return lambda *args: run_fixed(*args, scheme, _NO_TABLE, _NO_TABLE)
    if record.kicks is not None and record.drifts is not None:
        drifts, kicks = record.drifts, record.kicks
        return lambda *args: run_fixed(*args, DKD, drifts, kicks)
    if name == "wisdom_holman":
        return lambda *args: (run_wh_operator if args[1][4][6] else wh_run)(*args)
    if name == "ias15":
        return run_ias15
    raise ValueError(f"the {name} integrator cannot apply forces")
