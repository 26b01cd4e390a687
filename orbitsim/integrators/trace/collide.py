"""Collisions inside TRACE's Bulirsch-Stoer sub-steps: the search, the merge, the record.

Two bodies in an encounter can touch in the middle of an outer step, where the end-of-step events
scan (:mod:`orbitsim.events.pairs`) never looks, and two point masses that pass through each
other make the BS sub-steps shrink to nothing. So, as REBOUND's TRACE does, the bodies that BS
integrates are searched after every *accepted* sub-step (REBOUND ``reb_collision_search`` with
the encounter map, integrator_trace.c:818-822):

* ``direct``: the pair overlaps, ``|dx| <= r_i + r_j``, and approaches, ``dv . dx <= 0``;
* ``line``: the straight segment drawn back from the end of the sub-step with the end relative
  velocity comes within ``r_i + r_j`` (REBOUND draws it back over the last *outer* step; the
  sub-step is what was just integrated, so it is used here).

What a contact does depends on ``collisions.resolve``:

* ``merge``: the higher index joins the lower (REBOUND ``reb_collision_resolve_merge``, in its
  order of operations: ``v = (v_i m_i + v_j m_j) / M`` as a product with ``1 / M``, likewise x,
  ``M = m_i + m_j`` in one addition, ``R = cbrt(R_i^3 + R_j^3)``). The body that joined becomes a
  *husk*: mass 0 and radius 0, left out of the BS set for the rest of the step, so every sum it
  still enters adds exact zeros and the bits match REBOUND, which removes it. The run loop takes
  the husk out after the step (:mod:`orbitsim.events.driver`). The energy the merge takes out of
  the system, ``E_before - E_after`` (the pair's kinetic and potential terms and the change of
  every third body's potential, which REBOUND leaves out), is recorded with the contact.
* ``halt`` and ``log``: the contact is recorded once per pair and step; nothing merges.

Any contact makes the step final (``ST_FORCE_ACCEPT``): a merge cannot be redone.

Contacts go to ``hits`` (rows of :data:`HIT_COLUMNS`), which the run loop drains after the step.
"""

from __future__ import annotations

import math

import numpy as np

from orbitsim._jit import jit
from orbitsim.events.layout import DETECT_DIRECT, DETECT_NONE, RESOLVE_MERGE

__all__ = ["COLLIDE_LENGTH", "DETECT_NONE", "HIT_COLUMNS", "collide_set", "merge_pair"]

#: Columns of a ``hits`` row: the pair (kept, joined), the time of the sub-step's end, separation
#: and relative speed there, r_i + r_j, the energy taken out (0 unless merged), merged (1/0).
HIT_COLUMNS = ("keep", "lose", "time", "distance", "speed", "reach", "energy_out", "merged")
H_KEEP, H_LOSE, H_TIME, H_DIST, H_SPEED, H_REACH, H_ENERGY, H_MERGED = range(8)
#: ``collide`` int64 slots: detection, resolution, hits recorded, hits that found the table full.
K_DETECT, K_RESOLVE, K_HITS, K_LOST = range(4)
COLLIDE_LENGTH = 4


@jit
def _touching(pos, vel, a, b, reach, detect, h):
    """Squared separation if bodies a and b touch (``detect`` rule), else -1."""
    dx = pos[0, a] - pos[0, b]
    dy = pos[1, a] - pos[1, b]
    dz = pos[2, a] - pos[2, b]
    dvx = vel[0, a] - vel[0, b]
    dvy = vel[1, a] - vel[1, b]
    dvz = vel[2, a] - vel[2, b]
    r2 = dx * dx + dy * dy + dz * dz
    if detect == DETECT_DIRECT:
        if r2 > reach * reach or dvx * dx + dvy * dy + dvz * dz > 0.0:
            return -1.0
        return r2
    # line: the segment from the sub-step's start (drawn back with the end velocity) to its end
    v2 = dvx * dvx + dvy * dvy + dvz * dvz
    bx = dx - h * dvx
    by = dy - h * dvy
    bz = dz - h * dvz
    closest = min(r2, bx * bx + by * by + bz * bz)
    if v2 > 0.0:
        t_closest = (dx * dvx + dy * dvy + dz * dvz) / v2
        if 0.0 <= t_closest / h <= 1.0:
            cx = dx - t_closest * dvx
            cy = dy - t_closest * dvy
            cz = dz - t_closest * dvz
            closest = min(closest, cx * cx + cy * cy + cz * cz)
    return closest if closest <= reach * reach else -1.0


@jit
def _third_body_change(pos, m, G, keep, lose, mass, x, y, z):
    """Sum over the other massive bodies k of G m_k (M/|x_k - X| - m_i/|x_k - x_i| - m_j/|x_k - x_j|):
    how much the merge lowers their potential energy with the pair (second order in the pair's
    separation, since X is the pair's centre of mass)."""
    change = 0.0
    for k in range(pos.shape[1]):
        if k == keep or k == lose or m[k] == 0.0:
            continue
        dkx, dky, dkz = pos[0, k] - x, pos[1, k] - y, pos[2, k] - z
        after = mass / math.sqrt(dkx * dkx + dky * dky + dkz * dkz)
        before = 0.0
        for b in (keep, lose):
            if m[b] != 0.0:
                ex, ey, ez = pos[0, k] - pos[0, b], pos[1, k] - pos[1, b], pos[2, k] - pos[2, b]
                before += m[b] / math.sqrt(ex * ex + ey * ey + ez * ez)
        change += G * m[k] * (after - before)
    return change


