"""The one explicit, ordered list of orbitsim's integrators, and the name/alias lookup.

Adding a scheme: write its module (``SPEC``, ``step``, ``run``; the contract is in
:mod:`orbitsim.integrators.base`) and append the module's name, which is its ``SPEC.name``, to
:data:`MODULE_NAMES`. ``tests/test_registry.py`` then checks it as part of the whole.

The modules are imported when first asked for. Looking up a scheme by its name imports that
scheme alone, so a run's start-up does not pay for the other eight: importing them costs about
50 ms, 5% of a warm ``orbitsim run``, most of it the Wisdom-Holman operators. Looking up an alias,
or reading :data:`MODULES` or :data:`INTEGRATORS`, imports them all.
"""

from __future__ import annotations

import difflib
import functools
import importlib
from types import ModuleType
from typing import Any

from orbitsim.integrators.base import IntegratorSpec

#: Every integrator module's name, in the order ``orbitsim list integrators`` shows them.
MODULE_NAMES: tuple[str, ...] = (
    "euler",
    "semi_implicit_euler",
    "verlet",
    "leapfrog",
    "rk4",
    "leapfrog4",
    "leapfrog6",
    "leapfrog8",
    "wisdom_holman",
    "ias15",
    "trace",
)


def _module(name: str) -> ModuleType:
    return importlib.import_module(f"{__package__}.{name}")


@functools.cache
def _modules() -> tuple[ModuleType, ...]:
    return tuple(_module(name) for name in MODULE_NAMES)


@functools.cache
def _by_name() -> dict[str, ModuleType]:
    return {name: module for module in _modules() for name in module.SPEC.names}


def __getattr__(attr: str) -> Any:
    """``MODULES`` (every integrator module) and ``INTEGRATORS`` (their specs), in
    :data:`MODULE_NAMES` order, imported on first use."""
    if attr == "MODULES":
        return _modules()
    if attr == "INTEGRATORS":
        return tuple(module.SPEC for module in _modules())
    raise AttributeError(f"module {__name__!r} has no attribute {attr!r}")


class UnknownIntegratorError(ValueError):
    """Raised for a name that is neither an integrator nor an alias; lists the valid names."""


def valid_names() -> tuple[str, ...]:
    """Every accepted name and alias, sorted."""
    return tuple(sorted(_by_name()))


def _normalise(name: str) -> str:
    return name.strip().lower().replace("-", "_")


def get_module(name: str) -> ModuleType:
    """The module (``SPEC``, ``step``, ``run``) for an integrator name, alias or REBOUND name of the same
    scheme (``whfast``: :mod:`orbitsim.integrators.rebound_names`)."""
    from orbitsim.integrators.rebound_names import SAME_SCHEME

    key = _normalise(name) if isinstance(name, str) else ""
    key = SAME_SCHEME.get(key, key)
    if key in MODULE_NAMES:
        return _module(key)
    module = _by_name().get(key)
    if module is None:
        raise UnknownIntegratorError(_unknown_message(name, key))
    return module


def _unknown_message(name: Any, key: str) -> str:
    """One line for an unknown name: REBOUND's closest scheme, else the nearest valid name, then every name."""
    from orbitsim.integrators.rebound_names import SAME_SCHEME, closest_scheme

    specs = [m.SPEC for m in _modules()]
    names = ", ".join(spec.name for spec in specs)
    aliases = ", ".join(a for spec in specs for a in spec.aliases)
    rebound = closest_scheme(key) if key else None
    if rebound is not None:
        return f"unknown integrator {name!r}: REBOUND's {key} is not in orbitsim; {rebound} (valid names: {names})"
    close = difflib.get_close_matches(key, [*_by_name(), *SAME_SCHEME], n=1, cutoff=0.6) if key else []
    hint = f"; did you mean {close[0]!r}?" if close else ""
    return f"unknown integrator {name!r}{hint} (valid names: {names}; aliases: {aliases})"


def get_spec(name: str) -> IntegratorSpec:
    """The :class:`IntegratorSpec` for an integrator name or alias."""
    return get_module(name).SPEC


def canonical_name(name: str) -> str:
    """The registry name for a name or alias (``"kdk"`` -> ``"verlet"``)."""
    return get_spec(name).name
