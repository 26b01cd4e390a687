"""The integrator record every scheme declares, and the loops and pieces the schemes share.

Each scheme is one :class:`Integrator` record (``VERLET``, ``IAS15``, ...; the registry,
:mod:`orbitsim.integrators.registry`, lists them), with every hook the engine calls declared in
it and a default where a scheme has nothing to say. Callers use the record's fields, never
``getattr`` on a module. In order:

1. ``spec``: an :class:`IntegratorSpec` (name, aliases, order, symplecticity, reversibility, force
   evaluations per step, scratch slots, citation).
2. ``step(pos, vel, acc, m, force, dt, work)``: one whole step of size ``dt``, in place.
   ``pos``, ``vel``, ``acc`` are ``(3, N)``; ``m`` is ``(N,)``; ``force`` is the force context
   of :func:`orbitsim.physics.force_context.make_force` (a run's forces in its ``forces`` field); ``work``
   is what ``make_work`` made. On entry ``acc`` holds the accelerations at ``pos``; on exit it
   holds those at the new ``pos`` when ``spec.fsal`` is true (first-same-as-last: kick-drift-kick
   schemes reuse the last force evaluation), otherwise whatever the scheme last evaluated.
3. ``run(state, force, dt, work, t0, n_done, targets, record, out)``: the loop of a run. For each
   ``k`` it takes whole steps until the step count reaches ``targets[k]`` and, when ``record[k]``,
   writes a sample with :func:`record_sample`. Returns ``(samples_written, n_done, finite)``; it
   stops early, with ``finite`` false, at the first sample whose state is not finite or when the
   scheme fails (a Kepler solve, a Bulirsch-Stoer sub-step). A step is never shortened: sample
   times fall on whole steps (an adaptive scheme's "step" is its output grid, ias15).
4. ``run_watched(..., out, watch)``: ``run`` with the events check after every step
   (:mod:`orbitsim.events`); a fourth result, True when the call stopped for the Python side.
5. ``settings``: what a scenario may give (``integrator: {name: ..., <key>: <value>}``), key ->
   :class:`Setting` (default, doc string, allowed values); empty for a scheme that takes none.
6. ``validate_settings(settings) -> dict``: the settings checked, normalised and with every
   default filled in; raises ValueError naming the key. Default: accepts none.
7. ``make_work(m, G, settings) -> work``: the scheme's state and scratch beside ``pos``/``vel``.
   Default: ``spec.work_slots`` scratch arrays, ``(work_slots, 3, N)``.
8. ``carry_over(old_work, new_work)``: what the scheme keeps when the bodies change (a merge, a
   removal) and ``work`` is made afresh. Default: nothing.
9. ``check_bodies(m)``: the scheme's demands on the masses (a central body); raises ValueError.
   Default: none.
10. ``clock_time(work, grid_time) -> float``: the time of the state, for a scheme that keeps its
    own clock. Default: the grid time ``t0 + n dt``.
11. ``failure_message(work) -> str | None``: why the run stopped, when the scheme knows. Default: None.
12. ``counters(work) -> dict | None``: the scheme's own counts (accepted steps, ...), written to
    the trace's attributes. Default: None (a fixed-step scheme counts nothing but steps).
13. ``take_merges(work) -> (rows, radii) | None``: the merges the scheme made inside its last step
    (TRACE's Bulirsch-Stoer sub-steps), for :mod:`orbitsim.events.driver`. Default: None.
14. ``handoff(work) -> (pairs, bodies, flags) | None``: what the last step integrated with its own
    sub-steps, for the events' unresolved-step check. Default: None.
15. ``run_constants``: indices of ``work`` entries a restored checkpoint does not override (the
    run's own end time). Default: none.
16. ``kicks``, ``drifts``: the coefficient tables of a drift-kick-drift composition. Default: None.
17. ``run_chaos(state, tangent, force, dt, work, t0, n_done, targets, record, out, indicators, megno)``:
    ``run`` with the first-order variational (tangent) equations stepped beside the bodies by the
    scheme's own operators and MEGNO's sums read after every step (:mod:`orbitsim.chaos`):
    :func:`chaos_sample_loop` around the scheme's ``advance_chaos``. ``tangent`` is a
    :class:`Tangent`, ``megno`` a :class:`~orbitsim.chaos.megno.MegnoState`; each sample also writes
    ``indicators[r] = (MEGNO, mLCE)``. Returns ``(samples_written, n_done, finite, megno)``.
    Default: None, a scheme without variational equations (:func:`chaos_schemes` lists the others).
18. ``check_chaos(settings) -> str | None``: why these settings have no variational equations (one
    line), or None. Default: None (every setting has them).
19. ``make_tangent(dpos, dvel, halvings=0) -> tangent``: the scheme's tangent record for ``run_chaos``,
    holding copies of the (3, N) tangent vector; whatever its type, it has ``dpos``, ``dvel`` and
    ``halvings`` (int64 (1,)) as :class:`Tangent` has. Default: :func:`make_tangent`. ias15's carries
    its tangent polynomial beside them (:class:`~orbitsim.integrators.ias15.tangent.IAS15Tangent`).

One loop, each scheme's own steps
---------------------------------
Every scheme writes the steps between two samples once, as an ``advance``:

    advance(pos, vel, acc, m, force, dt, work, t0, n_done, n_to) -> (n_done, ok)

takes the steps from ``n_done`` to ``n_to`` in place and returns the step count it reached and
False when the scheme failed. Its ``run`` is :func:`sample_loop` around it, and its ``run_watched``
:func:`orbitsim.events.kernels.watched_run` around it (one step per call, the events check after
each); ``step`` is one step of it. ias15 and trace, which take sub-steps of their own inside a
step, watch those inside their own ``advance`` and keep their own watched loops.

Both loops are inlined (:func:`orbitsim._jit.jit_inline`) into each scheme's cached ``@jit run``,
which hands them its ``advance`` as an argument. That caches fully: Numba resolves the argument
when the scheme's ``run`` is compiled, and the cache entry is that ``run``'s. (What never hits the
on-disk cache is a jitted function passed *from Python* to a jitted one, or a closure built by a
factory: one ``run`` per scheme, each naming its own ``advance``, is what keeps every scheme in
the cache.) A single switch over every scheme would compile all of them on a user's first run.

Forces reach every scheme through the hooks of :mod:`orbitsim.forces.hooks`, which compile to
nothing for a force context without forces: position-only forces join gravity in each force
evaluation, velocity-dependent ones are the equations of motion of euler, rk4 and ias15 and an
operator around each step of the symplectic schemes. Each ``advance`` unpacks what it needs once
and calls the force kernels from its own loop body (:mod:`orbitsim.physics.gravity` says why).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np

from orbitsim._jit import jit, jit_inline
from orbitsim.chaos.megno import lyapunov, megno_value
from orbitsim.forces.hooks import record_force_energy
from orbitsim.physics.diagnostics import angular_momentum_into, kinetic_energy, momentum_into, potential_of

#: Columns of the ``scalars`` sample buffer.
SCALAR_COLUMNS = ("kinetic", "potential", "px", "py", "pz", "lx", "ly", "lz")


@dataclass(frozen=True)
class IntegratorSpec:
    """Metadata of one fixed-step scheme; the registry holds one per integrator module."""

    name: str
    aliases: tuple[str, ...]
    order: int
    symplectic: bool
    reversible: bool
    force_evals: int
    work_slots: int
    fsal: bool
    summary: str
    reference: str
    module: str
    adaptive: bool = False  # chooses its own steps: ``dt`` is then the output grid (see ias15)

    @property
    def names(self) -> tuple[str, ...]:
        """The name followed by its aliases."""
        return (self.name, *self.aliases)


@dataclass(frozen=True)
class Setting:
    """One setting a scenario may give a scheme (``integrator: {name: ias15, epsilon: 1e-10}``).

    ``default`` is what the run uses when the scenario does not give it; ``doc`` says what it
    does, in one line (``orbitsim list integrators --settings`` prints it); ``choices`` are the
    values allowed when the setting is one of a list (the scheme's ``validate_settings`` has the
    last word on values either way).
    """

    default: Any
    doc: str
    choices: tuple[Any, ...] = ()


def setting_defaults(settings: Mapping[str, Setting]) -> dict[str, Any]:
    """Every setting's default, in the scheme's order."""
    return {key: setting.default for key, setting in settings.items()}


def accept_no_settings(settings: Mapping[str, Any] | None) -> dict[str, Any]:
    """The ``validate_settings`` of a scheme without settings: none but ``name`` (the integrator's
    name in a scenario mapping) is accepted. Raises ValueError naming the first other key."""
    given = sorted(key for key in (settings or {}) if key != "name")
    if given:
        raise ValueError(f"this integrator takes no settings, got {given[0]!r}")
    return {}


def _no_carry_over(old_work: Any, new_work: Any) -> None:
    """Nothing to keep across a change of bodies."""


def _any_bodies(m: np.ndarray) -> None:
    """No demands on the masses."""


def _grid_clock(work: Any, grid_time: float) -> float:
    """The time of the state is the grid's, ``t0 + n dt``."""
    return grid_time


