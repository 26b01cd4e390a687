"""The Wisdom-Holman tangent map: first-order variational equations stepped with the map itself.

A tangent vector delta = (dr, dv) per body rides with the state and is carried by the derivative
of each operator of the step (Rein & Tamayo 2016 [1]_, as REBOUND's WHFast integrates its
first-order variational particles [2]_):

* the Jacobi transforms are linear, so the tangent vector is transformed with the same weights;
* the Kepler drift's derivative (:func:`kepler_drift_tangent`): with the shifted Lagrange
  coefficients f, g, fd, gd of the drift (:mod:`orbitsim.physics.kepler`),

      dr' = dr + f dr + g dv + df r0 + dg v0,     dv' = dv + fd dr + gd dv + dfd r0 + dgd v0,

  where df, dg, dfd, dgd follow from differentiating the universal Kepler equation at fixed dt:
  dX = -(X dr0 + G2 deta0 + G3 dzeta0 + (eta0 dG2/dbeta + zeta0 dG3/dbeta) dbeta) / r, with
  dG_n/dbeta = (n G_{n+2} - X G_{n+1}) / 2 (Stiefel's G-functions up to G5, :func:`stiefel_g6`);
* the interaction kick's derivative (:func:`interaction_kick_tangent`): the tangent gravity of
  :mod:`orbitsim.physics.tangent` without the (0, 1) pair, in Jacobi coordinates, plus the
  derivative of the Jacobi term ``G M_i r'_i / |r'_i|^3`` for i >= 2.

The step (:func:`tangent_step`) is WHFast's with ``safe_mode = 1``, the arrangement REBOUND
demands for MEGNO: from the inertial state, K(dt/2) I(dt) K(dt/2), back to inertial coordinates,
so the state between steps is the inertial (pos, vel) and (dpos, dvel) alone. A chaos run's bodies
therefore differ from a plain Wisdom-Holman run's (which merges the half drifts) by round-off.
After each step :func:`orbitsim.chaos.step.megno_after_step` reads the tangent state, as WHFast
does at the end of its step. Jacobi coordinates only, without correctors (as REBOUND: its
variational WHFast refuses other coordinates; its correctors are not built here).

Every operator takes plain arrays and scalars of one system, allocates nothing and works in place,
so an ensemble kernel can call the body-level pieces per system.

References
----------
.. [1] Rein, H. & Tamayo, D. (2016), "Second-order variational equations for N-body simulations",
       MNRAS 459, 2275.
.. [2] REBOUND, ``src/integrator_whfast.c``: ``reb_integrator_whfast_kepler_solver`` (its
       variational part), ``reb_integrator_whfast_interaction_step``, ``reb_integrator_whfast_step``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from orbitsim._jit import jit, jit_inline, jit_llvm_inline
from orbitsim.chaos.step import megno_after_step
from orbitsim.forces.tangent import add_tangent_kick_forces
from orbitsim.integrators.base import chaos_sample_loop, grid_time
from orbitsim.integrators.wisdom_holman.operators import interaction_kick, record_failure
from orbitsim.physics.coordinates import inertial_to_jacobi, jacobi_to_inertial
from orbitsim.physics.kepler import (
    KEPLER_NOT_CONVERGED,
    KEPLER_OK,
    KEPLER_SINGULAR,
    fg_apply,
    lagrange_coefficients,
)
from orbitsim.physics.kepler_solver import SINGULAR, setup, solve
from orbitsim.physics.tangent import SKIP_PAIR_0_1, tangent_accelerations

#: 1/n! for n = 0..15: the series of c4 and c5 run to z^5 / 15!.
_INV_FACTORIAL = np.array([1.0 / math.factorial(n) for n in range(16)])
#: Bound on the quartering loop of :func:`stiefel_g6` (4^520 exceeds the largest float64).
_MAX_QUARTERINGS = 520


@jit_inline
def _g6_series(z):
    """``(c1, c2, c3, c4, c5)`` at ``|z| <= 0.1``: c4 and c5 by their series, then ``c_n = 1/n! - z c_{n+2}``."""
    c5 = _INV_FACTORIAL[15]
    c4 = _INV_FACTORIAL[14]
    for k in range(13, 4, -2):
        c5 = _INV_FACTORIAL[k] - z * c5
        c4 = _INV_FACTORIAL[k - 1] - z * c4
    c3 = _INV_FACTORIAL[3] - z * c5
    c2 = _INV_FACTORIAL[2] - z * c4
    c1 = 1.0 - z * c3
    return c1, c2, c3, c4, c5


@jit_inline
def _g6_products(X, z, c1, c2, c3, c4, c5):
    """``G0..G5`` from ``c1..c5`` at ``z = beta X^2``."""
    c0 = 1.0 - z * c2
    X2 = X * X
    X3 = X2 * X
    return c0, c1 * X, c2 * X2, c3 * X3, c4 * X3 * X, c5 * X3 * X2


@jit_inline
def stiefel_g6(beta, X):
    """Stiefel's G-functions ``G0..G5`` at ``X`` for ``beta`` (``G_n = X^n c_n(beta X^2)``).

    REBOUND's method (``stumpff_cs``): the argument is quartered until |z| <= 0.1, c4 and c5 are
    summed by their series (to z^5 / 15!, below 1e-17 of the sum), c0..c3 follow from
    ``c_n = 1/n! - z c_{n+2}``, and the quarter-argument identities bring them back.
    """
    z = beta * X * X
    n = 0
    while abs(z) > 0.1 and n < _MAX_QUARTERINGS:
        z = z * 0.25
        n += 1
    c1, c2, c3, c4, c5 = _g6_series(z)
    for _ in range(n):
        z = z * 4.0
        c5 = (c5 + c4 + c3 * c2) * 0.0625
        c4 = (1.0 + c1) * c3 * 0.125
        c3 = 1.0 / 6.0 - z * c5
        c2 = 0.5 - z * c4
        c1 = 1.0 - z * c3
    return _g6_products(X, z, c1, c2, c3, c4, c5)


@jit_inline
def stiefel_g6_short(beta, X):
    """:func:`stiefel_g6` without quarterings, branch free: the same bits where ``|beta X^2| <= 0.1``; and
    ``z = beta X^2`` for the caller to check that it was."""
    z = beta * X * X
    c1, c2, c3, c4, c5 = _g6_series(z)
    G0, G1, G2, G3, G4, G5 = _g6_products(X, z, c1, c2, c3, c4, c5)
    return G0, G1, G2, G3, G4, G5, z


@jit_inline
def _poison_tangent(pos, vel, dpos, dvel, i):
    for c in range(3):
        pos[c, i] = np.nan
        vel[c, i] = np.nan
        dpos[c, i] = np.nan
        dvel[c, i] = np.nan


@jit_inline
def drift_derivative(x, y, z, vx, vy, vz, dx, dy, dz, dvx, dvy, dvz, mu, r0, r0i, eta0, zeta0, beta, X, ri, f, g, fd,
                     gd, Gs0, Gs1, Gs2, Gs3, Gs4, Gs5):
    """The tangent vector after the drift (module docstring): ``(dr', dv')`` from the start state and its
    tangent, the solve's terms, the shifted Lagrange coefficients and ``G0..G5`` at the full step's root."""
    dr0 = (dx * x + dy * y + dz * z) * r0i
    dbeta = -2.0 * mu * dr0 * r0i * r0i - 2.0 * (dvx * vx + dvy * vy + dvz * vz)
    deta0 = dx * vx + dy * vy + dz * vz + x * dvx + y * dvy + z * dvz
    dzeta0 = -beta * dr0 - r0 * dbeta
    G3beta = 0.5 * (3.0 * Gs5 - X * Gs4)
    G2beta = 0.5 * (2.0 * Gs4 - X * Gs3)
    G1beta = 0.5 * (Gs3 - X * Gs2)
    tbeta = eta0 * G2beta + zeta0 * G3beta
    dX = -1.0 * ri * (X * dr0 + Gs2 * deta0 + Gs3 * dzeta0 + tbeta * dbeta)
    dG1 = Gs0 * dX + G1beta * dbeta
    dG2 = Gs1 * dX + G2beta * dbeta
    dG3 = Gs2 * dX + G3beta * dbeta
    dr = dr0 + Gs1 * deta0 + Gs2 * dzeta0 + eta0 * dG1 + zeta0 * dG2
    df = mu * Gs2 * dr0 * r0i * r0i - mu * dG2 * r0i
    dg = -mu * dG3
    dfd = -mu * dG1 * r0i * ri + mu * Gs1 * (dr0 * r0i + dr * ri) * r0i * ri
    dgd = -mu * dG2 * ri + mu * Gs2 * dr * ri * ri
    return (dx + (f * dx + g * dvx + df * x + dg * vx),
            dy + (f * dy + g * dvy + df * y + dg * vy),
            dz + (f * dz + g * dvz + df * z + dg * vz),
            dvx + (fd * dx + gd * dvx + dfd * x + dgd * vx),
            dvy + (fd * dy + gd * dvy + dfd * y + dgd * vy),
            dvz + (fd * dz + gd * dvz + dfd * z + dgd * vz))


@jit_inline
def kepler_drift_tangent(pos, vel, dpos, dvel, i, mu, dt):
    """Kepler drift by ``dt`` of body ``i`` (about ``mu``) and of its tangent vector, in place.

    The body moves with the same bits as :func:`orbitsim.physics.kepler.kepler_drift` (the same
    setup, solve and update); its tangent vector by the drift's derivative (module docstring).
    Returns a :mod:`orbitsim.physics.kepler` status; on a failure all four columns are nan.
    """
    x, y, z = pos[0, i], pos[1, i], pos[2, i]
    vx, vy, vz = vel[0, i], vel[1, i], vel[2, i]
    dx, dy, dz = dpos[0, i], dpos[1, i], dpos[2, i]
    dvx, dvy, dvz = dvel[0, i], dvel[1, i], dvel[2, i]
    if mu == 0.0:
        pos[0, i], pos[1, i], pos[2, i] = x + dt * vx, y + dt * vy, z + dt * vz
        dpos[0, i], dpos[1, i], dpos[2, i] = dx + dt * dvx, dy + dt * dvy, dz + dt * dvz
        return KEPLER_OK
    r0 = math.sqrt(x * x + y * y + z * z)
    eta0 = x * vx + y * vy + z * vz
    r0i, zeta0, beta, dt_eff, X, stage = setup(r0, vx * vx + vy * vy + vz * vz, eta0, mu, dt)
    if stage == SINGULAR:
        _poison_tangent(pos, vel, dpos, dvel, i)
        return KEPLER_SINGULAR
    X, G1, G2, G3, r, converged = solve(r0, eta0, zeta0, beta, dt_eff, X, stage)
    if not converged:
        _poison_tangent(pos, vel, dpos, dvel, i)
        return KEPLER_NOT_CONVERGED
    ri, f, g, fd, gd = lagrange_coefficients(mu, dt_eff, r0i, G1, G2, G3, r)
    pos[0, i], pos[1, i], pos[2, i], vel[0, i], vel[1, i], vel[2, i] = fg_apply(x, y, z, vx, vy, vz, f, g, fd, gd)
    if dt_eff != dt:
        # The solve dropped whole periods; the derivative at the full dt keeps the secular shear
        # of the period's dependence on beta, so X is taken back to the full step's root.
        X += round(dt / (2.0 * math.pi * mu / (beta * math.sqrt(beta)))) * (2.0 * math.pi / math.sqrt(beta))
    Gs0, Gs1, Gs2, Gs3, Gs4, Gs5 = stiefel_g6(beta, X)
    (dpos[0, i], dpos[1, i], dpos[2, i],
     dvel[0, i], dvel[1, i], dvel[2, i]) = drift_derivative(x, y, z, vx, vy, vz, dx, dy, dz, dvx, dvy, dvz, mu, r0,
                                                            r0i, eta0, zeta0, beta, X, ri, f, g, fd, gd,
                                                            Gs0, Gs1, Gs2, Gs3, Gs4, Gs5)
    return KEPLER_OK


@jit_llvm_inline
def kepler_step_tangent(jpos, jvel, djpos, djvel, mu, h):
    """Kepler drift by ``h`` of bodies 1..N-1 and their tangent vectors, then the centre of mass
    (column 0) and its variation move with their constant velocities. Returns ``(status, body)``."""
    for i in range(1, jpos.shape[1]):
        status = kepler_drift_tangent(jpos, jvel, djpos, djvel, i, mu[i], h)
        if status != KEPLER_OK:
            return status, i
    for c in range(3):
        jpos[c, 0] += h * jvel[c, 0]
        djpos[c, 0] += h * djvel[c, 0]
    return KEPLER_OK, 0


@jit_inline
def interaction_kick_tangent(jpos, jvel, djpos, djvel, m, G, eps2, h, weights, mu, ipos, acc, dipos, dacc, force):
    """The kick I(h) of the Jacobi state and of its tangent vector; ``ipos``, ``acc``, ``dipos``,
    ``dacc`` (3, N) are scratch.

    The bodies are kicked by :func:`~.operators.interaction_kick` (which leaves the inertial
    positions in ``ipos``). The tangent vector: its inertial positions, the tangent gravity
    without the (0, 1) pair (and the position forces' derivatives,
    :func:`orbitsim.forces.tangent.add_tangent_kick_forces`), their Jacobi transform, then, for
    i >= 2, the derivative of the Jacobi term ``G M_i r'_i / |r'_i|^3`` (added first, as REBOUND).
    """
    interaction_kick(jpos, jvel, m, G, eps2, h, None, weights, mu, ipos, acc, force)
    jacobi_to_inertial(djpos, weights, dipos)
    tangent_accelerations(ipos, m, G, eps2, dipos, dacc, np.int64(SKIP_PAIR_0_1))
    add_tangent_kick_forces(force, ipos, m, dipos, dacc)
    # to Jacobi, in place: columns 1.. are the same arithmetic as the bodies' kick; column 0 (the centre of
    # mass) is not read, and megno_after_step rewrites the whole array
    inertial_to_jacobi(dacc, weights, dacc)
    jacobi_term_tangent_kick(jpos, djpos, djvel, dacc, mu, h)


@jit_inline
def jacobi_term_tangent_kick(jpos, djpos, djvel, dacc, mu, h):
    """The tangent kick of Jacobi bodies 1..N-1 by ``h``: ``h`` times the Jacobi-transformed tangent
    accelerations ``dacc`` (3, N), plus, for i >= 2, the derivative of the Jacobi term
    ``G M_i r'_i / |r'_i|^3`` (added first, as REBOUND). In place on ``djvel``; also the GPU ensemble's
    (orbitsim.gpu.ensemble_kernels), so the two share these operations."""
    n = jpos.shape[1]
    for i in range(1, n):
        if i > 1:
            x, y, z = jpos[0, i], jpos[1, i], jpos[2, i]
            rj2i = 1.0 / (x * x + y * y + z * z)
            rj3iM = math.sqrt(rj2i) * rj2i * mu[i]
            prefac1 = h * rj3iM
            rdr = djpos[0, i] * x + djpos[1, i] * y + djpos[2, i] * z
            prefac2 = -h * 3.0 * rdr * (rj3iM * rj2i)
            djvel[0, i] += prefac1 * djpos[0, i] + prefac2 * x
            djvel[1, i] += prefac1 * djpos[1, i] + prefac2 * y
            djvel[2, i] += prefac1 * djpos[2, i] + prefac2 * z
        djvel[0, i] += h * dacc[0, i]
        djvel[1, i] += h * dacc[1, i]
        djvel[2, i] += h * dacc[2, i]


@jit_llvm_inline
def tangent_step(pos, vel, dpos, dvel, m, G, eps2, dt, weights, mu, jpos, jvel, djpos, djvel, ipos, acc, dipos, dacc,
                 force):
    """One Wisdom-Holman step of the inertial state and its tangent vector, in place (safe mode:
    to Jacobi coordinates, K(dt/2) I(dt) K(dt/2), back to inertial). The other (3, N) arrays are
    scratch. Returns ``(status, body)``; on a Kepler failure the failing body's columns are nan."""
    inertial_to_jacobi(pos, weights, jpos)
    inertial_to_jacobi(vel, weights, jvel)
    inertial_to_jacobi(dpos, weights, djpos)
    inertial_to_jacobi(dvel, weights, djvel)
    half = 0.5 * dt
    status, body = kepler_step_tangent(jpos, jvel, djpos, djvel, mu, half)
    if status != KEPLER_OK:
        return status, body
    interaction_kick_tangent(jpos, jvel, djpos, djvel, m, G, eps2, dt, weights, mu, ipos, acc, dipos, dacc, force)
    status, body = kepler_step_tangent(jpos, jvel, djpos, djvel, mu, half)
    if status != KEPLER_OK:
        return status, body
    jacobi_to_inertial(jpos, weights, pos)
    jacobi_to_inertial(jvel, weights, vel)
    jacobi_to_inertial(djpos, weights, dpos)
    jacobi_to_inertial(djvel, weights, dvel)
    return KEPLER_OK, 0


