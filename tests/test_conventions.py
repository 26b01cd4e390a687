"""The house rules that a reviewer would otherwise have to remember, checked on every test run.

* **Every jitted function goes through** :mod:`orbitsim._jit`. Nothing outside it calls Numba's
  compilers (``njit``, ``jit``, ``vectorize``, ``guvectorize``, ``cfunc``, ``generated_jit``,
  ``stencil``, ``jit_module``, ``jitclass``, ``cuda.jit``), however they are imported or renamed: one
  module owns the flags (exact IEEE arithmetic, ``cache=True``, the error model), and a function
  compiled elsewhere would get Numba's defaults, uncached.
* **Its source is in the cache hash.** Numba's cache index watches only the file that holds a cached
  function, so a kernel keeps running the old machine code of a callee edited in another file;
  :mod:`orbitsim._jit` therefore keys the cache directory by a hash of the files named in
  ``_KERNEL_SOURCES``. Those must cover every module that defines a jitted function or a Numba
  extension (``overload``, ``intrinsic``, ...), and every module whose objects a jitted function
  reaches by import (a global is compiled in as a constant). The set is computed here from the
  source with :mod:`ast`, so a new kernel module outside the listed folders fails this test rather
  than serving stale code.
* **Extensions compile nothing of their own.** Every ``overload`` is declared ``inline="always"``:
  its body then becomes part of the cached jitted caller, with the caller's flags; a non-inlined
  overload is compiled separately under Numba's default flags (``error_model="python"``). And a
  process that finds the kernels in the cache compiles nothing: the same runs in a second process
  load every dispatcher from the cache (:func:`test_a_second_process_compiles_nothing`).
* **No module over** :data:`MAX_LINES` **lines** unless its docstring says why, in a paragraph that
  begins with :data:`WHY_LONG`. Split by concept, not by count; a carved-out module must not import
  the class it was carved from (``test_import_graph.py`` fails on the circle that would make).

Each detector is also run on a small fake source that breaks its rule, so none can pass by seeing
nothing.
"""

from __future__ import annotations

import ast
import functools
import json
import os
import subprocess
import sys
import textwrap
from dataclasses import dataclass
from pathlib import Path

import pytest


def _repo_root() -> Path:
    """The checkout's root (the folder of ``pyproject.toml``), wherever this file is moved in tests/."""
    here = Path(__file__).resolve()
    return next(p for p in here.parents if (p / "pyproject.toml").is_file())


ROOT = _repo_root()
PACKAGE = ROOT / "orbitsim"
JIT_MODULE = PACKAGE / "_jit.py"

#: Numba's entry points that compile a function; only :mod:`orbitsim._jit` may reach them.
NUMBA_COMPILERS = frozenset({"njit", "jit", "vectorize", "guvectorize", "cfunc", "generated_jit", "stencil",
                             "jit_module", "jitclass"})
#: Numba's extension API: allowed where it is the mechanism (hooks that compile to nothing, the stop
#: flag's intrinsic); what it defines is compiled into jitted callers, so its module must be hashed.
NUMBA_EXTENSIONS = frozenset({"overload", "overload_method", "overload_attribute", "overload_classmethod",
                              "intrinsic", "register_jitable", "lower_builtin", "type_callable", "typeof_impl",
                              "box", "unbox", "register_model", "make_attribute_wrapper"})

#: The size above which a module must say why it is one module.
MAX_LINES = 400
#: How that paragraph of the module docstring begins.
WHY_LONG = "Why one module:"


# -- names, as a module binds them ---------------------------------------------------------------------


