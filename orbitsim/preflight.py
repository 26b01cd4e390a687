"""The checks a run makes before its first step, in one place: ``orbitsim run`` and ``orbitsim validate``
both call them, so ``validate`` never says ok to what ``run`` refuses.

* :func:`check_initial_state`: the first sample must be finite. T, U, P and L of the initial state
  are what the run stores first; a product of masses, positions, velocities and G that overflows
  float64 (two bodies of ``m: 1e300``) would give E0 = -inf and every later |dE/E| = nan.
* :func:`check_overlaps`: no two bodies may overlap at the start (closer than r_i + r_j) unless
  ``events.collisions`` is set, which then logs and resolves them as a collision at step 0.
* :func:`check_disk`: the trace (:func:`trace_bytes`) must fit in the free space of its directory.
* the run's wall time, measured on this machine, is :mod:`orbitsim.estimate`'s.

Checks raise :class:`~orbitsim.scenario.ScenarioError` naming the file and the key to change; each
is cheap beside the run it guards (see each function for its cost).
"""

from __future__ import annotations

import functools
import math
import shutil
from pathlib import Path

import numpy as np

from orbitsim.io.schema import BODY_ARRAYS, SCALARS, VECTORS
from orbitsim.scenario import Scenario, ScenarioError

__all__ = ["check_disk", "check_initial_state", "check_overlaps", "format_bytes", "sample_count", "trace_bytes"]

#: Bytes of a trace per body whatever the samples: mass, name, the resolved scenario text (~250 bytes
#: a body) and the final state a complete trace keeps (48 bytes a body), rounded up.
TRACE_BYTES_PER_BODY = 400
#: Bytes of a trace whatever N: HDF5 metadata, attributes, provenance (generously).
TRACE_BYTES_FIXED = 32 * 2**10
#: Interval plans with more sample times than this are counted by an upper bound, not walked.
EXACT_COUNT_MAX_TIMES = 2**20
#: Unsoftened systems up to this N get their potential from numpy (0.5 MiB at 256), larger ones from
#: the run's jitted diagnostic (whose first call costs ~0.3 s of Numba start-up).
NUMPY_POTENTIAL_MAX_N = 256
#: A bound below this counts as safely finite (float64 overflows at 1.8e308; rounding is far smaller).
_SAFE = 1e300


def sample_count(scenario: Scenario) -> tuple[int, bool]:
    """Samples the run records, and whether that count is exact (else an upper bound).

    Interval plans are walked only up to :data:`EXACT_COUNT_MAX_TIMES` sample times: beyond that the
    count is ``min(sample times, steps + 1)``, which may count twice a step two sample times share.
    """
    plan = scenario.sample_plan()
    times = getattr(plan, "n_times", None)
    if times is None or times <= EXACT_COUNT_MAX_TIMES:
        return plan.count(), True
    return min(int(times), scenario.steps + 1) + 1, False  # + 1: the last step is always sampled


def trace_bytes(scenario: Scenario, samples: int | None = None) -> int:
    """Bytes the run needs on disk: its trace, twice over with ``output.checkpoint``.

    A sample stores the scalars ``time, step, kinetic, potential, energy, energy_error`` and the
    3-vectors ``momentum, angular_momentum`` (96 bytes), plus positions and velocities (48 N
    bytes) when recorded. Counted uncompressed, so an upper bound: the writer's gzip saved about
    half on the bundled scenarios' series. With checkpoints, the journal and the trace built from
    it coexist at the end of the run, hence twice.
    """
    n = scenario.n_bodies
    per_sample = 8 * (len(SCALARS) + 3 * len(VECTORS))
    if scenario.record_positions:
        per_sample += 8 * 3 * n * len(BODY_ARRAYS)
    count = sample_count(scenario)[0] if samples is None else samples
    need = per_sample * count + TRACE_BYTES_PER_BODY * n + TRACE_BYTES_FIXED
    return need * (2 if scenario.checkpoints else 1)


def format_bytes(nbytes: float) -> str:
    """``1536`` -> ``"1.5 KiB"``."""
    unit = 0
    while nbytes >= 1024 and unit < 4:
        nbytes, unit = nbytes / 1024, unit + 1
    return f"{nbytes:.3g} {('B', 'KiB', 'MiB', 'GiB', 'TiB')[unit]}"


