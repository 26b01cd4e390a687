"""The ensemble on one GPU: one CUDA thread per system, FP64, the body count a compile-time constant.

A kernel factory per (scheme, N) (:func:`wh_variational_kernel`, :func:`fixed_step_kernel`) closes over N,
so every per-thread ``cuda.local.array((3, N))`` has a constant shape: NVVM unrolls the loops over the
bodies and keeps the arrays in registers (a body count passed at run time put them in local memory,
10x slower in the issue's measurement). The watched body is a constant too, for the same reason. One
exception: the Wisdom-Holman step's loop over bodies, each a whole Kepler solve, is not unrolled, so the
Jacobi arrays it indexes live in local memory (416 bytes at N = 4; ``benchmarks/gpu_ptx_report.py``).
The Kepler iteration count differs between threads, so a warp waits for its slowest system. The global
arrays are laid out ``(3, N, K)``, the system index innermost, so a warp's 32 threads read one body's
coordinate of 32 systems in one coalesced access.

One source of truth. The step is made of the CPU ensemble's own jitted functions, which numba-cuda
compiles for the device from the same Python source when a kernel calls them: the Jacobi transforms,
the Kepler drift and its tangent (:mod:`orbitsim.physics.kepler`,
:mod:`orbitsim.integrators.wisdom_holman.tangent`), the tangent gravity
(:mod:`orbitsim.physics.tangent`), MEGNO's sums and rescaling (:mod:`orbitsim.chaos.megno`), the stop
reasons and orbit tracking (:mod:`orbitsim.ensemble.kernels`), the energy terms
(:mod:`orbitsim.physics.diagnostics`). Restated here, each with its reason:

* the gravity kicks (:func:`jacobi_gravity_kick`, :func:`pair_accelerations`): the CPU kick polls the
  host's stop flag and the run's force context, neither of which exists on the device, and the GPU
  takes ``1 / r^3`` from ``libdevice.rsqrt`` (1.4x over ``1 / sqrt`` on an H100, issue 30);
* :func:`wh_tangent_kepler_kick_kepler` and :func:`megno_read`: the CPU's call that kick and the force
  context's tangent forces; the operations between are the same calls in the same order (in place);
* :func:`run_wh_variational` / :func:`run_fixed_step`: the CPU's per-system loop receives host scratch
  and the force context; this one the thread's local arrays.

Agreement: not bitwise. NVVM contracts multiply-adds into FMAs and ``rsqrt`` rounds differently from
``G / (r2 sqrt(r2))``, so a GPU system agrees with the CPU ensemble to ~1e-13 relative over short runs
(tests/gpu_ensemble/, under Numba's CUDA simulator, which has neither FMA nor rsqrt and so
tests the operations; ``benchmarks/gpu_check.py`` measures the real device). A chaotic system
amplifies any round-off, so over long runs chaotic pixels differ in their digits, not their verdict.

Statuses as on the CPU (:mod:`orbitsim.ensemble.status`): each thread stops its own system at the end of
the step in which it escaped, collided or diverged, and touches no other system's memory.
"""

from __future__ import annotations

import math
from functools import cache
from typing import Any

from numba import float64

from orbitsim._jit import cuda_device, cuda_kernel
from orbitsim.chaos.megno import MegnoState, deltad_delta, megno_update, rescale_power_of_two
from orbitsim.ensemble.kernels import _stop_reason, jacobi_elements_ae, record_chaos_indicators, track_orbit
from orbitsim.ensemble.status import (
    COMPLETE,
    DELTA_A,
    DIVERGED,
    ENERGY_ERROR,
    LYAPUNOV,
    MAX_E,
    MEGNO,
    N_COLUMNS,
    SURVIVAL_TIME,
)
from orbitsim.gpu.device import require_cuda
from orbitsim.gpu.rsqrt import rsqrt
from orbitsim.integrators.wisdom_holman.tangent import jacobi_term_tangent_kick, kepler_step_tangent
from orbitsim.physics.coordinates import inertial_to_jacobi, jacobi_to_inertial
from orbitsim.physics.diagnostics import _potential_small, kinetic_energy
from orbitsim.physics.kepler import KEPLER_OK
from orbitsim.physics.tangent import ALL_PAIRS, SKIP_PAIR_0_1, tangent_accelerations

