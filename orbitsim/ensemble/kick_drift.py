"""Ensemble kernels of the kick-drift schemes: velocity Verlet and the leapfrog of order 2, 4, 6 and 8.

These are the schemes a dynamicist maps with when Wisdom-Holman's Kepler split does not apply (close
encounters, no dominant body). Every system of the ensemble takes the scheme's own variational step,
its ``advance_chaos`` (:func:`orbitsim.integrators.verlet.advance_chaos`,
:func:`orbitsim.integrators.leapfrog.advance_chaos2` ... ``advance_chaos8``): the bodies, the tangent
vector (tangent gravity, :mod:`orbitsim.physics.tangent`) and MEGNO's sums after every step
(:func:`orbitsim.chaos.step.megno_after_step`), so a system of the ensemble gets, bit for bit, what
:func:`orbitsim.chaos.run.chaos_run` gets for that system alone (tests/ensemble/test_kick_drift.py).
The steps are taken one at a time (``n_to = n_done + 1``) so that each system can stop after the step
in which it escaped, collided or diverged; both schemes' ``advance_chaos`` give the same bits however
the steps are cut (verlet makes its tangent accelerations afresh on entry for that reason, at the
cost of one tangent-gravity evaluation a step).

Stops and indicators are the Wisdom-Holman ensemble's (:mod:`orbitsim.ensemble.kernels`), by the
same functions: ``_stop_reason`` on the positions after each step, ``track_orbit`` on the Jacobi
elements of body ``watch`` (the inertial state converted with the same weights and ``mu``),
``_energy`` at the start and at the stop (a kick-drift state is synchronised between steps, so
nothing is drifted first), MEGNO and the mLCE from the sums at the stop.

Layout: the system index first, as :mod:`orbitsim.ensemble.kernels`; systems are independent, so
``prange`` deals them out and a system's bits depend on nothing but its own input. The force context
is one for all systems: with N <= :data:`orbitsim.physics.gravity.SMALL_N_MAX` it is the all-pairs
kernel's, which writes nothing but ``acc`` (the front door refuses larger N).

One parallel kernel per scheme, each naming its ``advance_chaos`` as a module global: a kernel given
the step as an argument, or made by a factory, would miss Numba's on-disk cache
(docs/design.md), and one kernel per scheme compiles only the scheme a map uses.
"""

from __future__ import annotations

import math

import numpy as np
from numba import prange

from orbitsim._jit import jit, jit_inline, jit_parallel_exact
from orbitsim.chaos.megno import MegnoState
from orbitsim.ensemble.kernels import _energy, _stop_reason, jacobi_elements_ae, record_chaos_indicators, track_orbit
from orbitsim.ensemble.status import (
    COMPLETE,
    DIVERGED,
    ENERGY_ERROR,
)
from orbitsim.integrators.base import Tangent
from orbitsim.integrators.leapfrog import advance_chaos2, advance_chaos4, advance_chaos6, advance_chaos8
from orbitsim.integrators.verlet import advance_chaos as verlet_advance_chaos
from orbitsim.physics.coordinates import inertial_to_jacobi
from orbitsim.physics.force_context import newtonian_accelerations


@jit_inline
def run_kick_drift_system(advance_chaos, pos, vel, acc, m, force, dt, work, t_start, n_steps, escape_r2, radii,
                          check_collisions, watch, weights, mu, tangent, jpos, jvel, rows, out):
    """Step one system and its tangent vector with ``advance_chaos`` ``n_steps`` times (or until it
    stops); indicators into ``out`` (columns of :mod:`orbitsim.ensemble.status`). ``pos``, ``vel``
    (3, N): the start, left holding the state at the stop; ``acc`` (3, N), ``jpos``, ``jvel`` (3, N):
    scratch; ``tangent``: the scheme's :class:`~orbitsim.integrators.base.Tangent`. Returns
    ``(status, steps_done)``.

    ``acc`` is made at the start state as :func:`orbitsim.chaos.run.chaos_run` makes it (velocity
    Verlet's first kick reads it), and MEGNO's sums start at ``t_start``, as ``chaos_run``'s.
    """
    n = pos.shape[1]
    G = force.G
    e0 = _energy(pos, vel, m, G, rows)
    newtonian_accelerations(force, pos, m, acc)
    inertial_to_jacobi(pos, weights, jpos)
    inertial_to_jacobi(vel, weights, jvel)
    a0, max_e = jacobi_elements_ae(jpos, jvel, mu, watch)
    delta_a = 0.0
    megno = MegnoState(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, t_start, 0)
    status = COMPLETE
    done = 0
    while done < n_steps:
        done, _, megno = advance_chaos(pos, vel, acc, m, force, dt, work, t_start, done, done + 1, tangent, megno)
        status = _stop_reason(pos, radii, escape_r2, check_collisions)
        if status == DIVERGED:
            break
        inertial_to_jacobi(pos, weights, jpos)
        inertial_to_jacobi(vel, weights, jvel)
        max_e, delta_a = track_orbit(jpos, jvel, mu, watch, a0, max_e, delta_a)
        if status != COMPLETE:
            break
    t = t_start + done * dt
    record_chaos_indicators(out, t, max_e, delta_a, megno)
    if status == DIVERGED:
        out[ENERGY_ERROR] = np.nan
        return status, done
    out[ENERGY_ERROR] = abs((_energy(pos, vel, m, G, rows) - e0) / e0)
    for i in range(n):
        if not (math.isfinite(vel[0, i]) and math.isfinite(vel[1, i]) and math.isfinite(vel[2, i])):
            out[ENERGY_ERROR] = np.nan
            return DIVERGED, done
    return status, done


