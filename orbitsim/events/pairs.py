"""Checks over the pairs of bodies after a step: contacts (collisions) and close encounters, and
each body's dominant attractor for the unresolved-step check (:mod:`orbitsim.events.bodies`).

See :mod:`orbitsim.events.kernels` for what each check means.
"""

from __future__ import annotations

import math

from orbitsim._jit import jit, jit_inline, stop_requested
from orbitsim.events.layout import (
    C_CENTRAL,
    C_DETECT,
    C_ENC,
    C_ENC_HALT,
    C_RESOLVE,
    C_UNRES,
    DETECT_DIRECT,
    DETECT_NONE,
    ENC_HILL,
    ENC_NONE,
    EV_COLLISION,
    EV_ENCOUNTER,
    F_ENC,
    F_G,
    N_PAIRS,
    P_I,
    P_J,
    P_KIND,
    P_LAST,
    P_START,
    PAIR_CONTACT,
    PAIR_ENCOUNTER,
    PAIR_F_COLS,
    PAIR_I_COLS,
    PF_DMIN,
    PF_LIMIT,
    PF_TMIN,
    PF_VMIN,
    RESOLVE_HALT,
    RESOLVE_LOG,
    RESOLVE_MERGE,
    STOP_HALT,
    STOP_NONE,
    STOP_RESOLVE,
    find_pair,
    log_event,
    open_pair,
)


@jit_inline
def hermite_min(ro2, rn2, dro2, drn2, dt):
    """Minimum over the step of the cubic Hermite fit to the squared separation r^2(s), s in [0, 1],
    from its end values ``ro2``, ``rn2`` and time derivatives ``dro2``, ``drn2`` (= 2 r . v).

    Returns ``(min r^2, s at the minimum)``. The cubic's derivative is a quadratic a s^2 + b s + c;
    its roots inside the step are the candidates (the prediction of REBOUND MERCURIUS's
    ``encounter_predict``). The roots are taken in the cancellation-free form q / a and c / q with
    q = -(b + sign(b) sqrt(b^2 - 4ac)) / 2: for a straight-line passage r^2 is quadratic, a is zero
    or round-off, and (-b +- root) / 2a would lose every digit (a pass mid-step was missed).
    """
    best, s_best = ro2, 0.0
    if rn2 < best:
        best, s_best = rn2, 1.0
    a = 6.0 * (ro2 - rn2) + 3.0 * dt * (dro2 + drn2)
    b = 6.0 * (rn2 - ro2) - 2.0 * dt * (2.0 * dro2 + drn2)
    c = dt * dro2
    q = -0.5 * (b + math.copysign(math.sqrt(max(0.0, b * b - 4.0 * a * c)), b))
    s1 = q / a if a != 0.0 else -1.0
    s2 = c / q if q != 0.0 else -1.0
    for s in (s1, s2):
        if 0.0 < s < 1.0:
            u = 1.0 - s
            r2 = u * u * (1.0 + 2.0 * s) * ro2 + s * s * (3.0 - 2.0 * s) * rn2 + s * u * u * dt * dro2 \
                - s * s * u * dt * drn2
            r2 = max(r2, 0.0)
            if r2 < best:
                best, s_best = r2, s
    return best, s_best


@jit_inline
def _hermite_speed(dxo, dvo, dxn, dvn, s, dt):
    """Relative speed at s from the cubic Hermite fit of the relative position (one component)."""
    # d/ds of h00 x0 + h10 dt v0 + h01 x1 + h11 dt v1, divided by dt
    h00 = 6.0 * s * s - 6.0 * s
    h10 = 3.0 * s * s - 4.0 * s + 1.0
    h01 = -h00
    h11 = 3.0 * s * s - 2.0 * s
    return (h00 * dxo + h01 * dxn) / dt + h10 * dvo + h11 * dvn


