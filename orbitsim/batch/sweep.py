"""Sweep files: load, validate and expand them into fully resolved, hashed cases.

A sweep file is YAML::

    name: integrators_vs_dt          # optional; default: the file's stem
    description: free text           # optional
    base: two_body_eccentric         # bundled name, path (relative to this file), or an inline mapping
    overrides:                       # optional; applied to every case first
      steps: 2000
    grid:                            # cartesian product, first key varies slowest ...
      integrator: [euler, verlet, leapfrog4]
      dt: [0.01, 0.005]
    # ... or an explicit list instead of `grid`:
    # cases:
    #   - {integrator: verlet, dt: 0.01}
    #   - {integrator: rk4, bodies.1.e: 0.9}

Keys of ``overrides``, ``grid`` and ``cases`` are dotted key paths into the base scenario's YAML
document (:mod:`orbitsim.batch.overrides`). Every case is validated by the scenario loader itself
(:func:`orbitsim.scenario.scenario_from_dict`) before anything runs, and an invalid case fails the
whole sweep with the sweep key that holds the bad value, e.g. ``sweep.yaml: grid.dt[2]: ...``.
With ``skip_invalid`` such a case (or one that repeats an earlier case's scenario) is kept aside
as an :class:`InvalidCase` instead, and the others make the sweep; an error of the file itself (its
layout, its base scenario, every case invalid) still fails it.

Each case's run id is the first :data:`RUN_ID_CHARS` hex digits of the SHA-256 of its fully resolved
scenario YAML, so it depends on the physics only: not on the case's position, the sweep's name or
how the value was written. Growing a grid and rerunning therefore reuses every run already done.
"""

from __future__ import annotations

import copy
import itertools
import re
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from orbitsim.batch.overrides import OverrideError, apply_override, path_components, paths_overlap
from orbitsim.data import SWEEPS, locate

__all__ = ["RUN_ID_CHARS", "Case", "InvalidCase", "Sweep", "SweepError", "load_sweep", "sweep_from_dict"]

#: Hex digits of the run id: 64 bits, so a collision within any sweep is never a practical concern.
RUN_ID_CHARS = 16

#: The name is the default output directory, so it must be a plain file name.
_NAME_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.+-]*$")
_TOP_KEYS = ("name", "description", "base", "overrides", "grid", "cases")


class SweepError(ValueError):
    """An invalid sweep file; ``str()`` is one line: ``<file>: <sweep key>: <reason> (line <n>)``."""

    def __init__(self, file: str, key: str, message: str, line: int | None = None) -> None:
        self.file = file
        self.key = key
        self.message = " ".join(str(message).split())
        self.line = line
        super().__init__(self.message)

    def __str__(self) -> str:
        text = ": ".join(part for part in (self.file, self.key, self.message) if part)
        return f"{text} (line {self.line})" if self.line else text


@dataclass(frozen=True)
class Case:
    """One run of a sweep.

    ``sha256`` is the scenario's (computed once: hashing a large resolved scenario is not free).
    ``params`` maps each swept key path to its value in this case; ``where`` maps the same key
    paths to the sweep-file location of the value (``grid.dt[2]``, ``cases[3].dt``).
    """

    index: int
    params: dict[str, Any]
    where: dict[str, str]
    scenario: Any
    sha256: str

    @property
    def run_id(self) -> str:
        """The first :data:`RUN_ID_CHARS` hex digits of :attr:`sha256`."""
        return self.sha256[:RUN_ID_CHARS]


@dataclass(frozen=True)
class InvalidCase:
    """A case that is not a valid scenario, kept aside by ``skip_invalid``; ``error`` says why."""

    index: int
    params: dict[str, Any]
    where: dict[str, str]
    error: SweepError

    @property
    def message(self) -> str:
        """The error without the file name: ``grid.dt[2]: must be > 0, got -0.5 (line 5)``."""
        return str(SweepError("", self.error.key, self.error.message, self.error.line))


@dataclass(frozen=True)
class Sweep:
    """A validated sweep: its cases in file order and the key paths that vary between them.

    ``cases`` are the valid cases; ``invalid`` is empty unless the sweep was loaded with
    ``skip_invalid``. Together they are every case of the file, each with its own ``index``.
    """

    name: str
    file: str
    text: str
    params: tuple[str, ...]
    cases: tuple[Case, ...]
    invalid: tuple[InvalidCase, ...] = ()


