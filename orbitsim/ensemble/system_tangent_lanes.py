"""Whole Wisdom-Holman systems with their variational equations in SIMD lanes: MEGNO for LANES systems at once.

:func:`orbitsim.ensemble.kernels.run_ensemble_variational` steps one system and its tangent vector per
``prange`` iteration (:func:`~orbitsim.ensemble.kernels.run_system_variational`). Here LANES systems (a group)
take each step together, in the block layout of :mod:`orbitsim.ensemble.system_lanes` (read its docstring:
one block of LANES-wide rows per body, unsigned offsets, what one block needs from another copied by
``_copy_row``): each lane performs the scalar step's operations in the same order, with no fastmath, so each
system keeps its bits (tests/ensemble/test_system_tangent_lanes.py compares every output bit for bit):

* :func:`orbitsim.integrators.wisdom_holman.tangent.tangent_step` (WHFast's safe mode): the inertial state
  and tangent vector to Jacobi coordinates, K(dt/2) with the drift's derivative, the interaction kick of the
  bodies and of the tangent vector (the tangent gravity without the (0, 1) pair, its Jacobi transform, the
  Jacobi term's derivative), K(dt/2), back to inertial coordinates;
* :func:`orbitsim.chaos.step.megno_after_step`: the tangent gravity of every pair at the new state, the
  sums of ``deltad_delta`` body by body, :func:`orbitsim.chaos.megno.megno_update`;
* ``track_orbit`` and ``_stop_reason`` of :mod:`orbitsim.ensemble.kernels` on the inertial state.

The block layout and the tangent step's operators (Jacobi transforms, drift, tangent gravity, kick) are in
:mod:`orbitsim.ensemble.system_tangent_step`; here are MEGNO's read, the stop test, the group's loop and the
kernel.

Where the scalar step would branch, the lanes take the common case and a lane outside it is done by the scalar
code: a body's drift that is not a short step, leaves the Stumpff series, does not settle in
:data:`~orbitsim.physics.kepler_solver.NEWTON_FAST_ITERATIONS` or needs a quartered G6 is drifted by
:func:`orbitsim.integrators.wisdom_holman.tangent.kepler_drift_tangent` (as :mod:`orbitsim.ensemble.lanes`
does for a map's test body); a lane whose |delta|^2 nears the rescaling bar is tested and rescaled by
:func:`orbitsim.chaos.megno.rescale_power_of_two` itself on a copy of its tangent vector.

A lane stops alone, at the step the scalar kernel stops (a failed drift: its inertial state stays as before
that step, as the scalar step leaves it; or the stop test after MEGNO's read); its inertial and MEGNO rows are
then no longer written. The Jacobi, kick and drift rows are scratch recomputed every step, so they are written
for every lane. The indicator row and energy error at the end are the scalar kernel's code, once per system.

The kernel takes ``G`` and ``eps2``, not a force context: it has no forces beyond gravity, so
:func:`orbitsim.ensemble.run.run_ensemble` calls it only for a force-free context.
"""

from __future__ import annotations

import numpy as np

from orbitsim._jit import jit, stop_requested, wide_vectors
from orbitsim.chaos.megno import RESCALE_ABOVE, MegnoState, deltad_delta_body, megno_update, rescale_power_of_two
from orbitsim.ensemble.kernels import _energy, jacobi_elements_ae, record_chaos_indicators
from orbitsim.ensemble.parallel import aligned_zeros, over_threads
from orbitsim.ensemble.status import COMPLETE, DIVERGED, ENERGY_ERROR
from orbitsim.ensemble.system_lanes import (
    LANES,
    _copy_rows,
    _rank_code,
    _row,
    start_row_sums,
    stop_failed_drifts,
    stop_lane,
    stop_test_lanes,
    track_orbit_lanes,
)
from orbitsim.ensemble.system_tangent_step import (
    A0,
    BLOCK_ROWS,
    CARRY,
    DACC,
    DELTA_A,
    DIPOS,
    DP,
    DV,
    IPOS,
    JP,
    JV,
    LIVE,
    M_COV_YT,
    M_MEAN_T,
    M_MEAN_Y,
    M_VAR_T,
    M_YS,
    M_YSS,
    MASS,
    MAX_E,
    MU,
    NEAR,
    OTHER,
    OTHER_S,
    RADIUS,
    RANK,
    STOP_CODE,
    STOP_STEP,
    WEIGHT,
    P,
    V,
    block,
    drift_tangent_lanes,
    kick_tangent_lanes,
    tangent_gravity_lanes,
    to_inertial_lanes,
    to_jacobi_lanes,
)
from orbitsim.physics.coordinates import inertial_to_jacobi

