"""Typed, path-aware access to one mapping of a scenario document.

Every check a scenario file needs at the level of a single value lives here, so every message has
the same shape: ``<key path>: <what is wrong>, got <value>``. Unknown keys are errors, with the
closest valid key suggested (a misspelt ``stpes`` silently ignored would run the wrong thing).
"""

from __future__ import annotations

import difflib
import math
import numbers
from collections.abc import Iterable, Mapping
from typing import Any

import numpy as np

from orbitsim.scenario.errors import ScenarioError

__all__ = ["MAX_STEPS", "MISSING", "Fields", "check_count", "check_number", "describe", "join_path",
           "steps_limit_error", "unknown_key_error"]

#: The most steps a scenario may count: 2**53. A sample's time is ``step * dt`` in float64, which
#: holds every whole number exactly only up to 2**53; beyond it two steps can share one time (and
#: beyond 2**63 a step no longer fits the int64 ``step`` column at all). At 10^8 steps a second
#: this is still three years of stepping, so no real run is refused.
MAX_STEPS = 2**53


class _Missing:
    def __repr__(self) -> str:
        return "MISSING"


#: Default marking a required key.
MISSING: Any = _Missing()


def join_path(path: str, key: str | int) -> str:
    """``join_path("bodies", 2)`` -> ``"bodies[2]"``; ``join_path("output", "every")`` -> ``"output.every"``."""
    if isinstance(key, int):
        return f"{path}[{key}]"
    return f"{path}.{key}" if path else key


def describe(value: Any) -> str:
    """A short, readable rendering of a bad value for an error message."""
    kind = {bool: "boolean", str: "string", list: "list", dict: "mapping", type(None): "nothing"}
    for cls, name in kind.items():
        if type(value) is cls:
            text = repr(value) if cls is not dict else "{...}"
            text = text if len(text) <= 40 else text[:37] + "..."
            return f"{name} {text}" if cls not in (type(None),) else "nothing (null or empty)"
    return repr(value)


def unknown_key_error(key: str, path: str, allowed: Iterable[str]) -> ScenarioError:
    """Error for an unknown key, suggesting the closest valid one (``difflib``)."""
    allowed = list(dict.fromkeys(allowed))  # each key once, in first-seen order
    close = difflib.get_close_matches(key, allowed, n=1, cutoff=0.6)
    hint = f"did you mean {close[0]!r}?" if close else f"valid keys here: {', '.join(allowed)}"
    return ScenarioError(f"unknown key {key!r}; {hint}", key=join_path(path, key))