def module_name(path: Path, root: Path = ROOT) -> str:
    parts = list(path.relative_to(root).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _bindings(tree: ast.Module, module: str, is_package: bool) -> dict[str, str]:
    """Local name -> dotted origin, for every import anywhere in the module (functions included)."""
    bound: dict[str, str] = {}
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.asname:
                    bound[alias.asname] = alias.name
                else:
                    head = alias.name.split(".")[0]
                    bound[head] = head
        elif isinstance(node, ast.ImportFrom):
            source = node.module or ""
            if node.level:
                base = module.split(".")
                base = base if is_package else base[:-1]
                base = base[: len(base) - (node.level - 1)]
                source = ".".join(base + ([source] if source else []))
            for alias in node.names:
                bound[alias.asname or alias.name] = f"{source}.{alias.name}"
    return bound


def _dotted(node: ast.AST, bound: dict[str, str]) -> str | None:
    """``numba.extending.overload`` for ``extending.overload`` after ``from numba import extending``."""
    if isinstance(node, ast.Name):
        return bound.get(node.id)
    if isinstance(node, ast.Attribute):
        head = _dotted(node.value, bound)
        return f"{head}.{node.attr}" if head else None
    if isinstance(node, ast.Call):
        return _dotted(node.func, bound)  # @overload(f, inline="always"), @jit(...)
    return None


@dataclass(frozen=True)
class Source:
    """One Python file: its dotted name, its tree and what its names are bound to."""

    path: Path
    module: str
    tree: ast.Module
    bound: dict[str, str]

    @classmethod
    def read(cls, path: Path, root: Path = ROOT) -> Source:
        return _read_source(path, root, path.stat().st_mtime_ns)

    def where(self, node: ast.AST) -> str:
        return f"{self.path.relative_to(ROOT) if self.path.is_relative_to(ROOT) else self.path}:{node.lineno}"


@functools.cache
def _read_source(path: Path, root: Path, mtime_ns: int) -> Source:
    """Parsed once per file version: several tests walk the same sources."""
    module = module_name(path, root)
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    return Source(path, module, tree, _bindings(tree, module, path.name == "__init__.py"))


def _python_files(*folders: Path) -> list[Path]:
    return sorted(p for folder in folders for p in folder.rglob("*.py") if ".venv" not in p.parts)


def jit_decorators(jit_module: Path = JIT_MODULE) -> frozenset[str]:
    """The decorators :mod:`orbitsim._jit` offers: its functions that call ``numba.njit`` themselves."""
    source = Source.read(jit_module, jit_module.parents[1])
    found = set()
    for node in source.tree.body:
        if isinstance(node, ast.FunctionDef) and any(
                isinstance(call, ast.Call) and _dotted(call.func, source.bound) == "numba.njit"
                for call in ast.walk(node)):
            found.add(f"orbitsim._jit.{node.name}")
    return frozenset(found)


# -- the detectors ---------------------------------------------------------------------------------------


def direct_compilers(source: Source) -> list[str]:
    """Every place that reaches one of Numba's compilers directly (an import of one counts)."""
    found = []
    for node in ast.walk(source.tree):
        names: list[str] = []
        if isinstance(node, ast.ImportFrom) and not node.level and (node.module or "").split(".")[0] == "numba":
            names = [f"{node.module}.{alias.name}" for alias in node.names]
        elif isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, (ast.Name, ast.Attribute)):
            names = [_dotted(node, source.bound) or ""]
        for name in names:
            parts = name.split(".")
            if parts[0] == "numba" and parts[-1] in NUMBA_COMPILERS:
                found.append(f"{source.where(node)} {name}")
    return sorted(set(found))


def _decorated_by(node: ast.AST, source: Source, wanted: frozenset[str]) -> list[str]:
    """The names in ``wanted`` among the decorators of a function or class ``node``."""
    if not isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
        return []
    return [name for d in node.decorator_list if (name := _dotted(d, source.bound) or "") in wanted]


#: :mod:`orbitsim._jit`'s wrappers of Numba's extension API (an always-inlined overload with jit's flags).
JIT_EXTENSIONS = frozenset({"orbitsim._jit.overload_inline"})


def _extension(name: str) -> bool:
    parts = name.split(".")
    return (parts[0] == "numba" and parts[-1] in NUMBA_EXTENSIONS) or name in JIT_EXTENSIONS


@dataclass(frozen=True)
class Kernels:
    """What one module compiles: its jitted functions and extensions, and the package modules they reach."""

    jitted: tuple[str, ...]
    extensions: tuple[str, ...]
    reaches: tuple[str, ...]


def kernels_of(source: Source, decorators: frozenset[str]) -> Kernels:
    """The jitted functions (decorated, or wrapped by a call such as ``run = jit(_run)``) and the
    Numba extensions that ``source`` defines, and the ``orbitsim`` objects their bodies name."""
    jitted, extensions, bodies = [], [], []
    functions = {n.name: n for n in ast.walk(source.tree) if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef))}
    for node in ast.walk(source.tree):
        if isinstance(node, ast.Call) and (name := _dotted(node.func, source.bound) or "") in decorators:
            jitted.append(f"{source.where(node)} {name}(...)")
            for arg in node.args:  # the function it compiles: a lambda, or one defined in this module
                wrapped = functions.get(arg.id) if isinstance(arg, ast.Name) else arg
                bodies.extend([wrapped] if isinstance(wrapped, (ast.Lambda, ast.FunctionDef)) else [])
        for name in _decorated_by(node, source, decorators):
            jitted.append(f"{source.where(node)} {name}")
            bodies.append(node)
        for d in getattr(node, "decorator_list", ()):
            name = _dotted(d, source.bound) or ""
            if _extension(name):
                extensions.append(f"{source.where(node)} {name}")
                bodies.append(node)
    reaches = set()
    for body in bodies:
        for node in ast.walk(body):
            name = _dotted(node, source.bound) if isinstance(node, (ast.Name, ast.Attribute)) else None
            if name and name.split(".")[0] == "orbitsim":
                reaches.add(name)
    return Kernels(tuple(jitted), tuple(extensions), tuple(sorted(reaches)))


