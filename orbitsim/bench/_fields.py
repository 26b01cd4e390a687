"""Typed, located access to the keys of a matrix document (used by :mod:`orbitsim.bench.matrix`), and
the validated :class:`Group` every kind's reader and runner takes (here, below the readers of each kind,
so that they need not import the matrix module that dispatches to them).

Every failure raises :class:`BenchMatrixError`, whose ``str()`` is one line naming the file and
the key path, e.g. ``my_bench.yaml: groups[1].n[2]: expected an integer >= 2, got 'many'``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

__all__ = ["GENERATED_SYSTEMS", "BenchMatrixError", "Group", "Reader", "join"]

#: Systems the benchmark builds itself; anything else is passed to ``load_scenario``.
GENERATED_SYSTEMS = ("plummer", "planets", "planetesimals")


class BenchMatrixError(ValueError):
    """An invalid matrix; ``str()`` is one line: ``<file>: <key>: <reason>``."""

    def __init__(self, file: str, key: str, message: str) -> None:
        self.file = file
        self.key = key
        self.message = " ".join(str(message).split())
        super().__init__(self.message)

    def __str__(self) -> str:
        return ": ".join(part for part in (self.file, self.key, self.message) if part)


@dataclass(frozen=True)
class Group:
    """One validated group: its kind, name, repeat counts and kind-specific ``params``."""

    name: str
    kind: str
    repeats: int
    warmup: int
    params: dict[str, Any] = field(default_factory=dict)


class Reader:
    """Typed access to mapping keys that raises :class:`BenchMatrixError` with the key path."""

    def __init__(self, source: str) -> None:
        self.source = source

    def error(self, key: str, message: str) -> BenchMatrixError:
        return BenchMatrixError(self.source, key, message)

    def mapping(self, doc: Any, path: str, allowed: tuple[str, ...]) -> Mapping[str, Any]:
        if not isinstance(doc, Mapping):
            raise self.error(path or "(top level)", f"expected a mapping, got {type(doc).__name__}")
        for key in doc:
            if key not in allowed:
                raise self.error(join(path, str(key)), f"unknown key; valid keys: {', '.join(allowed)}")
        return doc

    def integer(self, g: Mapping[str, Any], key: str, path: str, default: int, *, minimum: int) -> int:
        return _as_int(self, g.get(key, default), join(path, key), minimum)

    def optional_integer(self, g: Mapping[str, Any], key: str, path: str, *, minimum: int) -> int | None:
        value = g.get(key)
        return None if value is None else _as_int(self, value, join(path, key), minimum)

    def integers(self, g: Mapping[str, Any], key: str, path: str, default: list[int] | None, *,
                 minimum: int) -> list[int]:
        value = g.get(key, default)
        if value is None:
            raise self.error(join(path, key), "is required")
        items = value if isinstance(value, list) else [value]
        if not items:
            raise self.error(join(path, key), "expected at least one value")
        return [_as_int(self, v, f"{join(path, key)}[{k}]", minimum) for k, v in enumerate(items)]

    def steps_by_n(self, g: Mapping[str, Any], path: str) -> dict[int, int]:
        """``{N: steps}`` for the orbitsim cases at those N (empty when absent)."""
        value = g.get("steps_by_n", {})
        if not isinstance(value, Mapping):
            raise self.error(join(path, "steps_by_n"), f"expected a mapping N: steps, got {value!r}")
        key = join(path, "steps_by_n")
        return {_as_int(self, n, f"{key}", 2): _as_int(self, k, f"{key}.{n}", 1) for n, k in value.items()}

    def number(self, g: Mapping[str, Any], key: str, path: str, default: float, *, allow_zero: bool = False) -> float:
        value = _yaml_number(g.get(key, default))
        ok = isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)
        if not ok or value < 0 or (value == 0 and not allow_zero):
            bound = ">= 0" if allow_zero else "> 0"
            raise self.error(join(path, key), f"expected a finite number {bound}, got {value!r}")
        return float(value)

    def flag(self, g: Mapping[str, Any], key: str, path: str, default: bool) -> bool:
        value = g.get(key, default)
        if not isinstance(value, bool):
            raise self.error(join(path, key), f"expected true or false, got {value!r}")
        return value

    def string(self, g: Mapping[str, Any], key: str, path: str, default: str) -> str:
        value = g.get(key, default)
        if not isinstance(value, str) or not value.strip():
            raise self.error(join(path, key), f"expected a non-empty string, got {value!r}")
        return value.strip()

    def strings(self, g: Mapping[str, Any], key: str, path: str, default: list[str], *,
                choices: tuple[str, ...] | None = None) -> list[str]:
        value = g.get(key, default)
        items = value if isinstance(value, list) else [value]
        if not items:
            raise self.error(join(path, key), "expected at least one value")
        for k, item in enumerate(items):
            if not isinstance(item, str) or (choices is not None and item not in choices):
                valid = f"; valid: {', '.join(choices)}" if choices else ""
                raise self.error(f"{join(path, key)}[{k}]", f"unexpected value {item!r}{valid}")
        return [str(item) for item in items]

    def integrator_names(self, g: Mapping[str, Any], key: str, path: str, default: list[str], *,
                         single: bool = False) -> list[str]:
        """orbitsim integrator names checked against the registry (``all`` allowed unless single)."""
        from orbitsim.integrators.registry import UnknownIntegratorError, get_spec  # noqa: PLC0415 -- lazy: loads numba

        if single and isinstance(g.get(key), list):
            raise self.error(join(path, key), "expected one integrator name, got a list")
        names = self.strings(g, key, path, default)
        if names == ["all"] and not single:
            return names
        for k, name in enumerate(names):
            try:
                get_spec(name)
            except UnknownIntegratorError as err:
                raise self.error(f"{join(path, key)}" + ("" if single else f"[{k}]"), str(err)) from None
        return names

    def system(self, g: Mapping[str, Any], path: str, default: str) -> tuple[str, int | None]:
        """The system name and, for a scenario, its number of bodies (generated systems: None)."""
        name = self.string(g, "system", path, default)
        if name in GENERATED_SYSTEMS:
            return name, None
        try:
            from orbitsim.bench.systems import scenario_size  # noqa: PLC0415 -- lazy: loads numpy

            return name, scenario_size(name)
        except Exception as err:  # any failure to load it is a matrix error at this key
            raise self.error(join(path, "system"), f"not {' or '.join(GENERATED_SYSTEMS)}, and not a "
                             f"loadable scenario: {err}") from None

    def sizes(self, g: Mapping[str, Any], key: str, path: str, fixed: int | None) -> list[int]:
        """Body counts: required for a generated system; a scenario fixes N (``n`` may repeat it)."""
        if fixed is None:
            return self.integers(g, key, path, None, minimum=2)
        sizes = self.integers(g, key, path, [fixed], minimum=2)
        if any(n != fixed for n in sizes):
            raise self.error(join(path, key), f"the scenario has {fixed} bodies; got {sizes}")
        return sizes


def _yaml_number(value: Any) -> Any:
    """YAML 1.1 reads ``2e9`` (no dot) as a string; accept it as the number that was meant."""
    if isinstance(value, str):
        try:
            return float(value)
        except ValueError:
            return value
    return value


def _as_int(r: Reader, value: Any, key: str, minimum: int) -> int:
    value = _yaml_number(value)
    if isinstance(value, float) and value.is_integer():
        value = int(value)  # YAML reads 1e6 as a float; a whole number is what was meant
    if not isinstance(value, int) or isinstance(value, bool) or value < minimum:
        raise r.error(key, f"expected an integer >= {minimum}, got {value!r}")
    return value


def join(path: str, key: str) -> str:
    return f"{path}.{key}" if path else key
