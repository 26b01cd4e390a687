"""A variational run from Python: bodies, a scheme and dt in; MEGNO and mLCE at every sample out.

:func:`chaos_run` is the front door of every scheme's ``run_chaos`` (contract item 17 of
:mod:`orbitsim.integrators.base`): it validates, refuses in one line what has no variational
equations (:func:`orbitsim.integrators.registry.chaos_refusal`), builds the force context, the
scheme's work, the :class:`~orbitsim.integrators.base.Tangent` and MEGNO's sums, and calls the
jitted loop. The initial variation is either given (``variation``: (N, 6) rows dx dy dz dvx dvy
dvz per body, e.g. REBOUND's variational particle after ``init_megno``) or drawn from ``seed``
(:func:`orbitsim.chaos.megno.random_initial_variation`). ``resume`` continues a :class:`ChaosResult`
with the same bits as an uninterrupted run, from copies of its state, its tangent record (the
scheme's ``make_tangent``) and its ``work`` (an adaptive scheme's clock and polynomials), with the
first call's settings. For ias15, ``dt`` is the output grid, as in its plain run: IAS15 chooses its
own steps and lands exactly on each grid time.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from orbitsim.chaos.megno import MegnoState, megno_start, random_initial_variation

if TYPE_CHECKING:
    from orbitsim.forces.table import ForceSet


@dataclass
class ChaosResult:
    """Samples of a variational run, and the whole state needed to continue it bit for bit."""

    times: np.ndarray  #: (S,) sample times
    megno: np.ndarray  #: (S,) MEGNO <Y> at each sample (REBOUND's ``megno()``)
    mlce: np.ndarray  #: (S,) the slope of <Y> (REBOUND's ``lyapunov()``); its inverse is the Lyapunov time
    positions: np.ndarray  #: (3, N) final positions
    velocities: np.ndarray  #: (3, N) final velocities
    dpos: np.ndarray  #: (3, N) final tangent positions (scaled by 2^-200 per halving)
    dvel: np.ndarray  #: (3, N) final tangent velocities
    halvings: int  #: exact 2^-200 rescalings of the tangent vector so far
    sums: MegnoState  #: MEGNO's running sums
    steps_done: int  #: steps taken since the run's t0
    finite: bool  #: False when the run stopped at a non-finite state or a failed step
    #: The scheme's tangent record (its ``make_tangent``; ``dpos``, ``dvel`` are the arrays above) and
    #: its ``work`` at the end: what ``resume`` continues from (ias15's polynomials and clock are there).
    tangent: Any = None
    work: Any = None


def _variation(variation: Any, seed: int | None, n: int) -> tuple[np.ndarray, np.ndarray]:
    if variation is None:
        return random_initial_variation(n, 0 if seed is None else int(seed))
    rows = np.asarray(variation, dtype=np.float64)
    if rows.shape != (n, 6):
        raise ValueError(f"variation must be {n} rows of 6 numbers (dx dy dz dvx dvy dvz per body), got {rows.shape}")
    if not np.all(np.isfinite(rows)) or not np.any(rows != 0.0):
        raise ValueError("variation must be finite and not all zero")
    return np.ascontiguousarray(rows[:, :3].T), np.ascontiguousarray(rows[:, 3:].T)


def _copied(record: Any) -> Any:
    """A copy of a scheme's record (an array, or a NamedTuple of arrays and scalars) sharing no array."""
    if isinstance(record, np.ndarray):
        return record.copy()
    return type(record)(*(np.copy(f) if isinstance(f, np.ndarray) else f for f in record))