#: Rows of the (TANGENT_SCRATCH_ROWS, 3, N) scratch of :func:`tangent_advance`: the Jacobi state and
#: tangent vector, the inertial positions and accelerations of the kick, the tangent's inertial
#: positions and accelerations.
T_JPOS, T_JVEL, T_DJPOS, T_DJVEL, T_IPOS, T_ACC, T_DIPOS, T_DACC = range(8)
TANGENT_SCRATCH_ROWS = 8


@jit_inline
def tangent_advance(pos, vel, dpos, dvel, m, force, dt, weights, mu, scratch, megno, t0, n_done, n_to):
    """Steps ``n_done`` .. ``n_to`` of :func:`tangent_step`, each followed by MEGNO's read
    (:func:`orbitsim.chaos.step.megno_after_step` at ``t0 + n dt``).

    ``weights`` (N,) are the Jacobi weights, ``mu`` (N,) the Kepler parameters ``G M_i``,
    ``scratch`` (:data:`TANGENT_SCRATCH_ROWS`, 3, N). Returns ``(n_done, status, body, megno,
    halvings)``: the step count reached, the Kepler status and failing body (the state is then
    nan), the MEGNO sums and the number of 2^-200 rescalings of the tangent state.
    """
    jpos, jvel, djpos, djvel = scratch[T_JPOS], scratch[T_JVEL], scratch[T_DJPOS], scratch[T_DJVEL]
    ipos, acc, dipos, dacc = scratch[T_IPOS], scratch[T_ACC], scratch[T_DIPOS], scratch[T_DACC]
    G = force.G
    eps2 = force.eps2
    halvings = 0
    while n_done < n_to:
        status, body = tangent_step(pos, vel, dpos, dvel, m, G, eps2, dt, weights, mu, jpos, jvel, djpos, djvel,
                                    ipos, acc, dipos, dacc, force)
        if status != KEPLER_OK:
            return n_done, status, body, megno, halvings
        n_done += 1
        megno, k = megno_after_step(megno, pos, m, force, dpos, dvel, dacc, t0 + n_done * dt, dt)
        halvings += k
    return n_done, KEPLER_OK, 0, megno, halvings