def _chaos_everywhere(settings: Mapping[str, Any]) -> None:
    """Every setting of the scheme has variational equations."""
    return None


def _nothing(work: Any) -> None:
    """The scheme has nothing to report (no failure detail, counters, in-step merges or handoff)."""
    return None


@dataclass(frozen=True, eq=False)
class Integrator:
    """One scheme: its metadata, its jitted entry points and every hook the engine calls
    (the numbered contract is in this module's docstring). Hooks left out get the defaults.
    Each record is one object, compared by identity (its tables are arrays)."""

    spec: IntegratorSpec
    step: Callable[..., Any]
    run: Callable[..., Any]
    run_watched: Callable[..., Any]
    settings: Mapping[str, Setting] = field(default_factory=dict)
    validate_settings: Callable[[Mapping[str, Any] | None], dict[str, Any]] = accept_no_settings
    make_work: Callable[..., Any] | None = None  # None: spec.work_slots scratch arrays (filled in below)
    carry_over: Callable[[Any, Any], None] = _no_carry_over
    check_bodies: Callable[[np.ndarray], None] = _any_bodies
    clock_time: Callable[[Any, float], float] = _grid_clock
    failure_message: Callable[[Any], str | None] = _nothing
    counters: Callable[[Any], dict[str, Any] | None] = _nothing
    take_merges: Callable[[Any], tuple[np.ndarray, np.ndarray] | None] = _nothing
    handoff: Callable[[Any], tuple[np.ndarray, np.ndarray, int] | None] = _nothing
    run_constants: tuple[int, ...] = ()
    kicks: np.ndarray | None = None
    drifts: np.ndarray | None = None
    run_chaos: Callable[..., Any] | None = None
    check_chaos: Callable[[Mapping[str, Any]], str | None] = _chaos_everywhere
    make_tangent: Callable[..., Any] | None = None  # None: the shared Tangent (filled in below)

    def default_settings(self) -> dict[str, Any]:
        """Every setting's default, in the scheme's order (empty for a scheme without settings)."""
        return setting_defaults(self.settings)

    def __post_init__(self) -> None:
        if self.make_work is None:
            object.__setattr__(self, "make_work", _ScratchWork(self.spec.work_slots))
        if self.make_tangent is None:
            object.__setattr__(self, "make_tangent", make_tangent)
        if (self.kicks is None) != (self.drifts is None):
            raise ValueError(f"{self.spec.name}: a composition declares both kicks and drifts")


