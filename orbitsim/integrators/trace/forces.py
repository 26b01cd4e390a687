"""TRACE's three force evaluations, in REBOUND's order of floating-point operations.

TRACE (Lu, Hernandez & Rein 2024) splits the democratic heliocentric Hamiltonian as

    H = H_Kepler(star + each body) + H_interaction(pairs) + H_jump,

and moves every pair that its switching function flags (``interacts[a, b]``, a < b) out of the
interaction part into the part integrated by Bulirsch-Stoer. Hence three right-hand sides:

* :func:`interaction_kick`: the half-step velocity kick by the planet-planet forces of the
  *unflagged* pairs (REBOUND ``..._calculate_acceleration_mode_interaction`` plus
  ``..._interaction_step``). The star never appears: star-planet forces live in H_Kepler.
* :func:`encounter_derivatives`: the encounter ODE of the bodies in the encounter set, in
  democratic heliocentric coordinates: each body feels ``-G m0 x / |x|^3`` plus the flagged pairs;
  in a PARTIAL_BS pericentre step the jump velocity ``sum_i m_i v_i / m0`` is added to every drift
  (REBOUND ``reb_integrator_trace_nbody_derivatives``).
* :func:`newton_derivatives`: the plain Newtonian N-body ODE in the inertial frame, used by the
  FULL_BS pericentre step (REBOUND ``reb_integrator_bs_nbody_derivatives`` with basic gravity).

Test particles follow REBOUND's ``testparticle_type = 0``: bodies at index >= ``n_active`` feel the
active bodies and pull on nothing. Every loop keeps REBOUND's non-OpenMP order (pairs i outer, j
inner, both members accumulated as the pair is visited), its ``G / (r*r*r)`` prefactor and the
softening added inside the square root, so that the sums round as REBOUND's do.

BS state vectors interleave the six coordinates of each body, ``y[6k:6k+6] = (x, y, z, vx, vy, vz)``
of the k-th body of the ODE, as REBOUND's do: the stability check of the BS step sums over y in
order, and the same layout gives the same sums.
"""

from __future__ import annotations

import math

from orbitsim._jit import jit_inline, jit_llvm_inline

#: ODE kinds dispatched by :func:`derivatives` (an integer switch keeps the BS kernel cacheable).
ODE_NEWTON = 0
ODE_ENCOUNTER = 1


@jit_inline
def interaction_kick(pos, vel, m, G, softening2, n_active, interacts, acc, h):
    """Kick the barycentric velocities of bodies 1..N-1 by h times the unflagged pair forces.

    ``pos``, ``vel`` (3, N) democratic heliocentric, in place; ``acc`` (3, N) scratch.
    """
    n = pos.shape[1]
    for c in range(3):
        for i in range(n):
            acc[c, i] = 0.0
    for i in range(2, n_active):
        for j in range(1, i):
            if interacts[j, i]:
                continue  # a flagged pair's force belongs to the encounter integration
            dx = pos[0, i] - pos[0, j]
            dy = pos[1, i] - pos[1, j]
            dz = pos[2, i] - pos[2, j]
            r = math.sqrt(dx * dx + dy * dy + dz * dz + softening2)
            prefact = G / (r * r * r)
            prefact_j = -prefact * m[j]
            prefact_i = prefact * m[i]
            acc[0, i] += prefact_j * dx
            acc[1, i] += prefact_j * dy
            acc[2, i] += prefact_j * dz
            acc[0, j] += prefact_i * dx
            acc[1, j] += prefact_i * dy
            acc[2, j] += prefact_i * dz
    for i in range(max(n_active, 2), n):
        for j in range(1, n_active):
            if interacts[j, i]:
                continue
            dx = pos[0, i] - pos[0, j]
            dy = pos[1, i] - pos[1, j]
            dz = pos[2, i] - pos[2, j]
            r = math.sqrt(dx * dx + dy * dy + dz * dz + softening2)
            prefact_j = -(G / (r * r * r)) * m[j]
            acc[0, i] += prefact_j * dx
            acc[1, i] += prefact_j * dy
            acc[2, i] += prefact_j * dz
    for c in range(3):
        for i in range(1, n):
            vel[c, i] += h * acc[c, i]


@jit_inline
def _pair_prefactor(dx, dy, dz, G, softening2):
    """``G / r^3`` of a pair at separation (dx, dy, dz), softened inside the square root."""
    r = math.sqrt(dx * dx + dy * dy + dz * dz + softening2)
    return G / (r * r * r)


