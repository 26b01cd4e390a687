"""``output.chaos``: the chaos indicators a run records, and the initial variation they start from.

A scenario asks for MEGNO and the mLCE (the Lyapunov exponent; :mod:`orbitsim.chaos`) with

    output:
      chaos: {indicator: megno, seed: 0}          # a tangent vector drawn from the seed (default 0)

or with the initial tangent vector given explicitly, per body by name (bodies left out start
with a zero variation):

    output:
      chaos:
        indicator: megno
        variation: {Jupiter: {dr: [1.0, 0.0, 0.0], dv: [0.0, 0.0, 0.0]}}

``seed`` follows REBOUND's ``init_megno(seed=...)`` convention as
:func:`orbitsim.chaos.megno.random_initial_variation` does (every body's six components drawn from
N(0, 1) and normalised to length 1, numpy's generator); ``variation`` reproduces any other start,
e.g. REBOUND's variational particle. Only ``megno`` is an indicator (it gives both MEGNO and the
mLCE, as REBOUND's ``megno()`` and ``lyapunov()`` come from the same sums).

What cannot run the variational equations is refused here in one line naming the key: a scheme (or
settings) without them (:func:`orbitsim.integrators.registry.chaos_refusal`'s words), a force whose
derivative is not built (never silently left out of the tangent equations), and an ``events``
section (a merge or a removal would change the tangent vector's bodies mid-run).
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from typing import Any, NamedTuple

import numpy as np

from orbitsim.scenario.errors import ScenarioError
from orbitsim.scenario.fields import Fields, describe, join_path

__all__ = ["CHAOS_KEYS", "INDICATORS", "TANGENT_CONVENTION", "ChaosConfig", "chaos_attrs", "chaos_to_dict",
           "check_chaos_run", "indicators_text", "read_chaos"]

#: The keys of ``output.chaos``.
CHAOS_KEYS = ("indicator", "seed", "variation")
#: Keys of one body's entry in ``output.chaos.variation``.
VARIATION_KEYS = ("dr", "dv")
#: The indicators a scenario may ask for (``megno`` records MEGNO and the mLCE).
INDICATORS = ("megno",)
#: What the tangent vector is, as a trace's attribute ``chaos_tangent_convention`` says it.
TANGENT_CONVENTION = ("first-order variations (dr, dv) of every body's inertial position and velocity, in the "
                      "scenario's units; MEGNO and the mLCE read (delta'.delta)/(delta.delta) over all bodies, as "
                      "REBOUND's megno() and lyapunov() do")


class ChaosConfig(NamedTuple):
    """``output.chaos`` resolved: the indicator and either a seed or an explicit (N, 6) variation."""

    indicator: str
    seed: int | None  #: None when ``variation`` is given
    variation: np.ndarray | None  #: (N, 6) rows dx dy dz dvx dvy dvz per body, or None

    def initial_tangent(self, n_bodies: int) -> tuple[np.ndarray, np.ndarray]:
        """The initial tangent vector ``(dpos, dvel)``, each (3, N): drawn from the seed, or as given."""
        if self.variation is None:
            from orbitsim.chaos.megno import random_initial_variation  # noqa: PLC0415 - lazy: loads numba

            return random_initial_variation(n_bodies, int(self.seed or 0))
        return np.ascontiguousarray(self.variation[:, :3].T), np.ascontiguousarray(self.variation[:, 3:].T)


def read_chaos(value: Any, names: Sequence[str]) -> ChaosConfig | None:
    """``output.chaos`` as given (a mapping, or an already resolved :class:`ChaosConfig`) resolved for
    the bodies ``names``; None when absent. Raises :class:`ScenarioError` naming the key."""
    if value is None:
        return None
    if isinstance(value, ChaosConfig):
        if value.variation is not None and value.variation.shape != (len(names), 6):
            raise ScenarioError(f"the variation was given for {value.variation.shape[0]} bodies, the scenario has "
                                f"{len(names)}", key="output.chaos.variation")
        return value
    section = Fields(value, "output.chaos", CHAOS_KEYS, "chaos section")
    indicator = section.string("indicator", "megno", choices=INDICATORS)
    section.one_of("seed", "variation", required=False)
    if section.has("variation"):
        return ChaosConfig(indicator, None, _read_variation(section, names))
    seed = section.raw("seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or not 0 <= seed < 2**63:
        raise section.error("seed", f"must be a whole number from 0 to 2**63 - 1, got {describe(seed)}")
    return ChaosConfig(indicator, int(seed), None)


def _read_variation(section: Fields, names: Sequence[str]) -> np.ndarray:
    """``variation: {BODY: {dr: [3], dv: [3]}, ...}`` as (N, 6) rows (zero for a body not named)."""
    given = section.raw("variation")
    path = section.key("variation")
    if not isinstance(given, Mapping) or not given:
        raise ScenarioError(f"expected a mapping of body names to {{dr: [x, y, z], dv: [x, y, z]}}, got "
                            f"{describe(given)}", key=path)
    rows = np.zeros((len(names), 6))
    for body, entry in given.items():
        if body not in names:
            raise ScenarioError(f"unknown body {body!r}; bodies: {', '.join(names[:20])}"
                                f"{' ...' if len(names) > 20 else ''}", key=join_path(path, str(body)))
        fields = Fields(entry, join_path(path, str(body)), VARIATION_KEYS, "variation of a body")
        k = list(names).index(body)
        for column, key in ((0, "dr"), (3, "dv")):
            if fields.has(key):
                rows[k, column:column + 3] = fields.vector3(key)
    if not np.any(rows != 0.0):
        raise ScenarioError("the initial variation is zero: MEGNO and the mLCE read the ratio (delta'.delta) / "
                            "(delta.delta), which needs a non-zero tangent vector", key=path)
    return rows


def chaos_to_dict(config: ChaosConfig, names: Sequence[str]) -> dict[str, Any]:
    """``output.chaos`` as the resolved scenario writes it (loading it back gives the same bits):
    the seed, or every body with a non-zero variation, in the bodies' order."""
    out: dict[str, Any] = {"indicator": config.indicator}
    if config.variation is None:
        out["seed"] = int(config.seed or 0)
    else:
        out["variation"] = {name: {"dr": [float(c) for c in row[:3]], "dv": [float(c) for c in row[3:]]}
                            for name, row in zip(names, config.variation, strict=True) if np.any(row != 0.0)}
    return out


