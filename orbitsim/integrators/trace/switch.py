"""TRACE's switching functions and the encounter bookkeeping before and after a step.

Two criteria decide which parts of a step leave the Wisdom-Holman map (Lu, Hernandez & Rein
2024, section 2), both evaluated on democratic heliocentric data (heliocentric x, barycentric v):

* **Pair criterion** (:func:`pair_flagged`, REBOUND ``reb_integrator_trace_switch_default``): bodies
  i and j are in an encounter if they come closer than ``r_crit_hill`` times the larger of their
  modified Hill radii ``|x_i| (m_i / 3 m0)^(1/3)`` within half a step, assuming straight-line
  relative motion: forward when approaching, backward when receding. The pre-step check so looks
  ahead over the first half of the step and the post-step check back over the second half, which
  keeps the switch time-symmetric. All comparisons are made on sixth powers (no cube roots).
* **Pericentre criterion** (:func:`pericentre_flagged`, ``..._switch_peri_default``): body j is
  near pericentre when ``dt^2 > eta^2 tau^2``, with Pham, Rein & Spiegel's (2024, eq. 16)
  timescale ``tau^2 = 2 |a|^2 / (|j|^2 + |a| |s|)`` from the heliocentric Kepler acceleration a, jerk
  j and snap s. Test particles (index >= n_active) never trigger it.

The bookkeeping (:func:`pre_step_check`, :func:`post_step_check`) fills ``interacts`` (upper
triangle, REBOUND's ``current_Ks``), the encounter set ``enc[0]`` (1 for each body in it; the star
always; ``enc[1]`` keeps the pre-step set for the post-step check) and the ``state`` flags
(``ST_*``, the first slots of the int64 bookkeeping array). The post-step check only adds flags
to the pre-step ones and reports whether any is new; the caller then redoes the step with the
union. The order of the loops, the early return of the FULL_* modes and the count kept in
``ST_ENC_N`` all follow REBOUND, since they decide which steps are redone.
"""

from __future__ import annotations

import math

from orbitsim._jit import jit_inline, jit_llvm_inline

#: ``peri_mode`` ids (REBOUND's ``REB_INTEGRATOR_TRACE_PERIMODE_*``).
PARTIAL_BS = 0
FULL_BS = 1
FULL_IAS15 = 2

#: Slots of the int64 ``state`` array: pericentre flag (REBOUND ``current_C``), only test particles
#: in encounters (``tponly_encounter``), size of the encounter set and its active part (star
#: included), a collision happened (``force_accept``), failure status.
ST_CURRENT_C, ST_TPONLY, ST_ENC_N, ST_ENC_N_ACTIVE, ST_FORCE_ACCEPT, ST_STATUS = range(6)
STATE_LENGTH = 6


@jit_inline
def hill_radius6(x, y, z, m_i, m0):
    """Sixth power of the modified Hill radius ``|x| (m_i / 3 m0)^(1/3)`` (0 for a test particle).

    Per body, not per pair: :func:`_flag_pairs` keeps these in a scratch row, which leaves the
    bits as they were (the same operations on the same values) and saves two divisions per pair.
    """
    if m_i == 0.0:
        return 0.0
    d2 = x * x + y * y + z * z
    mr = m_i / (3.0 * m0)
    return d2 * d2 * d2 * mr * mr


@jit_inline
def pair_flagged(xi, yi, zi, xj, yj, zj, dvx, dvy, dvz, dcrit_max6, h2):
    """Whether bodies i and j (heliocentric x, relative velocity dv = v_i - v_j) come within
    ``dcrit_max6^(1/6)`` (r_crit_hill times the larger :func:`hill_radius6`) within h2 (= dt/2)
    of now.

    Scalar arguments only: a jitted function that takes arrays pays a reference-count round trip
    per array and call, which doubled the cost of this check (measured).
    """
    dx = xi - xj
    dy = yi - yj
    dz = zi - zj
    rp = dx * dx + dy * dy + dz * dz
    if rp * rp * rp < dcrit_max6:
        return True
    v2 = dvx * dvx + dvy * dvy + dvz * dvz
    qv = dx * dvx + dy * dvy + dz * dvz
    if qv == 0.0:
        return False  # closest approach is now, checked above
    d = 1 if qv < 0.0 else -1  # +1 approaching (look forward), -1 receding (look back)
    tmin = -d * qv / v2
    if tmin < h2:
        dmin2 = rp - qv * qv / v2  # the closest approach lies within the window
    else:
        dmin2 = rp + 2 * d * qv * h2 + v2 * h2 * h2  # straight line at the window's edge
    return dmin2 * dmin2 * dmin2 < dcrit_max6