# Per scheme, a system function and a parallel kernel that differ only in the advance_chaos they name
# (see the module docstring for why there is one of each per scheme). The system function is a jitted
# call, not inlined into the prange body: inlined there, Numba's parfor array analysis fails on the
# MEGNO tuple the step returns. Arguments: pos, vel, acc, dpos, dvel, dacc, jpos, jvel (K, 3, N);
# tscratch (K, R, 3, N) (the Tangent's scratch, unread by these schemes); halvings int64 (K, 1); work
# (K, 0, 3, N) (these schemes' make_work); m, radii, weights, mu (K, N); status, steps int64 (K,);
# out (K, N_COLUMNS); a system function takes system k's slices.


@jit
def system_verlet(pos, vel, acc, dpos, dvel, dacc, tscratch, halvings, m, force, dt, t_start, n_steps, escape_r2,
                  radii, check_collisions, watch, weights, mu, jpos, jvel, work, rows, out):
    """:func:`run_kick_drift_system` with velocity Verlet's step, for one system."""
    tangent = Tangent(dpos, dvel, dacc, tscratch, halvings)
    return run_kick_drift_system(verlet_advance_chaos, pos, vel, acc, m, force, dt, work, t_start, n_steps,
                                 escape_r2, radii, check_collisions, watch, weights, mu, tangent, jpos, jvel, rows, out)


@jit_parallel_exact
def run_ensemble_verlet(pos, vel, acc, dpos, dvel, dacc, tscratch, halvings, m, force, dt, t_start, n_steps,
                        escape_r2, radii, check_collisions, watch, weights, mu, jpos, jvel, work, rows, status,
                        steps, out):
    """:func:`system_verlet` for every system k, in parallel over k."""
    for k in prange(pos.shape[0]):
        st, done = system_verlet(pos[k], vel[k], acc[k], dpos[k], dvel[k], dacc[k], tscratch[k], halvings[k], m[k],
                                force, dt, t_start, n_steps, escape_r2, radii[k], check_collisions, watch, weights[k],
                                mu[k], jpos[k], jvel[k], work[k], rows, out[k])
        status[k] = st
        steps[k] = done


@jit
def system_leapfrog2(pos, vel, acc, dpos, dvel, dacc, tscratch, halvings, m, force, dt, t_start, n_steps, escape_r2,
                     radii, check_collisions, watch, weights, mu, jpos, jvel, work, rows, out):
    """:func:`run_kick_drift_system` with the order-2 leapfrog's step, for one system."""
    tangent = Tangent(dpos, dvel, dacc, tscratch, halvings)
    return run_kick_drift_system(advance_chaos2, pos, vel, acc, m, force, dt, work, t_start, n_steps, escape_r2, radii,
                                 check_collisions, watch, weights, mu, tangent, jpos, jvel, rows, out)


@jit_parallel_exact
def run_ensemble_leapfrog2(pos, vel, acc, dpos, dvel, dacc, tscratch, halvings, m, force, dt, t_start, n_steps,
                           escape_r2, radii, check_collisions, watch, weights, mu, jpos, jvel, work, rows, status,
                           steps, out):
    """:func:`system_leapfrog2` for every system k, in parallel over k."""
    for k in prange(pos.shape[0]):
        st, done = system_leapfrog2(pos[k], vel[k], acc[k], dpos[k], dvel[k], dacc[k], tscratch[k], halvings[k],
                                   m[k], force, dt, t_start, n_steps, escape_r2, radii[k], check_collisions, watch,
                                   weights[k], mu[k], jpos[k], jvel[k], work[k], rows, out[k])
        status[k] = st
        steps[k] = done


