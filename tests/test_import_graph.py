"""No import circles among orbitsim's modules.

The graph is read from the source with :mod:`ast`, not from ``sys.modules``, so it counts every import a
module can make: at the top, inside functions, and under ``if TYPE_CHECKING:``. An edge ``a -> b`` means
module ``a`` contains an import that executes ``b``:

- ``import orbitsim.x.y`` and ``from orbitsim.x.y import name`` execute ``orbitsim.x.y``;
- ``from orbitsim.x import y`` executes ``orbitsim.x.y`` when ``y`` is a submodule, else ``orbitsim.x``;
- relative imports (``from . import y``, ``from ..x import y``) resolve against the importing module;
- ``importlib.import_module("orbitsim.x")`` with a literal name counts like ``import orbitsim.x``;
- importing ``orbitsim.x.y`` also executes the ``__init__`` of every package on the way
  (``orbitsim.x``), unless that package already encloses the importer (a submodule runs only after its
  package's ``__init__`` has begun, so that edge is already paid); a package named outright
  (``from orbitsim.x import name`` inside ``orbitsim.x.z``) always counts, since ``name`` must exist.

A circle is a path of such edges back to its start. The test names every strongly connected set of
modules and one concrete circle inside it with the file and line of each import, so the report says what
to cut. Why no circles: a module in a circle cannot be understood, tested, or imported on its own, and a
circle that is harmless today (an import inside a function) becomes an ImportError the day someone moves
that import to the top.
"""

from __future__ import annotations

import ast
import itertools
from dataclasses import dataclass
from pathlib import Path

PACKAGE_ROOT = Path(__file__).resolve().parents[1] / "orbitsim"


@dataclass(frozen=True)
class ImportEdge:
    """One import statement: ``importer`` executes ``target`` at ``path``:``line``."""

    importer: str
    target: str
    path: str
    line: int


def module_names(package_root: Path = PACKAGE_ROOT) -> dict[str, Path]:
    """Dotted name of every module under ``package_root`` (``orbitsim.x.__init__`` -> ``orbitsim.x``)."""
    names: dict[str, Path] = {}
    top = package_root.name
    for path in sorted(package_root.rglob("*.py")):
        parts = [top, *path.relative_to(package_root).with_suffix("").parts]
        if parts[-1] == "__init__":
            parts = parts[:-1]
        names[".".join(parts)] = path
    return names


def _is_package(name: str, modules: dict[str, Path]) -> bool:
    return modules[name].name == "__init__.py"


def _resolve_relative(importer: str, level: int, module: str | None, modules: dict[str, Path]) -> str:
    """Absolute name of ``from <level dots><module> import ...`` written in ``importer``."""
    base = importer.split(".")
    if not _is_package(importer, modules):
        base = base[:-1]  # a plain module's relative imports start from its package
    if level > 1:
        base = base[: len(base) - (level - 1)]
    return ".".join(base + ([module] if module else []))


def _literal_import_module(node: ast.Call) -> str | None:
    """The name in ``importlib.import_module("...")`` when it is a literal string, else None."""
    func = node.func
    called = func.attr if isinstance(func, ast.Attribute) else func.id if isinstance(func, ast.Name) else None
    if called != "import_module" or not node.args:
        return None
    first = node.args[0]
    return first.value if isinstance(first, ast.Constant) and isinstance(first.value, str) else None


def _targets_of(node: ast.AST, importer: str, modules: dict[str, Path]) -> list[str]:
    """The package modules that one AST node imports by name (empty for anything else)."""
    top = importer.split(".")[0]
    if isinstance(node, ast.Import):
        return [alias.name for alias in node.names if alias.name.split(".")[0] == top]
    if isinstance(node, ast.ImportFrom):
        source = _resolve_relative(importer, node.level, node.module, modules) if node.level else node.module
        if source is None or source.split(".")[0] != top:
            return []
        targets = []
        for alias in node.names:
            submodule = f"{source}.{alias.name}"
            targets.append(submodule if submodule in modules else source)
        return targets
    if isinstance(node, ast.Call):
        name = _literal_import_module(node)
        return [name] if name is not None and name.split(".")[0] == top else []
    return []


def import_edges(package_root: Path = PACKAGE_ROOT) -> list[ImportEdge]:
    """Every import edge between modules of the package, with where it is written."""
    modules = module_names(package_root)
    edges: list[ImportEdge] = []
    for importer, path in modules.items():
        tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
        relative_path = str(path.relative_to(package_root.parent))
        for node in ast.walk(tree):
            for target in _targets_of(node, importer, modules):
                parts = target.split(".")
                # The packages on the way run their __init__ first, unless they already enclose the importer.
                executed = [".".join(parts[:i]) for i in range(1, len(parts))] + [target]
                for name in executed:
                    encloses_importer = importer == name or importer.startswith(name + ".")
                    if name in modules and (name == target or not encloses_importer):
                        edges.append(ImportEdge(importer, name, relative_path, node.lineno))
    return edges


