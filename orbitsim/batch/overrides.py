"""Dotted key paths into raw scenario documents: ``integrator``, ``generator.seed``, ``bodies.1.e``.

A sweep never edits a :class:`~orbitsim.scenario.Scenario`; it edits the YAML document the scenario
was loaded from and validates the result with :func:`orbitsim.scenario.scenario_from_dict`. Working on
the raw document keeps one validator (the scenario's) and lets every error name a key path.

Rules for a path ``a.b.1.c``:

* components are separated by ``.``; a component that indexes a list must be a whole number
  ``0 <= i < len(list)`` (lists are never grown: a sweep varies bodies, it does not invent them);
* a missing mapping key is created (with empty mappings on the way), so a sweep can set an optional
  key the base scenario leaves at its default; the scenario's validator then rejects a misspelt one;
* the value ``null`` *removes* a mapping key, so that its default applies. That is how a sweep trades
  one key for its alternative, e.g. ``steps: null`` with ``t_end: 20`` (a scenario takes only one).
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from typing import Any

__all__ = ["OverrideError", "apply_override", "path_components", "paths_overlap"]

_INDEX_RE = re.compile(r"\[(\d+)\]")


class OverrideError(ValueError):
    """A dotted key path that does not fit the document; ``path`` is the offending path."""

    def __init__(self, path: str, message: str) -> None:
        super().__init__(message)
        self.path = path
        self.message = message


def path_components(path: str) -> tuple[str, ...]:
    """Split ``"bodies.1.e"`` (or ``"bodies[1].e"``) into ``("bodies", "1", "e")``.

    Both spellings are accepted so that a key path reported by the scenario validator can be
    compared with a key path written in a sweep file.
    """
    text = _INDEX_RE.sub(r".\1", str(path))
    return tuple(part for part in text.split(".") if part != "")


def paths_overlap(a: Sequence[str], b: Sequence[str]) -> int:
    """How closely two key paths are related: the length of their common prefix when one path
    contains the other (``bodies.1`` and ``bodies.1.e``) or both are keys of one mapping
    (``bodies.1.a`` and ``bodies.1.e``: changing ``e`` can make ``a`` invalid); else 0."""
    common = 0
    for x, y in zip(a, b, strict=False):
        if x != y:
            break
        common += 1
    nested = common == min(len(a), len(b))
    siblings = common >= 1 and common == len(a) - 1 == len(b) - 1
    return common if nested or siblings else 0


def _child(container: Any, part: str, done: str, path: str, create: bool) -> Any:
    """Step from ``container`` into ``part``; ``done`` is the path walked so far (for errors)."""
    where = done or "the scenario"
    if isinstance(container, list):
        if not part.isdigit():
            raise OverrideError(path, f"{where} is a list; {part!r} is not an index")
        index = int(part)
        if index >= len(container):
            raise OverrideError(path, f"{where} has {len(container)} entries; no index {index}")
        return container[index]
    if isinstance(container, dict):
        if part not in container:
            if not create:
                raise OverrideError(path, f"{where} has no key {part!r}")
            container[part] = {}
        return container[part]
    raise OverrideError(path, f"{where} is a {type(container).__name__}, not a mapping or list")


def apply_override(doc: dict[str, Any], path: str, value: Any) -> None:
    """Set ``doc[path] = value`` in place, following the dotted ``path``.

    Parameters
    ----------
    doc : dict
        A raw scenario document (as loaded from YAML); modified in place.
    path : str
        Dotted key path, e.g. ``"dt"``, ``"generator.seed"``, ``"bodies.1.e"``.
    value : object
        Any YAML value; it replaces whatever is at ``path``. ``None`` removes a mapping key.

    Raises
    ------
    OverrideError
        If ``path`` is empty, indexes past the end of a list, or walks into a scalar.
    """
    parts = path_components(path)
    if not parts:
        raise OverrideError(path, "empty key path")
    node: Any = doc
    for depth, part in enumerate(parts[:-1]):
        node = _child(node, part, ".".join(parts[:depth]), path, create=True)
    last = parts[-1]
    done = ".".join(parts[:-1])
    if isinstance(node, list):
        _child(node, last, done, path, create=False)  # validates the index
        node[int(last)] = value
    elif isinstance(node, dict):
        if value is None:
            node.pop(last, None)
        else:
            node[last] = value
    else:
        raise OverrideError(path, f"{done or 'the scenario'} is a {type(node).__name__}, not a mapping or list")
