"""The :class:`Scenario`: one validated, fully resolved run description.

A Scenario holds explicit Cartesian bodies (whatever the file used: elements, the ephemeris or a
generator), the whole-step count, and the sampling plan. Its :meth:`Scenario.to_yaml` text loads
back into a Scenario with the same bits, which is why a trace stores that text and its SHA-256.
"""

from __future__ import annotations

import dataclasses
import hashlib
import re
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from orbitsim.gpu.support import DEVICES, gpu_refusal
from orbitsim.integrators.rebound_names import leapfrog_order
from orbitsim.sampling import EveryPlan, IntervalPlan
from orbitsim.scenario.bodies import check_body_arrays, check_coincident
from orbitsim.scenario.data import DEFAULT_SAMPLES, ScenarioData
from orbitsim.scenario.direction import check_direction
from orbitsim.scenario.errors import ScenarioError
from orbitsim.scenario.events import check_elements_output, check_events, check_radii
from orbitsim.scenario.fields import check_number, describe
from orbitsim.scenario.overrides import resolve_overrides
from orbitsim.scenario.settings import check_settings
from orbitsim.scenario.time_checks import check_time
from orbitsim.scenario.timing import resolve_steps
from orbitsim.units import UNIT_SYSTEMS

if TYPE_CHECKING:
    from orbitsim.sampling import SamplePlan

__all__ = ["DEFAULT_SAMPLES", "FRAMES", "POSITIONS_MAX_N", "Scenario", "resolve_steps"]

#: ``output.positions`` defaults to true up to this many bodies (positions dominate a trace's size).
POSITIONS_MAX_N = 1000
FRAMES = ("as_given", "barycentric")
#: A name becomes the default output file name, so it must be a plain file name.
_NAME_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.+-]*$")


