"""Safe YAML reading with key paths and line numbers, and deterministic YAML writing.

Reading: the document is *composed* into YAML nodes by a safe loader and converted to plain Python
by :func:`parse_yaml`, which walks the nodes itself. Walking them (rather than letting PyYAML
construct the document) is what lets every error name its key path (``bodies[2].v``) and line,
and catch duplicate keys, which PyYAML silently keeps the last of. Only the standard scalar tags
construct values; any tag that would build an object is refused. Two deviations from YAML 1.1,
both because scenario authors expect them:

* ``1e-3`` is a float (YAML 1.1 demands ``1.0e-3`` and would read a *string*);
* dates are not converted to ``datetime`` objects: ``epoch: 2000-01-01`` stays a string.

Writing: :func:`dump_value` emits flow-style YAML that is also JSON-compatible for strings, with
floats written by ``repr`` so that reading them back gives the same bits.
"""

from __future__ import annotations

import json
import math
import re
from typing import Any

import yaml

from orbitsim.scenario.errors import ScenarioError

__all__ = ["dump_value", "format_float", "parse_yaml"]

#: A document with more nodes than this is refused: it guards against alias "billion laughs"
#: expansion, and is far above any hand-written scenario (generators make large systems).
MAX_NODES = 5_000_000
#: Deeper nesting than this is not a scenario (and guards against recursive aliases).
MAX_DEPTH = 64

_MAP_TAG = "tag:yaml.org,2002:map"
_SEQ_TAG = "tag:yaml.org,2002:seq"
_FLOAT_TAG = "tag:yaml.org,2002:float"
_TIMESTAMP_TAG = "tag:yaml.org,2002:timestamp"
_SCALAR_TAGS = frozenset(f"tag:yaml.org,2002:{t}" for t in ("str", "int", "float", "bool", "null"))

_FLOAT_RE = re.compile(
    r"""^(?:[-+]?[0-9][0-9_]*\.[0-9_]*(?:[eE][-+]?[0-9]+)?
    |[-+]?[0-9][0-9_]*[eE][-+]?[0-9]+
    |[-+]?\.[0-9_]+(?:[eE][-+]?[0-9]+)?
    |[-+]?\.(?:inf|Inf|INF)
    |\.(?:nan|NaN|NAN))$""",
    re.X,
)

_BASE_LOADER: type = getattr(yaml, "CSafeLoader", yaml.SafeLoader)  # libyaml parses ~10x faster


class _Loader(_BASE_LOADER):  # type: ignore[misc, valid-type]
    """Safe loader: standard tags only, no timestamps, ``1e-3`` read as a float."""


_Loader.yaml_implicit_resolvers = {
    first: [(tag, regexp) for tag, regexp in resolvers if tag != _TIMESTAMP_TAG]
    for first, resolvers in yaml.SafeLoader.yaml_implicit_resolvers.items()
}
_Loader.add_implicit_resolver(_FLOAT_TAG, _FLOAT_RE, list("-+0123456789."))


def _syntax_error(err: yaml.YAMLError) -> str:
    """One line from a PyYAML error: the problem and where it is."""
    mark = getattr(err, "problem_mark", None) or getattr(err, "context_mark", None)
    problem = getattr(err, "problem", None) or str(err)
    context = getattr(err, "context", None)
    text = f"{context}: {problem}" if context else problem
    where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
    return f"YAML syntax error: {text}{where}"


def parse_yaml(text: str, source: str) -> tuple[Any, dict[str, int]]:
    """Parse one YAML document safely.

    Parameters
    ----------
    text : str
        The YAML text.
    source : str
        File name for error messages.

    Returns
    -------
    document : Any
        Plain Python (dict, list, str, int, float, bool, None).
    lines : dict[str, int]
        1-based line of every key path, e.g. ``{"bodies[0].m": 7}``.

    Raises
    ------
    ScenarioError
        For a syntax error, a duplicate key, a non-string key, a tag that is not a standard
        scalar tag, or a document that is too large or too deep.
    """
    loader = _Loader(text)
    try:
        node = loader.get_single_node()
        lines: dict[str, int] = {}
        walker = _Walker(loader, source, lines)
        return (walker.value(node, "", 0) if node is not None else None), lines
    except yaml.YAMLError as err:
        raise ScenarioError(_syntax_error(err), file=source) from None
    finally:
        loader.dispose()