cuda = require_cuda()

#: Threads per block: a multiple of the warp; 128 leaves registers for the unrolled local arrays.
THREADS_PER_BLOCK = 128


@cuda_device
def energy(pos, vel, m, G):
    """Total energy of one system, the CPU ensemble's ``_energy`` for N < 64 (its small-N potential)."""
    return kinetic_energy(vel, m) + -G * _potential_small(pos, m, 0.0)


@cuda_device
def pair_accelerations(pos, m, G, acc):
    """Newtonian accelerations of every pair into ``acc`` (3, N), each pair once (third law), 1/r^3 by rsqrt."""
    n = pos.shape[1]
    for c in range(3):
        for i in range(n):
            acc[c, i] = 0.0
    for i in range(n):
        for j in range(i + 1, n):
            dx = pos[0, j] - pos[0, i]
            dy = pos[1, j] - pos[1, i]
            dz = pos[2, j] - pos[2, i]
            rinv = rsqrt(dx * dx + dy * dy + dz * dz)
            g_r3 = G * (rinv * rinv * rinv)
            mj = m[j] * g_r3
            mi = m[i] * g_r3
            acc[0, i] += mj * dx
            acc[1, i] += mj * dy
            acc[2, i] += mj * dz
            acc[0, j] -= mi * dx
            acc[1, j] -= mi * dy
            acc[2, j] -= mi * dz


@cuda_device
def jacobi_gravity_kick(jpos, jvel, m, G, h, weights, mu, ipos, acc):
    """The Wisdom-Holman interaction kick I(h) in Jacobi coordinates (``interaction_kick`` with JACOBI):
    the inertial positions into ``ipos``, the pair accelerations without the (0, 1) pair, their Jacobi
    transform in ``acc``, plus ``G M_i r'_i / |r'_i|^3`` for i >= 2, times h into ``jvel``."""
    n = jpos.shape[1]
    jacobi_to_inertial(jpos, weights, ipos)
    for c in range(3):
        for i in range(n):
            acc[c, i] = 0.0
    for i in range(n):
        start = 2 if i == 0 else i + 1
        for j in range(start, n):
            dx = ipos[0, j] - ipos[0, i]
            dy = ipos[1, j] - ipos[1, i]
            dz = ipos[2, j] - ipos[2, i]
            rinv = rsqrt(dx * dx + dy * dy + dz * dz)
            g_r3 = G * (rinv * rinv * rinv)
            mj = m[j] * g_r3
            mi = m[i] * g_r3
            acc[0, i] += mj * dx
            acc[1, i] += mj * dy
            acc[2, i] += mj * dz
            acc[0, j] -= mi * dx
            acc[1, j] -= mi * dy
            acc[2, j] -= mi * dz
    inertial_to_jacobi(acc, weights, acc)  # columns 1.. as the CPU kick's transform; column 0 is not read
    for i in range(1, n):
        ax = acc[0, i]
        ay = acc[1, i]
        az = acc[2, i]
        if i > 1:
            x = jpos[0, i]
            y = jpos[1, i]
            z = jpos[2, i]
            rinv = rsqrt(x * x + y * y + z * z)
            k = mu[i] * (rinv * rinv * rinv)
            ax += k * x
            ay += k * y
            az += k * z
        jvel[0, i] += h * ax
        jvel[1, i] += h * ay
        jvel[2, i] += h * az