@jit
def scan_pairs(watch, pos, vel, m, n_done, t0, dt):
    """One pass over the pairs: contacts, encounters, and each body's dominant attractor.

    The per-pair tests are written out in this loop, on arrays taken out of ``watch`` once: an
    inlined helper given arrays takes and drops a reference to each on every call (measured:
    ~160 ns a pair, 15x the tests themselves), so helpers are called only for a hit.
    """
    iconf, fconf, radii, prev = watch.iconf, watch.fconf, watch.radii, watch.prev
    best, attractor, hill = watch.best, watch.attractor, watch.hill
    n = pos.shape[1]
    detect, resolve = iconf[C_DETECT], iconf[C_RESOLVE]
    enc, unres = iconf[C_ENC], iconf[C_UNRES]
    G = fconf[F_G]
    central = iconf[C_CENTRAL]
    stop = STOP_NONE
    if unres != 0:
        for i in range(n):
            best[i] = 0.0
            attractor[i] = -1
    hill_scale = 0.0
    if enc == ENC_HILL and m[central] > 0.0:
        hill_scale = fconf[F_ENC] / (3.0 * m[central]) ** (1.0 / 3.0)
        for k in range(n):  # per body once, so each pair's bound below costs no root
            hill[0, k] = _distance(pos, k, central)
            hill[1, k] = hill_scale * (2.0 * m[k]) ** (1.0 / 3.0)
    limit = fconf[F_ENC]
    for i in range(n):
        if stop_requested():  # a stop (orbitsim.stopping): the caller undoes the call, watch included
            return stop
        for j in range(i + 1, n):
            dx = pos[0, i] - pos[0, j]
            dy = pos[1, i] - pos[1, j]
            dz = pos[2, i] - pos[2, j]
            rn2 = dx * dx + dy * dy + dz * dz
            if unres != 0 and rn2 > 0.0:
                pull_i = G * m[j] / rn2
                pull_j = G * m[i] / rn2
                if pull_i > best[i]:
                    best[i] = pull_i
                    attractor[i] = j
                if pull_j > best[j]:
                    best[j] = pull_j
                    attractor[j] = i
            if detect == DETECT_NONE and enc == ENC_NONE:
                continue
            ox = prev[0, 0, i] - prev[0, 0, j]
            oy = prev[0, 1, i] - prev[0, 1, j]
            oz = prev[0, 2, i] - prev[0, 2, j]
            if detect != DETECT_NONE:
                reach = radii[i] + radii[j]
                if reach > 0.0:
                    d2 = rn2 if detect == DETECT_DIRECT else segment_min2(ox, oy, oz, dx, dy, dz)
                    if d2 < reach * reach:
                        stop = max(stop, _contact(watch, vel, i, j, n_done, t0, dt, d2, reach, resolve))
            if enc == ENC_NONE:
                continue
            if enc == ENC_HILL:
                if i == central or j == central or hill_scale == 0.0:
                    continue
                # (m_i + m_j)^(1/3) <= (2 max m)^(1/3), (r_i + r_j) / 2 <= max r: a bound first
                limit = max(hill[1, i], hill[1, j]) * max(hill[0, i], hill[0, j])
            ovx = prev[1, 0, i] - prev[1, 0, j]
            ovy = prev[1, 1, i] - prev[1, 1, j]
            ovz = prev[1, 2, i] - prev[1, 2, j]
            nvx = vel[0, i] - vel[0, j]
            nvy = vel[1, i] - vel[1, j]
            nvz = vel[2, i] - vel[2, j]
            ro2 = ox * ox + oy * oy + oz * oz
            # Within one step a pair closes by at most about dt (|v_start| + |v_end|): farther apart
            # than the limit plus that at both ends, it cannot have come within the limit, so no fit
            # is needed. (a + b)^2 <= 2 a^2 + 2 b^2 keeps the test free of roots.
            travel2 = 2.0 * dt * dt * (ovx * ovx + ovy * ovy + ovz * ovz + nvx * nvx + nvy * nvy + nvz * nvz)
            if min(ro2, rn2) > 2.0 * limit * limit + 2.0 * travel2:
                continue
            d2, s = hermite_min(ro2, rn2, 2.0 * (ox * ovx + oy * ovy + oz * ovz),
                                2.0 * (dx * nvx + dy * nvy + dz * nvz), dt)
            if enc == ENC_HILL:
                limit = hill_scale * (m[i] + m[j]) ** (1.0 / 3.0) * 0.5 * (hill[0, i] + hill[0, j])
            if d2 < limit * limit:
                sx = _hermite_speed(ox, ovx, dx, nvx, s, dt)
                sy = _hermite_speed(oy, ovy, dy, nvy, s, dt)
                sz = _hermite_speed(oz, ovz, dz, nvz, s, dt)
                time = t0 + (n_done - 1 + s) * dt
                speed = math.sqrt(sx * sx + sy * sy + sz * sz)
                stop = max(stop, _encounter(watch, i, j, n_done, time, math.sqrt(d2), speed, limit))
    return stop


