"""Checks of single bodies after a step: a step too long for the body's orbit (unresolved), and
escapes. See :mod:`orbitsim.events.kernels` for what each check means.
"""

from __future__ import annotations

import math

import numpy as np

from orbitsim._jit import jit, jit_inline
from orbitsim.events.layout import (
    B_ESCAPED,
    B_UNRESOLVED,
    C_ESCAPE,
    ESC_HALT,
    ESC_REMOVE,
    EV_ESCAPE,
    EV_UNRESOLVED,
    F_ESC_R,
    F_ETA,
    F_G,
    STOP_HALT,
    STOP_NONE,
    STOP_RESOLVE,
    log_event,
)


@jit_inline
def two_body_tau2(x, y, z, vx, vy, vz, gm):
    """tau^2 = 2 |a|^2 / (|a'|^2 + |a| |a''|) of the relative two-body motion about ``gm``
    (Pham, Rein & Spiegel 2024, eq. 16; the derivatives of a = -gm r / r^3 in closed form)."""
    d2 = x * x + y * y + z * z
    d = math.sqrt(d2)
    pre2 = -gm / (d2 * d)
    ax, ay, az = pre2 * x, pre2 * y, pre2 * z
    a = math.sqrt(ax * ax + ay * ay + az * az)
    pre3 = gm / (d2 * d2 * d)
    jx = pre3 * (-vx * (y * y + z * z) + 2.0 * x * x * vx + 3.0 * x * (y * vy + z * vz))
    jy = pre3 * (-vy * (x * x + z * z) + 2.0 * y * y * vy + 3.0 * y * (x * vx + z * vz))
    jz = pre3 * (-vz * (x * x + y * y) + 2.0 * z * z * vz + 3.0 * z * (y * vy + x * vx))
    j2 = jx * jx + jy * jy + jz * jz
    pre4 = gm / (d2 * d2 * d2 * d)
    rv = x * vx + y * vy + z * vz
    sx = pre4 * (d2 * (-ax * (y * y + z * z) + 2.0 * x * x * ax + vx * (y * vy + z * vz)
                       + x * (4.0 * vx * vx + 3.0 * (y * ay + vy * vy + z * az + vz * vz)))
                 - 5.0 * rv * (-vx * (y * y + z * z) + 2.0 * x * x * vx + 3.0 * x * (y * vy + z * vz)))
    sy = pre4 * (d2 * (-ay * (x * x + z * z) + 2.0 * y * y * ay + vy * (x * vx + z * vz)
                       + y * (4.0 * vy * vy + 3.0 * (x * ax + vx * vx + z * az + vz * vz)))
                 - 5.0 * rv * (-vy * (x * x + z * z) + 2.0 * y * y * vy + 3.0 * y * (x * vx + z * vz)))
    sz = pre4 * (d2 * (-az * (y * y + x * x) + 2.0 * z * z * az + vz * (y * vy + x * vx)
                       + z * (4.0 * vz * vz + 3.0 * (y * ay + vy * vy + x * ax + vx * vx)))
                 - 5.0 * rv * (-vz * (y * y + x * x) + 2.0 * z * z * vz + 3.0 * z * (y * vy + x * vx)))
    s = math.sqrt(sx * sx + sy * sy + sz * sz)
    den = j2 + a * s
    return 2.0 * a * a / den if den > 0.0 else np.inf


@jit_inline
def _pericentre_tau2(x, y, z, vx, vy, vz, gm):
    """tau^2 at the pericentre of the osculating two-body orbit of (r, v) about ``gm``."""
    hx = y * vz - z * vy
    hy = z * vx - x * vz
    hz = x * vy - y * vx
    h2 = hx * hx + hy * hy + hz * hz
    r = math.sqrt(x * x + y * y + z * z)
    v2 = vx * vx + vy * vy + vz * vz
    energy = 0.5 * v2 - gm / r
    e = math.sqrt(max(0.0, 1.0 + 2.0 * energy * h2 / (gm * gm)))
    if h2 == 0.0:
        return np.inf  # radial: there is no pericentre short of a collision
    rp = h2 / (gm * (1.0 + e))
    return two_body_tau2(rp, 0.0, 0.0, 0.0, math.sqrt(h2) / rp, 0.0, gm)


#: Bits of a handoff's flags (:func:`check_unresolved`): the integrator took the whole step with its
#: own adaptive sub-steps (TRACE's full_bs and full_ias15 pericentre steps); a massless body's orbit
#: about body 0 is a Kepler drift, exact at any dt, with no term of its own in the step's other
#: operators (TRACE's democratic heliocentric map, which never switches such a body either).
HAND_WHOLE_STEP, HAND_MASSLESS_KEPLER = 1, 2