def defining_module(dotted: str, modules: dict[str, Path]) -> str | None:
    """The module of ``orbitsim.a.b.name``: the longest prefix that is a module of the package."""
    parts = dotted.split(".")
    for k in range(len(parts), 0, -1):
        if ".".join(parts[:k]) in modules:
            return ".".join(parts[:k])
    return None


def hashed(path: Path, kernel_sources: tuple[str, ...], package: Path = PACKAGE) -> bool:
    """True when ``path`` is one of the files :func:`orbitsim._jit._source_hash` reads."""
    rel = path.relative_to(package).as_posix()
    return any(rel == part or rel.startswith(part.rstrip("/") + "/") for part in kernel_sources)


def uncovered_kernel_modules(package: Path, kernel_sources: tuple[str, ...], decorators: frozenset[str]) -> list[str]:
    """Every module with compiled code, or whose objects compiled code reaches, outside the hash."""
    sources = [Source.read(p, package.parent) for p in _python_files(package)]
    modules = {s.module: s.path for s in sources}
    missing = []
    for source in sources:
        kernels = kernels_of(source, decorators)
        if (kernels.jitted or kernels.extensions) and not hashed(source.path, kernel_sources, package):
            first = (kernels.jitted or kernels.extensions)[0]
            missing.append(f"{source.module} defines compiled code ({first}) but is not in _KERNEL_SOURCES")
        for name in kernels.reaches:
            owner = defining_module(name, modules)
            if owner and not hashed(modules[owner], kernel_sources, package):
                missing.append(f"{source.module}'s compiled code reaches {name}, whose module {owner} "
                               "is not in _KERNEL_SOURCES")
    return sorted(set(missing))


def overloads_not_inlined(source: Source) -> list[str]:
    """Every ``@overload`` (and its method/attribute kin) declared without ``inline="always"``."""
    found = []
    for node in ast.walk(source.tree):
        for d in getattr(node, "decorator_list", ()):
            name = _dotted(d, source.bound) or ""
            if name.split(".")[0] == "numba" and name.split(".")[-1].startswith("overload"):
                inline = [k.value for k in getattr(d, "keywords", ()) if k.arg == "inline"]
                if not (inline and isinstance(inline[0], ast.Constant) and inline[0].value == "always"):
                    found.append(f"{source.where(node)} {name}")
    return found


def long_modules(package: Path = PACKAGE, limit: int = MAX_LINES) -> list[str]:
    """Modules over ``limit`` lines whose docstring does not say why in a :data:`WHY_LONG` paragraph."""
    found = []
    for path in _python_files(package):
        text = path.read_text(encoding="utf-8")
        lines = len(text.splitlines())
        if lines <= limit:
            continue
        doc = ast.get_docstring(ast.parse(text)) or ""
        reason = next((p for p in doc.split("\n\n") if p.strip().startswith(WHY_LONG)), "")
        if len(reason.split()) < len(WHY_LONG.split()) + 8:  # a reason, not the bare heading
            found.append(f"{path.relative_to(package.parent)}: {lines} lines")
    return found


# -- the tests -------------------------------------------------------------------------------------------


def test_the_jit_module_offers_the_decorators_this_test_looks_for() -> None:
    assert {"orbitsim._jit.jit", "orbitsim._jit.jit_inline", "orbitsim._jit.jit_force"} <= jit_decorators()


def test_nothing_outside_the_jit_module_calls_numbas_compilers() -> None:
    found = [hit for path in _python_files(PACKAGE, ROOT / "tests", ROOT / "benchmarks") if path != JIT_MODULE
             for hit in direct_compilers(Source.read(path))]
    assert not found, "compile through orbitsim._jit's decorators (add one there if a new kind is needed):\n" + \
        "\n".join(found)