class _Walker:
    """Converts composed nodes to Python while recording key paths and lines."""

    def __init__(self, loader: Any, source: str, lines: dict[str, int]) -> None:
        self.loader = loader
        self.source = source
        self.lines = lines
        self.nodes = 0

    def error(self, path: str, node: yaml.Node, reason: str) -> ScenarioError:
        return ScenarioError(reason, file=self.source, key=path or None, line=node.start_mark.line + 1)

    def value(self, node: yaml.Node, path: str, depth: int) -> Any:
        self.nodes += 1
        if self.nodes > MAX_NODES or depth > MAX_DEPTH:
            short = path if len(path) <= 60 else path[:60] + "..."
            raise self.error(short, node, f"document too large or too deeply nested (limits: {MAX_NODES} "
                             f"values, depth {MAX_DEPTH}); use a generator for large systems")
        if path:
            self.lines.setdefault(path, node.start_mark.line + 1)
        if isinstance(node, yaml.MappingNode):
            return self.mapping(node, path, depth)
        if isinstance(node, yaml.SequenceNode):
            if node.tag != _SEQ_TAG:
                raise self.error(path, node, f"tag {node.tag!r} is not allowed (plain lists only)")
            return [self.value(item, f"{path}[{i}]", depth + 1) for i, item in enumerate(node.value)]
        return self.scalar(node, path)

    def mapping(self, node: yaml.MappingNode, path: str, depth: int) -> dict[str, Any]:
        if node.tag != _MAP_TAG:
            raise self.error(path, node, f"tag {node.tag!r} is not allowed (plain mappings only)")
        out: dict[str, Any] = {}
        first_line: dict[str, int] = {}
        for key_node, value_node in node.value:
            key = self.scalar(key_node, path) if isinstance(key_node, yaml.ScalarNode) else key_node
            line = key_node.start_mark.line + 1
            if not isinstance(key, str):
                shown = "a list or mapping" if isinstance(key, yaml.Node) else repr(key)
                raise self.error(path, key_node, f"keys must be plain words, got {shown}")
            child = f"{path}.{key}" if path else key
            if key in out:
                raise ScenarioError(f"duplicate key {key!r} (first given on line {first_line[key]}); "
                                    "remove one of them", file=self.source, key=child, line=line)
            first_line[key] = line
            self.lines[child] = line
            out[key] = self.value(value_node, child, depth + 1)
        return out

    def scalar(self, node: yaml.Node, path: str) -> Any:
        if node.tag not in _SCALAR_TAGS:  # `!!python/...` and friends would build objects
            raise self.error(path, node, f"tag {node.tag!r} is not allowed (plain numbers, text, true/false "
                             "and null only)")
        try:
            return self.loader.construct_object(node, deep=True)
        except yaml.constructor.ConstructorError as err:
            raise self.error(path, node, f"cannot read value ({err.problem}); "
                             "only plain numbers, strings, booleans and null are allowed") from None
        except (ValueError, OverflowError) as err:  # e.g. an int too long to convert
            raise self.error(path, node, f"cannot read value: {err}") from None


def format_float(value: float) -> str:
    """``repr`` of a finite float, always with a ``.`` so any YAML 1.1 reader sees a float.

    ``repr`` is the shortest string that reads back to the same bits, which is what makes a
    resolved scenario reproduce a run exactly.
    """
    text = repr(float(value))
    if "." in text and "n" not in text:  # the common case; "n" catches inf and nan
        return text
    if not math.isfinite(value):
        raise ValueError(f"cannot write non-finite number {value!r}")
    mantissa, sep, exponent = text.partition("e")
    if "." not in mantissa:
        mantissa += ".0"
    return mantissa + (f"e{exponent}" if sep else "")


_PLAIN_KEY = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
#: Words YAML 1.1 reads as booleans or null: never written as plain keys.
_RESERVED_WORDS = frozenset("y n yes no on off true false null".split())


def _dump_key(key: str) -> str:
    """A mapping key: plain when it is a simple word, else quoted."""
    if _PLAIN_KEY.match(key) and key.lower() not in _RESERVED_WORDS:
        return key
    return json.dumps(key, ensure_ascii=False)


def dump_value(value: Any) -> str:
    """One-line flow YAML for a scalar, list or mapping of them (strings JSON-quoted)."""
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return format_float(value)
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False)
    if isinstance(value, dict):
        return "{" + ", ".join(f"{_dump_key(str(k))}: {dump_value(v)}" for k, v in value.items()) + "}"
    if isinstance(value, list | tuple):
        return "[" + ", ".join(dump_value(v) for v in value) + "]"
    if hasattr(value, "item"):  # numpy scalar
        return dump_value(value.item())
    raise TypeError(f"cannot write {type(value).__name__} as YAML")