@dataclass(frozen=True, eq=False)
class Scenario(ScenarioData):
    """A validated scenario; build it with :func:`~orbitsim.scenario.load_scenario`.

    Its fields and the quantities that follow from them are those of
    :class:`~orbitsim.scenario.data.ScenarioData` (documented there); this class validates and
    normalises them on construction, and adds the sampling plan, the notes, the resolved YAML text,
    its SHA-256 and stored form, and :meth:`with_overrides`.
    """

    def __post_init__(self) -> None:
        try:
            self._validate()
        except ScenarioError as err:
            raise err.located(self.source) from None

    def _set(self, name: str, value: Any) -> None:
        object.__setattr__(self, name, value)  # frozen: only validation may normalise fields

    def _validate(self) -> None:
        self._validate_bodies()
        if not isinstance(self.name, str) or not _NAME_RE.match(self.name):
            raise ScenarioError(f"name must be a plain file name (letters, digits, _ . + -), got "
                                f"{describe(self.name)}", key="name")
        if not isinstance(self.description, str):
            raise ScenarioError(f"expected text, got {describe(self.description)}", key="description")

        if isinstance(self.units, str):  # unit-system names are case-insensitive, stored lower case
            self._set("units", self.units.strip().lower())
        if self.units not in UNIT_SYSTEMS:
            raise ScenarioError(f"unknown unit system {self.units!r}; valid: {', '.join(UNIT_SYSTEMS)}",
                                key="units")
        self._set("G", check_number(self.G, "G", positive=True))
        self._validate_integrator()
        self._validate_time()
        self._set("softening", check_number(self.softening, "softening", minimum=0.0))
        if self.frame not in FRAMES:
            raise ScenarioError(f"frame must be one of {', '.join(FRAMES)}, got {self.frame!r}", key="frame")
        if self.record_positions is None:
            self._set("record_positions", self.n_bodies <= POSITIONS_MAX_N)
        elif not isinstance(self.record_positions, bool):
            raise ScenarioError(f"expected true or false, got {describe(self.record_positions)}",
                                key="output.positions")
        check_coincident(self.positions, self.names, None, self.softening)
        self._validate_events()
        self._validate_forces()
        self._validate_chaos()
        check_direction(self.integrator, self.dt, self.events, self.forces)  # dt < 0: backwards, where possible
        self._validate_device()
        if self.integrator_state is not None:
            from orbitsim.scenario.integrator_state import check_integrator_state  # noqa: PLC0415 -- lazy: off `orbitsim validate`

            self._set("integrator_state", check_integrator_state(self.integrator_state, self.n_bodies))

    def _validate_forces(self) -> None:
        """Resolve the forces (again: a new integrator or new bodies may not fit them) and check that
        the integrator can apply each; the forces package is imported only when there are some."""
        if not self.forces:
            self._set("forces", ())
            return
        from orbitsim.forces.compat import check_run  # noqa: PLC0415 -- lazy: off `orbitsim run`/`validate`
        from orbitsim.scenario.forces import read_forces  # noqa: PLC0415 -- lazy: off `orbitsim run`/`validate`

        self._set("forces", read_forces(self.forces, self.names, self.units, masses=self.masses, G=self.G))
        for k, entry in enumerate(self.forces):
            refusal = check_run((entry["force"],), self.integrator, self.integrator_settings or {},
                                self.events is not None)
            if refusal is not None:
                raise ScenarioError(refusal, key=f"forces[{k}]")

    def _validate_chaos(self) -> None:
        """``output.chaos`` resolved, and refused in one line where the variational equations cannot run
        (:mod:`orbitsim.scenario.chaos`); nothing is imported for a scenario without it."""
        if self.chaos is None:
            return
        from orbitsim.scenario.chaos import check_chaos_run, read_chaos  # noqa: PLC0415 -- lazy: off `orbitsim run`

        self._set("chaos", read_chaos(self.chaos, self.names))
        check_chaos_run(self.integrator, self.integrator_settings or {}, self.forces, self.events is not None)

    def _validate_device(self) -> None:
        """``device``: cpu or gpu; on the GPU, what it does not carry is refused in one line naming what it
        does (:mod:`orbitsim.gpu.support`, which loads nothing of numba-cuda)."""
        if self.device not in DEVICES:
            raise ScenarioError(f"device must be one of {', '.join(DEVICES)}, got {describe(self.device)}",
                                key="device")
        refusal = gpu_refusal(self) if self.device == "gpu" else None
        if refusal is not None:
            raise ScenarioError(refusal[1], key=refusal[0])

    def _validate_events(self) -> None:
        self._set("radii", check_radii(self.radii, self.n_bodies))
        check_events(self.events, self.integrator)
        check_elements_output(self.record_elements, self.elements_primary, self.names)

    def _validate_bodies(self) -> None:
        arrays = check_body_arrays(self.masses, self.positions, self.velocities, self.names)
        for attr, value in zip(("masses", "positions", "velocities", "names"), arrays, strict=True):
            self._set(attr, value)

    def _validate_integrator(self) -> None:
        from orbitsim.integrators.registry import UnknownIntegratorError, get_integrator  # noqa: PLC0415 -- lazy: loads numba

        settings = self.integrator_settings or {}
        name = self.integrator
        if isinstance(settings, Mapping):  # REBOUND's leapfrog with `order: 4` is leapfrog4
            try:
                name, settings = leapfrog_order(name, dict(settings))
            except ValueError as err:
                raise ScenarioError(str(err), key="integrator.order") from None
        try:
            scheme = get_integrator(name)
        except UnknownIntegratorError as err:
            raise ScenarioError(str(err), key="integrator") from None
        self._set("integrator", scheme.spec.name)
        if not isinstance(settings, Mapping):
            raise ScenarioError(f"integrator settings must be a mapping, got {describe(settings)}",
                                key="integrator")
        self._set("integrator_settings", check_settings(scheme, dict(settings)))
        try:
            scheme.check_bodies(self.masses)  # a scheme's demands on the bodies (a central mass)
        except ValueError as err:
            raise ScenarioError(str(err), key="bodies") from None

    def _validate_time(self) -> None:
        for name, value in check_time(self).items():
            self._set(name, value)

    def sample_plan(self) -> SamplePlan:
        """The sampling plan: step 0 first, ``steps`` last, produced block by block."""
        if self.adaptive:
            return EveryPlan(self.steps, 1)  # the grid is the output grid
        if self.interval is not None:
            return IntervalPlan(self.steps, abs(self.dt), self.interval)  # backwards: the same steps
        return EveryPlan(self.steps, int(self.sample_every))

    def sample_steps(self) -> np.ndarray:
        """Step indices of the samples: 0 first, ``steps`` last (int64, increasing; the whole plan
        in memory, so prefer :meth:`sample_plan` for long runs)."""
        return self.sample_plan().steps()

    def notes(self) -> list[str]:
        """Things a user should know before running, one line each (may be empty)."""
        notes = []
        if self.integrator_state is not None:
            from orbitsim.scenario.integrator_state import mismatch_note  # noqa: PLC0415 -- lazy: off `orbitsim validate`

            notes += [note for note in (mismatch_note(self),) if note]
        if self.dissipative:
            notes.append("migration adds or removes energy on purpose: the energy error measures it, not the "
                         "integrator's error")
        if self.adaptive:
            return notes  # t_end is reached exactly, and every output interval is sampled
        if not self.t_end_is_whole:
            notes.append(f"t_end = {self.t_end:.10g} is not a whole number of steps of dt = {self.dt:g}: the run "
                         f"takes {self.steps} whole steps and ends at t = {self.end_time:.10g} "
                         "(a step is never shortened)")
        if self.interval is not None and self.interval < abs(self.dt):
            notes.append(f"output.interval = {self.interval:g} is shorter than dt = {self.dt:g}: every step "
                         "is sampled")
        return notes

    # -- serialisation -----------------------------------------------------------------------

    def to_dict(self) -> dict[str, Any]:
        """The fully resolved scenario as plain Python (what :meth:`to_yaml` writes; see
        :func:`orbitsim.scenario.serialize.scenario_to_dict`)."""
        from orbitsim.scenario.serialize import scenario_to_dict  # noqa: PLC0415 -- lazy: off `orbitsim validate`

        return scenario_to_dict(self)

    def to_yaml(self) -> str:
        """The fully resolved scenario as YAML text; loading it reproduces the same bits.

        The text is built once and kept (a 16k-body scenario takes a few tenths of a second),
        which is one more reason to treat the arrays as read-only.
        """
        cached = self.__dict__.get("_yaml")
        if cached is None:
            from orbitsim.scenario.serialize import scenario_to_yaml  # noqa: PLC0415 -- lazy: off `orbitsim validate`

            cached = scenario_to_yaml(self)
            self._set("_yaml", cached)
        return cached

    @property
    def sha256(self) -> str:
        """Hex SHA-256 of :meth:`to_yaml` (UTF-8): identifies what was run, not where it came from.

        Computed once; a large scenario's text is hashed line by line rather than built whole.
        """
        cached = self.__dict__.get("_sha256")
        if cached is None:
            if "_yaml" in self.__dict__ or self.stored_form()[1] is None:  # the text is at hand, or small
                cached = hashlib.sha256(self.to_yaml().encode("utf-8")).hexdigest()
            else:
                from orbitsim.scenario.serialize import scenario_text_sha256  # noqa: PLC0415 -- lazy: off `orbitsim validate`

                cached = scenario_text_sha256(self)
            self._set("_sha256", cached)
        return cached

    def stored_form(self) -> tuple[str, dict[str, np.ndarray] | None]:
        """What a trace or a checkpoint stores: the whole :meth:`to_yaml` text, or for a large
        scenario the text without its per-body rows and the rows as arrays (see
        :func:`orbitsim.scenario.serialize.stored_form`). Built once and kept."""
        cached = self.__dict__.get("_stored")
        if cached is None:
            from orbitsim.scenario.serialize import stored_form  # noqa: PLC0415 -- lazy: off `orbitsim validate`

            cached = stored_form(self, self.to_yaml)
            self._set("_stored", cached)
        return cached

    def with_overrides(self, **changes: Any) -> Scenario:
        """A new, re-validated Scenario with some fields replaced.

        ``steps`` clears ``t_end``; ``t_end`` (or a new ``dt`` when the scenario was given by
        ``t_end``) re-resolves ``steps``; ``every`` clears ``interval`` and vice versa; a
        different ``integrator`` (a name, or a mapping ``{name: ..., <settings>}``) drops the old
        integrator's settings unless ``integrator_settings`` is given. ``None`` values are ignored.

        Raises
        ------
        ScenarioError
            For an unknown field or an invalid value (naming the field).
        """
        fields = resolve_overrides(self, changes)
        new = dataclasses.replace(self, **fields)
        if not {"names", "masses", "positions", "velocities"} & fields.keys():
            new.remember_origins(self.origins)
        if fields.keys() <= {"source"}:  # not part of the text: its hash and stored form stay (seconds at 10^6 bodies)
            for kept in ("_yaml", "_sha256", "_stored"):
                if kept in self.__dict__:
                    new._set(kept, self.__dict__[kept])
        return new

    def remember_origins(self, origins: Any) -> None:
        """Record where each body came from in the file (``"bodies[2]"``, ``"generator"``), so a later
        check of the whole system (:mod:`orbitsim.preflight`) can name the key to fix.

        Not a field: it says nothing about what is run, so it is neither serialised nor hashed.
        """
        if origins is not None and len(origins) == self.n_bodies:
            self._set("_origins", tuple(origins))

    def remember_input(self, notes: Any) -> None:
        """Record what the file's numbers meant (angle unit, axes) for ``validate``; not serialised."""
        self._set("_input_notes", tuple(notes))

    @property
    def input_notes(self) -> tuple[str, ...]:
        """Lines on how the file's input was read (``angles in degrees (angles: deg)``); may be empty."""
        return self.__dict__.get("_input_notes", ())

    @property
    def origins(self) -> tuple[str, ...] | None:
        """Key path each body came from, when the scenario was loaded from a file; else None."""
        return self.__dict__.get("_origins")
