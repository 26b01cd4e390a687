"""The ensemble kernel: K systems of the same N stepped by the Wisdom-Holman map in one jitted call.

Layout. Every array has the system index first, ``(K, 3, N)`` for states and ``(K, N)`` for masses
and the per-body constants, so system k's slice ``a[k]`` is one contiguous ``(3, N)`` block in the
layout :mod:`orbitsim.integrators.wisdom_holman.operators` works on: the step below is made of those
same jitted operators (:func:`~orbitsim.physics.kepler.kepler_drift_bodies`,
:func:`~orbitsim.integrators.wisdom_holman.operators.interaction_kick`), not a second copy of them,
so a system of the ensemble gets the bits a single Wisdom-Holman run gets (tests/ensemble).
Systems are independent: nothing is summed across them, so a system's bits do not depend on which
chunk or thread ran it, and ``prange`` deals them out to the cores. The arrays a step writes (the
mapping state and its scratch) are allocated once by the caller, never in the loop.

Each system stops alone, at the end of the step in which one of these was seen (after the kick,
from the inertial positions the kick evaluated):

* escape: a body's squared distance from body 0 exceeds ``escape_r2``;
* collision (only when ``check_collisions``): two bodies closer than the sum of their ``radii``;
* divergence: a Kepler drift that failed (its bodies are set to nan) or a non-finite position.

A stopped system's slices are left as they were; it never touches another system's.

Indicators (columns of :mod:`orbitsim.ensemble.status`), per system:

* ``survival_time``: the time the system stopped, ``t_start + n dt`` after its n-th step;
* ``max_e``, ``delta_a``: the largest Jacobi eccentricity of body ``watch`` and the largest
  ``|a - a_0| / |a_0|`` of its Jacobi semi-major axis, read after every kick (Jacobi elements about
  the interior bodies' mass, with ``mu = G M_i``, as REBOUND's default ``orbits()``);
* ``energy_error``: ``|E_end - E_0| / |E_0|`` of the synchronised inertial state at the stop; a
  massless body carries no energy, so it measures the massive bodies only;
* ``megno``, ``lyapunov`` (:func:`run_ensemble_variational` only, NaN otherwise): MEGNO <Y> and the
  mLCE at the stop, from a tangent vector stepped by the Wisdom-Holman tangent map
  (:mod:`orbitsim.integrators.wisdom_holman.tangent`, REBOUND's WHFast in safe mode) and read after every
  step as a single-system chaos run reads it (:mod:`orbitsim.chaos.step`). That step keeps the inertial
  state between steps, so its bodies differ from :func:`run_ensemble_wh`'s by round-off.

:mod:`orbitsim.ensemble.system_lanes` and :mod:`orbitsim.ensemble.system_tangent_lanes` step 16 systems side
by side in SIMD lanes with these kernels' bits; the kernels here are their reference (``lanes=False``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import prange

from orbitsim._jit import jit, jit_inline, jit_parallel_exact
from orbitsim.chaos.megno import MegnoState, lyapunov, megno_value
from orbitsim.chaos.step import megno_after_step
from orbitsim.ensemble.status import (
    COLLIDED,
    COMPLETE,
    DELTA_A,
    DIVERGED,
    ENERGY_ERROR,
    ESCAPED,
    LYAPUNOV,
    MAX_E,
    MEGNO,
    SURVIVAL_TIME,
)
from orbitsim.integrators.wisdom_holman.operators import interaction_kick
from orbitsim.integrators.wisdom_holman.tangent import (
    T_ACC,
    T_DACC,
    T_DIPOS,
    T_DJPOS,
    T_DJVEL,
    T_IPOS,
    T_JPOS,
    T_JVEL,
    tangent_step,
)
from orbitsim.physics.coordinates import inertial_to_jacobi, jacobi_to_inertial
from orbitsim.physics.diagnostics import kinetic_energy, potential_energy
from orbitsim.physics.kepler import KEPLER_OK, kepler_drift_bodies


@jit
def jacobi_elements_ae(jpos, jvel, mu, i):
    """Semi-major axis and eccentricity of Jacobi body ``i`` about ``mu[i] = G M_i`` (a < 0: hyperbola)."""
    return elements_ae(jpos[0, i], jpos[1, i], jpos[2, i], jvel[0, i], jvel[1, i], jvel[2, i], mu[i])


@jit_inline
def elements_ae(x, y, z, vx, vy, vz, k):
    """Semi-major axis and eccentricity of the orbit (x, v) about ``k = G M``, branch free (a < 0: hyperbola)."""
    r = math.sqrt(x * x + y * y + z * z)
    v2 = vx * vx + vy * vy + vz * vz
    energy = 0.5 * v2 - k / r
    hx = y * vz - z * vy
    hy = z * vx - x * vz
    hz = x * vy - y * vx
    h2 = hx * hx + hy * hy + hz * hz
    e2 = 1.0 + 2.0 * energy * h2 / (k * k)
    return -k / (2.0 * energy), math.sqrt(e2) if e2 > 0.0 else 0.0


@jit_inline
def track_orbit(jpos, jvel, mu, watch, a0, max_e, delta_a):
    """``max_e`` and ``delta_a`` after a step: the largest Jacobi e of body ``watch`` and |a - a0| / |a0|."""
    a, e = jacobi_elements_ae(jpos, jvel, mu, watch)
    spread = abs(a - a0) / abs(a0)
    return (e if e > max_e else max_e), (spread if spread > delta_a else delta_a)


@jit_inline
def record_chaos_indicators(out, t, max_e, delta_a, megno):
    """A variational system's row at its stop time ``t``: survival time, max e, delta a, MEGNO and the
    mLCE. One place for every variational kernel (Wisdom-Holman, kick-drift, the GPU's)."""
    out[SURVIVAL_TIME] = t
    out[MAX_E] = max_e
    out[DELTA_A] = delta_a
    out[MEGNO] = megno_value(megno, t)
    out[LYAPUNOV] = lyapunov(megno)


@jit
def _energy(pos, vel, m, G, rows):
    return kinetic_energy(vel, m) + potential_energy(pos, m, G, 0.0, rows)


@jit
def _stop_reason(ipos, radii, escape_r2, check_collisions):
    """ESCAPED, COLLIDED, DIVERGED or COMPLETE (nothing seen) for inertial positions ``ipos``."""
    n = ipos.shape[1]
    for i in range(n):
        if not (math.isfinite(ipos[0, i]) and math.isfinite(ipos[1, i]) and math.isfinite(ipos[2, i])):
            return DIVERGED
    for i in range(1, n):
        dx = ipos[0, i] - ipos[0, 0]
        dy = ipos[1, i] - ipos[1, 0]
        dz = ipos[2, i] - ipos[2, 0]
        if dx * dx + dy * dy + dz * dz > escape_r2:
            return ESCAPED
    if check_collisions:
        for i in range(n):
            for j in range(i + 1, n):
                reach = radii[i] + radii[j]
                if reach <= 0.0:
                    continue
                dx = ipos[0, j] - ipos[0, i]
                dy = ipos[1, j] - ipos[1, i]
                dz = ipos[2, j] - ipos[2, i]
                if dx * dx + dy * dy + dz * dz < reach * reach:
                    return COLLIDED
    return COMPLETE


@jit
def synchronize_jacobi(jpos, jvel, mu, weights, dt, spos, svel, ks, kstage, pos, vel):
    """Inertial state of a lagging Jacobi mapping state (owing K(dt/2)) into ``pos``, ``vel``;
    ``spos``/``svel`` receive the drifted copy. Returns the Kepler status."""
    for c in range(3):
        for i in range(jpos.shape[1]):
            spos[c, i] = jpos[c, i]
            svel[c, i] = jvel[c, i]
    half = 0.5 * dt
    status, _ = kepler_drift_bodies(spos, svel, mu, half, 1, ks, kstage)
    for c in range(3):
        spos[c, 0] += half * svel[c, 0]
    jacobi_to_inertial(spos, weights, pos)
    jacobi_to_inertial(svel, weights, vel)
    return status


@jit
def run_system(pos, vel, m, G, dt, t_start, n_steps, escape_r2, radii, check_collisions, watch,
               jpos, jvel, ipos, iacc, weights, mu, ks, kstage, rows, out):
    """Step one system ``n_steps`` times (or until it stops); indicators into ``out`` (columns of
    :mod:`orbitsim.ensemble.status`). ``pos``, ``vel`` (3, N): the start, overwritten with the
    synchronised inertial state at the stop. Returns ``(status, steps_done)``.

    The step is :func:`orbitsim.integrators.wisdom_holman._advance_to`'s for Jacobi coordinates
    without correctors or forces: K(dt/2 at the start, then dt), centre-of-mass drift, I(dt).
    """
    e0 = _energy(pos, vel, m, G, rows)
    inertial_to_jacobi(pos, weights, jpos)
    inertial_to_jacobi(vel, weights, jvel)
    a0, e_start = jacobi_elements_ae(jpos, jvel, mu, watch)
    max_e = e_start
    delta_a = 0.0
    status = COMPLETE
    done = 0
    half = 0.5 * dt
    eps2 = 0.0
    while done < n_steps:
        h = half if done == 0 else dt
        kstatus, _ = kepler_drift_bodies(jpos, jvel, mu, h, 1, ks, kstage)
        if kstatus != KEPLER_OK:
            status = DIVERGED
            done += 1
            break
        for c in range(3):
            jpos[c, 0] += h * jvel[c, 0]  # the centre of mass drifts
        interaction_kick(jpos, jvel, m, G, eps2, dt, None, weights, mu, ipos, iacc, None)
        done += 1
        max_e, delta_a = track_orbit(jpos, jvel, mu, watch, a0, max_e, delta_a)
        status = _stop_reason(ipos, radii, escape_r2, check_collisions)
        if status != COMPLETE:
            break
    return finish_system(pos, vel, m, G, dt, t_start, done, status, max_e, delta_a, e0, jpos, jvel, ipos, iacc,
                         weights, mu, ks, kstage, rows, out)


@jit
def finish_system(pos, vel, m, G, dt, t_start, done, status, max_e, delta_a, e0, jpos, jvel, ipos, iacc, weights, mu,
                  ks, kstage, rows, out):
    """The end of :func:`run_system` (and of a system in SIMD lanes, :mod:`orbitsim.ensemble.system_lanes`): the
    row of ``out`` of a system stopped with ``status`` after ``done`` steps, its Jacobi mapping state ``jpos``,
    ``jvel`` synchronised into ``pos``, ``vel`` (left as they were for a DIVERGED system), its energy error
    against ``e0``. ``ipos``, ``iacc``, ``ks``, ``kstage`` are scratch. Returns ``(status, done)``."""
    n = pos.shape[1]
    out[SURVIVAL_TIME] = t_start + done * dt
    out[MAX_E] = max_e
    out[DELTA_A] = delta_a
    out[MEGNO] = np.nan
    out[LYAPUNOV] = np.nan
    if status == DIVERGED:
        out[ENERGY_ERROR] = np.nan
        return status, done
    if done > 0 and synchronize_jacobi(jpos, jvel, mu, weights, dt, ipos, iacc, ks, kstage, pos, vel) != KEPLER_OK:
        out[ENERGY_ERROR] = np.nan
        return DIVERGED, done
    out[ENERGY_ERROR] = abs((_energy(pos, vel, m, G, rows) - e0) / e0)
    for i in range(n):
        if not (math.isfinite(pos[0, i]) and math.isfinite(vel[0, i])):
            return DIVERGED, done
    return status, done


@jit
def run_system_variational(pos, vel, dpos, dvel, m, force, dt, t_start, n_steps, escape_r2, radii, check_collisions,
                           watch, weights, mu, scratch, rows, out):
    """:func:`run_system` with the tangent vector ``dpos``, ``dvel`` (3, N) carried by the Wisdom-Holman
    tangent map (:func:`orbitsim.integrators.wisdom_holman.tangent.tangent_step`, REBOUND's WHFast in
    safe mode: the inertial state between steps) and MEGNO read after every step
    (:func:`orbitsim.chaos.step.megno_after_step`), as a single-system chaos run does. ``scratch``
    (TANGENT_SCRATCH_ROWS, 3, N). Fills the MEGNO and Lyapunov columns too."""
    jpos, jvel, djpos, djvel = scratch[T_JPOS], scratch[T_JVEL], scratch[T_DJPOS], scratch[T_DJVEL]
    ipos, acc, dipos, dacc = scratch[T_IPOS], scratch[T_ACC], scratch[T_DIPOS], scratch[T_DACC]
    G = force.G
    e0 = _energy(pos, vel, m, G, rows)
    inertial_to_jacobi(pos, weights, jpos)
    inertial_to_jacobi(vel, weights, jvel)
    a0, max_e = jacobi_elements_ae(jpos, jvel, mu, watch)
    delta_a = 0.0
    megno = MegnoState(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, t_start, 0)
    status = COMPLETE
    done = 0
    while done < n_steps:
        kstatus, _ = tangent_step(pos, vel, dpos, dvel, m, G, force.eps2, dt, weights, mu, jpos, jvel, djpos, djvel,
                                  ipos, acc, dipos, dacc, force)
        done += 1
        if kstatus != KEPLER_OK:
            status = DIVERGED
            break
        megno, _ = megno_after_step(megno, pos, m, force, dpos, dvel, dacc, t_start + done * dt, dt)
        max_e, delta_a = track_orbit(jpos, jvel, mu, watch, a0, max_e, delta_a)
        status = _stop_reason(pos, radii, escape_r2, check_collisions)
        if status != COMPLETE:
            break
    t = t_start + done * dt
    record_chaos_indicators(out, t, max_e, delta_a, megno)
    if status == DIVERGED:
        out[ENERGY_ERROR] = np.nan
        return status, done
    out[ENERGY_ERROR] = abs((_energy(pos, vel, m, G, rows) - e0) / e0)
    return status, done


@jit_parallel_exact
def run_ensemble_variational(pos, vel, dpos, dvel, m, force, dt, t_start, n_steps, escape_r2, radii,
                             check_collisions, watch, weights, mu, scratch, rows, status, steps, out):
    """:func:`run_system_variational` for every system k (``dpos``, ``dvel`` (K, 3, N); ``scratch``
    (K, TANGENT_SCRATCH_ROWS, 3, N); the rest as :func:`run_ensemble_wh`), in parallel over k."""
    for k in prange(pos.shape[0]):
        st, done = run_system_variational(pos[k], vel[k], dpos[k], dvel[k], m[k], force, dt, t_start, n_steps,
                                          escape_r2, radii[k], check_collisions, watch, weights[k], mu[k], scratch[k],
                                          rows, out[k])
        status[k] = st
        steps[k] = done


@jit_parallel_exact
def run_ensemble_wh(pos, vel, m, G, dt, t_start, n_steps, escape_r2, radii, check_collisions, watch,
                    jpos, jvel, ipos, iacc, weights, mu, ks, kstage, rows, status, steps, out):
    """:func:`run_system` for every system k (``pos``, ``vel``: (K, 3, N); ``m``, ``weights``, ``mu``,
    ``radii``: (K, N); scratch as :func:`run_system`'s with K first), in parallel over k.
    ``status``, ``steps`` int64 (K,) and ``out`` (K, N_COLUMNS) receive each system's results."""
    for k in prange(pos.shape[0]):
        st, done = run_system(pos[k], vel[k], m[k], G, dt, t_start, n_steps, escape_r2, radii[k],
                              check_collisions, watch, jpos[k], jvel[k], ipos[k], iacc[k], weights[k], mu[k],
                              ks[k], kstage[k], rows, out[k])
        status[k] = st
        steps[k] = done


#: Whether the ensemble has variational equations (MEGNO, Lyapunov time): :func:`run_ensemble_variational`.
HAS_VARIATIONS = True