def chaos_run(
    masses: Any,
    positions: Any,
    velocities: Any,
    *,
    integrator: str,
    dt: float,
    steps: int,
    every: int = 1,
    G: float = 1.0,
    softening: float = 0.0,
    settings: dict[str, Any] | None = None,
    variation: Any = None,
    seed: int | None = 0,
    t0: float = 0.0,
    resume: ChaosResult | None = None,
    forces: ForceSet | None = None,
) -> ChaosResult:
    """Integrate the bodies and their tangent vector for ``steps`` steps of ``dt`` (from ``resume``'s
    state when given), sampling MEGNO and mLCE every ``every`` steps (and at the last step).
    ``forces`` (a :class:`~orbitsim.forces.table.ForceSet` for the N bodies) act on the bodies and,
    through their derivatives (:mod:`orbitsim.forces.tangent`), on the tangent vector.

    Raises ValueError, one line, for a scheme, settings or a force without variational equations, a
    bad variation, or bad numbers.
    """
    from orbitsim.integrators.registry import chaos_refusal, get_integrator  # noqa: PLC0415 - lazy: loads numba
    from orbitsim.physics.diagnostics import potential_rows_scratch  # noqa: PLC0415 - lazy: loads numba
    from orbitsim.physics.force_context import accelerations_at, make_force  # noqa: PLC0415 - lazy: loads numba
    from orbitsim.results import SampleBuffers  # noqa: PLC0415 - lazy: loads numba

    why = chaos_refusal(integrator, settings, () if forces is None else forces.names)
    if why is not None:
        raise ValueError(why)
    if not (math.isfinite(dt) and dt != 0.0) or int(steps) != steps or steps < 0 or every < 1:
        raise ValueError(f"dt must be finite and non-zero, steps >= 0 and every >= 1; got {dt}, {steps}, {every}")
    record = get_integrator(integrator)
    m = np.ascontiguousarray(masses, dtype=np.float64).reshape(-1)
    n = m.shape[0]
    record.check_bodies(m)
    if resume is None:
        pos = np.array(np.asarray(positions, dtype=np.float64).T, order="C")
        vel = np.array(np.asarray(velocities, dtype=np.float64).T, order="C")
        tangent = record.make_tangent(*_variation(variation, seed, n))
        sums, n_done = megno_start(t0), 0
    else:
        pos, vel = resume.positions.copy(), resume.velocities.copy()
        tangent = (record.make_tangent(resume.dpos, resume.dvel, resume.halvings) if resume.tangent is None
                   else _copied(resume.tangent))
        sums, n_done = resume.sums, resume.steps_done
    if pos.shape != (3, n) or vel.shape != (3, n):
        raise ValueError(f"positions and velocities must have shape ({n}, 3)")
    force = make_force(G, softening, n)
    if forces is not None and forces.ids.shape[0] > 0:
        from orbitsim.forces.hooks import forced_context  # noqa: PLC0415 - lazy: loads numba

        if forces.per_body.shape[2] != n:
            raise ValueError(f"forces are for {forces.per_body.shape[2]} bodies, the run has {n}")
        force = forced_context(force, forces, n)
    work = record.make_work(m, G, settings)
    acc = np.zeros((3, n))
    accelerations_at(force, pos, m, acc)
    if resume is not None and resume.work is not None:
        work = _copied(resume.work)  # what the scheme carries from step to step: ias15's clock and polynomials
    last = n_done + int(steps)
    targets = np.unique(np.append(np.arange(n_done, last + 1, every, dtype=np.int64), last))
    if resume is not None:
        targets = targets[targets > n_done]
    buffers = SampleBuffers(targets.shape[0], n, False)
    indicators = np.zeros((targets.shape[0], 2))
    written, n_end, finite, sums = record.run_chaos(
        (pos, vel, acc, m), tangent, force, float(dt), work, float(t0), np.int64(n_done), targets,
        np.ones(targets.shape[0], dtype=np.bool_), buffers.views(potential_rows_scratch(n)), indicators, sums)
    k = int(written)
    return ChaosResult(buffers.times[:k].copy(), indicators[:k, 0].copy(), indicators[:k, 1].copy(), pos, vel,
                       tangent.dpos, tangent.dvel, int(tangent.halvings[0]), sums, int(n_end), bool(finite), tangent,
                       work)
