"""Maps over a massless body: the massive bodies are stepped once, every pixel steps only its test body.

A map that varies a massless body (the bundled ``jupiter_saturn`` map moves a test planet between
Jupiter and Saturn) gives every pixel the same massive bodies: a body of mass 0 pulls nothing, its
Jacobi weight ``m / M`` is 0, and every term it adds to a massive body is ``0 * x``, a signed zero that
leaves the sum's bits alone. So in :func:`orbitsim.ensemble.kernels.run_system_variational` the massive
bodies and their tangent vectors take the same bits in every pixel, whatever the test body does (as
long as it stays finite, and it stops its pixel the step it does not). This module's kernel steps them
once per block of steps (:func:`orbitsim.ensemble.massive_record.massive_block`), which keeps, per step,
the few numbers the test body reads from them (the record); every pixel then steps only its test body,
LANES pixels side by side in SIMD lanes (:func:`orbitsim.ensemble.lanes.pixel_block_lanes`), with the same
operations in the same order as the whole-system step, so its bits are those of
:func:`run_system_variational` (tests/ensemble/test_restricted.py compares them bit for bit).

The tangent vector of a pixel is ``(s * delta_massive, delta_test)``: its massive part is the shared
one times ``s = 2^(-200 h)``, ``h`` the pixel's rescalings (:func:`orbitsim.chaos.megno.rescale_power_of_two`
scales the whole vector by 2^-200). Scaling by a power of two commutes with every rounding of the
linear tangent map, so ``s * shared`` is the value the whole-system step holds (until it would be
subnormal, where it is at most 2^-1022 of the test body's part and moves none of its bits).

Conditions (:func:`restricted_applies`): the test body is the last body, massless in every system,
and the massive bodies' masses, start states, radii and initial variation are the same bits in every
system. A massive tangent vector that grows past 2^300 (a chaotic massive system) ends the shortcut:
:func:`run_restricted_variational` returns False and the caller runs the whole-system kernel.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numba import prange

from orbitsim._jit import jit, jit_inline, jit_parallel_exact
from orbitsim.chaos.megno import MegnoState, lyapunov, megno_value
from orbitsim.ensemble.kernels import _energy, jacobi_elements_ae
from orbitsim.ensemble.lanes import (
    LANES,
    LIVE,
    M_COV_YT,
    M_MEAN_T,
    M_MEAN_Y,
    M_VAR_T,
    M_YS,
    M_YSS,
    NROWS,
    SCALE,
    STOP_CODE,
    STOP_STEP,
    TDP,
    TDV,
    TP,
    TRACK_A0,
    TRACK_DELTA_A,
    TRACK_MAX_E,
    TV,
    pixel_block_lanes,
)
from orbitsim.ensemble.massive_record import (
    BLOCK_STEPS,
    KEPLER_FAILED,
    R_STATUS,
    V_POS,
    V_VEL,
    massive_block,
    record_columns,
    record_value,
)
from orbitsim.ensemble.parallel import aligned_zeros
from orbitsim.ensemble.status import COMPLETE, DELTA_A, DIVERGED, ENERGY_ERROR, LYAPUNOV, MAX_E, MEGNO, SURVIVAL_TIME
from orbitsim.physics.coordinates import inertial_to_jacobi


@jit
def _start_group(g, grp, pos, vel, dpos, dvel, m, G, weights, mu, watch, rows, jscratch, e0):
    """Fill group ``grp``'s lanes from its pixels (their test bodies, start elements and energy ``e0``);
    lanes past the last pixel are padding: a copy of the group's first pixel, never live."""
    n_sys = pos.shape[0]
    q = pos.shape[2] - 1
    for lane in range(LANES):
        k = grp * LANES + lane
        real = k < n_sys
        if not real:
            k = grp * LANES
        else:
            e0[k] = _energy(pos[k], vel[k], m[k], G, rows)
        inertial_to_jacobi(pos[k], weights[k], jscratch[0])
        inertial_to_jacobi(vel[k], weights[k], jscratch[1])
        a0, e_start = jacobi_elements_ae(jscratch[0], jscratch[1], mu[k], watch)
        g[TRACK_A0 * LANES + lane] = a0
        g[TRACK_MAX_E * LANES + lane] = e_start
        g[SCALE * LANES + lane] = 1.0
        g[LIVE * LANES + lane] = 1.0 if real else -1.0
        for c in range(3):
            g[(TP + c) * LANES + lane] = pos[k, c, q]
            g[(TV + c) * LANES + lane] = vel[k, c, q]
            g[(TDP + c) * LANES + lane] = dpos[k, c, q]
            g[(TDV + c) * LANES + lane] = dvel[k, c, q]


