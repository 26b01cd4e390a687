"""Integrator settings (``integrator: {name: ..., <settings>}``) checked against the scheme's schema."""

from __future__ import annotations

import math
from typing import Any

from orbitsim.scenario.errors import ScenarioError
from orbitsim.scenario.fields import describe, unknown_key_error

__all__ = ["check_settings"]


def check_settings(module: Any, settings: dict[str, Any]) -> dict[str, Any]:
    """Check integrator settings against the module's ``SETTINGS`` (key -> type(s) or allowed values).

    Unknown keys are errors. When the module has ``validate_settings(settings) -> dict`` (which may
    normalise values, fill in defaults and check combinations), it has the last word on values.
    Otherwise each rule is a type or tuple of types (an int is accepted where a float is
    expected, a bool never as a number), a tuple/list/set of allowed values, or a callable that
    returns the checked value or raises ``ValueError``.
    """
    schema = getattr(module, "SETTINGS", None) or {}
    name = module.SPEC.name
    for key in settings:
        if key not in schema:
            if not schema:
                raise ScenarioError(f"integrator {name!r} takes no settings", key=f"integrator.{key}")
            raise unknown_key_error(key, "integrator", ["name", *schema])
    validator = getattr(module, "validate_settings", None)
    if validator is not None:
        try:
            return dict(validator(settings))
        except (TypeError, ValueError) as err:
            blamed = next((k for k in schema if f"'{k}'" in str(err)), None)
            raise ScenarioError(str(err), key=f"integrator.{blamed}" if blamed else "integrator") from None
    return {key: _check_setting(schema[key], value, f"integrator.{key}") for key, value in settings.items()}


def _check_setting(rule: Any, value: Any, path: str) -> Any:
    types = rule if isinstance(rule, tuple) and all(isinstance(r, type) for r in rule) else None
    if isinstance(rule, type):
        types = (rule,)
    if types is not None:
        # A bool is an int to Python but never a number to a user; an int is a fine float.
        is_bool = isinstance(value, bool)
        if float in types and isinstance(value, int) and not is_bool:
            value = float(value)
        if not isinstance(value, types) or (is_bool and bool not in types):
            wanted = " or ".join(t.__name__ for t in types)
            raise ScenarioError(f"expected {wanted}, got {describe(value)}", key=path)
        if isinstance(value, float) and not math.isfinite(value):
            raise ScenarioError(f"must be a finite number, got {value}", key=path)
        return value
    if isinstance(rule, list | tuple | set | frozenset):
        # `False in (0, 3)` is true in Python; a user writing false did not mean 0.
        if value not in rule or (isinstance(value, bool) and not any(r is value for r in rule)):
            raise ScenarioError(f"must be one of {', '.join(map(str, rule))}, got {describe(value)}", key=path)
        return value
    if callable(rule):
        try:
            return rule(value)
        except (TypeError, ValueError) as err:
            raise ScenarioError(str(err), key=path) from None
    raise TypeError(f"{path}: unsupported SETTINGS rule {rule!r}")
