"""The one explicit, ordered list of orbitsim's integrators, and the name/alias lookup.

Adding a scheme: write its module (``SPEC``, ``step``, ``run``; the contract is in
:mod:`orbitsim.integrators.base`), import it here and append it to :data:`MODULES`.
``tests/test_registry.py`` then checks it as part of the whole.
"""

from __future__ import annotations

from types import ModuleType

from orbitsim.integrators import (
    euler,
    leapfrog,
    leapfrog4,
    leapfrog6,
    leapfrog8,
    rk4,
    semi_implicit_euler,
    verlet,
    wisdom_holman,
)
from orbitsim.integrators.base import IntegratorSpec

#: Every integrator module, in the order ``orbitsim list integrators`` shows them.
MODULES: tuple[ModuleType, ...] = (
    euler,
    semi_implicit_euler,
    verlet,
    leapfrog,
    rk4,
    leapfrog4,
    leapfrog6,
    leapfrog8,
    wisdom_holman,
)

INTEGRATORS: tuple[IntegratorSpec, ...] = tuple(module.SPEC for module in MODULES)

_BY_NAME: dict[str, ModuleType] = {name: module for module in MODULES for name in module.SPEC.names}


class UnknownIntegratorError(ValueError):
    """Raised for a name that is neither an integrator nor an alias; lists the valid names."""


def valid_names() -> tuple[str, ...]:
    """Every accepted name and alias, sorted."""
    return tuple(sorted(_BY_NAME))


def _normalise(name: str) -> str:
    return name.strip().lower().replace("-", "_")


def get_module(name: str) -> ModuleType:
    """The module (``SPEC``, ``step``, ``run``) for an integrator name or alias."""
    try:
        return _BY_NAME[_normalise(name)]
    except (KeyError, AttributeError):
        names = ", ".join(spec.name for spec in INTEGRATORS)
        raise UnknownIntegratorError(
            f"unknown integrator {name!r}; valid names: {names} (aliases: "
            + ", ".join(a for spec in INTEGRATORS for a in spec.aliases)
            + ")"
        ) from None


def get_spec(name: str) -> IntegratorSpec:
    """The :class:`IntegratorSpec` for an integrator name or alias."""
    return get_module(name).SPEC


def canonical_name(name: str) -> str:
    """The registry name for a name or alias (``"kdk"`` -> ``"verlet"``)."""
    return get_spec(name).name