@jit
def _write_out(g, lane, k, code, n_steps_done, megno_steps, mpos, mvel, rec, row, t_start, dt, e0, m, G, rows, pos,
               vel, status, steps, out):
    """Pixel ``k`` (lane ``lane`` of ``g``) has stopped, or finished, after ``n_steps_done`` steps, its MEGNO
    sums after ``megno_steps``: its whole state (the massive bodies from ``rec`` row ``row``, or ``mpos``,
    ``mvel`` when ``row`` < 0), status, steps and indicator row, as
    :func:`orbitsim.ensemble.kernels.run_system_variational` writes them."""
    q = pos.shape[2] - 1
    for c in range(3):
        for i in range(q):
            if row < 0:
                pos[k, c, i] = mpos[c, i]
                vel[k, c, i] = mvel[c, i]
            else:
                pos[k, c, i] = record_value(rec, row, V_POS, q, c, i)
                vel[k, c, i] = record_value(rec, row, V_VEL, q, c, i)
        pos[k, c, q] = g[(TP + c) * LANES + lane]
        vel[k, c, q] = g[(TV + c) * LANES + lane]
    status[k] = code
    steps[k] = n_steps_done
    megno = MegnoState(g[M_YS * LANES + lane], g[M_YSS * LANES + lane], g[M_COV_YT * LANES + lane],
                       g[M_VAR_T * LANES + lane], g[M_MEAN_T * LANES + lane], g[M_MEAN_Y * LANES + lane], t_start,
                       megno_steps)
    t = t_start + n_steps_done * dt
    out[k, SURVIVAL_TIME] = t
    out[k, MAX_E] = g[TRACK_MAX_E * LANES + lane]
    out[k, DELTA_A] = g[TRACK_DELTA_A * LANES + lane]
    out[k, MEGNO] = megno_value(megno, t)
    out[k, LYAPUNOV] = lyapunov(megno)
    if code == DIVERGED:
        out[k, ENERGY_ERROR] = np.nan
    else:
        out[k, ENERGY_ERROR] = abs((_energy(pos[k], vel[k], m[k], G, rows) - e0) / e0)


@jit_inline
def _massive_slot(slot, mpos, mvel, mdpos, mdvel, m, force, dt, weights, mu, scratch, escape_r2, radii,
                  check_collisions, n_steps, rec, block_pos, block_vel, recorded, ok):
    """The massive bodies' next block (:func:`massive_block`, up to ``n_steps`` steps) into record slot ``slot``,
    their state before it into ``block_pos[slot]``, ``block_vel[slot]``, its step count and verdict into
    ``recorded[slot]``, ``ok[slot]``."""
    block_pos[slot, :, :] = mpos
    block_vel[slot, :, :] = mvel
    recorded[slot], ok[slot] = massive_block(mpos, mvel, mdpos, mdvel, m, force, dt, weights, mu, scratch, escape_r2,
                                             radii, check_collisions, n_steps, rec[slot])


def run_restricted_variational(pos: np.ndarray, vel: np.ndarray, dpos: np.ndarray, dvel: np.ndarray, m: np.ndarray,
                               force: Any, dt: float, t_start: float, n_steps: np.int64, escape_r2: float,
                               radii: np.ndarray, check_collisions: bool, watch: np.int64, weights: np.ndarray,
                               mu: np.ndarray, rows: np.ndarray, status: np.ndarray, steps: np.ndarray,
                               out: np.ndarray) -> bool:
    """:func:`orbitsim.ensemble.kernels.run_ensemble_variational` for systems whose last body is massless
    and whose other bodies (and their variations) are the same in every system (module docstring).
    Same arguments and results, less its scratch; ``watch`` must be the last body. Returns False, having
    written nothing meaningful, where the shortcut gave up (the caller then runs the whole-system kernel).
    The pixels are stepped LANES at a time (:mod:`orbitsim.ensemble.lanes`), group after group, block after
    block; the massive bodies' next block is stepped beside the pixels' current one, as one more task of the
    same ``prange`` (two record slots), so no thread waits for it. The groups' rows start cache lines
    (:func:`orbitsim.ensemble.parallel.aligned_zeros`; Numba's own ``np.zeros`` aligns to 32 bytes)."""
    n_groups = (pos.shape[0] + LANES - 1) // LANES
    groups = aligned_zeros((n_groups, NROWS * LANES))
    whole = aligned_zeros((n_groups, LANES, 3, 3, pos.shape[2]))  # a rescaled lane's tangent state
    return bool(_run_restricted(pos, vel, dpos, dvel, m, force, dt, t_start, n_steps, escape_r2, radii,
                                check_collisions, watch, weights, mu, rows, status, steps, out, groups, whole))