def test_every_module_with_compiled_code_is_in_the_cache_hash() -> None:
    from orbitsim._jit import _KERNEL_SOURCES

    for part in _KERNEL_SOURCES:  # a stale entry would silently hash nothing
        assert (PACKAGE / part).exists(), f"_KERNEL_SOURCES names {part}, which is not in the package"
    missing = uncovered_kernel_modules(PACKAGE, _KERNEL_SOURCES, jit_decorators())
    assert not missing, "add these to orbitsim._jit._KERNEL_SOURCES:\n" + "\n".join(missing)


def test_the_package_has_compiled_code_and_extensions_where_expected() -> None:
    """The detector sees the kernels that are there (else the coverage test could pass on nothing)."""
    decorators = jit_decorators()
    physics = kernels_of(Source.read(PACKAGE / "physics" / "gravity.py"), decorators)
    assert len(physics.jitted) >= 3
    assert kernels_of(Source.read(JIT_MODULE), decorators).extensions  # the stop flag's intrinsic and overload


def test_every_overload_is_inlined_into_its_cached_caller() -> None:
    found = [hit for path in _python_files(PACKAGE) for hit in overloads_not_inlined(Source.read(path))]
    assert not found, 'declare these overload(..., inline="always"):\n' + "\n".join(found)


def test_no_module_is_over_the_line_limit_without_saying_why() -> None:
    found = long_modules()
    assert not found, (f"over {MAX_LINES} lines: split by concept, or say why in a docstring paragraph "
                       f"beginning {WHY_LONG!r}:\n" + "\n".join(found))


# -- the detectors on sources that break each rule -------------------------------------------------------

FAKE_KERNELS = '''
"""A kernel module that breaks every rule."""
import numba
import numba as nb
from numba import njit as fast, prange
from numba.extending import overload
from orbitsim._jit import jit
from orbitsim import _jit
from orbitsim.units import G_SI
from .. import units


@numba.njit(cache=True)
def a(x):
    return x


@nb.vectorize
def b(x):
    return x


@jit
def c(x):
    return x * G_SI + units.AU


def _d(x):
    return x * units.YEAR


d = _jit.jit_force(_d)


@overload(len)
def e(x):
    return lambda x: 0


@_jit.overload_inline(abs)
def g(x):
    return lambda x: units.PC


def f():
    return numba.cuda.jit
'''


def _fake(tmp_path: Path, text: str = FAKE_KERNELS) -> tuple[Path, Source]:
    package = tmp_path / "orbitsim"
    (package / "kernels").mkdir(parents=True)
    for name in ("__init__.py", "units.py", "_jit.py", "kernels/__init__.py"):
        (package / name).write_text("", encoding="utf-8")
    (package / "_jit.py").write_text(JIT_MODULE.read_text(encoding="utf-8"), encoding="utf-8")
    path = package / "kernels" / "fake.py"
    path.write_text(textwrap.dedent(text), encoding="utf-8")
    return package, Source.read(path, tmp_path)


def test_the_detectors_see_each_kind_of_breach(tmp_path: Path) -> None:
    package, source = _fake(tmp_path)
    compilers = " ".join(direct_compilers(source))
    for name in ("numba.njit", "numba.vectorize", "numba.cuda.jit"):
        assert name in compilers, compilers
    kernels = kernels_of(source, jit_decorators())
    assert len(kernels.jitted) == 2 and len(kernels.extensions) == 2  # @jit c, _jit.jit_force(_d); e and g
    assert {"orbitsim.units.G_SI", "orbitsim.units.AU", "orbitsim.units.YEAR", "orbitsim.units.PC"} <= set(
        kernels.reaches)
    assert len(overloads_not_inlined(source)) == 1
    missing = "\n".join(uncovered_kernel_modules(package, ("_jit.py",), jit_decorators()))
    assert "orbitsim.kernels.fake defines compiled code" in missing and "module orbitsim.units" in missing
    assert not uncovered_kernel_modules(package, ("_jit.py", "kernels", "units.py"), jit_decorators())


def test_the_size_rule_wants_a_reason_not_a_heading(tmp_path: Path) -> None:
    package = tmp_path / "orbitsim"
    package.mkdir()
    body = "x = 1\n" * (MAX_LINES + 1)
    (package / "bare.py").write_text(f'"""Long.\n\n{WHY_LONG}\n"""\n{body}', encoding="utf-8")
    (package / "why.py").write_text(f'"""Long.\n\n{WHY_LONG} one table of coefficients, generated, that reads best '
                                    f'in one piece.\n"""\n{body}', encoding="utf-8")
    (package / "short.py").write_text(body[: 6 * MAX_LINES], encoding="utf-8")
    assert long_modules(package) == [f"orbitsim/bare.py: {MAX_LINES + 5} lines"]


