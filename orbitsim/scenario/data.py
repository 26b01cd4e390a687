"""What a scenario holds: :class:`ScenarioData`, the fields of a :class:`~orbitsim.scenario.Scenario`
and the quantities that follow from them alone.

:class:`~orbitsim.scenario.model.Scenario` is this record validated, with its behaviour (the
sampling plan, the resolved YAML text and its hash, overrides). The readers and writers that
:class:`Scenario` calls while validating or serialising itself (:mod:`~orbitsim.scenario.time_checks`,
:mod:`~orbitsim.scenario.overrides`, :mod:`~orbitsim.scenario.serialize`,
:mod:`~orbitsim.scenario.integrator_state`, :mod:`~orbitsim.scenario.forces`) take a
:class:`ScenarioData`, so none of them imports the class that calls it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from orbitsim.scenario.timing import adaptive_integrator, resolve_steps, run_span

__all__ = ["DEFAULT_SAMPLES", "ScenarioData"]

#: Without ``output.every`` or ``output.interval``, a run keeps about this many samples.
DEFAULT_SAMPLES = 1000


@dataclass(frozen=True, eq=False)
class ScenarioData:
    """The fields of a scenario; build a validated one, a :class:`~orbitsim.scenario.Scenario`, with
    :func:`~orbitsim.scenario.load_scenario`.

    Attributes
    ----------
    name, description : str
        ``name`` is also the default output file stem (``<name>.h5``).
    units : str
        Key of :data:`orbitsim.units.UNIT_SYSTEMS`.
    G : float
        Gravitational constant (the unit system's unless the file overrides it).
    integrator : str
        Canonical registry name.
    integrator_settings : dict
        Settings for the integrator, checked against its record's ``settings``.
    dt : float
        Fixed timestep (> 0); never shortened.
    steps : int
        Whole steps to take (resolved from ``t_end`` when the file gave that).
    t_end : float or None
        End time as the file gave it, else None; ``t_start + steps * dt <= t_end``.
    t_start : float
        Time of step 0 (default 0): sample n is at ``t_start + n * dt``.
    every : int or None
        Sample every K steps; None with ``interval`` None means about :data:`DEFAULT_SAMPLES`.
    interval : float or None
        Time between samples (on the last whole step not past each sample time).
    record_positions : bool
        Whether positions and velocities are stored at every sample.
    softening : float
        Plummer softening length (>= 0).
    frame : str
        The frame the file asked for; ``positions``/``velocities`` are already in it.
    names : tuple of str
        Unique body names.
    masses, positions, velocities : numpy.ndarray
        (N,), (N, 3), (N, 3) float64. Treat them as read-only; change them through
        :meth:`Scenario.with_overrides`. (They are not flagged read-only because Numba compiles a
        separate, uncached specialisation for read-only arrays, costing seconds per run.)
    source : str
        File path, bundled name or ``"<inline>"``: where error messages point.
    checkpoint_every, checkpoint_seconds : int or float or None
        ``output.checkpoint``: save a checkpoint once this many steps, or seconds of wall time,
        have passed since the last one (see ``docs/checkpoints.md``); None for neither.
    radii : numpy.ndarray or None
        (N,) body radii ``r`` for collisions; None when no body gave one (all zero).
    events : EventsConfig or None
        The ``events:`` section (:mod:`orbitsim.events`); None runs the plain fixed-dt loop.
    record_elements : bool
        ``output.elements``: store every body's osculating elements at every sample.
    elements_primary : str
        ``output.primary``: ``heaviest``, ``jacobi`` or a body name.
    forces : tuple of dict
        The ``forces:`` list, resolved (:mod:`orbitsim.scenario.forces`); empty for none.
    chaos : ChaosConfig or None
        ``output.chaos``: record MEGNO and the mLCE at every sample, from this initial variation
        (:mod:`orbitsim.scenario.chaos`); None for a run without the variational equations.
    device : str
        ``device``: ``cpu`` (the default) or ``gpu``, one CUDA GPU through numba-cuda
        (:mod:`orbitsim.gpu`; what it runs: :mod:`orbitsim.gpu.support`).
    """

    name: str
    description: str
    units: str
    G: float
    integrator: str
    integrator_settings: dict[str, Any]
    dt: float
    steps: int
    t_end: float | None
    every: int | None
    interval: float | None
    record_positions: bool | None
    softening: float
    frame: str
    names: tuple[str, ...]
    masses: np.ndarray = field(repr=False)
    positions: np.ndarray = field(repr=False)
    velocities: np.ndarray = field(repr=False)
    source: str = "<inline>"
    checkpoint_every: int | None = None
    checkpoint_seconds: float | None = None
    radii: np.ndarray | None = field(default=None, repr=False)
    events: Any = None
    record_elements: bool = False
    elements_primary: str = "heaviest"
    forces: tuple[dict[str, Any], ...] = ()
    t_start: float = 0.0  # time of step 0: sample n is at t_start + n * dt (orbitsim.scenario.timing)
    integrator_state: dict[str, Any] | None = None  # a scheme's own coordinates (orbitsim.scenario.integrator_state)
    chaos: Any = None  # output.chaos: a ChaosConfig (orbitsim.scenario.chaos), or None
    device: str = "cpu"  # where the run steps: cpu, or gpu (orbitsim.gpu)

    # -- derived quantities ------------------------------------------------------------------

    @property
    def n_bodies(self) -> int:
        """Number of bodies N."""
        return int(self.masses.shape[0])

    @property
    def dissipative(self) -> bool:
        """Whether a force adds or removes energy on purpose (``migration``): the energy error then
        measures the force, not the integrator (:attr:`orbitsim.forces.table.ForceSet.dissipative`)."""
        return any(entry["force"] == "migration" for entry in self.forces)

    @property
    def adaptive(self) -> bool:
        """Whether the integrator chooses its own steps (ias15 unless ``adaptive: false``)."""
        return adaptive_integrator(self.integrator, self.integrator_settings)

    @property
    def grid_dt(self) -> float:
        """The run loop's grid: ``dt`` for a fixed-step scheme; for an adaptive one the output
        interval (``output.interval``, or t_end / DEFAULT_SAMPLES), on which samples land exactly."""
        if not self.adaptive:
            return self.dt
        return self.interval if self.interval is not None else run_span(self.t_end, self.t_start) / DEFAULT_SAMPLES

    @property
    def run_settings(self) -> dict[str, Any]:
        """The integrator settings a run passes to its scheme: an adaptive one also gets its first
        trial step (``dt``) and where its last output interval ends (``t_end``)."""
        if not self.adaptive:
            return dict(self.integrator_settings)
        return {**self.integrator_settings, "first_dt": self.dt, "t_end": self.t_end}

    @property
    def end_time(self) -> float:
        """Time of the last step, ``t_start + steps * dt`` (<= ``t_end`` when that was given); ``t_end`` for
        an adaptive run, whose last sample lands on it exactly."""
        if self.adaptive:
            return float(self.t_end)
        return self.t_start + self.steps * self.dt

    @property
    def t_end_is_whole(self) -> bool:
        """False when ``t_end`` was given and is not a whole number of steps."""
        return self.t_end is None or resolve_steps(self.t_end, self.dt, self.t_start)[1]

    @property
    def sample_every(self) -> int | None:
        """The ``every`` actually used (the default when neither every nor interval was given)."""
        if self.interval is not None:
            return None
        if self.adaptive:
            return 1  # every output interval
        return self.every if self.every is not None else max(1, math.ceil(self.steps / DEFAULT_SAMPLES))

    @property
    def checkpoints(self) -> bool:
        """Whether ``output.checkpoint`` asks for periodic checkpoints."""
        return self.checkpoint_every is not None or self.checkpoint_seconds is not None