@jit
def merge_pair(pos, vel, m, radii, G, keep, lose):
    """Body ``lose`` joins ``keep`` in place (REBOUND's merge, module doc); ``lose`` becomes a
    husk (mass and radius 0, its state left as it was). Returns the energy taken out."""
    mi, mj = m[keep], m[lose]
    mass = mi + mj
    energy_before = 0.5 * mi * _norm2(vel, keep) + 0.5 * mj * _norm2(vel, lose)
    if mi != 0.0 and mj != 0.0:
        dx, dy, dz = pos[0, keep] - pos[0, lose], pos[1, keep] - pos[1, lose], pos[2, keep] - pos[2, lose]
        energy_before -= G * mi * mj / math.sqrt(dx * dx + dy * dy + dz * dz)
    third = 0.0
    if mass > 0.0:
        inv_mass = 1.0 / mass
        x = (pos[0, keep] * mi + pos[0, lose] * mj) * inv_mass
        y = (pos[1, keep] * mi + pos[1, lose] * mj) * inv_mass
        z = (pos[2, keep] * mi + pos[2, lose] * mj) * inv_mass
        third = _third_body_change(pos, m, G, keep, lose, mass, x, y, z)
        for c in range(3):
            vel[c, keep] = (vel[c, keep] * mi + vel[c, lose] * mj) * inv_mass
        pos[0, keep], pos[1, keep], pos[2, keep] = x, y, z
    else:  # two test particles: the midpoint and the mean velocity
        for c in range(3):
            vel[c, keep] = 0.5 * (vel[c, keep] + vel[c, lose])
            pos[c, keep] = 0.5 * (pos[c, keep] + pos[c, lose])
    m[keep] = mass
    m[lose] = 0.0
    ri, rj = radii[keep], radii[lose]
    radii[keep] = np.cbrt(ri * ri * ri + rj * rj * rj)
    radii[lose] = 0.0
    return energy_before - 0.5 * mass * _norm2(vel, keep) + third


@jit
def _norm2(vel, i):
    return vel[0, i] * vel[0, i] + vel[1, i] * vel[1, i] + vel[2, i] * vel[2, i]


@jit
def _record(hits, collide, keep, lose, time, r2, pos, vel, reach, merged):
    """Append a contact to ``hits`` and return its row; a full table counts it as lost (-1;
    reported, never silent). The table has a row per body, so merges always fit."""
    k = collide[K_HITS]
    if k >= hits.shape[0]:
        collide[K_LOST] += 1
        return -1
    dvx = vel[0, keep] - vel[0, lose]
    dvy = vel[1, keep] - vel[1, lose]
    dvz = vel[2, keep] - vel[2, lose]
    row = hits[k]
    row[H_KEEP], row[H_LOSE], row[H_TIME] = keep, lose, time
    row[H_DIST], row[H_SPEED], row[H_REACH] = math.sqrt(r2), math.sqrt(dvx * dvx + dvy * dvy + dvz * dvz), reach
    row[H_ENERGY], row[H_MERGED] = 0.0, 1.0 if merged else 0.0
    collide[K_HITS] = k + 1
    return k


@jit
def _seen(hits, collide, keep, lose):
    for k in range(min(collide[K_HITS], hits.shape[0])):
        if hits[k, H_KEEP] == keep and hits[k, H_LOSE] == lose:
            return True
    return False


@jit
def collide_set(pos, vel, m, radii, G, bodies, n_set, n_set_active, h, time, hits, collide):
    """Search the ``n_set`` bodies ``bodies[:n_set]`` (increasing indices) for contacts after a
    sub-step of ``h`` ending at ``time`` and resolve them (module doc).

    Merged bodies leave the list, which is compacted in place. Returns ``(n_set, n_set_active,
    contacts)``: the new sizes, and how many contacts were found.
    """
    detect, resolve = collide[K_DETECT], collide[K_RESOLVE]
    contacts = 0
    a = 0
    while a < n_set:
        b = a + 1
        while b < n_set:
            keep, lose = bodies[a], bodies[b]
            reach = radii[keep] + radii[lose]
            r2 = _touching(pos, vel, keep, lose, reach, detect, h) if reach > 0.0 else -1.0
            if r2 < 0.0:
                b += 1
                continue
            contacts += 1
            if resolve != RESOLVE_MERGE:
                if not _seen(hits, collide, keep, lose):
                    _record(hits, collide, keep, lose, time, r2, pos, vel, reach, np.bool_(False))
                b += 1
                continue
            row = _record(hits, collide, keep, lose, time, r2, pos, vel, reach, np.bool_(True))
            energy_out = merge_pair(pos, vel, m, radii, G, keep, lose)
            if row >= 0:
                hits[row, H_ENERGY] = energy_out
            for q in range(b, n_set - 1):  # the husk leaves the set; order kept
                bodies[q] = bodies[q + 1]
            if b < n_set_active:
                n_set_active -= 1
            n_set -= 1
        a += 1
    return n_set, n_set_active, contacts