class Fields:
    """Reads the keys of one mapping, checking names, presence, types and ranges.

    Parameters
    ----------
    value : Any
        The mapping (anything else is an error naming ``path``).
    path : str
        Key path of the mapping (``""`` for the document root).
    allowed : Iterable[str]
        Every key the mapping may hold.
    what : str
        What the mapping is, for the "expected a mapping" message.
    """

    def __init__(self, value: Any, path: str, allowed: Iterable[str], what: str = "mapping") -> None:
        if not isinstance(value, Mapping):
            article = "an" if what[:1] in "aeiou" else "a"
            raise ScenarioError(f"expected {article} {what} of keys and values, got {describe(value)}",
                                key=path or None)
        self.data = value
        self.path = path
        self.allowed = tuple(allowed)
        for key in value:
            if key not in self.allowed:
                raise unknown_key_error(key, path, self.allowed)

    def key(self, name: str) -> str:
        """Key path of ``name`` in this mapping."""
        return join_path(self.path, name)

    def error(self, name: str, reason: str) -> ScenarioError:
        """An error about key ``name``."""
        return ScenarioError(reason, key=self.key(name))

    def has(self, name: str) -> bool:
        """Whether ``name`` is given (a null value counts as not given)."""
        return self.data.get(name) is not None

    def raw(self, name: str, default: Any = MISSING) -> Any:
        """The value of ``name`` unchecked, or ``default``; a missing required key is an error."""
        if self.has(name):
            return self.data[name]
        if default is MISSING:
            raise self.error(name, f"required key {name!r} is missing")
        return default

    def number(self, name: str, default: Any = MISSING, *, minimum: float | None = None,
               positive: bool = False) -> float:
        """A finite float, optionally ``> 0`` (``positive``) or ``>= minimum``."""
        value = self.raw(name, default)
        return value if value is None else check_number(value, self.key(name), minimum=minimum, positive=positive)

    def integer(self, name: str, default: Any = MISSING, *, minimum: int | None = None,
                steps: bool = False) -> int:
        """A whole number (``1000`` or ``1e3``), optionally ``>= minimum``; a count of ``steps`` is at
        most :data:`MAX_STEPS`."""
        value = self.raw(name, default)
        if value is None:
            return value
        number: float | int = check_number(value, self.key(name))
        if isinstance(value, int | np.integer) and not isinstance(value, bool):
            number = int(value)  # exact: as a float, 2**53 + 1 would round to 2**53
        elif number != math.floor(number):
            raise self.error(name, f"must be a whole number, got {value}")
        if minimum is not None and number < minimum:
            raise self.error(name, f"must be >= {minimum}, got {value}")
        if steps and number > MAX_STEPS:
            raise steps_limit_error(f"{value} steps", self.key(name), _steps_fix(self.key(name)))
        return int(number)

    def string(self, name: str, default: Any = MISSING, *, choices: Iterable[str] | None = None,
               fold_case: bool = False) -> str:
        """A string, optionally one of ``choices``; with ``fold_case`` any case of a choice gives that
        choice (``AU-yr-Msun`` -> ``au-yr-msun``)."""
        value = self.raw(name, default)
        if value is None:
            return value
        if not isinstance(value, str):
            raise self.error(name, f"expected text, got {describe(value)}")
        if choices is not None:
            options = list(choices)
            if fold_case:
                value = next((o for o in options if o.casefold() == value.casefold()), value)
            if value not in options:
                close = difflib.get_close_matches(value, options, n=1, cutoff=0.6)
                hint = f"did you mean {close[0]!r}?" if close else f"valid values: {', '.join(options)}"
                raise self.error(name, f"unknown value {value!r}; {hint}")
        return value

    def boolean(self, name: str, default: Any = MISSING) -> bool:
        """``true`` or ``false``."""
        value = self.raw(name, default)
        if value is not None and not isinstance(value, bool):
            raise self.error(name, f"expected true or false, got {describe(value)}")
        return value

    def vector3(self, name: str) -> list[float]:
        """A list of three finite numbers."""
        value = self.raw(name)
        if not isinstance(value, list | tuple) or len(value) != 3:
            raise self.error(name, f"expected a list of 3 numbers [x, y, z], got {describe(value)}")
        return [check_number(item, join_path(self.key(name), i)) for i, item in enumerate(value)]

    def one_of(self, *names: str, required: bool = True) -> str | None:
        """The one key of ``names`` that is given; both, or neither when ``required``, is an error."""
        given = [n for n in names if self.has(n)]
        if len(given) > 1:
            raise ScenarioError(f"give only one of {' or '.join(names)}, not both",
                                key=self.key(given[1]))
        if not given and required:
            where = f" in {self.path}" if self.path else ""
            raise ScenarioError(f"give one of {' or '.join(names)}{where}", key=self.path or None)
        return given[0] if given else None


def check_number(value: Any, key: str, *, minimum: float | None = None, positive: bool = False) -> float:
    """``value`` as a finite float, with the range checks of :meth:`Fields.number`."""
    # numbers.Real admits numpy scalars (sweeps build documents with them); bool is never a number.
    if isinstance(value, bool | np.bool_) or not isinstance(value, numbers.Real):
        raise ScenarioError(f"expected a number, got {describe(value)}", key=key)
    try:
        number = float(value)
    except OverflowError:
        raise ScenarioError(f"number too large: {value}", key=key) from None
    if not math.isfinite(number):
        raise ScenarioError(f"must be a finite number, got {number}", key=key)
    if positive and number <= 0.0:
        raise ScenarioError(f"must be > 0, got {value}", key=key)
    if minimum is not None and number < minimum:
        raise ScenarioError(f"must be >= {minimum:g}, got {value}", key=key)
    return number


def check_count(value: Any, key: str) -> int:
    """``value`` as a count of steps: a whole number from 1 to :data:`MAX_STEPS`
    (a Python or numpy integer; never a bool)."""
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
        raise ScenarioError(f"must be a whole number >= 1, got {describe(value)}", key=key)
    if value > MAX_STEPS:
        raise steps_limit_error(f"{value} steps", key, _steps_fix(key))
    return int(value)


def _steps_fix(key: str) -> str:
    """How to fix a step count beyond the limit, by its key."""
    fixes = {"output.every": "sample more often", "output.checkpoint.every": "checkpoint more often"}
    return fixes.get(key, "shorten the run or use a longer dt")


def steps_limit_error(what: str, key: str, fix: str = "shorten the run or use a longer dt") -> ScenarioError:
    """The error for a step count beyond :data:`MAX_STEPS`; ``what`` says what was counted."""
    return ScenarioError(f"{what} is beyond the limit of {MAX_STEPS} steps (2**53: sample times step * dt are "
                         f"exact in float64 only up to there); {fix}", key=key)
