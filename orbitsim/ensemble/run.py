"""The front door of the ensemble kernels: validate K systems, allocate their scratch, run them.

:func:`run_ensemble` checks and coerces its input (the kernels assume clean arrays), allocates every
array a kernel writes once per call, and calls the scheme's kernel:
:func:`orbitsim.ensemble.system_lanes.run_ensemble_wh_lanes` (its scalar twin
:func:`orbitsim.ensemble.kernels.run_ensemble_wh`) for ``wisdom_holman``, with variations
:func:`orbitsim.ensemble.restricted.run_restricted_variational` where it applies, else
:func:`orbitsim.ensemble.system_tangent_lanes.run_ensemble_variational_lanes` (its scalar twin
:func:`orbitsim.ensemble.kernels.run_ensemble_variational`), and the scheme's kernel of
:mod:`orbitsim.ensemble.kick_drift` for ``verlet`` and the leapfrog orders.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from orbitsim.ensemble.status import N_COLUMNS, SCHEMES

__all__ = ["EnsembleResult", "EnsembleSystems", "check_variation", "prepare_systems", "run_ensemble"]


class EnsembleResult(NamedTuple):
    """What :func:`run_ensemble` returns, one row per system."""

    status: np.ndarray  #: int64 (K,): codes of :mod:`orbitsim.ensemble.status`
    steps: np.ndarray  #: int64 (K,): steps taken before the stop
    indicators: np.ndarray  #: (K, N_COLUMNS): the columns of :mod:`orbitsim.ensemble.status`
    pos: np.ndarray  #: (K, 3, N): inertial positions at the stop (synchronised)
    vel: np.ndarray  #: (K, 3, N): inertial velocities at the stop


def _as_systems(name: str, value: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    array = np.ascontiguousarray(value, dtype=np.float64)
    if array.shape != shape:
        raise ValueError(f"ensemble: {name} has shape {array.shape}, expected {shape}")
    return array.copy()


class EnsembleSystems(NamedTuple):
    """K systems checked and coerced by :func:`prepare_systems`: fresh contiguous float64 copies."""

    masses: np.ndarray  #: (K, N)
    pos: np.ndarray  #: (K, 3, N)
    vel: np.ndarray  #: (K, 3, N)
    radii: np.ndarray  #: (K, N), zeros when none were given
    check_collisions: bool  #: whether radii were given
    weights: np.ndarray  #: (K, N) Jacobi weights m_i / M_i (1 for body 0)
    mu: np.ndarray  #: (K, N) Kepler parameters G M_i


def prepare_systems(masses: np.ndarray, positions: np.ndarray, velocities: np.ndarray, *, G: float, dt: float,
                    n_steps: int, escape_distance: float, radii: np.ndarray | None, watch: int,
                    integrator: str = "wisdom_holman") -> EnsembleSystems:
    """Check K systems for an ensemble kernel (the CPU's and the GPU's, orbitsim.gpu.ensemble) and derive
    their Jacobi weights and Kepler parameters; raise ValueError with one line. Arguments as
    :func:`run_ensemble`'s."""
    m = np.ascontiguousarray(masses, dtype=np.float64)
    if m.ndim != 2 or m.shape[1] < 2:
        raise ValueError(f"ensemble: masses must have shape (K, N) with N >= 2, got {m.shape}")
    k, n = m.shape
    if not (m[:, 0] > 0.0).all():
        why = ("wisdom_holman needs a central body" if integrator == "wisdom_holman" else
               "the indicators follow Jacobi orbits about body 0 and escapes are measured from it")
        raise ValueError(f"ensemble: {why}: every system's first mass must be > 0")
    if (m < 0.0).any() or not np.isfinite(m).all():
        raise ValueError("ensemble: masses must be finite and >= 0")
    pos = _as_systems("positions", positions, (k, 3, n))
    vel = _as_systems("velocities", velocities, (k, 3, n))
    if not (np.isfinite(pos).all() and np.isfinite(vel).all()):
        raise ValueError("ensemble: start states must be finite")
    if not (dt > 0.0 and np.isfinite(dt)):
        raise ValueError(f"ensemble: dt must be finite and > 0, got {dt}")
    if int(n_steps) < 0:
        raise ValueError(f"ensemble: n_steps must be >= 0, got {n_steps}")
    if not 1 <= watch < n:
        raise ValueError(f"ensemble: watch must be a body index in 1..{n - 1}, got {watch}")
    if not escape_distance > 0.0:
        raise ValueError(f"ensemble: escape_distance must be > 0, got {escape_distance}")
    check_collisions = radii is not None
    r = np.zeros((k, n)) if radii is None else _as_systems("radii", radii, (k, n))
    interior = np.cumsum(m, axis=1)  # M_i summed left to right, as make_work's mu and jacobi_weights
    weights = m / interior
    weights[:, 0] = 1.0
    mu = G * interior
    return EnsembleSystems(m, pos, vel, r, check_collisions, weights, mu)