@jit
def system_leapfrog4(pos, vel, acc, dpos, dvel, dacc, tscratch, halvings, m, force, dt, t_start, n_steps, escape_r2,
                     radii, check_collisions, watch, weights, mu, jpos, jvel, work, rows, out):
    """:func:`run_kick_drift_system` with the order-4 leapfrog's step, for one system."""
    tangent = Tangent(dpos, dvel, dacc, tscratch, halvings)
    return run_kick_drift_system(advance_chaos4, pos, vel, acc, m, force, dt, work, t_start, n_steps, escape_r2, radii,
                                 check_collisions, watch, weights, mu, tangent, jpos, jvel, rows, out)


@jit_parallel_exact
def run_ensemble_leapfrog4(pos, vel, acc, dpos, dvel, dacc, tscratch, halvings, m, force, dt, t_start, n_steps,
                           escape_r2, radii, check_collisions, watch, weights, mu, jpos, jvel, work, rows, status,
                           steps, out):
    """:func:`system_leapfrog4` for every system k, in parallel over k."""
    for k in prange(pos.shape[0]):
        st, done = system_leapfrog4(pos[k], vel[k], acc[k], dpos[k], dvel[k], dacc[k], tscratch[k], halvings[k],
                                   m[k], force, dt, t_start, n_steps, escape_r2, radii[k], check_collisions, watch,
                                   weights[k], mu[k], jpos[k], jvel[k], work[k], rows, out[k])
        status[k] = st
        steps[k] = done


@jit
def system_leapfrog6(pos, vel, acc, dpos, dvel, dacc, tscratch, halvings, m, force, dt, t_start, n_steps, escape_r2,
                     radii, check_collisions, watch, weights, mu, jpos, jvel, work, rows, out):
    """:func:`run_kick_drift_system` with the order-6 leapfrog's step, for one system."""
    tangent = Tangent(dpos, dvel, dacc, tscratch, halvings)
    return run_kick_drift_system(advance_chaos6, pos, vel, acc, m, force, dt, work, t_start, n_steps, escape_r2, radii,
                                 check_collisions, watch, weights, mu, tangent, jpos, jvel, rows, out)


@jit_parallel_exact
def run_ensemble_leapfrog6(pos, vel, acc, dpos, dvel, dacc, tscratch, halvings, m, force, dt, t_start, n_steps,
                           escape_r2, radii, check_collisions, watch, weights, mu, jpos, jvel, work, rows, status,
                           steps, out):
    """:func:`system_leapfrog6` for every system k, in parallel over k."""
    for k in prange(pos.shape[0]):
        st, done = system_leapfrog6(pos[k], vel[k], acc[k], dpos[k], dvel[k], dacc[k], tscratch[k], halvings[k],
                                   m[k], force, dt, t_start, n_steps, escape_r2, radii[k], check_collisions, watch,
                                   weights[k], mu[k], jpos[k], jvel[k], work[k], rows, out[k])
        status[k] = st
        steps[k] = done


@jit
def system_leapfrog8(pos, vel, acc, dpos, dvel, dacc, tscratch, halvings, m, force, dt, t_start, n_steps, escape_r2,
                     radii, check_collisions, watch, weights, mu, jpos, jvel, work, rows, out):
    """:func:`run_kick_drift_system` with the order-8 leapfrog's step, for one system."""
    tangent = Tangent(dpos, dvel, dacc, tscratch, halvings)
    return run_kick_drift_system(advance_chaos8, pos, vel, acc, m, force, dt, work, t_start, n_steps, escape_r2, radii,
                                 check_collisions, watch, weights, mu, tangent, jpos, jvel, rows, out)


@jit_parallel_exact
def run_ensemble_leapfrog8(pos, vel, acc, dpos, dvel, dacc, tscratch, halvings, m, force, dt, t_start, n_steps,
                           escape_r2, radii, check_collisions, watch, weights, mu, jpos, jvel, work, rows, status,
                           steps, out):
    """:func:`system_leapfrog8` for every system k, in parallel over k."""
    for k in prange(pos.shape[0]):
        st, done = system_leapfrog8(pos[k], vel[k], acc[k], dpos[k], dvel[k], dacc[k], tscratch[k], halvings[k],
                                   m[k], force, dt, t_start, n_steps, escape_r2, radii[k], check_collisions, watch,
                                   weights[k], mu[k], jpos[k], jvel[k], work[k], rows, out[k])
        status[k] = st
        steps[k] = done


#: Registry name -> the scheme's ensemble kernel (the names :func:`orbitsim.ensemble.run.run_ensemble`
#: and ``orbitsim map`` accept besides ``wisdom_holman``).
KICK_DRIFT_KERNELS = {
    "verlet": run_ensemble_verlet,
    "leapfrog": run_ensemble_leapfrog2,
    "leapfrog4": run_ensemble_leapfrog4,
    "leapfrog6": run_ensemble_leapfrog6,
    "leapfrog8": run_ensemble_leapfrog8,
}