@cuda_device
def wh_tangent_kepler_kick_kepler(pos, vel, dpos, dvel, m, G, dt, weights, mu, ipos, acc, dacc):
    """The first part of a Wisdom-Holman step of the state and its tangent vector (``tangent_step``: WHFast's
    safe mode): to Jacobi coordinates, K(dt/2) I(dt) K(dt/2), **in place**, leaving the Jacobi state in
    ``pos``, ``vel``, ``dpos``, ``dvel`` for the caller to read and take back to inertial coordinates
    (:func:`jacobi_to_inertial_state`). The same operations as the CPU's in the same order; in place (the
    transforms allow it) so that one thread holds 7 arrays of (3, N), not 12: fewer registers spilled.
    ``acc`` holds the tangent's inertial positions after the kick. Returns the Kepler status."""
    inertial_to_jacobi(pos, weights, pos)
    inertial_to_jacobi(vel, weights, vel)
    inertial_to_jacobi(dpos, weights, dpos)
    inertial_to_jacobi(dvel, weights, dvel)
    half = 0.5 * dt
    status, _ = kepler_step_tangent(pos, vel, dpos, dvel, mu, half)
    if status != KEPLER_OK:
        return status
    jacobi_gravity_kick(pos, vel, m, G, dt, weights, mu, ipos, acc)
    jacobi_to_inertial(dpos, weights, acc)  # acc is free after the kick: the tangent's inertial positions
    tangent_accelerations(ipos, m, G, 0.0, acc, dacc, SKIP_PAIR_0_1)
    inertial_to_jacobi(dacc, weights, dacc)
    jacobi_term_tangent_kick(pos, dpos, dvel, dacc, mu, dt)
    status, _ = kepler_step_tangent(pos, vel, dpos, dvel, mu, half)
    return status


@cuda_device
def jacobi_to_inertial_state(pos, vel, dpos, dvel, weights):
    """The Jacobi state and tangent vector back to inertial coordinates, in place (the step's end)."""
    jacobi_to_inertial(pos, weights, pos)
    jacobi_to_inertial(vel, weights, vel)
    jacobi_to_inertial(dpos, weights, dpos)
    jacobi_to_inertial(dvel, weights, dvel)


@cuda_device
def megno_read(megno, pos, m, G, dpos, dvel, dacc, t, dt):
    """MEGNO's sums after a step that ended at ``t`` (``megno_after_step`` without forces), then the exact
    power-of-two rescaling of the tangent vector. Returns the new sums."""
    tangent_accelerations(pos, m, G, 0.0, dpos, dacc, ALL_PAIRS)
    dY = dt * 2.0 * (t - megno.initial_t) * deltad_delta(dpos, dvel, dacc)
    megno = megno_update(megno, t, dY, dt)
    rescale_power_of_two(dpos, dvel)
    return megno


@cuda_device
def run_wh_variational(pos, vel, dpos, dvel, m, G, dt, t_start, n_steps, escape_r2, radii, check_collisions, watch,
                       weights, mu, ipos, acc, dacc, out):
    """One system's run (``run_system_variational`` of the CPU ensemble): ``n_steps`` steps or until it stops;
    indicators into ``out`` (N_COLUMNS,). Returns ``(status, steps_done)``. A system that diverged is left
    with its Jacobi state of the failed step (NaN), where the CPU's keeps the inertial state before it."""
    e0 = energy(pos, vel, m, G)
    inertial_to_jacobi(pos, weights, ipos)
    inertial_to_jacobi(vel, weights, acc)
    a0, max_e = jacobi_elements_ae(ipos, acc, mu, watch)
    delta_a = 0.0
    megno = MegnoState(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, t_start, 0)
    status = COMPLETE
    done = 0
    while done < n_steps:
        kstatus = wh_tangent_kepler_kick_kepler(pos, vel, dpos, dvel, m, G, dt, weights, mu, ipos, acc, dacc)
        done += 1
        if kstatus != KEPLER_OK:
            status = DIVERGED
            break
        max_e, delta_a = track_orbit(pos, vel, mu, watch, a0, max_e, delta_a)  # the Jacobi state at the end
        jacobi_to_inertial_state(pos, vel, dpos, dvel, weights)
        megno = megno_read(megno, pos, m, G, dpos, dvel, dacc, t_start + done * dt, dt)
        status = _stop_reason(pos, radii, escape_r2, check_collisions)
        if status != COMPLETE:
            break
    t = t_start + done * dt
    record_chaos_indicators(out, t, max_e, delta_a, megno)
    if status == DIVERGED:
        out[ENERGY_ERROR] = math.nan
    else:
        out[ENERGY_ERROR] = abs((energy(pos, vel, m, G) - e0) / e0)
    return status, done