_U = np.uint64
#: |delta|^2 summed in the lanes' order is within a few ulps of rescale_power_of_two's sum; a lane above the bar
#: less this margin takes the exact test (a margin far above those ulps, far below any growth in a step).
_NEAR_MARGIN = 1.0 - 1e-9


@jit
def _megno_lanes(g, n, G, eps2, dt, t, t_start, n_before, width):
    """megno_after_step of the live lanes: the tangent gravity of every pair at the new state, deltad_delta's
    sums carried body by body, megno_update; marks in NEAR the lanes to test for a rescaling. Returns
    whether any lane is marked."""
    wide_vectors()
    for b in range(n):  # the new state into the rows the tangent gravity reads (scratch until the next kick)
        _copy_rows(g, block(b), IPOS, block(b), P, 3)
        _copy_rows(g, block(b), DIPOS, block(b), DP, 3)
    tangent_gravity_lanes(g, n, G, eps2, np.int64(1), width)
    b0 = block(0)
    for b in range(n):
        base = block(b)
        start_row_sums(g, BLOCK_ROWS, b, 0, CARRY, width)
        pxr, vxr, axr = _row(base, DP), _row(base, DV), _row(base, DACC)
        sd, s2, sn = _row(base, CARRY), _row(base, CARRY + 1), _row(base, CARRY + 2)
        for lane in range(_U(LANES)):
            dpx, dpy, dpz = g[pxr + lane], g[pxr + _U(LANES) + lane], g[pxr + _U(2 * LANES) + lane]
            dvx, dvy, dvz = g[vxr + lane], g[vxr + _U(LANES) + lane], g[vxr + _U(2 * LANES) + lane]
            dax, day, daz = g[axr + lane], g[axr + _U(LANES) + lane], g[axr + _U(2 * LANES) + lane]
            deltad, delta2 = g[sd + lane], g[s2 + lane]
            deltad, delta2 = deltad_delta_body(deltad, delta2, dpx, dpy, dpz, dvx, dvy, dvz, dax, day, daz)
            g[sd + lane], g[s2 + lane] = deltad, delta2
            g[sn + lane] += (dpx * dpx + dvx * dvx) + (dpy * dpy + dvy * dvy) + (dpz * dpz + dvz * dvz)
    _copy_rows(g, b0, CARRY, block(n - 1), CARRY, 3)
    liver, sd, s2, sn, near_r = _row(b0, LIVE), _row(b0, CARRY), _row(b0, CARRY + 1), _row(b0, CARRY + 2), \
        _row(b0, NEAR)
    ys, yss, cov, var = _row(b0, M_YS), _row(b0, M_YSS), _row(b0, M_COV_YT), _row(b0, M_VAR_T)
    mean_t, mean_y = _row(b0, M_MEAN_T), _row(b0, M_MEAN_Y)
    rescale = False
    for lane in range(LANES):
        ulane = _U(lane)
        dY = dt * 2.0 * (t - t_start) * (g[sd + ulane] / g[s2 + ulane])
        before = MegnoState(g[ys + ulane], g[yss + ulane], g[cov + ulane], g[var + ulane], g[mean_t + ulane],
                            g[mean_y + ulane], t_start, n_before)
        after = megno_update(before, t, dY, dt)
        live = g[liver + ulane] > 0.0
        g[ys + ulane] = after.ys if live else before.ys
        g[yss + ulane] = after.yss if live else before.yss
        g[cov + ulane] = after.cov_yt if live else before.cov_yt
        g[var + ulane] = after.var_t if live else before.var_t
        g[mean_t + ulane] = after.mean_t if live else before.mean_t
        g[mean_y + ulane] = after.mean_y if live else before.mean_y
        near = live and g[sn + ulane] > RESCALE_ABOVE * _NEAR_MARGIN
        g[near_r + ulane] = 1.0 if near else 0.0
        rescale |= near
    return rescale


@jit
def _rescale_lane(g, n, lane, whole):
    """rescale_power_of_two of lane ``lane``'s tangent vector (a copy in ``whole`` (2, 3, N)), written back."""
    ulane = _U(lane)
    for b in range(n):
        for c in range(3):
            whole[0, c, b] = g[_row(block(b), DP + c) + ulane]
            whole[1, c, b] = g[_row(block(b), DV + c) + ulane]
    if rescale_power_of_two(whole[0], whole[1]) > 0:
        for b in range(n):
            for c in range(3):
                g[_row(block(b), DP + c) + ulane] = whole[0, c, b]
                g[_row(block(b), DV + c) + ulane] = whole[1, c, b]