@jit_inline
def _add_pair(rows, src, dst, k, l, G, softening2, m_k, m_l, both, ghost_shift):
    """Add the pull of ODE body l on body k (and of k on l when ``both``) to row ``dst``.

    ``ghost_shift``: form ``dx = (0 + x_k) - x_l`` as REBOUND's basic gravity does (the 0 is its
    ghost-box offset; ``0.0 + x`` differs from x for x = -0.0, so it is kept where REBOUND has it).
    """
    xk = rows[src, 6 * k]
    yk = rows[src, 6 * k + 1]
    zk = rows[src, 6 * k + 2]
    if ghost_shift:
        xk = 0.0 + xk
        yk = 0.0 + yk
        zk = 0.0 + zk
    dx = xk - rows[src, 6 * l]
    dy = yk - rows[src, 6 * l + 1]
    dz = zk - rows[src, 6 * l + 2]
    prefact = _pair_prefactor(dx, dy, dz, G, softening2)
    prefact_l = -prefact * m_l
    rows[dst, 6 * k + 3] += prefact_l * dx
    rows[dst, 6 * k + 4] += prefact_l * dy
    rows[dst, 6 * k + 5] += prefact_l * dz
    if both:
        prefact_k = prefact * m_k
        rows[dst, 6 * l + 3] += prefact_k * dx
        rows[dst, 6 * l + 4] += prefact_k * dy
        rows[dst, 6 * l + 5] += prefact_k * dz


@jit_llvm_inline
def encounter_derivatives(rows, src, dst, m, G, softening2, bodies, n_bodies, n_bodies_active, interacts,
                          with_jump):
    """dy/dt of TRACE's encounter ODE at ``rows[src]`` into ``rows[dst]`` (first 6 n_bodies entries).

    ``bodies[k]`` is the particle index of ODE body k; ``bodies[0] = 0`` is the star, held at the
    origin with zero velocity. The first ``n_bodies_active`` ODE bodies (star included) are active.
    """
    G_m0 = -G * m[0]
    for q in range(6):
        rows[dst, q] = 0.0
    for k in range(1, n_bodies):
        x = rows[src, 6 * k]
        y = rows[src, 6 * k + 1]
        z = rows[src, 6 * k + 2]
        r = math.sqrt(x * x + y * y + z * z + softening2)
        prefact = G_m0 / (r * r * r)
        rows[dst, 6 * k + 3] = prefact * x
        rows[dst, 6 * k + 4] = prefact * y
        rows[dst, 6 * k + 5] = prefact * z
    for k in range(2, n_bodies_active):
        for l in range(1, k):
            if interacts[bodies[l], bodies[k]]:
                _add_pair(rows, src, dst, k, l, G, softening2, m[bodies[k]], m[bodies[l]], True, False)
    for k in range(max(n_bodies_active, 2), n_bodies):
        for l in range(1, n_bodies_active):
            if interacts[bodies[l], bodies[k]]:
                _add_pair(rows, src, dst, k, l, G, softening2, m[bodies[k]], m[bodies[l]], False, False)
    # The jump term (pericentre steps of PARTIAL_BS only, where every body is in the ODE): the
    # star's barycentric momentum moves the heliocentric origin. v + 0.0 is v otherwise.
    px = 0.0
    py = 0.0
    pz = 0.0
    if with_jump:
        for k in range(1, n_bodies):
            m_k = m[bodies[k]]
            px += rows[src, 6 * k + 3] * m_k
            py += rows[src, 6 * k + 4] * m_k
            pz += rows[src, 6 * k + 5] * m_k
        px /= m[0]
        py /= m[0]
        pz /= m[0]
    for k in range(1, n_bodies):
        rows[dst, 6 * k] = rows[src, 6 * k + 3] + px
        rows[dst, 6 * k + 1] = rows[src, 6 * k + 4] + py
        rows[dst, 6 * k + 2] = rows[src, 6 * k + 5] + pz


@jit_inline
def newton_derivatives(rows, src, dst, m, G, softening2, bodies, n_bodies, n_active):
    """dy/dt of the inertial Newtonian N-body ODE at ``rows[src]`` into ``rows[dst]``; ODE body k is
    particle ``bodies[k]`` (all bodies in order, less those a collision merged away)."""
    for k in range(n_bodies):
        for c in range(3):
            rows[dst, 6 * k + c] = rows[src, 6 * k + 3 + c]
            rows[dst, 6 * k + 3 + c] = 0.0
    for k in range(1, n_active):
        for l in range(k):
            _add_pair(rows, src, dst, k, l, G, softening2, m[bodies[k]], m[bodies[l]], True, True)
    for k in range(max(n_active, 1), n_bodies):
        for l in range(n_active):
            _add_pair(rows, src, dst, k, l, G, softening2, m[bodies[k]], m[bodies[l]], False, True)


@jit_llvm_inline
def derivatives(kind, rows, src, dst, m, G, softening2, bodies, n_bodies, n_bodies_active, interacts,
                with_jump):
    """dy/dt of the ODE ``kind`` (:data:`ODE_NEWTON` or :data:`ODE_ENCOUNTER`) from row src to dst."""
    if kind == ODE_ENCOUNTER:
        encounter_derivatives(rows, src, dst, m, G, softening2, bodies, n_bodies, n_bodies_active, interacts,
                              with_jump)
    else:
        newton_derivatives(rows, src, dst, m, G, softening2, bodies, n_bodies, n_bodies_active)