@dataclass(frozen=True)
class _ScratchWork:
    """The default ``make_work``: ``slots`` scratch arrays of shape (3, N), as one (slots, 3, N) array."""

    slots: int

    def __call__(self, m: np.ndarray, G: float, settings: Mapping[str, Any] | None = None) -> np.ndarray:
        return np.zeros((self.slots, 3, np.asarray(m).shape[0]))


@jit_inline
def drift(pos, vel, h):
    """x <- x + h v, in place."""
    for c in range(3):
        for i in range(pos.shape[1]):
            pos[c, i] += h * vel[c, i]


@jit_inline
def kick(vel, acc, h):
    """v <- v + h a, in place."""
    for c in range(3):
        for i in range(vel.shape[1]):
            vel[c, i] += h * acc[c, i]


@jit_inline
def kick_drift(pos, vel, acc, h_kick, h_drift):
    """v <- v + h_kick a, then x <- x + h_drift v with the new v: :func:`kick` then :func:`drift`
    in one pass, with the same arithmetic (each element's update is independent), so the same
    bits, and one loop's loads and stores fewer (6% of a 5-body step)."""
    for c in range(3):
        for i in range(pos.shape[1]):
            v_new = vel[c, i] + h_kick * acc[c, i]
            vel[c, i] = v_new
            pos[c, i] += h_drift * v_new