@jit_inline
def pericentre_flagged(x, y, z, dx, dy, dz, G_m0, dt, peri_crit_eta):
    """Whether a body at heliocentric (x, y, z) with velocity (dx, dy, dz) has a pericentre
    timescale (Pham, Rein & Spiegel 2024, eq. 16) below dt / eta.

    Each component is written as REBOUND writes it (its terms permuted per axis); reordering
    them changes the rounding. :func:`orbitsim.events.bodies.two_body_tau2` evaluates the same
    timescale in its own order; this one stays REBOUND's so that the switch flips on the same steps.
    """
    d2 = x * x + y * y + z * z
    d = math.sqrt(d2)
    prefact2 = -G_m0 / (d2 * d)
    ddx = prefact2 * x
    ddy = prefact2 * y
    ddz = prefact2 * z
    dd = math.sqrt(ddx * ddx + ddy * ddy + ddz * ddz)
    prefact3 = G_m0 / (d2 * d2 * d)
    dddx = prefact3 * (-dx * (y * y + z * z) + 2. * x * x * dx + 3. * x * (y * dy + z * dz))
    dddy = prefact3 * (-dy * (x * x + z * z) + 2. * y * y * dy + 3. * y * (x * dx + z * dz))
    dddz = prefact3 * (-dz * (x * x + y * y) + 2. * z * z * dz + 3. * z * (x * dx + y * dy))
    ddd2 = dddx * dddx + dddy * dddy + dddz * dddz
    prefact4 = G_m0 / (d2 * d2 * d2 * d)
    ddddx = prefact4 * (d2 * (-ddx * (y * y + z * z) + 2. * x * x * ddx + dx * (y * dy + z * dz)
                              + x * (4. * dx * dx + 3. * (y * ddy + dy * dy + z * ddz + dz * dz)))
                        - 5. * (x * dx + y * dy + z * dz) * (-dx * (y * y + z * z) + 2. * x * x * dx
                                                             + 3. * x * (y * dy + z * dz)))
    ddddy = prefact4 * (d2 * (-ddy * (x * x + z * z) + 2. * y * y * ddy + dy * (x * dx + z * dz)
                              + y * (4. * dy * dy + 3. * (x * ddx + dx * dx + z * ddz + dz * dz)))
                        - 5. * (y * dy + x * dx + z * dz) * (-dy * (x * x + z * z) + 2. * y * y * dy
                                                             + 3. * y * (x * dx + z * dz)))
    ddddz = prefact4 * (d2 * (-ddz * (y * y + x * x) + 2. * z * z * ddz + dz * (y * dy + x * dx)
                              + z * (4. * dz * dz + 3. * (y * ddy + dy * dy + x * ddx + dx * dx)))
                        - 5. * (z * dz + y * dy + x * dx) * (-dz * (y * y + x * x) + 2. * z * z * dz
                                                             + 3. * z * (y * dy + x * dx)))
    dddd = math.sqrt(ddddx * ddddx + ddddy * ddddy + ddddz * ddddz)
    tau_prs2 = 2. * dd * dd / (ddd2 + dd * dddd)
    return dt * dt > peri_crit_eta * peri_crit_eta * tau_prs2


@jit_inline
def _first_pericentre(pos, vel, m, G, dt, n_active, peri_crit_eta):
    """Whether any active body 1..n_active-1 is near pericentre (stops at the first)."""
    G_m0 = G * m[0]
    for j in range(1, n_active):
        if pericentre_flagged(pos[0, j], pos[1, j], pos[2, j], vel[0, j], vel[1, j], vel[2, j], G_m0, dt,
                              peri_crit_eta):
            return True
    return False