@jit
def tangent_run(pos, vel, dpos, dvel, m, force, dt, weights, mu, scratch, megno, t0, n_done, n_to):
    """:func:`tangent_advance` as a cached entry point (tests, benchmarks, one system at a time)."""
    return tangent_advance(pos, vel, dpos, dvel, m, force, dt, weights, mu, scratch, megno, t0, n_done, n_to)


@jit
def kepler_drift_tangent_at(pos, vel, dpos, dvel, i, mu, dt):
    """:func:`kepler_drift_tangent` as a cached entry point (tests)."""
    return kepler_drift_tangent(pos, vel, dpos, dvel, i, mu, dt)


@jit
def stiefel_g6_at(beta, X):
    """:func:`stiefel_g6` as a cached entry point (tests)."""
    return stiefel_g6(beta, X)


@jit_inline
def advance_chaos(pos, vel, acc, m, force, dt, work, t0, n_done, n_to, tangent, megno):
    """Steps ``n_done`` .. ``n_to`` of the bodies and their tangent vector with MEGNO's read after
    each (:func:`~.tangent.tangent_advance`: WHFast's safe-mode arrangement, Jacobi coordinates, no
    corrector); a Kepler failure is recorded as in :func:`advance`. Returns ``(n_done, ok, megno)``."""
    n_done, status, body, megno, halvings = tangent_advance(pos, vel, tangent.dpos, tangent.dvel, m, force, dt,
                                                            work.weights, work.mu, tangent.scratch, megno, t0,
                                                            n_done, n_to)
    tangent.halvings[0] += halvings
    if status != KEPLER_OK:
        record_failure(pos, vel, work, status, body, n_done + 1)
        return n_done, False, megno
    return n_done, True, megno


@jit
def run_chaos(state, tangent, force, dt, work, t0, n_done, targets, record, out, indicators, megno):
    """:func:`~orbitsim.integrators.base.chaos_sample_loop` of :func:`advance_chaos`."""
    return chaos_sample_loop(advance_chaos, grid_time, state, tangent, force, dt, work, t0, n_done, targets, record,
                             out, indicators, megno)


def check_chaos(settings: Mapping[str, Any]) -> str | None:
    """The variational map is built for Jacobi coordinates without correctors (as REBOUND's WHFast
    refuses its variational particles in other coordinates)."""
    if settings.get("coordinates", "jacobi") != "jacobi":
        return ("wisdom_holman's variational equations need coordinates 'jacobi' (as REBOUND's WHFast), "
                f"got {settings['coordinates']!r}")
    if settings.get("corrector", 0) != 0:
        return ("wisdom_holman's variational equations are built without correctors, "
                f"got corrector {settings['corrector']}")
    return None
