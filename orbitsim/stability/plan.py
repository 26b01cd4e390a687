"""What a map computes: the scenario, its axes, the time span and the start state of every pixel.

:func:`make_plan` checks, once and before anything is written, that an ensemble kernel can run the
scenario (the Wisdom-Holman map in Jacobi coordinates without correctors, or velocity Verlet or a
leapfrog order with at most :data:`~orbitsim.physics.gravity.SMALL_N_MAX` bodies; no forces or
softening) and that every pixel's start state is valid; a :class:`MapPlan` then gives any chunk of pixels its
start states (:func:`chunk_states`) and runs it (:func:`run_chunk`) wherever it is sent. The plan's
:func:`fingerprint` names what the pixels depend on, so a resumed map only reuses chunks of the
same map.
"""

from __future__ import annotations

import copy
import functools
import hashlib
import itertools
import json
import math
from typing import Any, NamedTuple

import numpy as np

from orbitsim.stability.axes import Axis, MapSpecError

__all__ = ["INDICATORS", "ChunkResult", "MapPlan", "PixelStates", "chunk_states", "fingerprint", "make_plan",
           "ready_kernels", "run_chunk"]

#: The indicators a map computes, all in one pass (the ``--indicator`` names).
INDICATORS = ("megno", "lyapunov_time", "survival_time", "max_e", "delta_a", "energy_error")
#: Default escape distance: this many times the largest start distance from body 0 over the map.
ESCAPE_FACTOR = 10.0


class PixelStates(NamedTuple):
    """Start states of consecutive pixels: masses (P, N), positions and velocities (P, 3, N)."""

    masses: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray


class MapPlan(NamedTuple):
    """Everything a chunk needs (plain data: it travels to a Dask worker as it is, without ``states``)."""

    doc: dict[str, Any]  #: the scenario document the pixels edit
    names: tuple[str, ...]
    axes: tuple[Axis, ...]  #: x, then y if given
    G: float
    dt: float
    t_start: float
    n_steps: int
    escape_distance: float
    watch: int  #: the body whose a and e the indicators follow (the x axis's body)
    radii: np.ndarray | None  #: (N,) or None: no collision check
    barycentric: bool
    chunk: int  #: pixels per chunk
    seed: int  #: seed of every pixel's initial variation (orbitsim.chaos.megno.random_initial_variation)
    #: the scheme (a name of orbitsim.ensemble.status.SCHEMES); the scenario document in ``doc`` names it
    #: too, so the fingerprint, which hashes ``doc``, already tells maps of two schemes apart
    integrator: str = "wisdom_holman"
    device: str = "cpu"  #: "cpu": orbitsim.ensemble; "gpu": orbitsim.gpu.ensemble (one CUDA thread a pixel)
    #: every pixel's start state, built once by :func:`make_plan` (None: each chunk builds its own, as a
    #: Dask task's plan does, which is sent without them); derived from the fields above, so not fingerprinted
    states: PixelStates | None = None

    @property
    def shape(self) -> tuple[int, int]:
        """(ny, nx) of the grids; ny = 1 for a one-axis map."""
        nx = len(self.axes[0].values)
        return (len(self.axes[1].values) if len(self.axes) > 1 else 1, nx)

    @property
    def n_pixels(self) -> int:
        ny, nx = self.shape
        return ny * nx

    @property
    def n_chunks(self) -> int:
        return -(-self.n_pixels // self.chunk)


class ChunkResult(NamedTuple):
    """One chunk's pixels, in pixel order (row-major over (y, x))."""

    index: int
    status: np.ndarray  #: int64 (P,)
    stop_time: np.ndarray  #: (P,)
    indicators: np.ndarray  #: (P, len(INDICATORS))
    seconds: float  #: wall time of the kernel call


def _pixel_values(plan: MapPlan, pixel: int) -> list[float]:
    _ny, nx = plan.shape
    iy, ix = divmod(pixel, nx)
    values = [float(plan.axes[0].values[ix])]
    if len(plan.axes) > 1:
        values.append(float(plan.axes[1].values[iy]))
    return values


class _PixelReader:
    """Reads pixels' start states as the scenario reads its bodies, the bodies before the first varied one
    read once (:func:`~orbitsim.scenario.bodies.read_body_prefix`): a pixel rereads only the varied bodies
    and those after them (which may depend on them): 0.12 ms a pixel of the bundled map before, 0.07 ms after."""

    def __init__(self, plan: MapPlan) -> None:
        from orbitsim.scenario.bodies import read_body_prefix  # noqa: PLC0415 - lazy: loads numba
        from orbitsim.scenario.fields import Fields  # noqa: PLC0415 - lazy: as above
        from orbitsim.scenario.loader import TOP_KEYS  # noqa: PLC0415 - lazy: as above

        self.plan = plan
        self.units = str(plan.doc.get("units", "nbody")).lower()
        self.first = min(axis.index for axis in plan.axes)
        self.fields = functools.partial(Fields, path="", allowed=TOP_KEYS, what="scenario")
        self.prefix = read_body_prefix(self.fields(plan.doc), plan.G, self.units, self.first)

    def state(self, pixel: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Masses (N,), positions and velocities (3, N) of one pixel."""
        from orbitsim.scenario.bodies import read_bodies, shift_to_barycentre  # noqa: PLC0415 - lazy: as above

        plan = self.plan
        doc = dict(plan.doc)
        bodies = list(doc["bodies"])
        for i in range(self.first, len(bodies)):  # the bodies read again get copies to edit
            bodies[i] = dict(bodies[i]) if isinstance(bodies[i], dict) else bodies[i]
        for axis, value in zip(plan.axes, _pixel_values(plan, pixel), strict=True):
            axis.apply(bodies[axis.index], value)
        doc["bodies"] = bodies
        read = read_bodies(self.fields(doc), plan.G, self.units, start=self.prefix)
        m, x, v = read.arrays()
        if plan.barycentric:
            x, v = shift_to_barycentre(m, x, v)
        return m, np.ascontiguousarray(x.T), np.ascontiguousarray(v.T)


def _stack(states: list[tuple[np.ndarray, np.ndarray, np.ndarray]]) -> PixelStates:
    return PixelStates(*(np.stack([s[part] for s in states]) for part in range(3)))


def chunk_states(plan: MapPlan, index: int) -> PixelStates:
    """(P, N) masses and (P, 3, N) positions and velocities of chunk ``index``'s pixels: a slice of the
    plan's ``states`` where it has them, else built here by a :class:`_PixelReader` (the same bits either way)."""
    first = index * plan.chunk
    last = min(first + plan.chunk, plan.n_pixels)
    if plan.states is None:
        reader = _PixelReader(plan)
        return _stack([reader.state(p) for p in range(first, last)])
    return PixelStates(*(a[first:last] for a in plan.states))


def without_states(plan: MapPlan) -> MapPlan:
    """The plan as a Dask task receives it: its chunk's start states travel beside it, not all of them."""
    return plan._replace(states=None)


def run_chunk(plan: MapPlan, index: int, states: PixelStates | None = None) -> ChunkResult:
    """Run chunk ``index`` of the map in one ensemble call (any process: a Dask worker too), from the
    chunk's start ``states`` (default :func:`chunk_states`)."""
    import time  # noqa: PLC0415 - lazy: kept beside its one use

    from orbitsim.ensemble.status import (  # noqa: PLC0415 - lazy: loads numba
        DELTA_A,
        ENERGY_ERROR,
        LYAPUNOV,
        MAX_E,
        MEGNO,
        SURVIVAL_TIME,
    )

    m, x, v = chunk_states(plan, index) if states is None else states
    started = time.perf_counter()
    result = _run_pixels(plan, m, x, v, plan.n_steps)
    seconds = time.perf_counter() - started
    cols = result.indicators
    with np.errstate(divide="ignore", invalid="ignore"):
        lyapunov_time = np.where(cols[:, LYAPUNOV] > 0.0, 1.0 / cols[:, LYAPUNOV], np.inf)
    lyapunov_time = np.where(np.isnan(cols[:, LYAPUNOV]), np.nan, lyapunov_time)
    table = np.column_stack([cols[:, MEGNO], lyapunov_time, cols[:, SURVIVAL_TIME], cols[:, MAX_E],
                             cols[:, DELTA_A], cols[:, ENERGY_ERROR]])
    return ChunkResult(index, result.status, cols[:, SURVIVAL_TIME].copy(), table, seconds)


def ready_kernels(plan: MapPlan) -> None:
    """Make the kernels this map's chunks call ready in this process: loaded from Numba's cache, or compiled
    on a first run. Chunk 0's pixels run for no step, which takes the chunks' own path through
    :func:`~orbitsim.ensemble.run_ensemble` (the same kernel choice, the same argument types) and changes
    nothing: the plan's start states are copied, never written."""
    m, x, v = chunk_states(plan, 0)
    _run_pixels(plan, m, x, v, 0)


def _run_pixels(plan: MapPlan, m: np.ndarray, x: np.ndarray, v: np.ndarray, n_steps: int) -> Any:
    """``n_steps`` steps of the pixels with start states ``m``, ``x``, ``v`` (and the map's initial variation)
    in one ensemble call on the plan's device; its :class:`~orbitsim.ensemble.run.EnsembleResult`."""
    from orbitsim.chaos.megno import random_initial_variation  # noqa: PLC0415 - lazy: loads numba
    from orbitsim.ensemble import run_ensemble  # noqa: PLC0415 - lazy: as above

    radii = None if plan.radii is None else np.tile(plan.radii, (m.shape[0], 1))
    dpos, dvel = random_initial_variation(m.shape[1], plan.seed)
    variation = (np.tile(dpos, (m.shape[0], 1, 1)), np.tile(dvel, (m.shape[0], 1, 1)))
    run = functools.partial(run_ensemble, integrator=plan.integrator)
    if plan.device == "gpu":  # make_plan let only the GPU's schemes with variational equations through
        from orbitsim.gpu.ensemble import run_ensemble_gpu  # noqa: PLC0415 - lazy: loads numba-cuda

        run = functools.partial(run_ensemble_gpu, scheme=plan.integrator)
    return run(m, x, v, G=plan.G, dt=plan.dt, n_steps=n_steps, t_start=plan.t_start,
               escape_distance=plan.escape_distance, radii=radii, watch=plan.watch, variation=variation)


def fingerprint(plan: MapPlan) -> str:
    """SHA-256 of everything the pixels' bits depend on (not the chunk size: a pixel's bits do not).

    The device is among them where it is the GPU (its pixels agree with the CPU's to round-off, not bit
    for bit), so a CPU map is never finished on the GPU or the other way round; a CPU map's fingerprint
    is what it was before the GPU existed."""
    record = {
        "doc": plan.doc, "axes": [(a.body, a.key, a.values.tolist(), a.log) for a in plan.axes], "G": plan.G,
        "dt": plan.dt, "t_start": plan.t_start, "n_steps": plan.n_steps, "escape": plan.escape_distance,
        "watch": plan.watch, "radii": None if plan.radii is None else plan.radii.tolist(),
        "barycentric": plan.barycentric, "seed": plan.seed,
    }
    if plan.device != "cpu":
        record["device"] = plan.device
    return hashlib.sha256(json.dumps(record, sort_keys=True, default=str).encode()).hexdigest()


#: Pixels a process reads at least: below 2 x this a map's start states are read in one process (a pool of forked
#: readers starts in ~50 ms, the time of ~1,000 pixels).
PIXELS_PER_READER = 4000


class _PixelsRead(NamedTuple):
    """The start states of pixels ``first .. last - 1`` (:func:`_read_pixels`), or the first one the scenario
    reader rejected."""

    states: PixelStates | None
    farthest: float  #: the largest start distance of a body from body 0 among them
    bad: tuple[int, str, str] | None  #: (pixel, reason, key) of the first rejected pixel


def _read_pixels(plan: MapPlan, first: int, last: int) -> _PixelsRead:
    """Read pixels ``first .. last - 1`` (in any process: a pool's forked reader too), stopping at the first one
    the scenario reader rejects."""
    from orbitsim.scenario.errors import ScenarioError  # noqa: PLC0415 - lazy: loads numba

    reader = _PixelReader(plan)
    states = []
    for pixel in range(first, last):
        try:
            states.append(reader.state(pixel))
        except ScenarioError as err:
            return _PixelsRead(None, 0.0, (pixel, err.reason, str(err.key)))
    read = _stack(states)
    x = read.positions
    farthest = float(np.max(np.sqrt(np.sum((x - x[:, :, :1]) ** 2, axis=1)))) if len(states) else 0.0
    return _PixelsRead(read, farthest, None)


def _state_workers(n_pixels: int) -> int:
    """Processes to read ``n_pixels`` start states in: this process's CPUs, at least
    :data:`PIXELS_PER_READER` pixels each; 1 where processes cannot be forked."""
    import multiprocessing  # noqa: PLC0415 - lazy: only large maps start processes
    import os  # noqa: PLC0415 - lazy: as above

    if "fork" not in multiprocessing.get_all_start_methods():
        return 1
    return max(1, min(len(os.sched_getaffinity(0)), n_pixels // PIXELS_PER_READER))


def _read_in_parallel(plan: MapPlan, workers: int) -> list[_PixelsRead]:
    """:func:`_read_pixels` over the whole map in ``workers`` forked processes, four ranges each (pixels differ
    in cost: a hyperbola's anomaly is solved differently), in pixel order. The readers run the scenario
    reader alone: no Numba kernel, so the parent's kernel threads, which a fork does not copy, are not missed."""
    import multiprocessing  # noqa: PLC0415 - lazy: only large maps start processes

    bounds = np.linspace(0, plan.n_pixels, 4 * workers + 1).astype(np.int64)
    light = without_states(plan)
    ranges = [(light, int(a), int(b)) for a, b in itertools.pairwise(bounds) if b > a]
    with multiprocessing.get_context("fork").Pool(workers) as pool:
        return pool.starmap(_read_pixels, ranges)


def make_plan(scenario: Any, doc: dict[str, Any], axes: list[Axis], t_end: float,
              escape_distance: float | None, chunk: int, seed: int = 0, device: str = "cpu",
              workers: int | None = None) -> MapPlan:
    """Check that the ensemble can run ``scenario`` over ``axes`` up to ``t_end``; raise :class:`MapSpecError`.

    Every pixel's start state is built here once, so a pixel the scenario reader rejects (``e = 1.2``
    with ``a > 0``) is reported before anything is written; the plan keeps them (``states``) for the
    chunks (building them twice cost 3.7 s of a 200 x 200 map). A large map reads them in ``workers``
    processes (default :func:`_state_workers`), the same bits as one process reads them.
    """
    from orbitsim.ensemble.status import SCHEMES  # noqa: PLC0415 - lazy: beside its use
    from orbitsim.integrators.registry import canonical_name  # noqa: PLC0415 - lazy: loads numba
    from orbitsim.physics.gravity import SMALL_N_MAX  # noqa: PLC0415 - lazy: as above

    name = canonical_name(scenario.integrator)
    if name not in SCHEMES:
        raise MapSpecError(f"integrator {name!r}: a map runs an ensemble kernel, which exists for "
                           f"{', '.join(SCHEMES)} only (leapfrog4/6/8 are {{name: leapfrog, order: 4/6/8}})")
    if device == "gpu" and name != "wisdom_holman":
        raise MapSpecError(f"integrator {name!r}: a map on the GPU runs wisdom_holman only (its GPU kernel carries "
                           f"the variational equations, for MEGNO); run this map without --device gpu")
    settings = dict(scenario.integrator_settings or {})
    if settings.get("coordinates", "jacobi") != "jacobi" or int(settings.get("corrector", 0) or 0) != 0:
        raise MapSpecError("integrator settings: the ensemble's Wisdom-Holman map is Jacobi coordinates without "
                           "a corrector; remove coordinates/corrector from the scenario")
    if name != "wisdom_holman" and len(scenario.names) > SMALL_N_MAX:
        raise MapSpecError(f"bodies: the {name} ensemble takes at most {SMALL_N_MAX} bodies per system (one all-pairs "
                           f"force kernel per pixel); the scenario has {len(scenario.names)}")
    if scenario.softening != 0.0:
        raise MapSpecError("softening: the ensemble kernel integrates unsoftened gravity; set softening: 0")
    if scenario.forces:
        raise MapSpecError("forces: the ensemble kernel integrates gravity alone; remove the forces section")
    if scenario.events is not None:  # never silently ignored: a pixel's own stops are not the section's
        raise MapSpecError("events: a map stops each pixel at its own escape (--escape-distance) or collision (the "
                           "bodies' radii), not as an events section says; remove the events section")
    if scenario.dt <= 0.0:
        raise MapSpecError(f"dt = {scenario.dt:g}: a map steps forward in time (dt > 0)")
    if not t_end > scenario.t_start:
        raise MapSpecError(f"--t-end {t_end:g}: must be after the scenario's t_start ({scenario.t_start:g})")
    n_steps = math.ceil((t_end - scenario.t_start) / scenario.dt - 1e-9)  # 1e-9: a whole number of steps
    if len(axes) > 1 and axes[0].body == axes[1].body and axes[0].key == axes[1].key:
        raise MapSpecError(f"--x and --y both vary {axes[0].body}.{axes[0].key}")
    watch = axes[0].index
    if watch == 0:
        raise MapSpecError(f"--x {axes[0].body}: the central body has no orbit to follow; vary a planet")
    plan = MapPlan(copy.deepcopy(doc), tuple(scenario.names), tuple(axes), float(scenario.G), float(scenario.dt),
                   float(scenario.t_start), n_steps, math.inf, watch,
                   None if scenario.radii is None else np.asarray(scenario.radii, dtype=np.float64),
                   scenario.frame == "barycentric", int(chunk), int(seed), name, device)
    if len(plan.names) != len(doc["bodies"]):
        raise MapSpecError("a map needs every body in the scenario's bodies list (no ephemeris or generator)")
    n_workers = _state_workers(plan.n_pixels) if workers is None else workers
    reads = _read_in_parallel(plan, n_workers) if n_workers > 1 else [_read_pixels(plan, 0, plan.n_pixels)]
    for read in reads:  # in pixel order: the bad pixel reported is the first, as a serial read meets it
        if read.bad is not None:
            pixel, reason, key = read.bad
            values = ", ".join(f"{a.body}.{a.key}={v:g}" for a, v in zip(axes, _pixel_values(plan, pixel),
                                                                         strict=True))
            raise MapSpecError(f"pixel {values}: {reason} (key {key})")
    states = PixelStates(*(np.concatenate([getattr(read.states, part) for read in reads])
                           for part in PixelStates._fields))
    farthest = max(read.farthest for read in reads)
    escape = ESCAPE_FACTOR * farthest if escape_distance is None else float(escape_distance)
    return plan._replace(escape_distance=escape, states=states)