@jit_parallel_exact
def _run_restricted(pos, vel, dpos, dvel, m, force, dt, t_start, n_steps, escape_r2, radii, check_collisions, watch,
                    weights, mu, rows, status, steps, out, groups, whole):
    """:func:`run_restricted_variational`'s kernel, its groups' rows and tangent scratch given."""
    n_sys = pos.shape[0]
    n = pos.shape[2]
    q = n - 1
    G = force.G
    eps2 = force.eps2
    mpos = pos[0, :, :q].copy()
    mvel = vel[0, :, :q].copy()
    mdpos = dpos[0, :, :q].copy()
    mdvel = dvel[0, :, :q].copy()
    mm = m[0, :q].copy()
    mweights = weights[0, :q].copy()
    mmu = mu[0, :q].copy()
    mradii = radii[0, :q].copy()
    mscratch = np.zeros((8, 3, q))
    mu_t = mu[0, q]
    radius = radii[0, q]
    # two record slots: the pixels read one block while the massive bodies are stepped into the other
    rec = np.zeros((2, BLOCK_STEPS, record_columns(q)))
    block_pos = np.zeros((2, 3, q))  # the massive bodies' state before each slot's block
    block_vel = np.zeros((2, 3, q))
    recorded = np.zeros(2, dtype=np.int64)
    ok = np.ones(2, dtype=np.bool_)
    n_groups = groups.shape[0]  # LANES pixels a group, the last one padded (run_restricted_variational)
    e0 = np.zeros(n_sys)
    jscratch = np.zeros((n_groups, 2, 3, n))
    # the helpers take np.int64 arguments: a prange index, and a literal, are typed otherwise inside a parfor
    # than outside it, and each type would compile a helper once more
    for grp in prange(n_groups):
        _start_group(groups[grp], np.int64(grp), pos, vel, dpos, dvel, m, G, weights, mu, watch, rows, jscratch[grp],
                     e0)
    done = np.int64(0)  # not the literal 0: pixel_block_lanes would compile once for Literal[int](0), once for int64
    cur = np.int64(0)
    if n_steps > 0:
        _massive_slot(cur, mpos, mvel, mdpos, mdvel, mm, force, dt, mweights, mmu, mscratch, escape_r2, mradii,
                      check_collisions, np.int64(min(BLOCK_STEPS, n_steps)), rec, block_pos, block_vel, recorded, ok)
    while done < n_steps:
        if not ok[cur]:
            return False
        n_rec = recorded[cur]
        # the next block is stepped beside this one's pixels (task 0 of the prange below), unless this block ends
        # the run or the massive bodies stopped in it (every pixel then stops in it too)
        ahead = np.int64(1) if done + n_rec < n_steps and rec[cur, n_rec - 1, R_STATUS] == COMPLETE else np.int64(0)
        nxt = np.int64(1) - cur
        n_next = np.int64(min(BLOCK_STEPS, n_steps - done - n_rec))
        cur_rec = rec[cur]
        for task in prange(n_groups + ahead):
            if task < ahead:
                _massive_slot(nxt, mpos, mvel, mdpos, mdvel, mm, force, dt, mweights, mmu, mscratch, escape_r2,
                              mradii, check_collisions, n_next, rec, block_pos, block_vel, recorded, ok)
                continue
            grp = task - ahead
            g = groups[grp]
            pixel_block_lanes(g, whole[grp], q, mm, G, eps2, dt, mu_t, cur_rec, n_rec, done, t_start, radius, mradii,
                              escape_r2, check_collisions)
            for lane in range(LANES):
                if g[LIVE * LANES + lane] != 0.0:
                    continue
                g[LIVE * LANES + lane] = -1.0
                k = np.int64(grp * LANES + lane)
                code = np.int64(g[STOP_CODE * LANES + lane])
                n_done = np.int64(g[STOP_STEP * LANES + lane])
                if code == KEPLER_FAILED:  # the state before the failed step, which MEGNO's sums never saw
                    _write_out(g, lane, k, np.int64(DIVERGED), done + n_done, done + n_done - 1, block_pos[cur],
                               block_vel[cur], cur_rec, n_done - 2, t_start, dt, e0[k], m, G, rows, pos, vel, status,
                               steps, out)
                else:
                    _write_out(g, lane, k, code, done + n_done, done + n_done, block_pos[cur], block_vel[cur],
                               cur_rec, n_done - 1, t_start, dt, e0[k], m, G, rows, pos, vel, status, steps, out)
        done += n_rec
        if ahead == 0:
            break
        cur = nxt
    for grp in prange(n_groups):
        g = groups[grp]
        for lane in range(LANES):
            if g[LIVE * LANES + lane] == 1.0:
                k = np.int64(grp * LANES + lane)
                _write_out(g, lane, k, np.int64(COMPLETE), n_steps, n_steps, mpos, mvel, rec[cur], np.int64(-1),
                           t_start, dt, e0[k], m, G, rows, pos, vel, status, steps, out)
    return True


def restricted_applies(masses: np.ndarray, positions: np.ndarray, velocities: np.ndarray, radii: np.ndarray,
                       dpos: np.ndarray, dvel: np.ndarray, watch: int) -> bool:
    """Whether :func:`run_restricted_variational` can run these systems: N >= 3, the last body massless in
    every system and watched, and the other bodies' masses, states, radii and variations the same bits."""
    n = masses.shape[1]
    if n < 3 or watch != n - 1 or (masses[:, n - 1] != 0.0).any():
        return False

    def same(a: np.ndarray) -> bool:
        head = np.ascontiguousarray(a[..., : n - 1]).view(np.uint64)
        return bool((head == head[:1]).all())

    return all(same(a) for a in (masses, positions, velocities, radii, dpos, dvel))
