"""The one explicit, ordered list of orbitsim's integrators, and the name/alias lookup.

Adding a scheme: write its module (its :class:`~orbitsim.integrators.base.Integrator` record, whose
contract is in :mod:`orbitsim.integrators.base`) and append ``(name, module)`` to :data:`SCHEMES`;
the module holds the record as the upper-case name (``verlet`` -> ``VERLET``). A family of schemes
may share one module (the four leapfrogs) or be a package (``ias15``, ``wisdom_holman``, ``trace``:
the package's ``__init__`` holds the record). ``tests/integrators/test_registry.py`` then checks it as part of
the whole.

The modules are imported when first asked for. Looking up a scheme by its name imports that
scheme's module alone, so a run's start-up does not pay for the others: importing them all costs
about 50 ms, 5% of a warm ``orbitsim run``, most of it the Wisdom-Holman operators. Looking up an
alias, or reading :data:`RECORDS` or :data:`INTEGRATORS`, imports them all.
"""

from __future__ import annotations

import difflib
import functools
import importlib
from typing import Any

from orbitsim.integrators.base import Integrator, IntegratorSpec
from orbitsim.integrators.rebound_names import SAME_SCHEME, closest_scheme

#: Every integrator, in the order ``orbitsim list integrators`` shows them: its name and the module
#: of ``orbitsim.integrators`` that holds its record.
SCHEMES: tuple[tuple[str, str], ...] = (
    ("euler", "euler"),
    ("semi_implicit_euler", "semi_implicit_euler"),
    ("verlet", "verlet"),
    ("leapfrog", "leapfrog"),
    ("rk4", "rk4"),
    ("leapfrog4", "leapfrog"),
    ("leapfrog6", "leapfrog"),
    ("leapfrog8", "leapfrog"),
    ("wisdom_holman", "wisdom_holman"),
    ("ias15", "ias15"),
    ("trace", "trace"),
)

#: Every integrator's name, in :data:`SCHEMES` order.
NAMES: tuple[str, ...] = tuple(name for name, _ in SCHEMES)
_MODULE_OF = dict(SCHEMES)


@functools.cache
def _record(name: str) -> Integrator:
    """The record of the scheme called ``name`` (a registry name), importing its module."""
    module = importlib.import_module(f"{__package__}.{_MODULE_OF[name]}")
    record = getattr(module, name.upper())  # declared, not optional: a module without it fails here
    if not isinstance(record, Integrator) or record.spec.name != name:
        raise TypeError(f"{module.__name__}.{name.upper()} is not the record of {name!r}")
    return record


@functools.cache
def _records() -> tuple[Integrator, ...]:
    return tuple(_record(name) for name in NAMES)


@functools.cache
def _by_name() -> dict[str, Integrator]:
    return {name: record for record in _records() for name in record.spec.names}


def __getattr__(attr: str) -> Any:
    """``RECORDS`` (every integrator's record) and ``INTEGRATORS`` (their specs), in
    :data:`SCHEMES` order, imported on first use."""
    if attr == "RECORDS":
        return _records()
    if attr == "INTEGRATORS":
        return tuple(record.spec for record in _records())
    raise AttributeError(f"module {__name__!r} has no attribute {attr!r}")


class UnknownIntegratorError(ValueError):
    """Raised for a name that is neither an integrator nor an alias; lists the valid names."""


def valid_names() -> tuple[str, ...]:
    """Every accepted name and alias, sorted."""
    return tuple(sorted(_by_name()))


def _normalise(name: str) -> str:
    return name.strip().lower().replace("-", "_")


def get_integrator(name: str) -> Integrator:
    """The record (``spec``, ``step``, ``run``, every hook) for an integrator name, alias or REBOUND
    name of the same scheme (``whfast``: :mod:`orbitsim.integrators.rebound_names`)."""
    key = _normalise(name) if isinstance(name, str) else ""
    key = SAME_SCHEME.get(key, key)
    if key in _MODULE_OF:
        return _record(key)
    record = _by_name().get(key)
    if record is None:
        raise UnknownIntegratorError(_unknown_message(name, key))
    return record


def _unknown_message(name: Any, key: str) -> str:
    """One line for an unknown name: REBOUND's closest scheme, else the nearest valid name, then every name."""
    specs = [record.spec for record in _records()]
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
    return get_integrator(name).spec


def canonical_name(name: str) -> str:
    """The registry name for a name or alias (``"kdk"`` -> ``"verlet"``)."""
    return get_spec(name).name


def chaos_schemes() -> tuple[str, ...]:
    """The names of the schemes with variational equations (a ``run_chaos``), in :data:`SCHEMES` order."""
    return tuple(record.spec.name for record in _records() if record.run_chaos is not None)


def chaos_refusal(name: str, settings: dict[str, Any] | None = None) -> str | None:
    """One line saying why scheme ``name`` with ``settings`` cannot run the variational equations
    (naming the schemes that can), or None when it can."""
    record = get_integrator(name)
    if record.run_chaos is None:
        return (f"integrator {record.spec.name!r} has no variational equations, so no chaos indicators; "
                f"schemes that have them: {', '.join(chaos_schemes())}")
    return record.check_chaos(record.validate_settings(settings))