@jit_inline
def handed_over(handoff, i, k, m):
    """Whether the motion of body ``i`` about ``k`` was not stepped with the fixed dt this step.

    ``handoff = (pairs, bodies, flags)``, what a hybrid integrator integrated with its own
    adaptive sub-steps: ``pairs`` (N, N) uint8, nonzero at [a, b] (a < b) for a pair whose mutual
    force went to them; ``bodies`` (N,), nonzero for a body whose orbit about body 0 did; ``flags``,
    :data:`HAND_WHOLE_STEP` | :data:`HAND_MASSLESS_KEPLER`.
    """
    pairs, bodies, flags = handoff
    if flags & HAND_WHOLE_STEP:
        return True
    if i == 0 or k == 0:
        other = k if i == 0 else i
        return bodies[other] != 0 or (flags & HAND_MASSLESS_KEPLER != 0 and m[other] == 0.0)
    return pairs[min(i, k), max(i, k)] != 0


@jit
def check_unresolved(watch, pos, vel, m, n_done, t0, dt, handoff):
    """Flag bodies whose step is longer than eta tau about their dominant attractor.

    ``handoff`` is None for a scheme that takes every step with the fixed dt. A hybrid scheme
    passes what it integrated with adaptive sub-steps this step (:func:`handed_over`; TRACE's
    close encounters and pericentre passages, :mod:`orbitsim.integrators.trace`): only what it
    stepped with the fixed dt is judged, so the encounters it hands to Bulirsch-Stoer are not
    reported as steps too long for them.
    """
    fconf, prev, body, attractor = watch.fconf, watch.prev, watch.body, watch.attractor
    G, eta = fconf[F_G], fconf[F_ETA]
    n = pos.shape[1]
    for i in range(n):
        k = attractor[i]
        if k < 0:
            body[i] &= ~B_UNRESOLVED
            continue
        if attractor[k] == i and (m[i] > m[k] or (m[i] == m[k] and i > k)):
            continue  # the pair is judged once, under its lighter body
        if handoff is not None:
            if handed_over(handoff, i, k, m):
                body[i] &= ~B_UNRESOLVED  # resolved by the integrator's own sub-steps
                continue
        x, y, z = pos[0, i] - pos[0, k], pos[1, i] - pos[1, k], pos[2, i] - pos[2, k]
        vx, vy, vz = vel[0, i] - vel[0, k], vel[1, i] - vel[1, k], vel[2, i] - vel[2, k]
        gm = G * (m[i] + m[k])
        r2 = x * x + y * y + z * z
        v2 = vx * vx + vy * vy + vz * vz
        # A lower bound on tau^2 from |a'| <= 4 gm v / r^3 and |a''| <= gm (4 gm / r^5 + 24 v^2 / r^4)
        # (triangle inequalities on the closed forms): when even it allows dt, the exact value is
        # not needed, which is nearly every step of a run whose steps are resolved.
        bound = 2.0 / (40.0 * v2 / r2 + 4.0 * gm / (r2 * math.sqrt(r2)))
        tau2 = bound if dt * dt <= eta * eta * bound else two_body_tau2(x, y, z, vx, vy, vz, gm)
        ox = prev[0, 0, i] - prev[0, 0, k]
        oy = prev[0, 1, i] - prev[0, 1, k]
        oz = prev[0, 2, i] - prev[0, 2, k]
        orv = ox * (prev[1, 0, i] - prev[1, 0, k]) + oy * (prev[1, 1, i] - prev[1, 1, k]) \
            + oz * (prev[1, 2, i] - prev[1, 2, k])
        if orv < 0.0 and x * vx + y * vy + z * vz > 0.0:  # passed its closest point within the step
            tau2 = min(tau2, _pericentre_tau2(x, y, z, vx, vy, vz, gm))
        if dt * dt > eta * eta * tau2:
            if body[i] & B_UNRESOLVED == 0:
                body[i] |= B_UNRESOLVED
                # The dt to suggest is the one that resolves the tightest point of this orbit, its
                # pericentre, not only the state after the step that was too long.
                tau = math.sqrt(min(tau2, _pericentre_tau2(x, y, z, vx, vy, vz, gm)))
                log_event(watch, EV_UNRESOLVED, n_done, n_done, i, k, t0 + n_done * dt,
                          math.sqrt(x * x + y * y + z * z), math.sqrt(vx * vx + vy * vy + vz * vz), eta * tau)
        else:
            body[i] &= ~B_UNRESOLVED