def check_disk(scenario: Scenario, directory: Path | str, samples: int | None = None) -> int:
    """Refuse a run whose trace (:func:`trace_bytes`) would not fit in ``directory``'s free space.

    Returns
    -------
    int
        The estimated bytes.

    Raises
    ------
    ScenarioError
        Naming ``output.positions`` when states are recorded, else the sampling key.
    """
    need = trace_bytes(scenario, samples)
    try:
        free = shutil.disk_usage(directory).free
    except OSError:
        return need  # a missing or unreadable directory is the output checks' to report
    if need <= free:
        return need
    states = bool(scenario.record_positions)  # states are at least half of every sample from N = 2 on
    key = "output.positions" if states else ("output.interval" if scenario.interval is not None else "output.every")
    fix = "set positions: false or sample less often" if states else "sample less often"
    raise ScenarioError(f"the trace needs about {format_bytes(need)} but {directory} has {format_bytes(free)} free: "
                        f"{fix}", file=scenario.source, key=key)


# -- the initial state -----------------------------------------------------------------------------


def check_overlaps(scenario: Scenario) -> None:
    """Refuse bodies that overlap at the start (centres closer than r_i + r_j) when nothing watches
    for collisions.

    The events watch checks contacts after each step, never the state a run starts from, and a
    run without ``events.collisions`` checks none: a planet placed inside its star ran, was flung
    out to 15.8 au with |dE/E| = 10.5, and said nothing of the overlap. With ``events.collisions``
    the overlap is a collision at step 0, resolved by the scenario's rule
    (:meth:`orbitsim.events.driver.Watcher.contacts_at_start`). Cost: a sweep over the bodies
    sorted by x (:func:`orbitsim.events.overlap.overlapping_pairs`), nothing without radii.

    Raises
    ------
    ScenarioError
        Naming both bodies, their distance and r_i + r_j, keyed at the later body's entry.
    """
    events = scenario.events
    if scenario.radii is None or (events is not None and events.collisions is not None):
        return
    from orbitsim.events.overlap import overlapping_pairs  # noqa: PLC0415 -- lazy: off `orbitsim run`/`validate`

    pairs = overlapping_pairs(scenario.positions, scenario.radii)
    if not pairs:
        return
    i, j, distance, reach = pairs[0]
    names = scenario.names
    more = f" (and {len(pairs) - 1} more pair{'s' if len(pairs) > 2 else ''})" if len(pairs) > 1 else ""
    origins = scenario.origins
    raise ScenarioError(f"bodies {names[i]!r} and {names[j]!r} overlap at the start: their centres are {distance:.6g} "
                        f"apart, less than r_i + r_j = {reach:.6g}{more}; move them apart or give smaller radii, or "
                        "add events: {collisions: {resolve: merge}} (or halt, or log) to treat it as a collision at "
                        "step 0", file=scenario.source, key=origins[j] if origins else f"bodies[{j}]")



def check_initial_state(scenario: Scenario) -> None:
    """Refuse a state whose first sample (T, U, E0 = T + U, momentum, angular momentum) is not finite.

    Finite masses, positions and velocities (checked when the scenario was built) can still overflow
    float64 in a product: ``m: 1e300`` gives G m m / r = inf. The run would then store E0 = -inf and
    a |dE/E| of nan at every sample. Cost: O(N) for T, P and L; U is O(N) too when softening bounds
    it (each pair term is at most G m_i m_j / eps), else computed as the run computes it.

    Raises
    ------
    ScenarioError
        Naming the body (``bodies[1].m``) whose product overflows, or ``bodies`` for a sum.
    """
    m, x, v = scenario.masses, scenario.positions, scenario.velocities
    with np.errstate(all="ignore"):  # overflow is what is looked for here: no RuntimeWarning on stderr
        v2 = v[:, 0] * v[:, 0] + v[:, 1] * v[:, 1] + v[:, 2] * v[:, 2]
        cross = np.cross(x, v)
        # what, its terms per body, and the factor to blame when that factor alone is not finite
        for what, terms, factor, part in (("kinetic energy m |v|^2 / 2", 0.5 * m * v2, v2, "v"),
                                          ("momentum m v", m[:, None] * v, v, "v"),
                                          ("angular momentum m x cross v", m[:, None] * cross, cross, "x")):
            _check_terms(scenario, what, terms, factor, part)
        if not math.isfinite(_potential(scenario)):
            _potential_error(scenario)