def check_variation(variation: tuple[np.ndarray, np.ndarray], k: int, n: int) -> tuple[np.ndarray, np.ndarray]:
    """(K, 3, N) copies of the initial tangent vectors; ValueError unless each system's is finite and non-zero."""
    dpos = _as_systems("variation positions", variation[0], (k, 3, n))
    dvel = _as_systems("variation velocities", variation[1], (k, 3, n))
    if not (np.isfinite(dpos).all() and np.isfinite(dvel).all()) or not (np.abs(dpos).sum(axis=(1, 2)) +
                                                                         np.abs(dvel).sum(axis=(1, 2)) > 0).all():
        raise ValueError("ensemble: every system's initial variation must be finite and non-zero")
    return dpos, dvel


def run_ensemble(masses: np.ndarray, positions: np.ndarray, velocities: np.ndarray, *, G: float, dt: float,
                 n_steps: int, t_start: float = 0.0, escape_distance: float = np.inf,
                 radii: np.ndarray | None = None, watch: int = 1,
                 variation: tuple[np.ndarray, np.ndarray] | None = None,
                 shared_massive: bool = True, integrator: str = "wisdom_holman", lanes: bool = True) -> EnsembleResult:
    """Run K systems of N bodies with the Wisdom-Holman map (Jacobi coordinates, no corrector), or with
    velocity Verlet or a leapfrog order and their variational equations (``integrator``).

    Parameters
    ----------
    masses : (K, N) array
        Masses; body 0 of every system is the central body (mass > 0).
    positions, velocities : (K, 3, N) arrays
        Inertial start states (not modified).
    G, dt : float
        Gravitational constant and step (dt > 0).
    n_steps : int
        Steps per system, unless it stops first.
    t_start : float
        Time of the start state (the survival times count from it).
    escape_distance : float
        A body farther than this from body 0 has escaped (inf: never).
    radii : (K, N) array, optional
        Body radii; with them, two bodies closer than the sum of their radii have collided.
    watch : int
        The body whose Jacobi a and e the ``max_e`` and ``delta_a`` indicators follow (>= 1).
    variation : pair of (K, 3, N) arrays, optional
        Initial tangent vectors (dr, dv): with them every system carries its variational equations
        (the Wisdom-Holman tangent map) and the ``megno`` and ``lyapunov`` columns are filled.
    shared_massive : bool
        With ``variation``, where the last body is massless, watched, and the other bodies are the same
        in every system (a map over a test particle), step those once for all systems
        (:mod:`orbitsim.ensemble.restricted`: the same bits, a fraction of the time). False: always
        the whole-system kernel (tests compare the two). Wisdom-Holman only.
    integrator : str
        A registry name of :data:`orbitsim.ensemble.status.SCHEMES`: ``wisdom_holman`` (the default),
        ``verlet``, ``leapfrog``, ``leapfrog4``, ``leapfrog6`` or ``leapfrog8``. The kick-drift schemes
        (:mod:`orbitsim.ensemble.kick_drift`) always carry their variational equations: they need
        ``variation``, and at most :data:`orbitsim.physics.gravity.SMALL_N_MAX` bodies per system.
    lanes : bool
        Wisdom-Holman: step :data:`orbitsim.ensemble.lanes.LANES` whole systems side by side in SIMD lanes, the
        same bits in a fraction of the time: without ``variation``
        (:mod:`orbitsim.ensemble.system_lanes`) and with it where the shared-massive path does not apply
        (:mod:`orbitsim.ensemble.system_tangent_lanes`: the tangent map and MEGNO in the lanes). False: one
        system at a time, the scalar kernels :func:`~orbitsim.ensemble.kernels.run_ensemble_wh` and
        :func:`~orbitsim.ensemble.kernels.run_ensemble_variational` (the reference; tests compare the two).

    Returns
    -------
    EnsembleResult
    """
    from orbitsim._jit import launch_threads  # noqa: PLC0415 - lazy: loads numba
    from orbitsim.ensemble.kernels import run_ensemble_wh  # noqa: PLC0415 - lazy: loads numba

    launch_threads()  # before a cached prange kernel is loaded (see launch_threads)
    if integrator not in SCHEMES:
        raise ValueError(f"ensemble: no ensemble kernel for integrator {integrator!r}; schemes: {', '.join(SCHEMES)}")
    m, pos, vel, r, check_collisions, weights, mu = prepare_systems(masses, positions, velocities, G=G, dt=dt,
                                                                    n_steps=n_steps, escape_distance=escape_distance,
                                                                    radii=radii, watch=watch, integrator=integrator)
    k, n = m.shape
    scratch = [np.zeros((k, 3, n)) for _ in range(4)]
    from orbitsim.physics.kepler import KEPLER_SCRATCH_ROWS  # noqa: PLC0415 - lazy: loads numba

    ks = np.zeros((k, KEPLER_SCRATCH_ROWS, n))
    kstage = np.zeros((k, n), dtype=np.int64)
    status = np.zeros(k, dtype=np.int64)
    steps = np.zeros(k, dtype=np.int64)
    out = np.zeros((k, N_COLUMNS))
    escape_r2 = float(escape_distance) ** 2
    if integrator != "wisdom_holman":
        return _run_kick_drift(integrator, m, pos, vel, G, dt, n_steps, t_start, escape_r2, r, check_collisions,
                               watch, weights, mu, variation, status, steps, out)
    if variation is not None:
        from orbitsim.ensemble.kernels import run_ensemble_variational  # noqa: PLC0415 - lazy: loads numba
        from orbitsim.integrators.wisdom_holman.tangent import TANGENT_SCRATCH_ROWS  # noqa: PLC0415 - as above
        from orbitsim.physics.force_context import make_force  # noqa: PLC0415 - lazy: as above

        dpos, dvel = check_variation(variation, k, n)
        force = make_force(float(G), 0.0, n)
        if shared_massive:
            from orbitsim.ensemble.restricted import (  # noqa: PLC0415 - lazy: loads numba
                restricted_applies,
                run_restricted_variational,
            )

            if restricted_applies(m, pos, vel, r, dpos, dvel, watch):
                rpos, rvel = pos.copy(), vel.copy()
                if run_restricted_variational(rpos, rvel, dpos, dvel, m, force, float(dt), float(t_start),
                                              np.int64(n_steps), escape_r2, r, check_collisions, np.int64(watch),
                                              weights, mu, np.zeros(0), status, steps, out):
                    return EnsembleResult(status, steps, out, rpos, rvel)
        scratch_t = np.zeros((k, TANGENT_SCRATCH_ROWS, 3, n))
        if lanes:  # force is gravity alone (make_force above), all the lanes kernel does
            from orbitsim.ensemble.system_tangent_lanes import (  # noqa: PLC0415 - lazy: loads numba
                run_ensemble_variational_lanes,
            )

            run_ensemble_variational_lanes(pos, vel, dpos, dvel, m, force.G, force.eps2, float(dt), float(t_start),
                                           np.int64(n_steps), escape_r2, r, check_collisions, np.int64(watch),
                                           weights, mu, scratch_t, np.zeros(0), status, steps, out)
        else:
            run_ensemble_variational(pos, vel, dpos, dvel, m, force, float(dt), float(t_start),
                                     np.int64(n_steps), escape_r2, r, check_collisions, np.int64(watch), weights, mu,
                                     scratch_t, np.zeros(0), status, steps, out)
        return EnsembleResult(status, steps, out, pos, vel)
    if lanes:
        from orbitsim.ensemble.system_lanes import run_ensemble_wh_lanes  # noqa: PLC0415 - lazy: loads numba

        kernel = run_ensemble_wh_lanes
    else:
        kernel = run_ensemble_wh
    kernel(pos, vel, m, float(G), float(dt), float(t_start), np.int64(n_steps), escape_r2, r, check_collisions,
           np.int64(watch), *scratch, weights, mu, ks, kstage, np.zeros(0), status, steps, out)
    return EnsembleResult(status, steps, out, pos, vel)