@jit
def is_finite_state(pos, vel):
    """True when every coordinate and velocity component is finite."""
    for c in range(3):
        for i in range(pos.shape[1]):
            if not (np.isfinite(pos[c, i]) and np.isfinite(vel[c, i])):
                return False
    return True


@jit
def record_sample(r, n_done, time, pos, vel, m, force, out):
    """Write sample ``r`` (time, step, energies, momenta, optionally the state) into ``out``.

    ``out`` is ``(times, steps, scalars, snapshots, rows)``: ``scalars`` (S, 8) in the order of
    :data:`SCALAR_COLUMNS`, ``snapshots`` (S, 2, 3, N) or empty when the state is not recorded,
    ``rows`` scratch for the potential. Returns False, writing nothing, if the state is not finite.

    The kinetic energy and momenta are inlined here (``jit_inline``): compiled apart, each was a library
    of its own that a first run compiled, wrapped and linked (0.3-0.4 s of every scheme's first run); a
    sample's arithmetic is the same either way. The finite check stays a function of its own: IAS15's
    step calls it too, and inlined there twice it cost that first run more than it saved here.
    """
    if not is_finite_state(pos, vel):
        return False
    times, steps, scalars, snapshots, rows = out
    times[r] = time
    steps[r] = n_done
    scalars[r, 0] = kinetic_energy(vel, m)
    scalars[r, 1] = potential_of(force, pos, m, rows)
    record_force_energy(force, pos, vel, m, scalars, r)  # a forced run's potential includes the forces'
    momentum_into(vel, m, scalars[r, 2:5])
    angular_momentum_into(pos, vel, m, scalars[r, 5:8])
    if snapshots.shape[0] > 0:
        # Element loops, not ``snapshots[r, 0] = pos``: Numba's slice assignment builds views and
        # checks broadcasting, ~1 us a sample at N = 9, a third of a 100-step stretch's overhead.
        for c in range(3):
            for i in range(pos.shape[1]):
                snapshots[r, 0, c, i] = pos[c, i]
                snapshots[r, 1, c, i] = vel[c, i]
    return True


@jit_inline
def grid_time(work, t0, n_done, dt):
    """The time of step ``n_done`` on the run's grid, ``t0 + n dt``: the sample time of every
    scheme that does not keep a clock of its own."""
    return t0 + n_done * dt