@cuda_device
def run_fixed_step(pos, vel, m, G, dt, t_start, n_steps, escape_r2, radii, check_collisions, watch, weights, mu, jpos,
                   jvel, acc, verlet, out):
    """One system's run of a fixed-step scheme: the drift-kick-drift leapfrog (orbitsim.integrators.leapfrog
    order 2: x += v dt/2, v += a dt, x += v dt/2) or, with ``verlet`` (a compile-time constant), velocity
    Verlet (orbitsim.integrators.verlet: v += a dt/2, x += v dt, a = a(x), v += a dt/2, the closing
    accelerations reused), with the CPU ensemble's stops and indicators (``max_e``, ``delta_a`` from the
    Jacobi orbit of ``watch`` after every step; ``megno``, ``lyapunov`` NaN). Returns ``(status, steps)``."""
    n = pos.shape[1]
    e0 = energy(pos, vel, m, G)
    inertial_to_jacobi(pos, weights, jpos)
    inertial_to_jacobi(vel, weights, jvel)
    a0, max_e = jacobi_elements_ae(jpos, jvel, mu, watch)
    delta_a = 0.0
    half = 0.5 * dt
    status = COMPLETE
    done = 0
    if verlet:
        pair_accelerations(pos, m, G, acc)
    while done < n_steps:
        if verlet:
            for c in range(3):
                for i in range(n):
                    vel[c, i] += half * acc[c, i]
                    pos[c, i] += dt * vel[c, i]
            pair_accelerations(pos, m, G, acc)
            for c in range(3):
                for i in range(n):
                    vel[c, i] += half * acc[c, i]
        else:
            for c in range(3):
                for i in range(n):
                    pos[c, i] += half * vel[c, i]
            pair_accelerations(pos, m, G, acc)
            for c in range(3):
                for i in range(n):
                    vel[c, i] += dt * acc[c, i]
                    pos[c, i] += half * vel[c, i]
        done += 1
        inertial_to_jacobi(pos, weights, jpos)
        inertial_to_jacobi(vel, weights, jvel)
        max_e, delta_a = track_orbit(jpos, jvel, mu, watch, a0, max_e, delta_a)
        status = _stop_reason(pos, radii, escape_r2, check_collisions)
        if status != COMPLETE:
            break
    out[SURVIVAL_TIME] = t_start + done * dt
    out[MAX_E] = max_e
    out[DELTA_A] = delta_a
    out[MEGNO] = math.nan
    out[LYAPUNOV] = math.nan
    if status == DIVERGED:
        out[ENERGY_ERROR] = math.nan
    else:
        out[ENERGY_ERROR] = abs((energy(pos, vel, m, G) - e0) / e0)
    return status, done