def load_sweep(path: str | Path, *, skip_invalid: bool = False) -> Sweep:
    """Read, validate and expand the sweep file at ``path``, or the bundled sweep of that name.

    A bundled sweep is named by its stem (``"integrators_dt"``; ``orbitsim list sweeps``); a file
    of that name in the working directory wins.

    The file is read by the scenario loader's YAML reader, so numbers such as ``1e-3`` mean the
    same in a sweep as in a scenario, duplicate keys are errors, and errors carry line numbers.
    With ``skip_invalid`` the invalid cases go to :attr:`Sweep.invalid` instead of failing it.

    Raises
    ------
    SweepError
        If the file is unreadable, malformed, or any case is not a valid scenario (with
        ``skip_invalid``: if no case is).
    """
    from orbitsim.scenario import ScenarioError  # noqa: PLC0415 -- lazy: loads yaml, numpy
    from orbitsim.scenario.yamlio import parse_yaml  # noqa: PLC0415 -- lazy: loads yaml, numpy

    try:
        found = locate(SWEEPS, path)
    except LookupError as err:
        raise SweepError(str(path), "", str(err)) from None
    label = str(path) if found == Path(path) else str(found)
    try:
        text = found.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as err:
        raise SweepError(label, "", f"cannot read sweep file ({getattr(err, 'strerror', None) or err})") from None
    try:
        doc, lines = parse_yaml(text, label)
    except ScenarioError as err:
        raise SweepError(label, err.key or "", err.reason, err.line) from None
    try:
        sweep = sweep_from_dict(doc, label, text=text, skip_invalid=skip_invalid)
    except SweepError as err:
        _locate(err, label, lines)
        raise
    for case in sweep.invalid:
        _locate(case.error, label, lines)
    return sweep


def _locate(err: SweepError, label: str, lines: dict[str, int]) -> None:
    if err.line is None and err.file == label:
        err.line = _line_of(err.key, lines)


def _line_of(key: str, lines: dict[str, int]) -> int | None:
    """Line of a sweep key path such as ``grid.dt[2]``, or of its nearest recorded ancestor."""
    key = key.split(" ")[0]  # "case 3 (...)" locations name no single key
    while key:
        if key in lines:
            return lines[key]
        cut = max(key.rfind("."), key.rfind("["))
        key = key[:cut] if cut > 0 else ""
    return None


def sweep_from_dict(doc: Any, file: str, *, text: str = "", skip_invalid: bool = False) -> Sweep:
    """Validate and expand a sweep document; ``file`` names it in errors and anchors relative paths.

    With ``skip_invalid`` a case that is not a valid scenario, or that repeats an earlier case's
    scenario, becomes an :class:`InvalidCase`; the sweep still fails when no case is valid.
    """
    if not isinstance(doc, dict):
        raise SweepError(file, "", "a sweep file must be a mapping with `base` and `grid` or `cases`")
    unknown = [k for k in doc if k not in _TOP_KEYS]
    if unknown:
        raise SweepError(file, str(unknown[0]), f"unknown key; valid keys: {', '.join(_TOP_KEYS)}")
    if ("grid" in doc) == ("cases" in doc):
        raise SweepError(file, "", "give exactly one of `grid` (a cartesian product) or `cases` (a list)")
    name = doc.get("name", Path(file).stem)
    if not isinstance(name, str) or not _NAME_RE.match(name):
        raise SweepError(file, "name", f"must be a plain file name (letters, digits, _ . + -), got {name!r}")
    base = _base_document(doc.get("base"), file)
    common = _mapping(doc.get("overrides", {}), file, "overrides")
    choices = list(_grid_cases(doc["grid"], file) if "grid" in doc else _listed_cases(doc["cases"], file))
    params = tuple(dict.fromkeys(p for values, _ in choices for p in values))
    cases: list[Case] = []
    invalid: list[InvalidCase] = []
    seen: dict[str, Case] = {}  # run id -> the first case with that scenario
    for index, (values, where) in enumerate(choices):
        settings = {**{p: (v, f"overrides.{p}") for p, v in common.items()},
                    **{p: (v, where[p]) for p, v in values.items()}}
        try:
            scenario = _resolve(base, settings, file, index)
            case = Case(index, values, where, scenario, str(scenario.sha256))
            _check_unique(case, seen, file)
        except SweepError as err:
            if not skip_invalid:
                raise
            invalid.append(InvalidCase(index, values, where, err))
            continue
        cases.append(seen.setdefault(case.run_id, case))
    if not cases:  # only with skip_invalid: a sweep with nothing to run is an invalid sweep
        raise invalid[0].error
    return Sweep(name=name, file=file, text=text, params=params, cases=tuple(cases), invalid=tuple(invalid))


def _mapping(value: Any, file: str, key: str) -> dict[str, Any]:
    if not isinstance(value, dict):
        raise SweepError(file, key, f"must be a mapping of key paths to values, got {type(value).__name__}")
    for path in value:
        if not isinstance(path, str) or not path_components(path):
            raise SweepError(file, f"{key}.{path}", "key paths must be non-empty strings such as `dt`")
    return value


def _grid_cases(grid: Any, file: str) -> Iterator[tuple[dict[str, Any], dict[str, str]]]:
    grid = _mapping(grid, file, "grid")
    if not grid:
        raise SweepError(file, "grid", "names no key paths to vary")
    for path, values in grid.items():
        if not isinstance(values, list) or not values:
            raise SweepError(file, f"grid.{path}", "must be a non-empty list of values")
    paths = list(grid)
    for combo in itertools.product(*(range(len(grid[p])) for p in paths)):
        values = {p: grid[p][i] for p, i in zip(paths, combo, strict=True)}
        yield values, {p: f"grid.{p}[{i}]" for p, i in zip(paths, combo, strict=True)}