def _check_terms(scenario: Scenario, what: str, terms: np.ndarray, factor: np.ndarray, part: str) -> None:
    rows = terms.reshape(terms.shape[0], -1)
    bad = np.flatnonzero(~np.isfinite(rows).all(axis=1))
    if bad.size:
        i = int(bad[0])
        part = part if not np.isfinite(factor[i]).all() else "m"
        raise _state_error(scenario, _body_key(scenario, i, part),
                           f"the {what} of body {scenario.names[i]!r} overflows float64 (m = {scenario.masses[i]:g}, "
                           f"|x| = {_norm(scenario.positions[i]):g}, |v| = {_norm(scenario.velocities[i]):g})")
    if not np.isfinite(rows.sum(axis=0)).all():
        raise _state_error(scenario, _whole_key(scenario), f"the total {what.split(' m')[0]} overflows float64")


def _norm(vector: np.ndarray) -> float:
    """|vector| without overflow in the squares (|(1e200, 0, 0)| is 1e200, not inf)."""
    biggest = float(np.max(np.abs(vector)))
    return biggest * float(np.linalg.norm(vector / biggest)) if biggest > 0.0 else 0.0


def _potential(scenario: Scenario) -> float:
    """U of the initial state, or a finite stand-in where softening proves U finite."""
    m, G, eps = scenario.masses, scenario.G, scenario.softening
    n = m.shape[0]
    if n < 2:
        return 0.0
    total = float(np.sum(m))
    if eps > 0.0 and total / eps < _SAFE and G * (total / eps) * total < _SAFE:
        return 0.0  # every pair term G m_i m_j / sqrt(r^2 + eps^2) <= G m_i m_j / eps: the sum is bounded
    if n <= NUMPY_POTENTIAL_MAX_N:
        x = scenario.positions
        r = np.sqrt(((x[None, :, :] - x[:, None, :]) ** 2).sum(axis=2) + eps * eps)
        terms = np.triu(m[None, :] / np.where(r > 0.0, r, 1.0), k=1)  # r = 0 only on the diagonal here
        return float(-G * np.sum(m * terms.sum(axis=1)))

    import numba  # noqa: PLC0415 -- lazy: loads numba

    from orbitsim.physics.diagnostics import potential_energy, potential_rows_scratch  # noqa: PLC0415 -- lazy: loads numba
    from orbitsim.stopping import run_interruptible  # noqa: PLC0415 -- lazy: off `orbitsim validate`

    pos = np.ascontiguousarray(scenario.positions.T)
    # Minutes at N = 10^6: Ctrl-C stops it within milliseconds (orbitsim.stopping.run_interruptible).
    call = functools.partial(potential_energy, pos, m, G, eps * eps, potential_rows_scratch(n))
    return float(run_interruptible(call, numba.get_num_threads()))


def _potential_error(scenario: Scenario) -> None:
    """Name the first pair whose term G m_i m_j / r overflows (rows in numpy, within a pair budget)."""
    m, x, G, eps = scenario.masses, scenario.positions, scenario.G, scenario.softening
    budget = 5 * 10**7  # pairs: ~1 s of numpy, on an error path only; past it, no pair is named
    for i in range(m.shape[0] - 1):
        budget -= m.shape[0] - 1 - i
        if budget < 0:
            break
        r = np.sqrt(((x[i + 1:] - x[i]) ** 2).sum(axis=1) + eps * eps)
        terms = G * m[i] * (m[i + 1:] / r)
        bad = np.flatnonzero(~np.isfinite(terms))
        if bad.size:
            j = i + 1 + int(bad[0])
            part = "m" if not math.isfinite(G * m[i] * m[j]) else "x"
            raise _state_error(scenario, _body_key(scenario, j, part),
                               f"the potential energy G m m / r of bodies {scenario.names[i]!r} and "
                               f"{scenario.names[j]!r} overflows float64 (G = {G:g}, m = {m[i]:g} and {m[j]:g}, "
                               f"r = {r[j - i - 1]:g})")
    raise _state_error(scenario, _whole_key(scenario), "the total potential energy overflows float64")


def _state_error(scenario: Scenario, key: str, what: str) -> ScenarioError:
    return ScenarioError(f"the initial energy or momentum would not be finite: {what}; use units in which these "
                         "numbers are smaller", file=scenario.source, key=key)


def _body_key(scenario: Scenario, i: int, part: str) -> str:
    """Key of body ``i``: ``bodies[i].m`` for a listed body, its generator or ephemeris entry otherwise."""
    origins = scenario.origins
    origin = origins[i] if origins else f"bodies[{i}]"
    return f"{origin}.{part}" if origin.startswith("bodies[") else origin


def _whole_key(scenario: Scenario) -> str:
    origins = scenario.origins
    return origins[0] if origins and len(set(origins)) == 1 else "bodies"