def _strongly_connected(graph: dict[str, set[str]]) -> list[list[str]]:
    """Tarjan's strongly connected components (iterative), each sorted; only those with a circle."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    on_stack: set[str] = set()
    stack: list[str] = []
    components: list[list[str]] = []
    counter = 0
    for root in sorted(graph):
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            advanced = False
            for child in children:
                if child not in index:
                    index[child] = low[child] = counter
                    counter += 1
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph[child]))))
                    advanced = True
                    break
                if child in on_stack:
                    low[node] = min(low[node], index[child])
            if advanced:
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.append(member)
                    if member == node:
                        break
                if len(component) > 1 or node in graph[node]:
                    components.append(sorted(component))
    return sorted(components)


def _one_circle(start: str, members: set[str], graph: dict[str, set[str]]) -> list[str]:
    """A shortest path start -> ... -> start inside one strongly connected set (breadth first)."""
    previous: dict[str, str] = {}
    frontier = [start]
    while frontier:
        following = []
        for node in frontier:
            for child in sorted(graph[node] & members):
                if child == start:
                    path = [node]
                    while path[-1] != start:
                        path.append(previous[path[-1]])
                    return [*reversed(path), start]
                if child not in previous:
                    previous[child] = node
                    following.append(child)
        frontier = following
    raise AssertionError(f"{start} is in a strongly connected set but no circle returns to it")


def import_circles(package_root: Path = PACKAGE_ROOT) -> list[str]:
    """One readable line block per circle: its modules and one concrete circle with file:line per edge."""
    edges = import_edges(package_root)
    graph: dict[str, set[str]] = {name: set() for name in module_names(package_root)}
    where: dict[tuple[str, str], str] = {}
    for edge in edges:
        graph[edge.importer].add(edge.target)
        where.setdefault((edge.importer, edge.target), f"{edge.path}:{edge.line}")
    reports = []
    for component in _strongly_connected(graph):
        circle = _one_circle(component[0], set(component), graph)
        steps = "\n".join(f"    {a} -> {b}  ({where[(a, b)]})" for a, b in itertools.pairwise(circle))
        reports.append(f"circle among {len(component)} modules: {', '.join(component)}\n{steps}")
    return reports


def test_the_package_has_no_import_circle() -> None:
    circles = import_circles()
    assert not circles, f"{len(circles)} import circle(s) in orbitsim:\n" + "\n".join(circles)


def test_the_graph_sees_every_kind_of_import(tmp_path: Path) -> None:
    """A small fake package with one circle per way of writing an import: each must be found."""
    root = tmp_path / "orbitsim"
    (root / "pkg").mkdir(parents=True)
    files = {
        "__init__.py": "",
        "pkg/__init__.py": "from orbitsim.pkg.reexported import thing\n",
        "pkg/reexported.py": "thing = 1\n",
        # inside a function, absolute
        "a.py": "def f():\n    import orbitsim.b\n",
        "b.py": "import orbitsim.a\n",
        # under TYPE_CHECKING, `from package import submodule`
        "c.py": "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from orbitsim import d\n",
        "d.py": "from orbitsim.c import name\n",
        # relative imports, one and two levels
        "pkg/e.py": "from . import f\n",
        "pkg/f.py": "from ..pkg.e import name\n",
        # a literal importlib.import_module
        "g.py": "import importlib\nimportlib.import_module('orbitsim.h')\n",
        "h.py": "from orbitsim import g\n",
        # a package __init__ that re-exports: importing pkg.reexported runs pkg/__init__ first
        "i.py": "from orbitsim.pkg.reexported import thing\n",
        "pkg/j.py": "import orbitsim.i\n",
        "pkg/uses_j.py": "",
    }
    files["pkg/__init__.py"] += "from orbitsim.pkg import j\n"
    for name, text in files.items():
        (root / name).write_text(text)
    circles = "\n".join(import_circles(root))
    assert "orbitsim.a, orbitsim.b" in circles
    assert "orbitsim.c, orbitsim.d" in circles
    assert "orbitsim.pkg.e, orbitsim.pkg.f" in circles
    assert "orbitsim.g, orbitsim.h" in circles
    assert "orbitsim.i, orbitsim.pkg, orbitsim.pkg.j" in circles
    # a submodule importing a sibling does not circle through its own package's __init__
    assert "orbitsim.pkg.reexported" not in circles
    assert "(orbitsim/a.py:2)" in circles
