"""Integrator settings (``integrator: {name: ..., <settings>}``) checked against the scheme's record."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from orbitsim.scenario.errors import ScenarioError
from orbitsim.scenario.fields import unknown_key_error

if TYPE_CHECKING:
    from orbitsim.integrators.base import Integrator

__all__ = ["check_settings"]


def check_settings(scheme: Integrator, settings: dict[str, Any]) -> dict[str, Any]:
    """Check integrator settings against the scheme's ``settings`` and ``validate_settings``.

    Unknown keys are errors, named with the closest valid one. The scheme's ``validate_settings``
    (which normalises values, fills in defaults and checks combinations) has the last word on
    values; its ValueError becomes a ScenarioError at the key it names.
    """
    schema = scheme.settings
    name = scheme.spec.name
    for key in settings:
        if key not in schema:
            if not schema:
                raise ScenarioError(f"integrator {name!r} takes no settings", key=f"integrator.{key}")
            raise unknown_key_error(key, "integrator", ["name", *schema])
    try:
        return dict(scheme.validate_settings(settings))
    except (TypeError, ValueError) as err:
        blamed = next((k for k in schema if f"'{k}'" in str(err)), None)
        raise ScenarioError(str(err), key=f"integrator.{blamed}" if blamed else "integrator") from None