@cache
def wh_variational_kernel(n: int, watch: int) -> Any:
    """The Wisdom-Holman + tangent map + MEGNO kernel for systems of ``n`` bodies whose body ``watch`` the
    ``max_e`` and ``delta_a`` indicators follow (both compile-time constants: an index known only at run time
    would move the arrays it indexes to local memory). Compiled at its first launch.

    Arguments, device arrays with the system index last: ``pos``, ``vel``, ``dpos``, ``dvel`` (3, N, K)
    (the start, overwritten with the state at the stop), ``m``, ``weights``, ``mu``, ``radii`` (N, K),
    scalars ``G``, ``dt``, ``t_start``, ``n_steps``, ``escape_r2``, ``check_collisions``, and
    the results ``status``, ``steps`` int64 (K,), ``out`` (N_COLUMNS, K).
    """

    @cuda_kernel
    def kernel(pos, vel, dpos, dvel, m, weights, mu, radii, G, dt, t_start, n_steps, escape_r2, check_collisions,
               status, steps, out):
        k = cuda.grid(1)
        if k >= pos.shape[2]:
            return
        p = cuda.local.array((3, n), float64)
        v = cuda.local.array((3, n), float64)
        dp = cuda.local.array((3, n), float64)
        dv = cuda.local.array((3, n), float64)
        ip = cuda.local.array((3, n), float64)
        acc = cuda.local.array((3, n), float64)
        dacc = cuda.local.array((3, n), float64)
        mk = cuda.local.array(n, float64)
        wk = cuda.local.array(n, float64)
        muk = cuda.local.array(n, float64)
        rk = cuda.local.array(n, float64)
        o = cuda.local.array(N_COLUMNS, float64)
        for i in range(n):
            mk[i] = m[i, k]
            wk[i] = weights[i, k]
            muk[i] = mu[i, k]
            rk[i] = radii[i, k]
            for c in range(3):
                p[c, i] = pos[c, i, k]
                v[c, i] = vel[c, i, k]
                dp[c, i] = dpos[c, i, k]
                dv[c, i] = dvel[c, i, k]
        st, done = run_wh_variational(p, v, dp, dv, mk, G, dt, t_start, n_steps, escape_r2, rk, check_collisions,
                                      watch, wk, muk, ip, acc, dacc, o)
        for i in range(n):
            for c in range(3):
                pos[c, i, k] = p[c, i]
                vel[c, i, k] = v[c, i]
                dpos[c, i, k] = dp[c, i]
                dvel[c, i, k] = dv[c, i]
        for col in range(N_COLUMNS):
            out[col, k] = o[col]
        status[k] = st
        steps[k] = done

    return kernel


@cache
def fixed_step_kernel(n: int, watch: int, scheme: str) -> Any:
    """The kernel of a fixed-step scheme, ``leapfrog`` or ``verlet`` (:func:`run_fixed_step`), for systems of
    ``n`` bodies: arguments as :func:`wh_variational_kernel`'s without ``dpos``, ``dvel``."""
    if scheme not in ("leapfrog", "verlet"):
        raise ValueError(f"no fixed-step GPU kernel for {scheme!r}")
    verlet = scheme == "verlet"

    @cuda_kernel
    def kernel(pos, vel, m, weights, mu, radii, G, dt, t_start, n_steps, escape_r2, check_collisions, status, steps,
               out):
        k = cuda.grid(1)
        if k >= pos.shape[2]:
            return
        p = cuda.local.array((3, n), float64)
        v = cuda.local.array((3, n), float64)
        jp = cuda.local.array((3, n), float64)
        jv = cuda.local.array((3, n), float64)
        acc = cuda.local.array((3, n), float64)
        mk = cuda.local.array(n, float64)
        wk = cuda.local.array(n, float64)
        muk = cuda.local.array(n, float64)
        rk = cuda.local.array(n, float64)
        o = cuda.local.array(N_COLUMNS, float64)
        for i in range(n):
            mk[i] = m[i, k]
            wk[i] = weights[i, k]
            muk[i] = mu[i, k]
            rk[i] = radii[i, k]
            for c in range(3):
                p[c, i] = pos[c, i, k]
                v[c, i] = vel[c, i, k]
        st, done = run_fixed_step(p, v, mk, G, dt, t_start, n_steps, escape_r2, rk, check_collisions, watch, wk, muk,
                                  jp, jv, acc, verlet, o)
        for i in range(n):
            for c in range(3):
                pos[c, i, k] = p[c, i]
                vel[c, i, k] = v[c, i]
        for col in range(N_COLUMNS):
            out[col, k] = o[col]
        status[k] = st
        steps[k] = done

    return kernel