def _listed_cases(cases: Any, file: str) -> Iterator[tuple[dict[str, Any], dict[str, str]]]:
    if not isinstance(cases, list) or not cases:
        raise SweepError(file, "cases", "must be a non-empty list of mappings")
    for i, entry in enumerate(cases):
        values = _mapping(entry if entry is not None else {}, file, f"cases[{i}]")
        yield dict(values), {p: f"cases[{i}].{p}" for p in values}


def _base_document(base: Any, file: str) -> tuple[dict[str, Any], str]:
    """The raw YAML document of the base scenario, and the label its errors name.

    A string is a path relative to the sweep file, else relative to the working directory, else
    the name of a bundled scenario (``orbitsim list scenarios``).
    """
    from orbitsim.scenario import ScenarioError, bundled_scenarios  # noqa: PLC0415 -- lazy: loads yaml, numpy
    from orbitsim.scenario.yamlio import parse_yaml  # noqa: PLC0415 -- lazy: loads yaml, numpy

    if base is None:
        raise SweepError(file, "base", "missing: name a bundled scenario, a scenario file, or give a mapping")
    if isinstance(base, dict):
        return base, ""
    if not isinstance(base, str) or not base:
        raise SweepError(file, "base", f"must be a scenario name, a path or a mapping, got {base!r}")
    candidates = [Path(file).parent / base, Path(base)]
    path = next((p for p in candidates if p.is_file()), None)
    bundled = bundled_scenarios()
    if path is None and base in bundled:
        path = bundled[base]
    if path is None:
        raise SweepError(file, "base", f"no scenario file or bundled scenario named {base!r}; "
                         f"bundled: {', '.join(bundled) or 'none'}")
    try:
        doc, _ = parse_yaml(path.read_text(encoding="utf-8"), str(path))
    except (OSError, UnicodeDecodeError) as err:
        raise SweepError(file, "base", f"cannot read {path}: {getattr(err, 'strerror', None) or err}") from None
    except ScenarioError as err:
        raise SweepError(file, "base", str(err)) from None
    if not isinstance(doc, dict):
        raise SweepError(file, "base", f"{path} is not a scenario (a YAML mapping)")
    return doc, str(path)


def _resolve(base: tuple[dict[str, Any], str], settings: dict[str, tuple[Any, str]], file: str,
             index: int) -> Any:
    """Apply one case's settings to a copy of the base document and validate it as a scenario."""
    from orbitsim.scenario import ScenarioError, scenario_from_dict  # noqa: PLC0415 -- lazy: loads yaml, numpy

    doc = copy.deepcopy(base[0])
    for path, (value, where) in settings.items():
        try:
            apply_override(doc, path, copy.deepcopy(value))
        except OverrideError as err:
            raise SweepError(file, where, err.message) from None
    try:
        return scenario_from_dict(doc, file)
    except ScenarioError as err:
        raise _blame(err, settings, base[1], file, index) from None


def _blame(err: Any, settings: dict[str, tuple[Any, str]], base_file: str, file: str, index: int) -> SweepError:
    """Point a scenario error at the sweep value that caused it; else at the base scenario.

    The swept key path sharing the longest prefix with the error's key path is blamed:
    ``grid.dt[2]`` for a bad ``dt``, ``grid.bodies.1[0]`` for an error in ``bodies[1].e``.
    """
    key = path_components(err.key or "")
    best, best_len, best_path = None, 0, ()
    for path, (_, where) in settings.items():
        overlap = paths_overlap(key, path_components(path))
        if overlap > best_len:
            best, best_len, best_path = where, overlap, path_components(path)
    if best is not None:
        reason = err.reason if key == best_path else f"{err.key}: {err.reason}"
        return SweepError(file, best, reason)
    context = _case_location(settings, index)
    if not base_file:  # an inline base: its keys are keys of this file
        return SweepError(file, f"base.{err.key}" if err.key else "base", f"{err.reason} (in {context})")
    located = ": ".join(p for p in (base_file, err.key, err.reason) if p)
    return SweepError(file, "base", f"{located} (in {context})")


def _case_location(settings: dict[str, tuple[Any, str]], index: int) -> str:
    located = [w for _, w in settings.values() if not w.startswith("overrides.")]
    return f"case {index} ({', '.join(located)})" if located else f"case {index}"


def _check_unique(case: Case, seen: dict[str, Case], file: str) -> None:
    """Two cases with one resolved scenario would race for one trace file: refuse up front."""
    other = seen.get(case.run_id)
    if other is not None:
        raise SweepError(
            file, _case_location({p: (None, w) for p, w in case.where.items()}, case.index),
            f"resolves to the same scenario as case {other.index} (run id {case.run_id}); "
            "remove one of them",
        )