def _run_kick_drift(integrator: str, m: np.ndarray, pos: np.ndarray, vel: np.ndarray, G: float, dt: float,
                    n_steps: int, t_start: float, escape_r2: float, radii: np.ndarray, check_collisions: bool,
                    watch: int, weights: np.ndarray, mu: np.ndarray, variation: tuple[np.ndarray, np.ndarray] | None,
                    status: np.ndarray, steps: np.ndarray, out: np.ndarray) -> EnsembleResult:
    """:func:`run_ensemble` for a kick-drift scheme: the checks only it needs, its scratch, its kernel."""
    from orbitsim.ensemble.kick_drift import KICK_DRIFT_KERNELS  # noqa: PLC0415 - lazy: loads numba
    from orbitsim.integrators.base import TANGENT_SCRATCH_ROWS  # noqa: PLC0415 - lazy: as above
    from orbitsim.physics.force_context import make_force  # noqa: PLC0415 - lazy: as above
    from orbitsim.physics.gravity import SMALL_N_MAX  # noqa: PLC0415 - lazy: as above

    k, n = m.shape
    if variation is None:
        raise ValueError(f"ensemble: {integrator}'s ensemble carries the variational equations: give variation "
                         "(only wisdom_holman has an ensemble without them)")
    if n > SMALL_N_MAX:
        raise ValueError(f"ensemble: {integrator}: at most {SMALL_N_MAX} bodies per system (one all-pairs force "
                         f"kernel per system), got {n}")
    dpos, dvel = check_variation(variation, k, n)
    force = make_force(float(G), 0.0, n)
    kernel = KICK_DRIFT_KERNELS[integrator]
    kernel(pos, vel, np.zeros((k, 3, n)), dpos, dvel, np.zeros((k, 3, n)), np.zeros((k, TANGENT_SCRATCH_ROWS, 3, n)),
           np.zeros((k, 1), dtype=np.int64), m, force, float(dt), float(t_start), np.int64(n_steps), escape_r2,
           radii, check_collisions, np.int64(watch), weights, mu, np.zeros((k, 3, n)), np.zeros((k, 3, n)),
           np.zeros((k, 0, 3, n)), np.zeros(0), status, steps, out)
    return EnsembleResult(status, steps, out, pos, vel)