@jit_inline
def sample_loop(advance, sample_time, state, force, dt, work, t0, n_done, targets, record, out):
    """The ``run`` of every scheme: ``advance`` to each target, a sample where ``record`` says.

    ``advance`` is the scheme's (module docstring); ``sample_time(work, t0, n_done, dt)`` the time
    a sample is stamped with (:func:`grid_time`, or an adaptive scheme's clock). Returns
    ``(samples_written, n_done, finite)``: ``finite`` is False when the scheme failed or a sample's
    state was not finite, and the loop stops there.
    """
    pos, vel, acc, m = state
    written = np.int64(0)  # not the literal 0: record_sample would compile twice (for Literal[int](0) and int64)
    for k in range(targets.shape[0]):
        if n_done < targets[k]:
            n_done, ok = advance(pos, vel, acc, m, force, dt, work, t0, n_done, targets[k])
            if not ok:
                return written, n_done, False
        if record[k]:
            if not record_sample(written, n_done, sample_time(work, t0, n_done, dt), pos, vel, m, force, out):
                return written, n_done, False
            written += 1
    return written, n_done, True


#: Rows of a :class:`Tangent`'s scratch: enough for every scheme's variational step (Wisdom-Holman's
#: Jacobi copies, :data:`orbitsim.integrators.wisdom_holman.tangent.TANGENT_SCRATCH_ROWS`).
TANGENT_SCRATCH_ROWS = 8


class Tangent(NamedTuple):
    """The variational state of a run beside its bodies (contract item 17).

    ``dpos``, ``dvel`` (3, N): the tangent vector, in the bodies' (inertial) frame, synchronised with
    ``pos``/``vel`` between steps; ``dacc`` (3, N): its accelerations (scratch; a kick-drift-kick
    scheme keeps those at the current state in it); ``scratch`` (:data:`TANGENT_SCRATCH_ROWS`, 3, N);
    ``halvings`` int64 (1,): how many exact 2^-200 rescalings the tangent vector has had
    (:func:`orbitsim.chaos.megno.rescale_power_of_two`), so ln |delta| stays known.
    """

    dpos: np.ndarray
    dvel: np.ndarray
    dacc: np.ndarray
    scratch: np.ndarray
    halvings: np.ndarray


def make_tangent(dpos: np.ndarray, dvel: np.ndarray, halvings: int = 0) -> Tangent:
    """A :class:`Tangent` holding copies of the (3, N) tangent vector ``dpos``, ``dvel``."""
    dpos = np.array(dpos, dtype=np.float64, order="C")
    dvel = np.array(dvel, dtype=np.float64, order="C")
    if dpos.ndim != 2 or dpos.shape[0] != 3 or dvel.shape != dpos.shape:
        raise ValueError(f"a tangent vector is two (3, N) arrays, got {dpos.shape} and {dvel.shape}")
    n = dpos.shape[1]
    return Tangent(dpos, dvel, np.zeros((3, n)), np.zeros((TANGENT_SCRATCH_ROWS, 3, n)),
                   np.array([halvings], dtype=np.int64))


@jit_inline
def chaos_sample_loop(advance_chaos, sample_time, state, tangent, force, dt, work, t0, n_done, targets, record, out,
                      indicators, megno):
    """The ``run_chaos`` of every scheme with variational equations: :func:`sample_loop` with the
    tangent state and MEGNO's sums stepped by ``advance_chaos``, and (MEGNO, mLCE) at each sample.

    ``advance_chaos(pos, vel, acc, m, force, dt, work, t0, n_done, n_to, tangent, megno)`` takes the
    steps from ``n_done`` to ``n_to`` and returns ``(n_done, ok, megno)``. ``indicators`` (S, 2).
    Returns ``(samples_written, n_done, finite, megno)``.
    """
    pos, vel, acc, m = state
    written = np.int64(0)
    for k in range(targets.shape[0]):
        if n_done < targets[k]:
            n_done, ok, megno = advance_chaos(pos, vel, acc, m, force, dt, work, t0, n_done, targets[k], tangent, megno)
            if not ok:
                return written, n_done, False, megno
        if record[k]:
            time = sample_time(work, t0, n_done, dt)
            if not record_sample(written, n_done, time, pos, vel, m, force, out):
                return written, n_done, False, megno
            indicators[written, 0] = megno_value(megno, time)
            indicators[written, 1] = lyapunov(megno)
            written += 1
    return written, n_done, True, megno