@jit
def run_tangent_group(g, n, G, eps2, dt, t_start, n_steps, escape_r2, check_collisions, watch, whole):
    """Step a group's live lanes and their tangent vectors ``n_steps`` times, each until it stops (LIVE 0,
    STOP_CODE, STOP_STEP in block 0), with MEGNO's read after every step. ``whole`` (2, 3, N) is scratch for a
    rescaled lane. Returns the steps taken by the lanes still live at the end (fewer where a stop of the kernels
    was asked for, :func:`orbitsim._jit.stop_requested`: the caller then throws the results away)."""
    wide_vectors()
    half = 0.5 * dt
    b0 = block(0)
    width = _U(g.size // (n * BLOCK_ROWS))  # LANES, counted at run time (see system_lanes.run_group)
    live_lanes = 0
    for lane in range(LANES):
        live_lanes += g[_row(b0, LIVE) + _U(lane)] > 0.0
    done = 0
    while done < n_steps and live_lanes > 0:
        if stop_requested():
            break
        to_jacobi_lanes(g, n, width)
        for phase in range(2):  # K(dt/2) I(dt) K(dt/2); one drift call site, so inlined and compiled once
            for b in range(1, n):
                if drift_tangent_lanes(g, block(b), half) > 0:
                    live_lanes -= stop_failed_drifts(g, n, b, done + 1, BLOCK_ROWS, LIVE, STOP_CODE, STOP_STEP)
            jx, vx = _row(b0, JP), _row(b0, JV)
            for r in range(3):  # the centre of mass and its variation drift
                for lane in range(width):
                    g[jx + _U(r * LANES) + lane] += half * g[vx + _U(r * LANES) + lane]
                    g[jx + _U((r + 6) * LANES) + lane] += half * g[vx + _U((r + 6) * LANES) + lane]
            if phase == 1:
                break
            kick_tangent_lanes(g, n, G, eps2, dt, width)
        done += 1
        to_inertial_lanes(g, n, width)
        if _megno_lanes(g, n, G, eps2, dt, t_start + done * dt, t_start, done - 1, width):
            for lane in range(LANES):
                if g[_row(b0, NEAR) + _U(lane)] > 0.0:
                    _rescale_lane(g, n, lane, whole)
        track_orbit_lanes(g, block(watch), JP, JV, MU, LIVE, A0)
        stop_test_lanes(g, n, escape_r2, check_collisions, width, BLOCK_ROWS, P, RADIUS, OTHER, OTHER_S, RANK)
        for lane in range(LANES):
            verdict = g[_row(b0, RANK) + _U(lane)]
            if verdict > 0.0 and g[_row(b0, LIVE) + _U(lane)] > 0.0:
                stop_lane(g, n, lane, _rank_code(verdict), done, BLOCK_ROWS, LIVE, STOP_CODE, STOP_STEP)
                live_lanes -= 1
    return done


@jit
def _start_group(g, grp, pos, vel, dpos, dvel, m, G, weights, mu, radii, watch, rows, scratch, e0):
    """Fill group ``grp``'s blocks from its systems (run_system_variational's start: energy, the watched body's
    Jacobi elements); lanes past the last system are padding, a copy of lane 0 that is never live."""
    n_sys, n = pos.shape[0], pos.shape[2]
    wb = block(watch)
    for lane in range(LANES):
        k = grp * LANES + lane
        ulane = _U(lane)
        if k >= n_sys:
            for row in range(n * BLOCK_ROWS):
                g[row * LANES + lane] = g[row * LANES]
            for b in range(n):
                g[_row(block(b), LIVE) + ulane] = -1.0
            continue
        e0[k] = _energy(pos[k], vel[k], m[k], G, rows)
        jpos, jvel = scratch[k, 0], scratch[k, 1]
        inertial_to_jacobi(pos[k], weights[k], jpos)
        inertial_to_jacobi(vel[k], weights[k], jvel)
        a0, e_start = jacobi_elements_ae(jpos, jvel, mu[k], watch)
        for b in range(n):
            base = block(b)
            for c in range(3):
                g[_row(base, P + c) + ulane] = pos[k, c, b]
                g[_row(base, V + c) + ulane] = vel[k, c, b]
                g[_row(base, DP + c) + ulane] = dpos[k, c, b]
                g[_row(base, DV + c) + ulane] = dvel[k, c, b]
            g[_row(base, MASS) + ulane] = m[k, b]
            g[_row(base, WEIGHT) + ulane] = weights[k, b]
            g[_row(base, MU) + ulane] = mu[k, b]
            g[_row(base, RADIUS) + ulane] = radii[k, b]
            g[_row(base, LIVE) + ulane] = 1.0
        g[_row(wb, A0) + ulane] = a0
        g[_row(wb, MAX_E) + ulane] = e_start
        g[_row(wb, DELTA_A) + ulane] = 0.0


@jit
def _finish_group(g, grp, done, pos, vel, dpos, dvel, m, G, dt, t_start, watch, rows, e0, status, steps, out):
    """Each system of group ``grp``: its inertial state and tangent vector into ``pos[k]``, ``vel[k]``,
    ``dpos[k]``, ``dvel[k]`` (where run_system_variational leaves them) and the end of run_system_variational
    (the indicator row, the energy error)."""
    n_sys, n = pos.shape[0], pos.shape[2]
    b0, wb = block(0), block(watch)
    for lane in range(LANES):
        k = grp * LANES + lane
        if k >= n_sys:
            break
        ulane = _U(lane)
        code, n_done = np.int64(COMPLETE), done
        if not g[_row(b0, LIVE) + ulane] > 0.0:
            code, n_done = np.int64(g[_row(b0, STOP_CODE) + ulane]), np.int64(g[_row(b0, STOP_STEP) + ulane])
        for b in range(n):
            for c in range(3):
                pos[k, c, b] = g[_row(block(b), P + c) + ulane]
                vel[k, c, b] = g[_row(block(b), V + c) + ulane]
                dpos[k, c, b] = g[_row(block(b), DP + c) + ulane]
                dvel[k, c, b] = g[_row(block(b), DV + c) + ulane]
        megno = MegnoState(g[_row(b0, M_YS) + ulane], g[_row(b0, M_YSS) + ulane], g[_row(b0, M_COV_YT) + ulane],
                           g[_row(b0, M_VAR_T) + ulane], g[_row(b0, M_MEAN_T) + ulane],
                           g[_row(b0, M_MEAN_Y) + ulane], t_start, n_done)
        record_chaos_indicators(out[k], t_start + n_done * dt, g[_row(wb, MAX_E) + ulane],
                                g[_row(wb, DELTA_A) + ulane], megno)
        if code == DIVERGED:
            out[k, ENERGY_ERROR] = np.nan
        else:
            out[k, ENERGY_ERROR] = abs((_energy(pos[k], vel[k], m[k], G, rows) - e0[k]) / e0[k])
        status[k] = code
        steps[k] = n_done


@jit
def _run_groups(first, last, groups, whole, e0, pos, vel, dpos, dvel, m, G, eps2, dt, t_start, n_steps, escape_r2,
                radii, check_collisions, watch, weights, mu, scratch, rows, status, steps, out):
    """Groups ``first .. last - 1`` of :func:`run_ensemble_variational_lanes`, one after another (one thread's
    range)."""
    n = pos.shape[2]
    for grp in range(first, last):
        g = groups[grp]
        _start_group(g, grp, pos, vel, dpos, dvel, m, G, weights, mu, radii, watch, rows, scratch, e0)
        done = run_tangent_group(g, np.int64(n), G, eps2, dt, t_start, n_steps, escape_r2, check_collisions, watch,
                                 whole[grp])
        _finish_group(g, grp, np.int64(done), pos, vel, dpos, dvel, m, G, dt, t_start, watch, rows, e0, status, steps,
                      out)


def run_ensemble_variational_lanes(pos: np.ndarray, vel: np.ndarray, dpos: np.ndarray, dvel: np.ndarray,
                                   m: np.ndarray, G: float, eps2: float, dt: float, t_start: float, n_steps: np.int64,
                                   escape_r2: float, radii: np.ndarray, check_collisions: bool, watch: np.int64,
                                   weights: np.ndarray, mu: np.ndarray, scratch: np.ndarray, rows: np.ndarray,
                                   status: np.ndarray, steps: np.ndarray, out: np.ndarray) -> None:
    """:func:`orbitsim.ensemble.kernels.run_ensemble_variational` without forces beyond gravity (``G``,
    ``eps2`` in place of its force context), LANES systems per group in SIMD lanes (module docstring): the same
    results bit for bit, ``dpos`` and ``dvel`` left with each system's last tangent vector as that kernel leaves
    them; the groups over the threads (:func:`orbitsim.ensemble.parallel.over_threads`; the last one padded).
    ``scratch`` (K, >= 2, 3, N)."""
    n_sys, n = pos.shape[0], pos.shape[2]
    n_groups = (n_sys + LANES - 1) // LANES
    groups = aligned_zeros((n_groups, n * BLOCK_ROWS * LANES))  # rows start cache lines (parallel.py)
    whole = np.zeros((n_groups, 2, 3, n))
    e0 = np.zeros(n_sys)
    over_threads(_run_groups, n_groups, groups, whole, e0, pos, vel, dpos, dvel, m, G, eps2, dt, t_start, n_steps,
                 escape_r2, radii, check_collisions, watch, weights, mu, scratch, rows, status, steps, out)
