"""Scenarios: YAML files -> validated, frozen, fully resolved :class:`Scenario` objects.

The schema, with examples, is in ``docs/scenarios.md``. In short::

    name: two_body_circular
    units: nbody            # nbody (G = 1), au-yr-msun, au-day-msun, si; G: overrides
    integrator: verlet      # or {name: ..., <settings>}
    dt: 0.01
    steps: 10000            # or t_end: (whole steps that fit; a step is never shortened)
    output: {every: 10, positions: true}
    bodies:
      - {name: star, m: 1.0, x: [0, 0, 0], v: [0, 0, 0]}
      - {name: planet, m: 1.0e-3, primary: star, a: 1.0, e: 0.0, M: 0}

Typical use::

    from orbitsim.scenario import load_scenario
    scenario = load_scenario("figure_eight")          # a bundled name or a path
    faster = scenario.with_overrides(integrator="leapfrog4", dt=0.01)
    text = faster.to_yaml()                            # reloads to the same bits

Every problem raises :class:`ScenarioError`, whose one-line ``str()`` names the file, the key path
and what to fix, e.g. ``x.yaml: bodies[1].m: mass must be >= 0, got -1 (line 12)``.
Importing this package does not import numba; building a Scenario does (the integrator registry).
"""

from orbitsim.scenario.errors import ScenarioError
from orbitsim.scenario.loader import TOP_KEYS, bundled_scenarios, config_dir, load_scenario, scenario_from_dict
from orbitsim.scenario.model import DEFAULT_SAMPLES, FRAMES, POSITIONS_MAX_N, Scenario, resolve_steps
from orbitsim.scenario.timing import MAX_STEPS

__all__ = [
    "DEFAULT_SAMPLES",
    "FRAMES",
    "MAX_STEPS",
    "POSITIONS_MAX_N",
    "TOP_KEYS",
    "Scenario",
    "ScenarioError",
    "bundled_scenarios",
    "config_dir",
    "load_scenario",
    "resolve_steps",
    "scenario_from_dict",
]