def chaos_attrs(config: ChaosConfig, names: Sequence[str]) -> dict[str, Any]:
    """A trace's root attributes for ``output.chaos``: ``chaos_indicator``, ``chaos_seed`` or
    ``chaos_variation`` (JSON of :func:`chaos_to_dict`'s mapping) and ``chaos_tangent_convention``."""
    given = chaos_to_dict(config, names)
    attrs: dict[str, Any] = {"chaos_indicator": config.indicator}
    if "seed" in given:
        attrs["chaos_seed"] = given["seed"]
    else:
        attrs["chaos_variation"] = json.dumps(given["variation"])
    attrs["chaos_tangent_convention"] = TANGENT_CONVENTION
    return attrs


#: Short time-unit names for a line of text, by unit system.
_TIME_UNIT = {"nbody": "time units", "au-yr-msun": "yr", "au-day-msun": "d", "si": "s"}


def indicators_text(megno: float, mlce: float, units: str) -> str:
    """``MEGNO = 2.003, mLCE = 1.2e-06 /yr, Lyapunov time = 8.3e+05 yr``: the run's summary and
    ``orbitsim info``. A Lyapunov time is 1 / mLCE only where the mLCE is positive: a regular orbit's
    hovers about 0 (of either sign), so its line says no exponential growth was measured."""
    unit = _TIME_UNIT.get(units, "time units")
    per = f"/{unit}" if unit != "time units" else "per time unit"
    head = f"MEGNO = {megno:.6g}, mLCE = {mlce:.3g} {per}"
    if mlce > 0.0:
        return f"{head}, Lyapunov time = {1.0 / mlce:.3g} {unit}"
    return f"{head}, no Lyapunov time (mLCE <= 0: no exponential growth measured)"


def check_chaos_run(integrator: str, settings: Mapping[str, Any], forces: Sequence[Mapping[str, Any]],
                    has_events: bool) -> None:
    """Refuse, in one line naming the key, a run whose variational equations orbitsim cannot integrate
    (:func:`orbitsim.chaos.state.variational_refusal`)."""
    from orbitsim.chaos.state import variational_refusal  # noqa: PLC0415 - lazy: loads numba

    refusal = variational_refusal(integrator, dict(settings), [entry["force"] for entry in forces], has_events)
    if refusal is not None:
        key, why = refusal
        raise ScenarioError(why, key="output.chaos" if key == "integrator" else key)