# -- at run time -----------------------------------------------------------------------------------------

#: Runs every registered integrator a few steps plain, with every kind of event and with the first
#: force it accepts, then counts the compilations (cache misses) of every Numba dispatcher loaded.
_WARM_RUNS = r'''
import gc, json, tempfile
from pathlib import Path
from numba.core.caching import NullCache
from numba.core.dispatcher import Dispatcher
from orbitsim.integrators.registry import INTEGRATORS
from orbitsim.runner import run_scenario
from orbitsim.scenario import ScenarioError, scenario_from_dict

BODIES = [{"name": "star", "m": 1.0, "x": [0, 0, 0], "v": [0, 0, 0], "r": 0.005},
          {"name": "b", "m": 1e-3, "primary": "star", "a": 1.0, "e": 0.05, "M": 10, "r": 0.0005},
          {"name": "c", "m": 5e-4, "primary": "star", "a": 1.6, "e": 0.1, "inc": 2.0, "M": 200, "r": 0.0005}]
EVENTS = {"collisions": {"detect": "line", "resolve": "merge"}, "encounters": {"hill": 1.0},
          "escape": {"distance": 50.0, "action": "remove"}, "unresolved": {"eta": 0.05}}
FORCES = [[{"force": "gr_potential", "source": "star", "c": 100.0}], [{"force": "gr", "source": "star", "c": 100.0}]]
counts = {"plain": 0, "events": 0, "forces": 0}
with tempfile.TemporaryDirectory() as folder:
    for spec in INTEGRATORS:
        timing = ({"t_end": 0.05, "output": {"interval": 0.025}} if spec.adaptive
                  else {"steps": 20, "output": {"every": 10}})
        base = {"units": "au-yr-msun", "integrator": spec.name, "dt": 0.002, **timing, "bodies": BODIES}
        kinds = [("plain", {}), ("events", {"events": EVENTS}), *(("forces", {"forces": f}) for f in FORCES)]
        forced = False
        for k, (kind, extra) in enumerate(kinds):
            if kind == "forces" and forced:
                continue  # one forced run per scheme: the first force it accepts
            try:
                sc = scenario_from_dict({"name": f"w{k}", **base, **extra})
            except ScenarioError:
                continue  # this scheme takes no such force
            run_scenario(sc, Path(folder) / f"{spec.name}_{k}.h5", handle_signals=False)
            counts[kind] += 1
            forced = forced or kind == "forces"
hits, misses, uncached = 0, {}, []
for obj in gc.get_objects():
    if isinstance(obj, Dispatcher) and obj.py_func.__module__.split(".")[0] == "orbitsim":
        name = f"{obj.py_func.__module__}.{obj.py_func.__qualname__}"
        hits += sum(obj._cache_hits.values())
        if sum(obj._cache_misses.values()):
            misses[name] = sum(obj._cache_misses.values())
        if obj.overloads and isinstance(obj._cache, NullCache):
            uncached.append(name)
print(json.dumps({"schemes": len(INTEGRATORS), **counts, "hits": hits, "misses": misses, "uncached": uncached}))
'''


@pytest.mark.slow  # compiles and then loads a run of every kind in fresh processes (~40 s cold)
def test_a_second_process_compiles_nothing() -> None:
    """What a run compiles is stored, and a second process loads all of it: no closure, no
    dispatcher passed from Python, no uncached overload compiles anew on every start."""
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_DISABLE_JIT"}
    reports = []
    for _ in range(2):  # the first may compile and store; the second must only load
        done = subprocess.run([sys.executable, "-c", _WARM_RUNS], capture_output=True, text=True, timeout=900,
                              env=env, cwd=ROOT)
        assert done.returncode == 0, done.stderr[-3000:]
        reports.append(json.loads(done.stdout.strip().splitlines()[-1]))
    second = reports[1]
    assert second["plain"] == second["events"] == second["schemes"] >= 5 and second["forces"] >= 3, second
    assert second["hits"] > 0, second
    assert second["misses"] == {}, f"compiled again in a warm process: {second['misses']}"
    assert second["uncached"] == [], f"compiled with no on-disk cache: {second['uncached']}"