@jit_inline
def _flag_pairs(pos, vel, m, dt, n_active, r_crit_hill, interacts, enc, state, hill6, star_radius):
    """Flag every pair (i < n_active, j > i) in an encounter; add both to the set; True if any
    flag was not already set. ``hill6`` (N,): scratch for the bodies' :func:`hill_radius6`.
    ``star_radius``: the star's physical radius when collisions are searched (else 0)."""
    n = pos.shape[1]
    h2 = dt / 2.0
    m0 = m[0]
    for i in range(n):
        hill6[i] = hill_radius6(pos[0, i], pos[1, i], pos[2, i], m[i], m0)
    if star_radius != 0.0:
        # The star sits at the origin (its "Hill radius" is 0); REBOUND uses its physical radius,
        # so a body about to hit the star joins the BS set, where the contact is searched.
        hill6[0] = star_radius * star_radius * star_radius * star_radius * star_radius * star_radius
    rc2 = r_crit_hill * r_crit_hill
    rc6 = rc2 * rc2 * rc2  # REBOUND's rc2 * rc2 * rc2 * max: the same left-to-right products
    new = False
    for i in range(n_active):
        for j in range(i + 1, n):
            dcrit_max6 = rc6 * (hill6[i] if hill6[i] > hill6[j] else hill6[j])
            if pair_flagged(pos[0, i], pos[1, i], pos[2, i], pos[0, j], pos[1, j], pos[2, j],
                            vel[0, i] - vel[0, j], vel[1, i] - vel[1, j], vel[2, i] - vel[2, j], dcrit_max6, h2):
                if not interacts[i, j]:
                    new = True
                interacts[i, j] = 1
                if not enc[0, i]:
                    enc[0, i] = 1
                    state[ST_ENC_N] += 1
                if not enc[0, j]:
                    enc[0, j] = 1
                    state[ST_ENC_N] += 1
                if j < n_active:
                    state[ST_TPONLY] = 0  # a massive pair: no Kepler-state restore
    return new


@jit_llvm_inline
def pre_step_check(pos, vel, m, G, dt, n_active, r_crit_hill, peri_crit_eta, peri_mode, interacts, enc,
                   state, hill6, star_radius):
    """Set the encounter flags at the start of a step (REBOUND ``pre_ts_check``); ``hill6`` (N,)
    is scratch."""
    n = pos.shape[1]
    # A pair flag is only ever set together with its bodies' encounter flags, which raises
    # ST_ENC_N above 1 for the rest of that step: after a step that ended with ST_ENC_N == 1 the
    # flags are all clear already, and the O(N^2) clear is skipped.
    if state[ST_ENC_N] != 1:
        for i in range(n):
            for j in range(i + 1, n):
                interacts[i, j] = 0
    for i in range(1, n):
        enc[0, i] = 0
    enc[0, 0] = 1
    state[ST_ENC_N] = 1
    state[ST_CURRENT_C] = 0
    state[ST_TPONLY] = 1
    if _first_pericentre(pos, vel, m, G, dt, n_active, peri_crit_eta):
        state[ST_CURRENT_C] = 1
        if peri_mode != PARTIAL_BS:
            # The whole step goes to FULL_BS: no pair flags, and the map backup is left stale
            # (harmless: the post-step check then puts every body in the set).
            return
        state[ST_TPONLY] = 0
        state[ST_ENC_N] = n
        for i in range(1, n):
            enc[0, i] = 1
    _flag_pairs(pos, vel, m, dt, n_active, r_crit_hill, interacts, enc, state, hill6, star_radius)
    for i in range(n):
        enc[1, i] = enc[0, i]


@jit_llvm_inline
def post_step_check(pos, vel, m, G, dt, n_active, r_crit_hill, peri_crit_eta, peri_mode, interacts, enc,
                    state, hill6, star_radius):
    """Add the flags of the end-of-step state; True if any is new, i.e. the step must be redone.

    ``ST_ENC_N`` keeps the pre-step count (REBOUND does not reset it), and bodies are added to it.
    In the FULL_* modes a pericentre step left ``interacts`` clear, so any pair flagged now is new.
    """
    n = pos.shape[1]
    new = False
    for i in range(n):
        enc[0, i] = enc[1, i]
    if not state[ST_CURRENT_C]:
        if _first_pericentre(pos, vel, m, G, dt, n_active, peri_crit_eta):
            state[ST_CURRENT_C] = 1
            new = True
            if peri_mode != PARTIAL_BS:
                return True
            state[ST_TPONLY] = 0
    if state[ST_CURRENT_C]:
        state[ST_ENC_N] = n
        for i in range(n):
            enc[0, i] = 1
    if _flag_pairs(pos, vel, m, dt, n_active, r_crit_hill, interacts, enc, state, hill6, star_radius):
        new = True
    return new