@jit_inline
def _bound_partner(pos, vel, m, i, G):
    """The body ``i`` is most tightly bound to (the lowest negative two-body energy per unit of
    reduced mass), or -1 when it is bound to none. Removed bodies (NaN) never compare lower."""
    partner, lowest = -1, 0.0
    for k in range(pos.shape[1]):
        if k == i or m[i] + m[k] <= 0.0:
            continue
        dx, dy, dz = pos[0, i] - pos[0, k], pos[1, i] - pos[1, k], pos[2, i] - pos[2, k]
        ux, uy, uz = vel[0, i] - vel[0, k], vel[1, i] - vel[1, k], vel[2, i] - vel[2, k]
        energy = 0.5 * (ux * ux + uy * uy + uz * uz) - G * (m[i] + m[k]) / math.sqrt(dx * dx + dy * dy + dz * dz)
        if energy < lowest:
            partner, lowest = k, energy
    return partner


@jit
def check_escapes(watch, pos, vel, m, n_done, t0, dt):
    """Bodies beyond R from the centre of mass on unbound orbits relative to the rest.

    A body bound to another (a binary member, a moon) is judged with its partner: the pair's
    centre of mass against the rest. Judged alone, its orbital speed in the pair would swing its
    energy above and below zero once an orbit, and a departing binary logged an escape per orbit.
    Once escaped, a body is escaped until it is bound again (not when it is back within R)."""
    iconf, fconf, body = watch.iconf, watch.fconf, watch.body
    G, limit = fconf[F_G], fconf[F_ESC_R]
    n = pos.shape[1]
    total = cx = cy = cz = ux0 = uy0 = uz0 = 0.0
    for i in range(n):
        total += m[i]
        cx += m[i] * pos[0, i]
        cy += m[i] * pos[1, i]
        cz += m[i] * pos[2, i]
        ux0 += m[i] * vel[0, i]
        uy0 += m[i] * vel[1, i]
        uz0 += m[i] * vel[2, i]
    if total <= 0.0:
        return STOP_NONE
    cx, cy, cz, ux0, uy0, uz0 = cx / total, cy / total, cz / total, ux0 / total, uy0 / total, uz0 / total
    stop = STOP_NONE
    for i in range(n):
        dx, dy, dz = pos[0, i] - cx, pos[1, i] - cy, pos[2, i] - cz
        d = math.sqrt(dx * dx + dy * dy + dz * dz)
        escaping = False
        speed = 0.0
        energy = 0.0
        # An escaped body stays escaped, inside R or not, until it is bound again: a binary member's
        # distance swings across R once an orbit while the pair leaves.
        if d > limit or body[i] & B_ESCAPED:
            # The unit that leaves: the body, or the body and the partner it is bound to.
            k = _bound_partner(pos, vel, m, i, G)
            mu = m[i] if k < 0 else m[i] + m[k]
            wi, wk = (1.0, 0.0) if k < 0 or mu <= 0.0 else (m[i] / mu, m[k] / mu)
            kk = i if k < 0 else k
            ex = wi * pos[0, i] + wk * pos[0, kk] - cx
            ey = wi * pos[1, i] + wk * pos[1, kk] - cy
            ez = wi * pos[2, i] + wk * pos[2, kk] - cz
            vx = wi * vel[0, i] + wk * vel[0, kk]
            vy = wi * vel[1, i] + wk * vel[1, kk]
            vz = wi * vel[2, i] + wk * vel[2, kk]
            rest = total - mu
            if rest > 0.0:
                # Relative to the rest's centre of mass: X_rest = (M X - mu x_unit) / (M - mu)
                f = total / rest
                rx, ry, rz = f * ex, f * ey, f * ez
                ux = f * (vx - ux0)
                uy = f * (vy - uy0)
                uz = f * (vz - uz0)
                speed = math.sqrt(ux * ux + uy * uy + uz * uz)
                energy = 0.5 * speed * speed - G * total / math.sqrt(rx * rx + ry * ry + rz * rz)
                escaping = energy > 0.0
        if not escaping:
            body[i] &= ~B_ESCAPED
            continue
        if body[i] & B_ESCAPED:
            continue
        body[i] |= B_ESCAPED
        log_event(watch, EV_ESCAPE, n_done, n_done, i, -1, t0 + n_done * dt, d, speed, energy)
        if iconf[C_ESCAPE] == ESC_HALT:
            stop = STOP_HALT
        elif iconf[C_ESCAPE] == ESC_REMOVE:
            stop = max(stop, STOP_RESOLVE)
    return stop