@jit_inline
def segment_min2(ox, oy, oz, dx, dy, dz):
    """Smallest squared separation on the straight segment from the start-of-step separation
    (ox, oy, oz) to the end-of-step one (dx, dy, dz)."""
    sx, sy, sz = dx - ox, dy - oy, dz - oz
    seg2 = sx * sx + sy * sy + sz * sz
    s = 0.0
    if seg2 > 0.0:
        s = min(1.0, max(0.0, -(ox * sx + oy * sy + oz * sz) / seg2))
    cx, cy, cz = ox + s * sx, oy + s * sy, oz + s * sz
    return cx * cx + cy * cy + cz * cz


@jit
def _contact(watch, vel, i, j, n_done, t0, dt, d2, reach, resolve):
    """Bodies i and j touch: log it (once per contact) and say whether Python must act."""
    dvx = vel[0, i] - vel[0, j]
    dvy = vel[1, i] - vel[1, j]
    dvz = vel[2, i] - vel[2, j]
    speed = math.sqrt(dvx * dvx + dvy * dvy + dvz * dvz)
    time = t0 + n_done * dt
    if resolve == RESOLVE_LOG:
        p = find_pair(watch, i, j, PAIR_CONTACT)
        if p >= 0:
            watch.pair_i[p, P_LAST] = n_done
            return STOP_NONE
        open_pair(watch, i, j, PAIR_CONTACT, n_done)
    log_event(watch, EV_COLLISION, n_done, n_done, i, j, time, math.sqrt(d2), speed, reach)
    if resolve == RESOLVE_HALT:
        return STOP_HALT
    if resolve == RESOLVE_MERGE:
        return STOP_RESOLVE
    return STOP_NONE


@jit
def _encounter(watch, i, j, n_done, time, d, speed, limit):
    """Pair (i, j) came within ``limit`` during step ``n_done`` (closest ``d`` at ``time``): open or
    extend its episode. Returns STOP_HALT when an encounter starts and ``halt`` was asked for."""
    p = find_pair(watch, i, j, PAIR_ENCOUNTER)
    if p < 0:
        p = open_pair(watch, i, j, PAIR_ENCOUNTER, n_done)
        if p < 0:
            return STOP_NONE
    pair_i, pair_f = watch.pair_i, watch.pair_f
    pair_i[p, P_LAST] = n_done
    if d < pair_f[p, PF_DMIN]:
        pair_f[p, PF_DMIN] = d
        pair_f[p, PF_TMIN] = time
        pair_f[p, PF_VMIN] = speed
        pair_f[p, PF_LIMIT] = limit
    if watch.iconf[C_ENC_HALT] != 0 and pair_i[p, P_START] == n_done:
        log_event(watch, EV_ENCOUNTER, n_done, n_done, i, j, time, d, speed, limit)
        return STOP_HALT
    return STOP_NONE


@jit_inline
def _distance(pos, i, k):
    dx = pos[0, i] - pos[0, k]
    dy = pos[1, i] - pos[1, k]
    dz = pos[2, i] - pos[2, k]
    return math.sqrt(dx * dx + dy * dy + dz * dz)


@jit
def close_episodes(watch, n_done):
    """Episodes not seen this step have ended: an encounter is logged with its closest approach;
    a contact (``resolve: log``) is simply forgotten. An encounter that halted the run is not
    logged twice."""
    iconf, pair_i, pair_f, counts = watch.iconf, watch.pair_i, watch.pair_f, watch.counts
    p = 0
    while p < counts[N_PAIRS]:
        if pair_i[p, P_LAST] >= n_done:
            p += 1
            continue
        if pair_i[p, P_KIND] == PAIR_ENCOUNTER and iconf[C_ENC_HALT] == 0:
            log_event(watch, EV_ENCOUNTER, pair_i[p, P_LAST], pair_i[p, P_START], pair_i[p, P_I], pair_i[p, P_J],
                 pair_f[p, PF_TMIN], pair_f[p, PF_DMIN], pair_f[p, PF_VMIN], pair_f[p, PF_LIMIT])
        last = counts[N_PAIRS] - 1
        for c in range(PAIR_I_COLS):
            pair_i[p, c] = pair_i[last, c]
        for c in range(PAIR_F_COLS):
            pair_f[p, c] = pair_f[last, c]
        counts[N_PAIRS] = last


